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

"""Sweeps on a real Dask ``distributed.LocalCluster`` (no mocks): Monte Carlo budgets and fleets.

Physics: the drift rate about platform z is −Q10/L11 (oracle O9 b; the default scene's
expectation −0.41035 °/h at Q10 = 1e-7 N m), so a sweep over the bias torque must give drift
rates proportional to it. Behaviour: draws depend on the seed and run index only; the table is
identical on 1 and 2 workers; a refused run does not stop the sweep; a re-run skips finished
runs; Ctrl-C leaves a readable table and exit code 130; the local workers' Dask records go to
``OUT/workers.log``, not the terminal.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
pq = pytest.importorskip("pyarrow.parquet", reason="the results table is Parquet: pip install '.[sweep]'")

from gyro_platform.sweep.command import finish, run_sweep  # noqa: E402
from gyro_platform.sweep.spec import SweepSpecError, load_sweep  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT.parent / "shared" / "data" / "bags"
O9B_DEG_H_PER_NM = -0.41035 / 1e-7      # drift z per unit bias torque on beta10 (default scene)
TIMING = {"cpu_s", "wall_s"}


def _write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _table(out: Path) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def _same(a: list[dict], b: list[dict]) -> bool:
    strip = [[{k: v for k, v in r.items() if k not in TIMING} for r in t] for t in (a, b)]
    return json.dumps(strip[0], sort_keys=True) == json.dumps(strip[1], sort_keys=True)


BIAS_SWEEP = """
scene: default
duration: 12
seed: 7
runs: 4
vary:
  bias_torque[4]: {dist: list, values: [1.0e-7, 2.0e-7, -1.0e-7, 0.5e-7]}
  support_coulomb: {dist: uniform, low: 2.0e-3, high: 8.0e-3}
"""


@pytest.mark.parametrize("text, fragment", [
    ("scene: default\nruns: 2\nvary: {nonsense_param: {dist: fixed, value: 1}}\n", "nonsense_param"),
    ("scene: default\nruns: 2\nvary: {unbalance: {dist: gamma, k: 1}}\n", "dist"),
    ("scene: default\nruns: 2\nvary: {unbalance: {dist: uniform, low: 2, high: 1}}\n", "low"),
    ("scene: default\nruns: 0\nvary: {unbalance: {dist: fixed, value: 1.0e-8}}\n", "runs"),
    ('scene: default\nruns: 2\nvary: {"bias_torque[9]": {dist: fixed, value: 1.0e-8}}\n',
     "sweep 'sweep.yaml': vary.bias_torque[9]: index 9 out of range"),
    ("scene: default\nruns: 2\nvary: {unbalance: {dist: fixed, value: 1}}\nruns: 3\n",
     "not valid YAML: line 4:1: duplicate key 'runs' (first at line 2:1)"),
    ("scene: default\nruns: 2\nvary: {unbalance: {dist: normal, mean: 0, std: 3e-8x}}\n", "std: expected a finite"),
    ("scene: default\nruns: 2\nvary: {servo_limit: {dist: fixed, value: -1.0}}\n", "servo_limit"),
    ("scene: no_such_scene\nruns: 2\nvary: {unbalance: {dist: fixed, value: 1.0e-8}}\n", "scene"),
    ("scene: default\nbags: [x.mcap]\n", "motion type is 'bag'"),
    ("scene: default\n", "either 'vary'"),
    ("scene: default\nruns: 2\nwat: 1\nvary: {unbalance: {dist: fixed, value: 1.0e-8}}\n", "wat"),
    ("scene: default\nruns: [2\n", "line"),
])
def test_bad_sweep_files_are_refused_naming_the_key(tmp_path, text, fragment):
    with pytest.raises(SweepSpecError) as e:
        load_sweep(_write(tmp_path, text))
    assert fragment in str(e.value)
    assert "\n" not in str(e.value).strip()


def test_numbers_in_sweep_files_are_read_as_in_scene_files(tmp_path):
    """``3e-8`` and ``2e6`` (YAML 1.1 strings: no dot) are the numbers they say, as in scenes."""
    spec = load_sweep(_write(tmp_path, "scene: default\nruns: 3\nduration: 2e0\nvary:\n"
                                       "  unbalance: {dist: normal, mean: 2e-8, std: 3e-8}\n"
                                       "  servo_kp: {dist: list, values: [2e6, 3.0e+6]}\n"))
    u = next(v for v in spec.vary if v.key == "unbalance")
    assert (u.dist, u.args) == ("normal", {"mean": 2e-8, "std": 3e-8})
    assert [spec.task(i).values["servo_kp"] for i in range(3)] == [2e6, 3e6, 2e6]
    assert spec.scene["duration"] == 2.0


def test_sweep_scene_with_a_repeated_key_is_refused(tmp_path):
    _write(tmp_path, "duration: 2\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\nduration: 3\n", "dup.yaml")
    spec = _write(tmp_path, "scene: dup.yaml\nruns: 2\nvary: {unbalance: {dist: fixed, value: 1.0e-8}}\n")
    with pytest.raises(SweepSpecError, match=r"^sweep 'sweep.yaml': scene dup.yaml: not valid YAML: line 3:1: "
                                             r"duplicate key 'duration' \(first at line 1:1\)$"):
        load_sweep(spec)


def test_draws_depend_on_seed_and_run_only(tmp_path):
    text = ("scene: default\nseed: 11\nruns: {n}\nvary:\n"
            "  unbalance: {{dist: normal, mean: 2.5e-8, std: 1.0e-8}}\n"
            "  bias_torque[1]: {{dist: uniform, low: -1.0e-8, high: 1.0e-8}}\n")
    small = load_sweep(_write(tmp_path, text.format(n=5), "a.yaml"))
    large = load_sweep(_write(tmp_path, text.format(n=50), "b.yaml"))
    assert [t.values for t in small.tasks()] == [t.values for t in large.tasks()[:5]]
    assert small.fingerprint() == large.fingerprint()          # a sweep can be extended in place
    vals = np.array([t.values["unbalance"] for t in large.tasks()])
    assert abs(vals.mean() - 2.5e-8) < 4 * 1e-8 / np.sqrt(vals.size)
    assert len({t.values["bias_torque[1]"] for t in large.tasks()}) == 50
    # the value lands where the key says: element 1 of the vector, the others from the scene
    task = large.task(3)
    assert task.scene["params"]["bias_torque"][1] == task.values["bias_torque[1]"]
    assert task.scene["params"]["bias_torque"][4] == 1.0e-7


@pytest.fixture(scope="module")
def bias_sweep(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bias")
    spec = load_sweep(_write(tmp, BIAS_SWEEP))
    one = run_sweep(spec, tmp / "w1", workers=1)
    finish(spec, tmp / "w1", one, plots=True)
    two = run_sweep(spec, tmp / "w2", workers=2)
    finish(spec, tmp / "w2", two, plots=False)
    return spec, tmp, one, two


def test_monte_carlo_drift_follows_the_bias_torque(bias_sweep):
    spec, tmp, one, _ = bias_sweep
    rows = _table(tmp / "w1")
    assert [r["status"] for r in rows] == ["ok"] * 4
    for r in rows:
        q10 = r["param:bias_torque[4]"]
        assert r["drift_rate_z_deg_per_h"] == pytest.approx(O9B_DEG_H_PER_NM * q10, rel=0.05)
        assert abs(r["drift_rate_x_deg_per_h"]) < 0.01 and abs(r["drift_rate_y_deg_per_h"]) < 0.01
        assert r["peak_gimbal_angle_rad"] < 1e-4 and r["cpu_s"] > 0
        assert 0 < r["error_estimate"] < 1e-6          # achieved local error, within atol + rtol·|y|
    summary = json.loads((tmp / "w1" / "summary.json").read_text())
    z = next(b for b in summary["drift_budget"] if b["axis"] == "z")
    rates = [r["drift_rate_z_deg_per_h"] for r in rows]
    assert z["std_deg_per_h"] == pytest.approx(np.std(rates, ddof=1))
    assert (tmp / "w1" / "budget.png").stat().st_size > 10_000


def test_results_identical_on_one_and_two_workers(bias_sweep):
    _, tmp, one, two = bias_sweep
    assert one.executed == two.executed == 4
    assert _same(_table(tmp / "w1"), _table(tmp / "w2"))
    csv = (tmp / "w2" / "results.csv").read_text().splitlines()
    assert len(csv) == 5 and "drift_rate_z_deg_per_h" in csv[0]


def test_refused_run_does_not_stop_the_sweep_and_rerun_skips_finished(tmp_path):
    spec = load_sweep(_write(tmp_path, "scene: default\nduration: 3\nruns: 3\n"
                                       'vary: {"spring[0]": {dist: list, values: [0.5, -1.0, 0.25]}}\n'))
    out = tmp_path / "out"
    first = run_sweep(spec, out, workers=1)
    assert [r["status"] for r in first.records] == ["ok", "refused", "ok"]
    assert "spring" in first.records[1]["message"]
    before = json.dumps(first.records, sort_keys=True)
    again = run_sweep(spec, out, workers=1)           # nothing left to do: no cluster, no run
    assert again.executed == 0 and again.skipped == 3
    (out / "runs" / "run_000002.json").unlink()       # as if killed before run 2 was written
    third = run_sweep(spec, out, workers=1)
    assert third.executed == 1
    assert _same(json.loads(before), third.records)
    other = load_sweep(_write(tmp_path, "scene: default\nduration: 3\nruns: 1\nseed: 5\n"
                                        "vary: {unbalance: {dist: fixed, value: 1.0e-8}}\n", "other.yaml"))
    from gyro_platform.sweep.store import StoreError

    with pytest.raises(StoreError, match="another sweep"):
        run_sweep(other, out, workers=1)


def test_fewer_runs_count_only_their_records_and_the_summary_is_strict_json(tmp_path):
    """The same sweep again with fewer runs: the summary, table and title cover runs 0 … runs − 1
    (they counted every record of the folder: "5 of 2 runs"); the σ of a single ok run is null,
    not NaN (which strict JSON parsers refuse)."""
    text = ("scene: default\nduration: 1\nruns: {n}\n"
            'vary: {{"bias_torque[4]": {{dist: list, values: [1.0e-7, 2.0e-7, 3.0e-7]}}}}\n')
    out = tmp_path / "out"
    three = load_sweep(_write(tmp_path, text.format(n=3), "three.yaml"))
    finish(three, out, run_sweep(three, out, workers=1), plots=False)
    one = load_sweep(_write(tmp_path, text.format(n=1), "one.yaml"))
    assert one.fingerprint() == three.fingerprint()
    res = run_sweep(one, out, workers=1)
    assert res.executed == 0 and [r["run"] for r in res.records] == [0] and res.beyond == 2
    summary = finish(one, out, res, plots=False)
    assert summary["records"] == 1 and summary["status_counts"] == {"ok": 1}
    assert len(_table(out)) == 1

    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")
    strict = json.loads((out / "summary.json").read_text(), parse_constant=refuse)
    z = next(b for b in strict["drift_budget"] if b["axis"] == "z")
    assert z["n"] == 1 and z["std_deg_per_h"] is None and z["mean_deg_per_h"] == pytest.approx(
        res.records[0]["drift_rate_z_deg_per_h"])
    for p in (out / "runs").glob("run_*.json"):
        json.loads(p.read_text(), parse_constant=refuse)


@pytest.mark.parametrize("name", ["results.csv", "results.parquet", "budget.png"])
def test_a_folder_where_a_result_file_goes_is_refused_before_any_run(tmp_path, capsys, name):
    from gyro_platform import cli

    spec = _write(tmp_path, "scene: default\nruns: 2\nvary: {unbalance: {dist: fixed, value: 1.0e-8}}\n")
    (tmp_path / "out" / name).mkdir(parents=True)
    assert cli.main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "1"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{name} is a folder" in err, err
    assert not (tmp_path / "out" / "runs").exists()


@pytest.mark.skipif(not BAGS.is_dir(), reason=f"real recordings absent: {BAGS}")
def test_fleet_replay_one_run_per_bag(tmp_path):
    spec = load_sweep(_write(tmp_path, f"scene: husky_replay\nduration: 8\nbags: [{BAGS}]\n"))
    assert len(spec.bags) == 2
    res = run_sweep(spec, tmp_path / "out", workers=2)
    by_bag = {Path(r["bag"]).name: r for r in res.records}
    husky = by_bag["robot_localization_husky_test1"]
    assert husky["status"] == "ok" and husky["n_samples"] > 100
    # the cabrillo recording has no /imu/data: bad input for this scene, and the sweep goes on
    cab = by_bag["cabrillo_rov_bno085_imu"]
    assert cab["status"] == "failed_input" and "/imu/data" in cab["message"]


def test_ctrl_c_leaves_a_readable_table_and_exit_130(tmp_path):
    spec = _write(tmp_path, "scene: default\nduration: 4\nruns: 400\n"
                            "vary: {unbalance: {dist: uniform, low: 0.0, high: 5.0e-8}}\n")
    out = tmp_path / "out"
    log = open(tmp_path / "log.txt", "w")
    proc = subprocess.Popen([sys.executable, "-m", "gyro_platform.cli", "sweep", str(spec), "--out", str(out),
                             "--workers", "1", "--no-plots"], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and len(list((out / "runs").glob("run_*.json"))) < 2:
            assert proc.poll() is None, (tmp_path / "log.txt").read_text()
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)          # Ctrl-C in a terminal: the whole process group
        code = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()
    text = (tmp_path / "log.txt").read_text()
    assert code == 130, text
    assert "Traceback" not in text
    assert (out / "workers.log").is_file()      # the workers' Dask records went there, not to the terminal
    rows = _table(out)
    assert 2 <= len(rows) < 400 and all(r["status"] == "ok" for r in rows)
    assert len(rows) == len(list((out / "runs").glob("run_*.json")))


@pytest.mark.parametrize("address, says", [("tcp://127.0.0.1:1", "Timed out trying to connect"),
                                           ("nonsense://x", "unknown address scheme")])
def test_unreachable_scheduler_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys, address, says):
    """Exit 2 means refused before anything is written: the scheduler is tried first."""
    from gyro_platform import cli
    from gyro_platform.sweep import command

    monkeypatch.setattr(command, "SCHEDULER_TIMEOUT_S", 1.0, raising=False)
    spec = _write(tmp_path, BIAS_SWEEP)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(spec), "--out", str(out), "--scheduler", address, "--no-plots"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith(f"gyro-platform sweep: error: --scheduler {address}: no Dask scheduler reachable: ")
    assert says in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("cpus, expect", [(1, "1"), (8, None)])
def test_a_local_cluster_as_large_as_the_cpus_compiles_in_one_process_per_worker(monkeypatch, cpus, expect):
    """Workers as many as the CPUs (or more) start with ``GYRO_PLATFORM_COMPILE_JOBS=1``: a cold
    worker's second compile process would take another worker's CPU; fewer workers than CPUs
    leave it unset (each worker may compile its output kernel beside it). The client's own
    environment is as it was."""
    from gyro_platform.engine import remote
    from gyro_platform.sweep import command

    monkeypatch.delenv(remote.COMPILE_JOBS_ENV, raising=False)
    monkeypatch.setattr(command, "compile_cpus", lambda: cpus)
    client = command.make_client(workers=1)
    try:
        seen = client.run(lambda: os.environ.get("GYRO_PLATFORM_COMPILE_JOBS"))
    finally:
        client.close()
        client.cluster.close()
    assert list(seen.values()) == [expect]
    assert remote.COMPILE_JOBS_ENV not in os.environ


WORKER_LOG_SCRIPT = """
import logging, sys
from pathlib import Path
from gyro_platform.sweep.command import close_client, make_client

def fail_loudly():
    try:
        raise OSError("the scheduler went away (made up)")
    except OSError:
        logging.getLogger("distributed.worker").exception("Failed to communicate during heartbeat.")
    logging.getLogger("distributed.worker").warning("a worker warning")

log = Path(sys.argv[1]) if sys.argv[1] != "-" else None
client = make_client(workers=1, worker_log=log)
try:
    client.run(fail_loudly)
finally:
    close_client(client)
print("closed")
"""


@pytest.mark.parametrize("to_file", [False, True])
def test_local_workers_log_into_the_sweeps_folder_not_the_terminal(tmp_path, to_file):
    """A local worker process inherits the command's stderr: an error Dask logs there (with its
    traceback, as the heartbeat of an interrupted sweep's worker does) reaches the terminal
    unless the cluster is made with ``worker_log``; then the file holds it, warnings too."""
    from gyro_platform.sweep.worker_log import log_size, logged_records

    log = tmp_path / "workers.log"
    log.write_text("2026-01-01 00:00:00,000 - distributed.worker - ERROR - an earlier sweep's\n")
    start = log_size(log)
    proc = subprocess.run([sys.executable, "-c", WORKER_LOG_SCRIPT, str(log) if to_file else "-"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "closed" in proc.stdout, proc.stderr
    text = log.read_text()
    if to_file:
        assert "Traceback" not in proc.stderr and "made up" not in proc.stderr, proc.stderr
        assert "Failed to communicate during heartbeat." in text and "OSError: the scheduler went away" in text
        assert "a worker warning" in text
        assert logged_records(log, start) == 1 and logged_records(log) == 2
    else:
        assert "Traceback" in proc.stderr and "made up" in proc.stderr
        assert logged_records(log, start) == 0 and logged_records(log) == 1


def test_a_varied_parameter_no_effect_of_the_scene_evaluates_is_said(tmp_path, capsys):
    """The default scene has no mass_unbalance effect: varying ``unbalance`` changes nothing (the
    drift of every run is the nominal one), so the sweep says so in one warning line and in its
    summary; ``bias_torque`` (an effect of that scene) gets no warning."""
    from gyro_platform import cli
    from gyro_platform.physics.options import EFFECTS, PARAM_EFFECTS
    from gyro_platform.physics.params import PlatformParams

    assert all(e in EFFECTS for need in PARAM_EFFECTS.values() for e in need)
    assert set(PARAM_EFFECTS) <= {f.name for f in __import__("dataclasses").fields(PlatformParams)}
    text = ("scene: default\nduration: 1\nruns: 2\nvary:\n"
            "  unbalance: {dist: list, values: [1.0e-8, 1.0e-6]}\n"
            '  "bias_torque[4]": {dist: fixed, value: 1.0e-7}\n')
    spec = load_sweep(_write(tmp_path, text))
    assert len(spec.warnings) == 1 and "vary.unbalance" in spec.warnings[0] and "mass_unbalance" in spec.warnings[0]
    out = tmp_path / "out"
    assert cli.main(["sweep", str(_write(tmp_path, text)), "--out", str(out), "--workers", "1", "--no-plots"]) == 0
    err = capsys.readouterr().err
    assert sum("warning: " in ln and "vary.unbalance" in ln for ln in err.splitlines()) == 1, err
    assert json.loads((out / "summary.json").read_text())["warnings"] == list(spec.warnings)
    table = _table(out)
    assert table[0]["drift_rate_z_deg_per_h"] == table[1]["drift_rate_z_deg_per_h"]     # unused indeed
