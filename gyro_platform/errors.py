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

"""Exceptions, exit codes and stop signals shared by every room (the leaf: imports only the
standard library).

Simulation errors derive from ``SimulationError`` (a ``ValueError``); bag errors from
``BagReadError``; ``ReplayError`` is a replay that cannot start; ``OutputError`` an output that
cannot be written. ``EXIT_*``/``EXIT_CODES``: the exit status of every ``gyro-platform``
command. :class:`StopSignals` turns SIGINT and SIGTERM into one orderly stop
(``KeyboardInterrupt`` / :class:`Terminated`) and :func:`deferred_signals` holds them off while
a file is being closed; :func:`check_output_path` refuses unwritable outputs before a run.
"""
from contextlib import contextmanager
import errno
import math
import numbers
import os
from pathlib import Path
import signal
import sqlite3
import sys
import tempfile
import threading


class SimulationError(ValueError):
    """The simulation cannot go on as asked; the state is left as it was before the call."""


class GimbalLockError(SimulationError):
    """A gimbal came so close to ±90° that the model's equations are singular there."""


class PrecessionInvalidError(SimulationError):
    """The precession approximation is invalid for this configuration (det G_R = 0, …)."""


class InputError(SimulationError):
    """An input sample cannot be used (non-finite, out of order, out of range)."""


class NonFiniteOutputError(SimulationError):
    """An output quantity came out NaN or infinite although the state is finite (e.g. bearing
    torques overflowing under an absurd specific force). The message names the quantity and the
    time; ``quantity`` (str), ``t`` (s) and, for a block of instants, ``block`` (the
    ``OutputBlock`` of the instants before it) tell a program. Nothing non-finite is published."""

    def __init__(self, message: str, quantity: str = "", t: float = float("nan")):
        super().__init__(message)
        self.quantity = quantity
        self.t = t


class ToleranceError(SimulationError):
    """The integrator cannot meet the asked tolerance (rtol/atol) within its step budget
    (``max_substeps``); the message names the time, the method, the estimate and the tolerance."""


# ---- bags and replay (not simulation errors: a bad file or option, not a bad state) -------
class BagReadError(Exception):
    """The input bag cannot be read (further); the message names the file and what failed."""


class BagPathError(BagReadError):
    """The input path is not a rosbag2 bag at all (missing, a ROS 1 bag, a YAML or other file,
    a folder without storage file): a bad input path, not damaged data."""


class ReplayError(Exception):
    """The replay cannot start as asked (no input topic, output exists, topic clash …)."""


class OutputError(Exception):
    """An output cannot be written: refused before the start (read-only or missing folder, a path
    under a file, a folder where a file goes) or failed during the run (disk full, file size
    limit, I/O error). The message names the path and the cause in one line."""


# ---- numbers ---------------------------------------------------------------------------------
def not_finite(x) -> str | None:
    """The one rule of every numeric flag and parameter (command-line flags, scene and sweep
    files, node parameters, ``GateConfig``): a real number, and finite. None if ``x`` is one,
    else why not in words the caller prefixes with the name (``expected a finite number, got
    inf``): ``inf`` is no "no limit" anywhere."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        return f"expected a number, got {type(x).__name__} {x!r}"
    return None if math.isfinite(x) else f"expected a finite number, got {float(x)!r}"


def check_number(name: str, x, unit: str = "", *, gt: float | None = None, ge: float | None = None,
                 le: float | None = None) -> float:
    """``x`` as a float if :func:`not_finite` has nothing against it and it is within the bounds
    (``> gt``, ``>= ge``, ``<= le``); else ValueError ``"{name} = {x} {unit}; …"`` (one line)."""
    what = f"{name} = {x!r}{' ' + unit if unit else ''}"
    why = not_finite(x)
    if why is None and gt is not None and not x > gt:
        why = f"must be > {gt:g}"
    elif why is None and ge is not None and not x >= ge:
        why = f"must be >= {ge:g}"
    elif why is None and le is not None and not x <= le:
        why = f"must be <= {le:g}"
    if why is not None:
        raise ValueError(f"{what}; {why}")
    return float(x)


# ---- exit status of every command (re-exported by ``gyro_platform.cli``) ----------------
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DATA, EXIT_WRITE = 0, 1, 2, 3, 4
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143          # 128 + SIGINT, 128 + SIGTERM
EXIT_CODES: dict[int, str] = {
    EXIT_OK: "success",
    EXIT_FAILED: "ran but failed: an expectation failed or was not evaluable, the simulation failed, "
                 "or the transport could not start",
    EXIT_USAGE: "bad argument or path, refused before anything is written (unknown flag, value out of "
                "range, missing file, not a bag/scene, invalid scene, unwritable output path, a run "
                "beyond the memory/step bounds)",
    EXIT_DATA: "unusable input data: a damaged bag (the readable part is processed and written), or no "
               "usable input sample (empty topic, every sample dropped or refused: no outputs)",
    EXIT_WRITE: "an output could not be written during the run (disk full, file size limit, I/O error); "
                "what was written is closed",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C, SIGINT); files written so far are closed and readable",
    EXIT_TERMINATED: "terminated (SIGTERM: systemd, docker stop, CI time-outs); the same orderly stop as Ctrl-C",
}


# ---- stop signals -------------------------------------------------------------------------
class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's ``KeyboardInterrupt`` so that every ``except
    KeyboardInterrupt`` makes the same orderly stop; :func:`stop_reason` tells them apart."""


def stop_reason(exc: BaseException) -> str:
    """``"terminated"`` for :class:`Terminated` (SIGTERM), else ``"interrupted"`` (Ctrl-C)."""
    return "terminated" if isinstance(exc, Terminated) else "interrupted"


def stop_exit_code(exc: BaseException) -> int:
    """Exit status of a stop: 143 after SIGTERM, 130 after Ctrl-C."""
    return EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED


class StopSignals:
    """SIGINT and SIGTERM as one orderly stop, for the time of a command (a context manager;
    only in the main thread, elsewhere it does nothing).

    The first signal raises ``KeyboardInterrupt`` (SIGINT) or :class:`Terminated` (SIGTERM) in
    the main thread: the command closes its outputs and writes its summary. Signals after that
    one raise nothing (the outputs are being closed; a traceback there would leave them
    unreadable): they are noted once on stderr. Inside :func:`deferred_signals` a first signal
    is held and raised when the block ends. ``final``: the process exits after the block (the
    command line): after a stop, later signals stay ignored up to the exit. ``SIGKILL`` cannot
    be caught: what survives it is what the writers committed (see the README)."""

    _active: "StopSignals | None" = None

    def __init__(self, prog: str = "gyro-platform", final: bool = False):
        self.prog = prog
        self.final = final                   # the process ends after the block (the command line)
        self.received: int | None = None     # the signal that started the stop
        self.pending: int | None = None      # a signal held by deferred_signals
        self.depth = 0                       # nesting of deferred_signals blocks
        self._old: dict[int, object] = {}
        self._outer: "StopSignals | None" = None
        self._noted = False

    def __enter__(self) -> "StopSignals":
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._old[s] = signal.signal(s, self._handler)
            self._outer, StopSignals._active = StopSignals._active, self
        return self

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            # the process is about to exit after a stop: a late signal must not turn the exit
            # status into "killed by SIGINT" (Python re-raises an unhandled KeyboardInterrupt so)
            signal.signal(s, signal.SIG_IGN if self.final and self.received is not None else h)
        self._old.clear()
        if StopSignals._active is self:
            StopSignals._active = self._outer

    @staticmethod
    def exception(signum: int) -> KeyboardInterrupt:
        return Terminated("terminated") if signum == signal.SIGTERM else KeyboardInterrupt()

    def _handler(self, signum: int, _frame) -> None:
        if self.received is not None:
            if not self._noted:
                self._noted = True
                print(f"{self.prog}: {signal.Signals(signum).name} ignored: already stopping, closing "
                      f"the outputs (SIGKILL would abandon them)", file=sys.stderr, flush=True)
            return
        if self.depth > 0:
            self.pending = self.pending or signum
            return
        self.received = signum
        raise self.exception(signum)

    @classmethod
    def raise_held(cls) -> None:
        """Raise a signal that :func:`deferred_signals` holds now, inside the block: for a wait
        that has changed nothing yet (kernels compiling before the block's first step), so that
        the stop does not wait for it."""
        stop = cls._active
        if stop is not None and stop.pending is not None and stop.received is None:
            stop.received, stop.pending = stop.pending, None
            raise stop.exception(stop.received)

    def release(self) -> None:
        """End of a deferred block: raise a held signal now."""
        if self.depth == 0 and self.pending is not None and self.received is None:
            self.received, self.pending = self.pending, None
            raise self.exception(self.received)


@contextmanager
def deferred_signals():
    """Hold SIGINT/SIGTERM off for the block (closing a bag, writing its metadata): a signal
    arriving inside is delivered when the block ends. With an active :class:`StopSignals` it
    raises then; without one (library use, main thread) the handlers in place before the block
    get the held signal (a Ctrl-C raises KeyboardInterrupt after the block; a SIGTERM with the
    default action ends the process). Off the main thread (where no signal is delivered) the
    block just runs: the main thread holds them while it waits for such a thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    stop = StopSignals._active
    if stop is not None:
        stop.depth += 1
        try:
            yield
        finally:
            stop.depth -= 1
        stop.release()
        return
    got: list[int] = []
    old = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for s in dict.fromkeys(got):
            h = old[s]
            if callable(h):
                h(s, None)
            elif h == signal.SIG_DFL:
                os.kill(os.getpid(), s)


# ---- output paths ----------------------------------------------------------------------------
#: OSError numbers of a write that cannot succeed (not a bug, not the input)
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EACCES,
                          errno.EPERM, errno.ENOTDIR, errno.EISDIR, errno.EEXIST})


def write_failure(exc: BaseException) -> str | None:
    """One line for an exception raised while writing outputs, None if it is not a write
    failure: ``OSError`` of ``WRITE_ERRNOS`` (disk full ``ENOSPC``, file size limit ``EFBIG``,
    read-only, I/O error …) and SQLite's "database or disk is full" / "disk I/O error"."""
    if isinstance(exc, OutputError):
        return str(exc)
    if isinstance(exc, OSError) and exc.errno in WRITE_ERRNOS:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return f"{where}{exc.strerror or exc}"
    if isinstance(exc, sqlite3.Error) or type(exc).__module__ == "apsw":     # either SQLite binding
        text = str(exc)
        if any(w in text for w in ("full", "disk", "I/O", "readonly", "unable to open")):
            return f"SQLite: {text}"
    cause = exc.__cause__ or exc.__context__
    if cause is not None and cause is not exc:
        inner = write_failure(cause)
        if inner is not None:
            return inner
    return None


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_folder(folder: Path, flag: str, path: Path) -> None:
    """A folder can take new files: make and remove a temporary file there."""
    if not folder.is_dir():
        raise OutputError(f"{flag} {path}: {folder} is a file, not a folder")
    try:
        fd, name = tempfile.mkstemp(prefix=".gyro-write-probe-", dir=folder)
        os.close(fd)
        os.unlink(name)
    except OSError as e:
        raise OutputError(f"{flag} {path}: cannot write in {folder}: {e.strerror or e}") from None


def check_output_path(path, flag: str = "--out", *, new: bool = False,
                      files: tuple[str, ...] = (), siblings: tuple = ()) -> None:
    """Refuse an output path that cannot be written, before anything runs (OutputError, one line).

    ``path``: the output folder (``new``: it must not exist, e.g. a bag); ``files``: names the
    command will write inside it (they must not be folders); ``siblings``: further paths it will
    write next to it (``OUT.summary.json``): not folders, writable if they exist. The nearest
    existing folder on the way is probed by creating and removing a temporary file (read-only
    file systems, permissions, a path under a file)."""
    path = Path(path)
    if new and (path.exists() or path.is_symlink()):
        raise OutputError(f"{flag} {path}: exists already; choose another (nothing is overwritten)")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{flag} {path}: is a file, not a folder")
    _probe_folder(_nearest_existing(path), flag, path)
    for name in files:
        if (path / name).is_dir():
            raise OutputError(f"{flag} {path}: {path / name} is a folder; the command writes a file there")
    for s in map(Path, siblings):
        if s.is_dir():
            raise OutputError(f"{flag} {path}: {s} is a folder; the command writes a file there")
        if s.exists() and not os.access(s, os.W_OK):
            raise OutputError(f"{flag} {path}: {s} exists and cannot be overwritten")
