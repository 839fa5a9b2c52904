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

"""Where a local cluster's worker processes log: ``OUT/workers.log``, not the sweep's terminal.

A local worker process inherits the command's stderr, and Dask's loggers there write to it
(``silence_logs``: warnings and errors). Their records are Dask's own (a heartbeat that finds
the scheduler gone while an interrupted sweep shuts the cluster down, memory warnings), with
tracebacks; what a run did is the sweep's record of it (``runs``, ``store``), and the command
says it in one line. :class:`WorkerLogFile`, a worker plugin given to the local cluster, moves
every stream handler of the worker process's loggers to one file (appended to, WARNING and
above) before the worker registers with its scheduler; if the file cannot be opened the
handlers stay. Imports ``distributed`` (where a sweep runs) and the standard library only.
"""
from __future__ import annotations

import logging
from pathlib import Path
import sys

from distributed.diagnostics.plugin import WorkerPlugin

__all__ = ["WorkerLogFile", "FORMAT", "log_size", "logged_records"]

#: Dask's own record format (``distributed.logging``'s default)
FORMAT = "%(asctime)s - %(name)s - %(levelname)s - %(message)s"


class WorkerLogFile(WorkerPlugin):
    """Worker plugin: the worker process's log records go to ``path`` (WARNING and above)."""

    name = "gyro-platform-worker-log"

    def __init__(self, path: str | Path):
        self.path = str(path)

    def setup(self, worker) -> None:
        try:
            handler = logging.FileHandler(self.path, mode="a", encoding="utf-8")
        except OSError:
            return                          # unwritable: the records stay on stderr
        handler.setFormatter(logging.Formatter(FORMAT))
        handler.setLevel(logging.WARNING)
        for logger in _stream_loggers():
            for old in [h for h in logger.handlers if _is_terminal(h)]:
                logger.removeHandler(old)
                logger.addHandler(handler)


def _stream_loggers() -> list[logging.Logger]:
    """The root logger and every logger made so far (Dask's, tornado's, …)."""
    made = [v for v in logging.root.manager.loggerDict.values() if isinstance(v, logging.Logger)]
    return [logging.root, *made]


def _is_terminal(handler: logging.Handler) -> bool:
    return (type(handler) is logging.StreamHandler
            and getattr(handler, "stream", None) in (sys.stderr, sys.stdout, sys.__stderr__, sys.__stdout__))


def log_size(path: Path) -> int:
    """Bytes in ``path`` now (0 if absent): where this sweep's records will start."""
    try:
        return path.stat().st_size
    except OSError:
        return 0


def logged_records(path: Path, start: int = 0) -> int:
    """How many error records ``path`` holds from byte ``start`` on (lines that open an ERROR or
    CRITICAL record in :data:`FORMAT`; 0 if absent). Warnings are kept in the file, not counted."""
    try:
        with open(path, "rb") as f:
            f.seek(start)
            text = f.read().decode("utf-8", errors="replace")
    except OSError:
        return 0
    return sum(1 for line in text.splitlines() if " - ERROR - " in line or " - CRITICAL - " in line)
