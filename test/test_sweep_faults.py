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

"""Sweeps under faults, on real Dask clusters (``distributed.LocalCluster`` in this process, or a
``dask scheduler`` / ``dask worker`` pair in subprocesses): nothing finished is lost, nothing
half-written is taken for a result, every fault ends in one line and a documented exit code.

* a worker SIGKILLed mid-run: its runs are recorded ``lost``, the sweep finishes, a re-run does
  exactly the lost runs again;
* the scheduler gone mid-sweep: one error line (exit 1), the finished records intact;
* a full disk (a file size limit, as ``test_faults``): exit 4, one line naming the file, no
  temporary left behind, the records so far readable;
* a record file that is damaged (truncated, JSON that is no record: it was a KeyError/TypeError
  traceback): named in one line and its run done again;
* two sweeps into one folder at once: the second refused (``OUT/.lock``); a SIGKILLed holder
  leaves no stale lock.

Runs are the default scene for 100 s (about 3 s of CPU each) where a fault must land mid-run,
1 s otherwise.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import resource
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
pq = pytest.importorskip("pyarrow.parquet", reason="the results table is Parquet: pip install '.[sweep]'")

from gyro_platform import cli  # noqa: E402
from gyro_platform.errors import OutputError  # noqa: E402
from gyro_platform.sweep.command import run_sweep  # noqa: E402
from gyro_platform.sweep.spec import load_sweep  # noqa: E402
from gyro_platform.sweep.store import atomic_write, replacing, StoreError, SweepLock  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
TIMING = {"cpu_s", "wall_s"}
QUICK = ("scene: default\nduration: 1\nruns: {n}\n"
         'vary: {{"bias_torque[4]": {{dist: uniform, low: 1.0e-7, high: 3.0e-7}}}}\n')
SLOW = ("scene: default\nduration: 100\nruns: {n}\n"
        'vary: {{"bias_torque[4]": {{dist: uniform, low: 1.0e-7, high: 3.0e-7}}}}\n')


def _spec(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _records(out: Path) -> dict[int, dict]:
    return {int(p.stem[4:]): json.loads(p.read_text()) for p in sorted((out / "runs").glob("run_*.json"))}


def _strip(rec: dict) -> dict:
    return {k: v for k, v in rec.items() if k not in TIMING}


def _temporaries(out: Path) -> list[Path]:
    return [p for p in out.rglob(".*") if p.name != ".lock"]


def _sweep_cmd(spec: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "gyro_platform.cli", "sweep", str(spec), "--out", str(out), "--no-plots", *extra]


def _wait_records(proc: subprocess.Popen, out: Path, n: int, timeout: float = 240.0) -> None:
    deadline = time.monotonic() + timeout
    while len(list((out / "runs").glob("run_*.json"))) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the sweep wrote no record in time"
        time.sleep(0.1)


def _stop_group(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=60)


# ---- damaged records ---------------------------------------------------------------------------
def test_damaged_records_are_named_and_their_runs_done_again(tmp_path, capsys):
    spec = _spec(tmp_path, QUICK.format(n=6))
    out = tmp_path / "out"
    assert cli.main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plots"]) == cli.EXIT_OK
    before = _records(out)
    runs = out / "runs"
    (runs / "run_000005.json").write_text('{"status": "ok"}')                        # KeyError: 'run' before
    (runs / "run_000004.json").write_text("null")                                    # TypeError before
    (runs / "run_000003.json").write_text(json.dumps({**before[1], "cpu_s": 0.0}))   # run 1's record in 3's file
    (runs / "run_000002.json").write_text(json.dumps({**before[2], "status": 7}))
    whole = (runs / "run_000001.json").read_bytes()
    (runs / "run_000001.json").write_bytes(whole[: len(whole) // 2])                 # truncated
    (runs / "run_000000.json").write_bytes(b"\xff\xfe not text")
    capsys.readouterr()
    assert cli.main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plots"]) == cli.EXIT_OK
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    named = [ln for ln in err.splitlines() if ln.startswith("warning: damaged run record")]
    assert len(named) == 6, err
    for i in range(6):
        line = next(ln for ln in named if f"run_{i:06d}.json" in ln)
        assert line.endswith(f"run {i} runs again"), line
    assert "holds run 1, not run 3" in err and "status 7" in err and "JSON null" in err and "not JSON" in err
    after = _records(out)
    assert {i: _strip(r) for i, r in after.items()} == {i: _strip(r) for i, r in before.items()}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["executed_now"] == 6 and len(summary["damaged_records_redone"]) == 6
    assert len(pq.read_table(out / "results.parquet")) == 6


def test_a_damaged_sweep_description_is_refused_in_one_line(tmp_path, capsys):
    spec = _spec(tmp_path, QUICK.format(n=1))
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.json").write_text("null")
    assert cli.main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plots"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sweep.json: damaged" in err and "Traceback" not in err


# ---- temporaries and full disk -------------------------------------------------------------------
def test_temporaries_are_unique_and_a_failed_write_leaves_none(tmp_path):
    target = tmp_path / "runs" / "run_000001.json"
    target.parent.mkdir()
    with replacing(target) as a, replacing(target) as b:
        assert a != b and a.parent == b.parent == target.parent and a.name.startswith(".run_000001.json.")
        a.write_text("A")
        b.write_text("B")
    assert target.read_text() == "A" and not _temporaries(tmp_path)      # the last to finish wins, whole
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~_umask())
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (200, hard))        # a full disk for this process
    try:
        with pytest.raises(OutputError) as e:
            atomic_write(target, b"x" * 5000)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert str(e.value).startswith(f"{target}: ") and "too large" in str(e.value) and "\n" not in str(e.value)
    assert target.read_text() == "A" and not _temporaries(tmp_path)     # the old file, no zero-byte leftover


def _umask() -> int:
    old = os.umask(0)
    os.umask(old)
    return old


def _fsize_limit(nbytes: int):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))
    return set_limit


@pytest.mark.parametrize("limit, fails", [(4096, "results.parquet"), (600, "runs/run_0000")])
def test_full_disk_during_a_sweep_is_exit_4_naming_the_file(tmp_path, limit, fails):
    """4 KiB: every record (≈1.3 KB) fits, the table (≈11 KB) does not; 600 B: the first record
    does not fit. Exit 4, one line naming the file, no temporary left, the records readable; a
    re-run with room does only what is missing."""
    spec = _spec(tmp_path, QUICK.format(n=3))
    out = tmp_path / "out"
    p = subprocess.run(_sweep_cmd(spec, out, "--workers", "1"), cwd=ROOT, env=ENV, capture_output=True, text=True,
                       timeout=600, preexec_fn=_fsize_limit(limit))
    assert p.returncode == cli.EXIT_WRITE == 4, p.stderr
    assert "Traceback" not in p.stderr
    lines = [ln for ln in p.stderr.splitlines() if "error" in ln]
    assert len(lines) == 1, p.stderr
    assert lines[0].startswith(f"gyro-platform sweep: error: cannot write the output: {out}/{fails}"), lines[0]
    assert "too large" in lines[0]
    assert not _temporaries(out), _temporaries(out)
    recs = _records(out)                                       # every record file parses
    assert all(r["status"] == "ok" for r in recs.values())
    assert len(recs) == (3 if fails == "results.parquet" else 0)
    again = subprocess.run(_sweep_cmd(spec, out, "--workers", "1"), cwd=ROOT, env=ENV, capture_output=True,
                           text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["executed_now"] == 3 - len(recs) and len(pq.read_table(out / "results.parquet")) == 3


# ---- two sweeps at once, stale lock ---------------------------------------------------------------
def test_a_second_sweep_into_the_folder_is_refused_and_a_killed_one_leaves_no_lock(tmp_path, capsys):
    spec = _spec(tmp_path, SLOW.format(n=8))
    out = tmp_path / "out"
    first = subprocess.Popen(_sweep_cmd(spec, out, "--workers", "1"), cwd=ROOT, env=ENV, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_records(first, out, 1)
        have = _records(out)
        code = cli.main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plots"])
        err = capsys.readouterr().err
        assert code == cli.EXIT_USAGE, err
        assert err.count("\n") == 1 and "another sweep is writing into this folder now" in err, err
        assert f"pid {first.pid}" in err and str(out / ".lock") in err
        with pytest.raises(StoreError, match="another sweep"):         # the library refuses alike
            run_sweep(load_sweep(spec), out, workers=1)
        assert first.poll() is None                                    # the first one goes on
        os.killpg(first.pid, signal.SIGKILL)                           # … until killed: no orderly exit
        first.wait(timeout=60)
    finally:
        _stop_group(first)
    assert (out / ".lock").exists()
    with SweepLock(out):                                               # the kernel dropped the lock
        pass
    for i, r in have.items():
        assert _records(out)[i] == r


# ---- a worker killed, the scheduler gone -----------------------------------------------------------
def test_a_sigkilled_worker_loses_its_runs_and_a_rerun_does_exactly_those(tmp_path):
    """Dask retries a task whose worker died (``distributed.scheduler.allowed-failures``, 3 by
    default) before it gives up (KilledWorker); 0 here, so that one SIGKILL makes a run lost."""
    import dask
    from distributed import Client, LocalCluster

    spec = load_sweep(_spec(tmp_path, SLOW.format(n=4)))
    out = tmp_path / "out"
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=50)
        client = Client(cluster)
    killed: list = []

    def kill_one_worker_mid_run():
        pids = client.run(os.getpid)
        busy_since: dict = {}
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            for addr, keys in client.processing().items():
                if keys:
                    busy_since.setdefault(addr, time.monotonic())
                    if time.monotonic() - busy_since[addr] > 1.5 and addr in pids:
                        killed.append((addr, list(keys)))
                        os.kill(pids[addr], signal.SIGKILL)
                        return
            time.sleep(0.05)

    try:
        killer = threading.Thread(target=kill_one_worker_mid_run)
        killer.start()
        res = run_sweep(spec, out, client=client)
        killer.join()
    finally:
        client.close()
        cluster.close()
    assert killed, "no worker was killed"
    status = {r["run"]: r["status"] for r in res.records}
    lost = {i for i, s in status.items() if s == "lost"}
    assert len(status) == 4 and lost and set(status.values()) <= {"ok", "lost"}, res.records
    assert all("KilledWorker" in r["message"] for r in res.records if r["status"] == "lost")
    ok_files = {i: (out / "runs" / f"run_{i:06d}.json").read_bytes() for i in status if i not in lost}
    again = run_sweep(spec, out, workers=1)
    assert again.executed == len(lost) and again.skipped == 4 - len(lost)
    assert {r["run"]: r["status"] for r in again.records} == dict.fromkeys(range(4), "ok")
    for i, data in ok_files.items():                                   # the finished runs were not redone
        assert (out / "runs" / f"run_{i:06d}.json").read_bytes() == data


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_scheduler_gone_mid_sweep_is_one_error_and_the_finished_records_stay(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = open(tmp_path / "dask.log", "w")
    sched = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                              "--no-dashboard"], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    procs = [sched]
    sweep = None
    try:
        worker = subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", address, "--nthreads", "1", "--nworkers", "1", "--no-dashboard"],
            env=ENV,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        procs.append(worker)
        spec = _spec(tmp_path, SLOW.format(n=6))
        out = tmp_path / "out"
        sweep = subprocess.Popen(_sweep_cmd(spec, out, "--scheduler", address), cwd=ROOT, env=ENV,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        _wait_records(sweep, out, 1)
        sched.kill()
        _, err = sweep.communicate(timeout=180)
    finally:
        for p in [*procs, *([sweep] if sweep else [])]:
            _stop_group(p)
        log.close()
    assert sweep.returncode == 1, err
    assert "Traceback" not in err and " ERROR " not in err, err
    lines = [ln for ln in err.splitlines() if "error" in ln.lower()]
    assert len(lines) == 1 and lines[0].startswith("gyro-platform sweep: error: the Dask scheduler went away"), err
    recs = _records(out)
    assert 1 <= len(recs) < 6 and all(r["status"] == "ok" for r in recs.values()), recs
    assert f"to do the {6 - len(recs)} left" in lines[0]
    assert sorted(r["run"] for r in pq.read_table(out / "results.parquet").to_pylist()) == sorted(recs)


def test_a_damaged_bag_of_a_fleet_is_failed_input_and_a_short_one_says_so(tmp_path):
    """A fleet over three MCAP bags: an intact 30 s one, the same cut at half its bytes (its
    readable part runs, as ``run`` does, but the figures cover a fragment: ``failed_input``, not
    ``ok`` with a 15 s drift in the budget), and an intact 10 s one (``ok``, its message says it
    ends before the scene's 30 s)."""
    from test_cli import bag_scene, small_bag

    bags = tmp_path / "fleet"
    bags.mkdir()
    whole = small_bag(bags / "whole", seconds=30.0, rate=400.0, storage="mcap")
    small_bag(bags / "short", seconds=10.0, rate=400.0, storage="mcap")
    cut = bags / "cut"
    cut.mkdir()
    data = next(whole.glob("*.mcap")).read_bytes()
    (cut / "cut.mcap").write_bytes(data[:len(data) // 2])
    scene = bag_scene(tmp_path, whole, duration=30.0)
    spec = load_sweep(_spec(tmp_path, f"scene: {scene}\nduration: 30\nbags: [{bags}]\n"))
    res = run_sweep(spec, tmp_path / "out", workers=1)
    by = {Path(r["bag"]).stem: r for r in res.records}
    assert by["whole"]["status"] == "ok" and by["whole"]["message"] == ""
    assert by["cut"]["status"] == "failed_input" and "damaged" in by["cut"]["message"]
    assert 0 < by["cut"]["sim_duration_s"] < 29.0                  # its readable part ran
    assert by["short"]["status"] == "ok" and "before the scene's duration" in by["short"]["message"]


def test_a_sweep_without_one_result_exits_1_in_one_line(tmp_path, capsys):
    """Every drawn configuration refused: the records are there, the budget has no data, and the
    command says so (it exited 0)."""
    spec = _spec(tmp_path, "scene: default\nduration: 1\nruns: 2\nseed: 1\n"
                           'vary: {"rotor_C[0]": {dist: normal, mean: 2.0e-5, std: 1.0e-4}}\n')
    out = tmp_path / "out"
    assert cli.main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plots"]) == cli.EXIT_FAILED
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and "none of the 2 runs gave a result" in err[0], err
    assert json.loads((out / "summary.json").read_text())["status_counts"] == {"refused": 2}
