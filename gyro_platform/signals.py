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

"""Stop signals of every command: :class:`StopSignals` turns SIGINT and SIGTERM into one orderly
stop (``KeyboardInterrupt`` / :class:`Terminated`, exit codes ``errors.EXIT_INTERRUPTED`` /
``EXIT_TERMINATED``), :func:`deferred_signals` holds them off while a file is being closed,
and :func:`exit_now` ends a process that is done (the commands and their helper processes);
:func:`end_process` ends one with nothing more run; :func:`exit_with_parent` ends a helper
process whose parent is gone.
A leaf room: imports ``errors`` and the standard library."""
import atexit
from contextlib import contextmanager
import os
import signal
import sys
import threading
import time
from typing import NoReturn

from .errors import EXIT_INTERRUPTED, EXIT_TERMINATED


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


def exit_now(code: int) -> NoReturn:
    """End this process with ``code`` once it is done (a command, a helper process): the
    ``atexit`` handlers run (helper processes stopped, logging flushed, temporary folders
    removed), stdout and stderr are flushed, then ``os._exit`` — without the interpreter's
    teardown of what a command leaves behind (~10⁵ objects, the compiled kernels' code:
    0.05–0.2 s after every ``run`` or ``replay``, measured). Where a thread other than the main
    one still runs (it would be cut off) or ``atexit`` cannot be run here, the usual exit
    (``sys.exit``)."""
    run_exitfuncs = getattr(atexit, "_run_exitfuncs", None)
    busy = any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread())
    if busy or run_exitfuncs is None:
        sys.exit(code)
    try:
        run_exitfuncs()
    finally:
        end_process(code)


def end_process(code: int) -> NoReturn:
    """stdout and stderr flushed, then ``os._exit(code)``: nothing more runs (no exit handler,
    no teardown of the interpreter). What :func:`exit_now` does after the exit handlers, and
    what an exit handler that must come last calls (``sweep.worker_close``)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):    # a closed pipe or stream, or none
            pass
    os._exit(code)


#: how often a helper process looks whether the process that started it is still there (s)
PARENT_POLL_S = 0.2
#: the environment entry in which a process names itself the parent of a helper it starts
PARENT_ENV = "GYRO_PLATFORM_PARENT_PID"


def parent_env() -> dict[str, str]:
    """The environment entry that names this process as the parent of a helper it starts
    (:func:`exit_with_parent` in the helper reads it)."""
    return {PARENT_ENV: str(os.getpid())}


def exit_with_parent(code: int = EXIT_TERMINATED) -> threading.Thread:
    """End this helper process (``os._exit(code)``, nothing more to run) as soon as the process
    that started it is gone: killed, or a Dask worker closed by its nanny, with no ``atexit``
    run to stop its helpers. The parent is the pid in ``PARENT_ENV`` (set by the starter,
    :func:`parent_env`; taken out of this process's environment), else this process's parent
    now; once it is gone this process has another parent (init or a subreaper), which a daemon
    thread checks every ``PARENT_POLL_S`` — beside a kernel compile too (numba's passes give the
    interpreter up every few ms, LLVM releases it). A parent gone before the helper got here
    ends it at the first check. Returns the thread."""
    named = os.environ.pop(PARENT_ENV, "")
    parent = int(named) if named.isdigit() else os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(code)

    th = threading.Thread(target=watch, name="gyro-parent-watch", daemon=True)
    th.start()
    return th
