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

"""A local worker's run stops, or stops waiting for a compile, when its worker closes.

An interrupted sweep cancels its runs and closes its local cluster: each worker's nanny asks
its worker to close, waits 4 s, then kills it. A worker whose run compiles its kernels (a cold
cache: tens of seconds, in one compile call) would not close before that, and the command would
wait for it. :class:`StopCompilesAtClose`, a worker plugin given to the local cluster, sets
:data:`CLOSING` when its worker closes (a plugin's teardown comes before the worker waits for
its running task); :func:`~gyro_platform.sweep.runs.execute_run` runs its scene inside
``physics.jit.abandon_compiles_when(CLOSING)``, so the run's wait for the compile ends at once
(the run ends with ``CompileAbandoned``: recorded nowhere, the sweep has stopped) and the worker
closes. A warm run gets ``CLOSING`` as ``run_scene``'s ``stop`` and ends at its next chunk
(~0.25 s) with ``RunStopped``, not when its scene is done. Imports ``distributed`` (where a sweep
runs), ``signals`` and the standard library only.
"""
from __future__ import annotations

import atexit
import threading

from distributed.diagnostics.plugin import WorkerPlugin

from ..signals import end_process

__all__ = ["CLOSING", "StopCompilesAtClose"]

#: set when this worker process's worker closes
CLOSING = threading.Event()


class StopCompilesAtClose(WorkerPlugin):
    """Worker plugin: :data:`CLOSING` clear while the worker runs, set once it closes."""

    name = "gyro-platform-stop-compiles-at-close"

    def setup(self, worker) -> None:
        CLOSING.clear()
        atexit.register(_end_closed_worker)     # registered first: runs after every later handler

    def teardown(self, worker) -> None:
        CLOSING.set()


def _end_closed_worker() -> None:
    """At the exit of a worker process whose worker closed, after the other exit handlers (its
    helper processes stopped): ``os._exit``, without the interpreter's teardown of the
    compiler's objects (~1 s after an abandoned compile, for the nanny to wait for):
    ``signals.end_process``."""
    if CLOSING.is_set():
        end_process(0)
