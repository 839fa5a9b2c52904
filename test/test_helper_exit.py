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

"""Helper processes do not outlive what started them, and a sweep stopped while its worker
compiles or runs does not wait for the compile or the run.

A helper (the second compile process, the interpreting helper, the set-up step's second part)
calls ``signals.exit_with_parent``: it ends once the process that started it is killed, where no
``atexit`` ran to stop it. A sweep interrupted while its local worker compiles its kernels on an
empty cache: the worker abandons the compile when it closes (``sweep.worker_close``), the
command ends with exit 130 long before the compile would have, and no process of the sweep is
left behind. Interrupted during a warm run, the run stops at its next chunk (``run_scene``'s
``stop``) and the command ends before the nanny's 4 s kill."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import time

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie (an orphan's zombie may wait for a reaper)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _with_marker(marker: str) -> list[int]:
    """Processes whose environment holds ``marker`` (NUMBA_CACHE_DIR=… of one test)."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                env = (d / "environ").read_bytes()
            except OSError:
                continue
            if marker.encode() in env.split(b"\0") and _alive(int(d.name)):
                found.append(int(d.name))
    return found


def _wait_gone(pids, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    left = list(pids)
    while left and time.monotonic() < deadline:
        time.sleep(0.05)
        left = [p for p in left if _alive(p)]
    return left


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_a_helper_ends_when_the_process_that_started_it_is_killed():
    """A process that called ``exit_with_parent`` ends once its parent is SIGKILLed, even when
    the parent is gone before the helper got to the call (it names its parent in the
    environment); the same process without the call (the control) lives on."""
    code = textwrap.dedent("""
        import os, signal, subprocess, sys
        from gyro_platform.signals import parent_env
        def child(watch):
            pre = "from gyro_platform.signals import exit_with_parent; exit_with_parent(); " if watch else ""
            return subprocess.Popen([sys.executable, "-c", pre + "import time; time.sleep(60)"],
                                    env={**os.environ, **parent_env()}, start_new_session=True,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        a, b = child(True), child(False)
        print(a.pid, b.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)     # at once: the helper may not have started yet
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    watched, control = map(int, out.stdout.split())
    try:
        assert out.returncode == -signal.SIGKILL
        assert _wait_gone([watched], 10.0) == []
        assert _alive(control)
    finally:
        for pid in (watched, control):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def _interrupt_sweep(spec: Path, tmp_path: Path, env: dict, ready, marker: str,
                     timeout: float) -> tuple[int, float, str]:
    """Start ``gyro-platform sweep spec`` on one local worker in its own process group, wait until
    ``ready(proc, log_text)``, Ctrl-C the group: (exit code, seconds from the signal to the exit,
    the log). Then every process carrying ``marker`` must be gone within 5 s."""
    log_path = tmp_path / "log.txt"
    with open(log_path, "w") as log:
        proc = subprocess.Popen([sys.executable, "-m", "gyro_platform.cli", "sweep", str(spec), "--out",
                                 str(tmp_path / "out"), "--workers", "1", "--no-plots"], cwd=ROOT, stdout=log,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True, env=env)
        try:
            deadline = time.monotonic() + timeout
            while not ready(proc, log_path.read_text()):
                assert proc.poll() is None and time.monotonic() < deadline, log_path.read_text()
                time.sleep(0.1)
            t0 = time.monotonic()
            os.killpg(proc.pid, signal.SIGINT)
            code = proc.wait(timeout=120)
            took = time.monotonic() - t0
        finally:
            if proc.poll() is None:
                proc.kill()
    left = _wait_gone(_with_marker(marker), 5.0)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert left == [], [Path(f"/proc/{p}/cmdline").read_bytes() for p in left if _alive(p)]
    return code, took, log_path.read_text()


def _cpu_s(pid: int) -> float:
    """CPU seconds (user + system) a process has used; 0 once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


VARY = "vary: {unbalance: {dist: uniform, low: 0.0, high: 5.0e-8}}\n"


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs /proc")
def test_a_sweep_interrupted_while_its_worker_compiles_ends_at_once_and_leaves_no_process(tmp_path):
    """Empty kernel cache: the worker's first run compiles for tens of seconds. Ctrl-C (the
    process group) during that compile: exit 130 with the one 'interrupted' line, no traceback,
    the command ended well before the nanny's 4 s kill of a worker that does not close, and
    within seconds no process of the sweep (the worker, its second compile process) is left."""
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    cache = tmp_path / "numba"
    spec = tmp_path / "sweep.yaml"
    spec.write_text("scene: default\nduration: 2\nruns: 4\n" + VARY)
    code, took, text = _interrupt_sweep(
        spec, tmp_path, {**os.environ, "NUMBA_CACHE_DIR": str(cache)},
        lambda proc, log: "compiled " in log,                  # the worker is inside its compile
        f"NUMBA_CACHE_DIR={cache}", 180)
    assert code == 130, text
    assert "Traceback" not in text and "gyro-platform sweep: interrupted" in text, text
    assert took < 3.5, text       # not the compile (tens of s), nor the nanny's 4 s: a loose bound


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs /proc")
def test_a_sweep_interrupted_during_a_warm_run_ends_at_the_runs_next_chunk(tmp_path):
    """Warm kernels (a first short sweep compiles them if the set-up step has not): the worker is
    seconds into a run of 20 simulated minutes (tens of seconds of work) when Ctrl-C comes. The run
    stops at its next chunk (``run_scene``'s ``stop`` is the closing worker's event), so the
    command ends with exit 130 and the one 'interrupted' line well before the nanny's 4 s kill of
    a worker that does not close (before: 2.8–4.2 s, the run going on until then)."""
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    marker = f"GYRO_PLATFORM_TEST_MARK={tmp_path.name}"
    env = {**os.environ, "GYRO_PLATFORM_TEST_MARK": tmp_path.name}
    (tmp_path / "short.yaml").write_text("scene: default\nduration: 2\nruns: 1\n" + VARY)
    (tmp_path / "long.yaml").write_text("scene: default\nduration: 1200\nruns: 1\n" + VARY)
    warm = subprocess.run([sys.executable, "-m", "gyro_platform.cli", "sweep", str(tmp_path / "short.yaml"), "--out",
                           str(tmp_path / "warm"), "--workers", "1", "--no-plots"], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, env=env)
    assert warm.returncode == 0, warm.stdout + warm.stderr

    def in_run(proc, log: str) -> bool:
        """The worker's process has used seconds of CPU beyond its start-up (imports ~2 s)."""
        return max([_cpu_s(p) for p in _with_marker(marker) if p != proc.pid] or [0.0]) >= 8.0

    code, took, text = _interrupt_sweep(tmp_path / "long.yaml", tmp_path, env, in_run, marker, 120)
    assert code == 130, text
    assert "Traceback" not in text and "gyro-platform sweep: interrupted" in text, text
    assert "0 run(s) finished" in text, text         # the run had not ended by itself
    assert took < 2.0, text       # the next chunk (~0.25 s) and the cluster's close, not the nanny's 4 s
