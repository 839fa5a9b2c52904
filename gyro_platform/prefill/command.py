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

"""``gyro-platform compile``: compile the kernels of the shipped configurations into the cache.

A first command of a code version on a machine compiles the numba kernels its model and method
need (tens of seconds on a 2 GHz core); every later process of the same code — other clones,
reinstalls, colcon installs, containers sharing the cache folder, Dask workers — loads them in
about half a second (``physics.jit``). This command pays that once where waiting is expected
(the set-up command, an image build, ``colcon build``): it runs, each for a moment and without
writing anything outside a temporary folder,

* the scene ``--scene`` (default ``default``, the README's first command) for a few samples,
* the node's per-message path (its warm-up, ``ros.warmup``) in the configuration of
  ``--params-file`` (default: the node's defaults, those of ``config/platform.yaml``),
* a replay in the node's model configuration (the replay's defaults) of a one-second
  synthetic 100 Hz Imu bag of each storage (mcap, sqlite3).

Before them it writes the package's bytecode (:func:`write_bytecode`): where the environment
forbids Python to write it (``PYTHONDONTWRITEBYTECODE=1``, as many container images and CI
runners set) or the source is read-only to the user, an editable or colcon ``--symlink-install``
of the package would otherwise compile every module from source in every process (~0.3 s of
each command here).

The scene's kernels (its model's) and the node's and replay's (the node's model) share
nothing, so with ``--jobs 2`` (the default on a machine of two or more cores) a second process
(``--part 1``) compiles the node's and the replay's while this one compiles the scene's: about
half the wall time (the cache index takes both: ``physics.jit``). It starts when this process
starts compiling (on a warm cache the steps run here, in turn). A signal stops both. The two
keep both CPUs busy, so their steps start no output-kernel helper of their own
(``engine.remote.OutputsAside``: ``GYRO_PLATFORM_COMPILE_JOBS=1`` for them; with one a cold
set-up step took 26 s instead of 20 here).

One line per step with its time on stdout; compile notices on stderr as for every command.
Exit 0, or 1 when a step failed (what the other steps compiled stays cached).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable

from ..engine.remote import one_compile_process
from ..errors import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED, EXIT_USAGE
from ..filesystem import child_env
from ..physics.jit import cache_dir, not_when_compiling, quiet_compile_header, when_compiling
from ..signals import exit_with_parent, parent_env, Terminated

__all__ = ["add_arguments", "parts", "run", "steps", "write_bytecode"]

#: length of the synthetic bags replayed (s) and their rate (Hz)
BAG_SECONDS = 1.0
BAG_RATE = 100.0
#: scene time run (s): a few samples and output instants
SCENE_SECONDS = 0.2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", default="default",
                        help="scene (file or name in config/scenes) whose kernels to compile (default: default)")
    parser.add_argument("--params-file", default=None, metavar="YAML",
                        help="the node's ROS 2 parameters file (default: the node's defaults)")
    parser.add_argument("--jobs", type=int, default=None, metavar="N",
                        help="processes compiling at once: 1, or 2 (the scene's kernels in one, the node's and the "
                             "replay's in the other; more act as 2; default 2 on a machine of two or more cores)")
    parser.add_argument("--part", type=int, default=None, help=argparse.SUPPRESS)       # a second process's
    parser.add_argument("--part-dir", default=None, help=argparse.SUPPRESS)             # share (see run)


def write_bytecode(package: Path | None = None) -> int:
    """Compile every module of ``package`` (default: this package's folder, as imported) to
    bytecode in its ``__pycache__``, as the import system names and validates it (source
    mtime and size), also where ``PYTHONDONTWRITEBYTECODE`` is set. Returns the number of
    modules; raises OSError naming the folder when a file could not be written."""
    import compileall

    package = Path(__file__).parents[1] if package is None else Path(package)
    if not compileall.compile_dir(str(package), quiet=2, workers=1):
        raise OSError(f"could not write the bytecode of every module under {package}")
    return sum(1 for _ in package.rglob("*.py"))


def _scene_step(name: str) -> None:
    from ..scenes.runner import run_scene
    from ..scenes.schema import load_scene

    run_scene(load_scene(name).with_duration(SCENE_SECONDS))


def _scene_exists(name: str) -> None:
    from ..scenes.schema import load_scene

    load_scene(name)        # ScenarioError (a ValueError) for a bad name or file


def _node_config(params_file: str | None):
    from ..ros.command import build_config
    from ..ros.parameters import NODE_NAME

    args = argparse.Namespace(params_file=params_file, scene=None)
    return build_config(args, NODE_NAME)[0]


def _node_step(config) -> None:
    from ..messages import jazzy_typestore, MessageTypes
    from ..ros.core import NodeCore
    from ..ros.dds_types import zero_message
    from ..ros.warmup import warm_up

    store = jazzy_typestore()
    core = NodeCore(config, MessageTypes.rosbags(store))
    warm_up(core, lambda: zero_message(store, core.input_type))


def _replay_step(storage: str, work: Path) -> None:
    from ..bench.bags import vehicle_imu, write_imu_bag
    from ..replay.loop import replay, ReplayConfig

    bag = write_imu_bag(work / f"in_{storage}", vehicle_imu(BAG_SECONDS, rate=BAG_RATE), storage=storage)
    summary = replay(bag, work / f"out_{storage}", ReplayConfig(plot=False))
    stopped = summary.get("interrupted_by")
    if stopped:                 # the replay stopped in order on a signal: so does this command
        raise Terminated("terminated") if stopped == "SIGTERM" else KeyboardInterrupt()
    if summary.get("error"):
        raise RuntimeError(summary["error"])


def steps(scene: str, params_file: str | None, work: Path) -> list[tuple[str, Callable[[], None]]]:
    """The steps of the command: (what, function) in order."""
    config = _node_config(params_file)
    return [(f"scene {scene}", lambda: _scene_step(scene)),
            ("node (per-message path)", lambda: _node_step(config)),
            ("replay (mcap)", lambda: _replay_step("mcap", work)),
            ("replay (sqlite3)", lambda: _replay_step("sqlite3", work))]


def parts(todo: list, jobs: int) -> list[list]:
    """The steps of each process: the scene's, and the node's and replay's (``jobs`` ≥ 2), or
    all in one."""
    return [todo[:1], todo[1:]] if jobs >= 2 else [todo]


def _run_steps(prog: str, todo: list) -> int:
    """Run ``todo`` in order, one line per step; the number of failed steps."""
    failed = 0
    for what, step in todo:
        t0 = time.perf_counter()
        try:
            step()
        except Exception as e:      # noqa: BLE001 - one line; the other steps still run
            failed += 1
            print(f"{prog}: {what}: failed: {type(e).__name__}: {e}", file=sys.stderr)
            continue
        print(f"  {what}: {time.perf_counter() - t0:.1f} s", flush=True)
    return failed


def _start_part(args: argparse.Namespace, part: int, work: Path) -> subprocess.Popen:
    """The process compiling share ``part`` (this command with ``--part``; its lines go to
    this process's stdout and stderr, its failure count to ``work/part-<part>``)."""
    cmd = [sys.executable, "-m", "gyro_platform", "compile", "--scene", args.scene, "--jobs", str(args.jobs),
           "--part", str(part), "--part-dir", str(work)]
    if args.params_file:
        cmd += ["--params-file", args.params_file]
    return subprocess.Popen(cmd, env={**child_env(), **parent_env()}, stdin=subprocess.DEVNULL)


def _stop_parts(children: list[subprocess.Popen], exc: BaseException | None) -> None:
    """A stop of this command (``exc``: its KeyboardInterrupt/Terminated) stops the other
    processes too, with the same signal (killed if still there after 2 s)."""
    for ch in children:
        if ch.poll() is None:
            ch.send_signal(signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)
    for ch in children:
        try:
            ch.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            ch.kill()
            ch.wait()


def run(args: argparse.Namespace) -> int:
    if args.jobs is None:
        args.jobs = 2 if (os.cpu_count() or 1) >= 2 else 1
    # the parts keep both CPUs busy: no output-kernel helper beside each (the second part inherits it)
    with one_compile_process(len(parts([None, None], args.jobs)) > 1):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """:func:`run` with ``--jobs`` set."""
    prog = "gyro-platform compile"
    if args.jobs < 1:
        print(f"{prog}: error: --jobs must be 1 or more", file=sys.stderr)
        return EXIT_USAGE
    own = args.part is not None                 # a share of a parallel compile (see _start_part)
    if own and (args.part_dir is None or not 1 <= args.part < len(parts([None, None], args.jobs))):
        print(f"{prog}: error: --part is the second process's own (given with --part-dir by the first)",
              file=sys.stderr)
        return EXIT_USAGE
    work = Path(args.part_dir) if own else Path(tempfile.mkdtemp(prefix="gyro_platform_compile_"))
    try:
        try:
            todo = steps(args.scene, args.params_file, work)
            _scene_exists(args.scene)
        except (ValueError, OSError) as e:       # ScenarioError, ConfigError
            print(f"{prog}: error: {e}", file=sys.stderr)
            return EXIT_USAGE
        shares = parts(todo, args.jobs)
        if own:
            exit_with_parent()                  # the first process killed: this share ends too
            quiet_compile_header()              # the first process said it
            failed = _run_steps(prog, shares[args.part])
            (work / f"part-{args.part}").write_text(str(failed))
            return EXIT_FAILED if failed else EXIT_OK
        print(f"{prog}: kernels cached in {cache_dir()}", flush=True)
        t_all = time.perf_counter()
        try:
            n_modules = write_bytecode()
        except OSError as e:                    # not fatal: the commands compile their modules themselves
            print(f"{prog}: note: {e}: each command compiles the package's modules from source", file=sys.stderr)
        else:
            print(f"  bytecode of {n_modules} modules: {time.perf_counter() - t_all:.1f} s", flush=True)
        started: dict[int, subprocess.Popen] = {}

        def start_the_others() -> None:         # this process compiles: the other parts beside it
            for k in range(1, len(shares)):
                try:
                    started[k] = _start_part(args, k, work)
                except OSError as e:            # not started: that part runs here, in turn
                    print(f"{prog}: a second process could not start ({e}): one process", file=sys.stderr)
                    return
            print(f"  ({len(started)} more process{'es' if len(started) > 1 else ''} compiling: "
                  + "; ".join(", ".join(w for w, _ in shares[k]) for k in started) + ")", flush=True)

        if len(shares) > 1:
            when_compiling(start_the_others)    # a warm cache: no process started, nothing to wait for
        try:
            failed = _run_steps(prog, shares[0])
            not_when_compiling(start_the_others)
            for k in range(1, len(shares)):
                ch = started.get(k)
                if ch is None:                  # not started: here, in turn
                    failed += _run_steps(prog, shares[k])
                    continue
                rc = ch.wait()
                if rc == EXIT_TERMINATED:
                    raise Terminated("terminated")
                if rc == EXIT_INTERRUPTED:
                    raise KeyboardInterrupt()
                done = work / f"part-{k}"
                failed += int(done.read_text()) if done.exists() else len(shares[k])
                if not done.exists():
                    print(f"{prog}: the process compiling {', '.join(w for w, _ in shares[k])} ended with "
                          f"status {rc}", file=sys.stderr)
        except BaseException as e:
            not_when_compiling(start_the_others)
            _stop_parts(list(started.values()), e)
            raise
        print(f"{prog}: {len(todo) - failed} of {len(todo)} steps in {time.perf_counter() - t_all:.1f} s", flush=True)
    finally:
        if not own:
            shutil.rmtree(work, ignore_errors=True)
    return EXIT_FAILED if failed else EXIT_OK
