# Copyright 2026 gyro_platform developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.


"""The start of both transports (rclpy ``node`` and plain-DDS ``dds``): the core, warmed up.

:func:`start_core` makes the node's :class:`~gyro_platform.ros.core.NodeCore` and warms it up
(:func:`warm_up`: a few synthetic samples through a throwaway core of the same configuration
before the node subscribes, so that numba loads every kernel the first real samples need from
its cache). When a kernel is missing from the cache (a first run of this code and configuration
on this machine: 20–60 s of compiling) it does not wait: the core's simulator answers from the
interpreted kernels in a helper process while a second one compiles them, then moves to the
compiled ones in the same state (``engine.remote``), so the node is ready in about a second
either way. :func:`freeze_startup_objects` then moves the start-up objects out of the garbage
collector's reach. Imports nothing of the transports (they and the ``gyro-platform node``
command import it: no circle in ``ros/``).
"""
from __future__ import annotations

import gc
import sys
from typing import Any, Callable

from .core import NodeCore
from ..engine.blas import limit_blas_threads

WARMUP_SAMPLES = 6
WARMUP_PERIOD_NS = 10_000_000      # 100 Hz


def warm_up(core: Any, make_input: Callable[[], Any], encode: Callable[[str, Any], None] | None = None) -> int:
    """Run ``WARMUP_SAMPLES`` synthetic input samples (at rest, 1 g up, 100 Hz) through a
    throwaway core of the same configuration, so that numba compiles (or loads from its cache)
    every kernel the first real samples need, before the node subscribes and says "ready".
    ``make_input()`` returns a zeroed input message of the binding; ``encode(topic, msg)``, if
    given, serialises each output (the DDS encoders). Returns the number of output messages."""
    limit_blas_threads()        # before any matrix is built (engine.blas)
    scratch = type(core)(core.config, core.types, simulator=core.make_simulator)
    n = 0
    t0 = 1_000_000_000
    for k in range(WARMUP_SAMPLES):
        msg = make_input()
        header = getattr(msg, "header", None)
        if header is not None:
            header.stamp.sec, header.stamp.nanosec = divmod(t0 + k * WARMUP_PERIOD_NS, 1_000_000_000)
            header.frame_id = core.config["vehicle_frame"]
        if hasattr(msg, "linear_acceleration"):
            msg.linear_acceleration.z = 9.81
        for topic, out in scratch.on_message(msg, t0 + k * WARMUP_PERIOD_NS) or ():
            n += 1
            if encode is not None:
                encode(topic, out)
    # the outputs at an arbitrary instant too (the grid may not have emitted after the last sample)
    for topic, out in scratch.emit(t0 + WARMUP_SAMPLES * WARMUP_PERIOD_NS):
        n += 1
        if encode is not None:
            encode(topic, out)
    scratch.diagnostics(t0)
    return n


def start_core(config: Any, types: Any, make_input: Callable[[], Any], *, prog: str,
               notice: Callable[[str], None] | None = None) -> NodeCore:
    """The node's core for ``config`` and the binding's ``types``, warmed up (:func:`warm_up`
    with ``make_input``). Kernels missing from the cache (seen at once: ``physics.jit.
    compiles_refused``, which needs ``compile_notices``; without it they compile here) are not
    waited for: the core takes a cold start's simulator (``engine.remote.ColdStart``), which
    answers from the interpreted kernels until the compiled ones are made in the background.
    ``notice(line)`` (default: stderr) says so, and when the node switches."""
    from ..physics.jit import can_refuse_compiles, CompileRefused, compiles_refused

    def warmed(simulator: Callable[..., Any] | None = None) -> NodeCore:
        core = NodeCore(config, types, simulator=simulator)
        warm_up(core, make_input)
        return core

    if can_refuse_compiles():
        try:
            with compiles_refused():
                return warmed()
        except CompileRefused:
            pass
        from ..engine.remote import ColdStart, HelperGone

        say = notice or (lambda line: _stderr(f"{prog}: {line}"))
        cold = ColdStart(config.params, config.options, prog, say)
        try:
            return warmed(cold.simulator)
        except HelperGone as e:             # the helper could not start: as without it
            cold.close()
            say(f"{e}; compiling here")
    return warmed()


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def freeze_startup_objects() -> None:
    """After the warm-up, before the first real sample (process entry points only): one full
    collection, then ``gc.freeze()``. The ~10⁵ objects of start-up (modules, compiled kernels,
    the model, message classes) move to the permanent generation, so that a collection during
    operation scans only what came after: a full collection of them takes ~40 ms, one callback
    stalled that long at 1 kHz input (the per-message path itself allocates nothing that lives).
    The collector is then on (an entry point may keep it off while the node starts:
    ``cli.platform_node``)."""
    gc.collect()
    gc.freeze()
    gc.enable()
