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

"""A cold start's simulator: the interpreted kernels in a helper process while the compiled
ones are made in another, then the compiled ones, in the same state bit for bit.

numba compiles a configuration's kernels in 20–60 s the first time (a fresh machine, a new code
version, an image run on another CPU). Where ``physics.jit.compiles_refused`` finds a kernel
missing from the cache, a :class:`ColdStart` starts two processes of this module:

* ``interpret``: the same :class:`~gyro_platform.engine.simulator.Simulator` with
  ``NUMBA_DISABLE_JIT=1``, i.e. the kernels' Python source, which gives the compiled kernels'
  results bit for bit (numba compiles without fast-math; ``test_plain_python.py``), at ~1–3 ms
  a sample on the linear model (a helper process: a second copy of the package in this one
  would patch numba twice, ``physics.jit``);
* ``compile``: a few samples through a compiled Simulator of the configuration, which fills
  the shared kernel cache (its compile notices on stderr: one line, then one per kernel).

:meth:`ColdStart.simulator` makes :class:`WarmingSimulator` objects, the Simulator interface
the node's pipeline uses (``push_plain``, ``push``, ``reset``, ``output_row``, ``stats``,
``system.stabilised``), answered by the helper and recorded. At its first call after the
compile process has ended, a WarmingSimulator builds the compiled Simulator (its kernels now
load from the cache), replays the record into it (the same calls must give the same errors),
checks that both give the same outputs and statistics, and from then on is the compiled one
(its methods bound on the instance: nothing added per call). If the compile process failed,
the rest compiles in this process (said on stderr, as any first run); if the replay differs,
the helper keeps answering (said once). Imports ``physics`` (``jit``), ``errors`` and ``signals``.
"""
from __future__ import annotations

import atexit
from contextlib import contextmanager
import itertools
from multiprocessing.connection import Connection
import os
from pathlib import Path
import subprocess
import sys
import time
from types import SimpleNamespace
from typing import Any, Callable

from .. import errors
from ..errors import SimulationError
from ..physics.jit import (compiled_elsewhere, CompileRefused, compiles_refused, not_when_compiling, notices_prog,
                           when_compiling)
from ..signals import exit_now, exit_with_parent, parent_env

__all__ = ["ColdStart", "WarmingSimulator", "HelperGone", "OutputsAside", "compile_jobs", "compile_cpus",
           "one_compile_process", "COMPILE_JOBS_ENV"]

#: the package's parent folder: the helper processes import the package from where this one did
_ROOT = str(Path(__file__).resolve().parents[2])
#: calls answered by the helper whose record replays the run (the rest only read)
RECORDED = ("push_plain", "push", "reset")


class HelperGone(RuntimeError):
    """The interpreting helper process ended (killed, out of memory): its answer is lost."""


def _spawn(mode: str, prog: str, env: dict[str, str]) -> tuple[subprocess.Popen, Connection, Connection]:
    """``python -m gyro_platform.engine.remote MODE`` with a pipe each way (pickled messages);
    its own session (a terminal's Ctrl-C is this process's to handle), stdout discarded,
    stderr shared (compile notices)."""
    to_r, to_w = os.pipe()
    from_r, from_w = os.pipe()
    path = os.environ.get("PYTHONPATH")
    env = {**os.environ, **env, **parent_env(), "PYTHONPATH": _ROOT + (os.pathsep + path if path else "")}
    try:
        proc = subprocess.Popen([sys.executable, "-m", "gyro_platform.engine.remote", mode, str(to_r), str(from_w),
                                 prog], pass_fds=(to_r, from_w), env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, start_new_session=True)
    finally:
        os.close(to_r)
        os.close(from_w)
    return proc, Connection(to_w, readable=False), Connection(from_r, writable=False)


#: ``GYRO_PLATFORM_COMPILE_JOBS=1``: a cold command compiles all its kernels itself (no
#: :class:`OutputsAside` helper)
COMPILE_JOBS_ENV = "GYRO_PLATFORM_COMPILE_JOBS"


def compile_cpus() -> int:
    """CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def compile_jobs() -> int:
    """Processes a cold command may compile its kernels in: 2 where this process may run on two
    or more CPUs, else 1; ``$GYRO_PLATFORM_COMPILE_JOBS`` (1 or 2) overrides."""
    env = os.environ.get(COMPILE_JOBS_ENV, "").strip()
    if env.isdigit() and int(env) >= 1:
        return min(int(env), 2)
    return 2 if compile_cpus() >= 2 else 1


@contextmanager
def one_compile_process(on: bool = True):
    """For the block, if ``on``: ``GYRO_PLATFORM_COMPILE_JOBS=1`` in this process's environment
    (and so in the processes started in it: no :class:`OutputsAside` helpers where other
    processes already keep the CPUs busy); the variable as it was after."""
    old = os.environ.get(COMPILE_JOBS_ENV)
    if on:
        os.environ[COMPILE_JOBS_ENV] = "1"
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(COMPILE_JOBS_ENV, None)
        else:
            os.environ[COMPILE_JOBS_ENV] = old


class OutputsAside:
    """On a cold kernel cache, the output kernel of one configuration (``params``, ``options``)
    compiled by a helper process (``outputs``) while this process compiles the stepping kernels:
    the two are independent and each takes ~40 % of a cold command's compile (numba compiles
    one kernel at a time in a process). Armed by the constructor: nothing happens unless this
    process starts compiling a kernel (``physics.jit.when_compiling``: a warm cache costs
    nothing) and :func:`compile_jobs` is 2. Then the helper starts, and this process's own
    compile of the output kernel, when it comes to it, waits for the helper and loads the
    kernel from the cache (``physics.jit.compiled_elsewhere``; if the helper failed, it
    compiles it here). Its notices (stderr): one line per kernel it compiled. :meth:`close`
    (also at exit) stops a helper still running."""

    def __init__(self, params: Any, options: Any):
        self.params, self.options = params, options
        self.proc: subprocess.Popen | None = None
        self._kernel: Any = None
        if compile_jobs() > 1:
            when_compiling(self._start)

    def _start(self) -> None:
        from .output_kernel import output_rows

        self.proc, to, back = _spawn("outputs", f"{notices_prog() or 'gyro-platform'} (second compile process)", {})
        try:
            to.send((self.params, self.options))
        except OSError:                      # it ended at once: the compile here loads or compiles
            pass
        to.close()
        back.close()
        self._kernel = output_rows
        compiled_elsewhere(output_rows, self._wait)
        atexit.register(self.close)

    def _wait(self) -> None:
        """Until the helper has ended (called on a compile thread: a signal still stops the
        command at once, ``physics.jit``)."""
        while self.proc is not None and self.proc.poll() is None:
            time.sleep(0.02)

    def close(self) -> None:
        """Disarm; stop the helper if it still runs. Idempotent."""
        atexit.unregister(self.close)
        not_when_compiling(self._start)
        if self._kernel is not None:
            compiled_elsewhere(self._kernel, None)
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.terminate()
            _reap(self.proc, 1.0)

    def __enter__(self) -> "OutputsAside":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _error(name: str, text: str) -> Exception:
    """The helper's exception, as the same class of ``errors`` when it is one of them."""
    cls = getattr(errors, name, None)
    if isinstance(cls, type) and issubclass(cls, Exception):
        return cls(text)
    return RuntimeError(f"{name}: {text}")


class ColdStart:
    """The two helper processes of one configuration (``params``, ``options``) and the
    factory of its simulators (:meth:`simulator`, what ``NodeCore`` takes). ``prog`` names the
    compile process's notices; ``notice(line)`` says what happens (the start, the switch).
    Ended by :meth:`close` (registered at exit)."""

    def __init__(self, params: Any, options: Any, prog: str, notice: Callable[[str], None]):
        self.params, self.options, self.prog, self.notice = params, options, prog, notice
        self.t0 = time.monotonic()
        self.compiler, to, back = _spawn("compile", f"{prog} (background compile)", {})
        try:
            to.send((params, options))
        except OSError:                      # it ended at once: its status says so (compile_ended)
            pass
        to.close()
        back.close()
        self.helper, self._to, self._from = _spawn("interpret", prog, {"NUMBA_DISABLE_JIT": "1"})
        self._ids = itertools.count(1)
        self.rc: int | None = None           # the compile process's exit status, once it ended
        self.switched = 0                    # simulators now on the compiled kernels
        atexit.register(self.close)
        # (the phrase every command's compile notice has, before the background compile's own)
        notice(f"the simulation kernels of this configuration are not compiled yet: compiling the simulation "
               f"kernels in the background (pid {self.compiler.pid}) and answering meanwhile from their "
               f"interpreted form (the same outputs, ~1-3 ms a sample); the node switches to them when they "
               f"are ready")

    def simulator(self, params: Any, options: Any) -> Any:
        """A simulator of ``params``/``options``: a :class:`WarmingSimulator` of this
        configuration until its compile has ended, then a compiled ``Simulator``. Another
        configuration before that raises ``SimulationError`` (a live model change waits for
        the compiled kernels)."""
        if self.compile_ended():
            from .simulator import Simulator
            return Simulator(params, options)
        if params != self.params or options != self.options:
            raise SimulationError(f"the model cannot change while its kernels compile "
                                  f"({time.monotonic() - self.t0:.0f} s so far); try again once the node says "
                                  f"it switched to the compiled kernels")
        return WarmingSimulator(self, params, options)

    def compile_ended(self) -> bool:
        """The compile process has ended (its status in ``rc``)."""
        if self.rc is None:
            rc = self.compiler.poll()
            if rc is None:
                return False
            self.rc = rc
        return True

    def call(self, sid: int, op: str, args: tuple = ()) -> Any:
        """One call on the helper's simulator ``sid``; its exception raised here."""
        try:
            self._to.send((sid, op, args))
            reply = self._from.recv()
        except (OSError, EOFError) as e:
            raise HelperGone(f"the interpreting helper process ended ({type(e).__name__}: {e})") from None
        if reply[0] == "ok":
            return reply[1]
        raise _error(reply[1], reply[2])

    def retire_helper(self, timeout: float = 5.0) -> None:
        """End the helper (a simulator has switched: ~100 MB less); another simulator of this
        start still on it replays its own record at its next call (``HelperGone``)."""
        for c in (self._to, self._from):
            c.close()                        # the helper sees the end of its input and exits
        _reap(self.helper, timeout)

    def close(self) -> None:
        """Stop the compile process (if running) and the helper; idempotent."""
        atexit.unregister(self.close)
        if self.compiler.poll() is None:
            self.compiler.terminate()
        _reap(self.compiler, 1.0)
        self.retire_helper(1.0)


def _reap(proc: subprocess.Popen, timeout: float) -> None:
    """Wait ``timeout`` s for ``proc`` to end, then kill it."""
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


class WarmingSimulator:
    """The Simulator interface over a helper's interpreted simulator, recorded; the compiled
    Simulator, in the same state, from its first call after the compile has ended (module doc).
    ``params``, ``options`` as ``Simulator``'s."""

    def __init__(self, cold: ColdStart, params: Any, options: Any):
        self.cold, self.params, self.options = cold, params, options
        self.sid = next(cold._ids)
        info = cold.call(self.sid, "new", (params, options))
        self.system = SimpleNamespace(stabilised=info["stabilised"])
        self.record: list[tuple[str, tuple, str | None]] | None = []
        self.local: Any = None              # the compiled Simulator, once switched
        self.kept = False                   # the replay differed: the helper answers for good

    # ---- the Simulator interface (until the switch) ---------------------------------------
    def push_plain(self, t: float, omega: tuple, specific_force: tuple | None) -> None:
        self._recorded("push_plain", (t, omega, specific_force))

    def push(self, sample: Any) -> None:
        self._recorded("push", (sample,))

    def reset(self) -> None:
        self._recorded("reset", ())

    def output_row(self) -> Any:
        if self._switch_now():
            return self.local.output_row()
        return self._ask("output_row")

    def __getattr__(self, name: str) -> Any:
        # stats, and after the switch whatever else of the compiled Simulator is asked for
        # (carry_state_from reads its engine): instance attributes and methods come first
        local = self.__dict__.get("local")
        if local is not None:
            return getattr(local, name)
        if name == "stats":
            return self._ask("stats")
        raise AttributeError(f"{name!r}: not available before the compiled kernels are loaded")

    @property
    def kernels(self) -> str:
        """Which kernels answer (the node's diagnostics show it)."""
        if self.local is not None:
            return "compiled"
        if self.kept:
            return "interpreted (the compiled kernels did not replay the run alike)"
        return "interpreted, compiling in the background"

    # ---- calls --------------------------------------------------------------------------
    def _ask(self, op: str, args: tuple = ()) -> Any:
        try:
            return self.cold.call(self.sid, op, args)
        except HelperGone:
            self._helper_gone()
            return getattr(self.local, op)(*args) if op != "stats" else self.local.stats

    def _helper_gone(self) -> None:
        """The helper ended: the record replayed into a Simulator compiled here. Without a record
        (it was dropped when a replay differed) the state is lost: SimulationError (the pipeline
        restarts the simulation at the sample and counts it)."""
        lost = self.record is None
        self._switch(compile_here=True)
        if lost:
            raise SimulationError("the interpreting helper ended and its state with it: the simulation restarts")

    def _recorded(self, op: str, args: tuple) -> None:
        if self._switch_now():
            getattr(self.local, op)(*args)
            return
        err = None
        try:
            self.cold.call(self.sid, op, args)
        except HelperGone:
            self._helper_gone()
            getattr(self.local, op)(*args)
            return
        except Exception as e:
            err = type(e).__name__
            raise
        finally:
            if self.record is not None and self.local is None:
                self.record.append((op, args, err))

    def _switch_now(self) -> bool:
        """Switched (now, or before) to the compiled Simulator: the compile has ended."""
        if self.local is not None:
            return True
        if self.kept or not self.cold.compile_ended():
            return False
        self._switch(compile_here=self.cold.rc != 0)
        return self.local is not None

    def _switch(self, compile_here: bool) -> None:
        """The compiled Simulator, the record replayed into it, checked against the helper;
        then bound. ``compile_here``: kernels missing from the cache compile in this process
        (the compile process failed, or the helper is gone)."""
        from .simulator import Simulator

        cold, t0 = self.cold, time.monotonic()
        if compile_here:
            why_here = f"the background compile ended with status {cold.rc}" if cold.rc else "the helper ended"
            cold.notice(f"{why_here}; compiling here")
        try:
            local, why = self._replayed(Simulator, refuse=not compile_here)
        except CompileRefused as e:
            cold.notice(f"{e} after the background compile; compiling the rest here")
            local, why = self._replayed(Simulator, refuse=False)
        checked = False
        if not compile_here:
            if not why:
                try:
                    why, checked = self._differs(local), True
                except HelperGone:          # retired by another simulator's switch: the replay's check only
                    pass
            if why:
                self.kept, self.record = True, None
                cold.notice(f"NOT switching to the compiled kernels: {why}; the interpreted kernels "
                            f"keep answering (slow, correct); please report this")
                return
        elif why:
            cold.notice(f"the compiled kernels did not replay the interpreted run alike ({why}); "
                        f"going on with them")
        n = len(self.record or ())
        self.local, self.record = local, None
        for name in ("push_plain", "push", "reset", "output_row"):
            setattr(self, name, getattr(local, name))        # bound: nothing added per call
        self.system = local.system
        cold.switched += 1
        if checked:
            cold.retire_helper()
        cold.notice(f"switched to the compiled kernels {time.monotonic() - cold.t0:.1f} s after the "
                    f"start ({n} calls replayed in {time.monotonic() - t0:.2f} s"
                    + ("; outputs and statistics identical to the interpreted run)" if checked else ")"))

    def _replayed(self, simulator: Callable, refuse: bool) -> tuple[Any, str | None]:
        """A compiled Simulator fed the record, and how it differed (None: every call raised
        what it raised in the helper, or nothing)."""
        if refuse:
            with compiles_refused():
                return self._replayed(simulator, refuse=False)
        local = simulator(self.params, self.options)
        why = None
        for op, args, err in self.record or ():
            got = None
            try:
                getattr(local, op)(*args)
            except CompileRefused:
                raise
            except Exception as e:  # noqa: BLE001 - compared with what the helper raised
                got = type(e).__name__
            if got != err and why is None:
                why = f"{op}{args!r} raised {got} compiled and {err} interpreted"
        return local, why

    def _differs(self, local: Any) -> str | None:
        """Why the compiled Simulator does not continue the interpreted one (None: it does)."""
        outs = []
        for ask in (lambda: self.cold.call(self.sid, "output_row"), local.output_row):
            try:
                outs.append(ask().tobytes())
            except SimulationError as e:
                outs.append(type(e).__name__)
        if outs[0] != outs[1]:
            return "the outputs differ after the replay"
        stats_remote, stats_local = self.cold.call(self.sid, "stats"), local.stats
        if stats_remote != stats_local:
            return f"the statistics differ after the replay ({stats_remote} / {stats_local})"
        return None


# ---- the helper processes ---------------------------------------------------------------
def _serve(inbox: Connection, outbox: Connection) -> int:
    """``interpret``: Simulators by id, one call per message, until the input ends."""
    from .simulator import Simulator

    sims: dict[int, Any] = {}
    while True:
        try:
            sid, op, args = inbox.recv()
        except (EOFError, OSError):
            return 0
        try:
            if op == "new":
                sim = sims[sid] = Simulator(*args)
                value: Any = {"stabilised": bool(sim.system.stabilised)}
            elif op == "stats":
                value = sims[sid].stats
            elif op in RECORDED or op == "output_row":
                value = getattr(sims[sid], op)(*args)
            else:
                raise ValueError(f"unknown call {op!r}")
            reply: tuple = ("ok", value)
        except Exception as e:  # noqa: BLE001 - handed to the caller, raised there
            reply = ("error", type(e).__name__, str(e))
        try:
            outbox.send(reply)
        except OSError:
            return 0


def _compile(inbox: Connection, prog: str) -> int:
    """``compile``: a few samples through a compiled Simulator of the configuration received,
    with the paths the node's pipeline takes (``push``, ``push_plain`` with and without a
    specific force, ``output_row``, ``reset``): their kernels into the cache. Exit 0 or 1."""
    from .inputs import RateSample
    from .simulator import Simulator
    from ..physics.jit import compile_notices

    import numpy as np

    params, options = inbox.recv()
    inbox.close()
    compile_notices(prog)
    sim = Simulator(params, options)
    g = (0.0, 0.0, 9.80665)                 # m/s², gravity's reaction: at rest
    sim.push(RateSample(1.0, np.zeros(3), np.array(g)))
    for k in range(1, 6):
        sim.push_plain(1.0 + 0.01 * k, (0.0, 0.0, 0.0), g)
        sim.output_row()
    try:
        sim.push_plain(1.1, (0.0, 0.0, 0.0), None)
    except SimulationError:                 # the model needs the specific force
        pass
    sim.reset()
    sim.push(RateSample(2.0, np.zeros(3), np.array(g)))
    sim.output_row()
    return 0


def _compile_outputs(inbox: Connection, prog: str) -> int:
    """``outputs``: the output kernel of the configuration received (:class:`OutputsAside`),
    called once on the initial state: compiled into the cache (or loaded from it). Exit 0."""
    from .simulator import Simulator
    from .snapshots import SEG_N, Snapshots
    from ..physics.jit import compile_notices, quiet_compile_header

    import numpy as np

    params, options = inbox.recv()
    inbox.close()
    compile_notices(prog, where="in the second process")
    quiet_compile_header()                  # the command said that kernels compile
    sim = Simulator(params, options)
    snaps = Snapshots(np.zeros(1), np.zeros(1), np.array(sim.y, dtype=float)[None, :], np.zeros((1, SEG_N)),
                      np.zeros(1, np.int64))
    try:
        sim.outputs_at(snaps)
    except SimulationError:                 # an instant made up for the compile: its values do not matter
        pass
    return 0


def main(argv: list[str]) -> int:
    """``python -m gyro_platform.engine.remote MODE IN_FD OUT_FD PROG`` (``ColdStart``'s)."""
    import signal

    mode, fd_in, fd_out, prog = argv[0], int(argv[1]), int(argv[2]), argv[3]
    exit_with_parent()                      # a parent killed (no atexit to stop this one): end too
    inbox = Connection(fd_in, writable=False)
    outbox = Connection(fd_out, readable=False)
    if mode == "interpret":
        signal.signal(signal.SIGINT, signal.SIG_IGN)        # the node stops it: the end of its input
        return _serve(inbox, outbox)
    outbox.close()
    try:
        return (_compile_outputs if mode == "outputs" else _compile)(inbox, prog)
    except (KeyboardInterrupt, EOFError):
        return 130
    except Exception as e:  # noqa: BLE001 - one line, the node (the command) compiles the rest itself
        print(f"{prog}: failed: {type(e).__name__}: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    exit_now(main(sys.argv[1:]))            # the kernels are in the cache: no teardown to wait for
