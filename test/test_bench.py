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

"""The benchmark's physics and plumbing (never its timings): the MuJoCo peer model is the same
carried platform as gyro_platform's (gimbal-angle trajectories agree), the generated Imu bag
decodes back to the motion it was made from, the consumer rows go through the real command and
report a missing bag as "not found", and bad benchmark options are refused."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gyro_platform import cli
from gyro_platform.bench import bags, consumer
from gyro_platform.bench.bench_scenes import ship_scene
from gyro_platform.physics.params import NAV1


@pytest.fixture(autouse=True)
def _bag_cache(tmp_path, monkeypatch):
    """Generated bags go to this test's folder, not the shared cache."""
    monkeypatch.setenv("GYRO_PLATFORM_BENCH_CACHE", str(tmp_path / "cache"))


# ---- the MuJoCo peer -------------------------------------------------------------------------

def _mujoco():
    pytest.importorskip("mujoco", reason="mujoco is not installed (pip install '.[test]'): the peer model needs it")
    from gyro_platform.bench import peer_mujoco

    return peer_mujoco


def test_mujoco_model_has_the_nav1_inertias_and_axes():
    pm = _mujoco()
    import mujoco

    mp = pm.MujocoPlatform.build(NAV1)
    m = mp.model
    body = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i): i for i in range(m.nbody)}
    np.testing.assert_allclose(m.body_inertia[body["frame4"]], NAV1.frame4, rtol=1e-12)
    np.testing.assert_allclose(m.body_inertia[body["housing10"]], NAV1.housing10, rtol=1e-12)
    C, A = NAV1.rotor_C[2], NAV1.rotor_A[2]
    np.testing.assert_allclose(m.body_inertia[body["rotor11"]], (A, C, A), rtol=1e-12)
    axes = {n: m.jnt_axis[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in pm.GIMBALS}
    # spec 1: alpha4 about +2, beta5 about +3, beta7 about -3, alpha9 about +3, beta10 about +1
    for n, a in {"alpha4": (0, 1, 0), "beta5": (0, 0, 1), "beta7": (0, 0, -1), "alpha9": (0, 0, 1),
                 "beta10": (1, 0, 0)}.items():
        np.testing.assert_allclose(axes[n], a, atol=1e-15)


def _both(pm, t, w, out_every):
    tg, g, _ = pm.gyro_run(t, w, pm.carried_options(1e-12, 1e-15, max_step=2.5e-4, integrator="rk4",
                                                    max_substeps=1 << 20), out_every=out_every)
    tm, m, _ = pm.mujoco_run(t, w, substeps=16, out_every=out_every)
    np.testing.assert_allclose(tg, tm, atol=1e-12)
    return g, m


def test_mujoco_peer_agrees_with_gyro_platform_on_ship_motion():
    """Ship roll/pitch, 1 s: the gimbals swing ~0.07 rad; both models give the same angles to
    1e-8 rad (what is left: the MuJoCo rotors' finite speed loop)."""
    pm = _mujoco()
    sc = ship_scene(1.0)
    g, m = _both(pm, sc.t, sc.omega, out_every=50)
    assert np.max(np.abs(g)) > 0.05          # the gimbals did move: the comparison means something
    np.testing.assert_allclose(m, g, atol=1e-8, rtol=0)


def test_mujoco_peer_carries_the_same_nutation_after_a_rate_step():
    """A 0.05 rad/s roll step excites the ≈ 90 Hz nutation; sampled every millisecond over
    0.15 s, both models give the same oscillation (amplitude ~1e-4 rad) to 2 % of it."""
    pm = _mujoco()
    sc = pm.steps_scene(1.0)
    n = int(0.2 * 1000)
    t, w = sc.t[:n], sc.omega[:n]
    g, m = _both(pm, t, w, out_every=1)
    after = t >= 0.05
    osc = g[after] - g[after].mean(axis=0)
    amp = np.max(np.abs(osc))
    assert amp > 2e-5
    assert np.max(np.abs(m[after] - g[after])) < 0.02 * amp


def test_peer_without_mujoco_is_a_note_not_a_crash(monkeypatch, tmp_path, capsys):
    from gyro_platform.bench import peer_mujoco

    monkeypatch.setattr(peer_mujoco, "available", lambda: "mujoco is not installed (test)")
    assert peer_mujoco.peer(tmp_path, quick=True, repeats=1, required=False) == 0
    assert peer_mujoco.peer(tmp_path, quick=True, repeats=1, required=True) == 1
    assert "peer comparison skipped: mujoco is not installed" in capsys.readouterr().out


# ---- the consumer benchmark's bags and rows --------------------------------------------------

def test_generated_imu_bag_reads_back_as_the_motion(tmp_path):
    """The 1 kHz Imu bag (rosbags writer, both storages) decodes through the replay's own reader
    and gate to exactly the samples it was made from."""
    imu = bags.vehicle_imu(0.5)
    assert imu.t.size == 501 and math.isclose(imu.t[1] - imu.t[0], 1e-3)
    for storage in ("sqlite3", "mcap"):
        path = bags.cached_imu_bag(0.5, storage)
        assert path.name.endswith(storage) and (path / "metadata.yaml").is_file()
        t, w, f = consumer.bag_samples(path)
        np.testing.assert_allclose(t, imu.t, atol=1e-12)
        np.testing.assert_array_equal(w, imu.omega)
        np.testing.assert_array_equal(f, imu.force)
    # a realistic vehicle: ~1 g upwards, noisy rates of a few deg/s
    assert 9.0 < np.mean(imu.force[:, 2]) < 10.6
    assert 1e-3 < np.std(imu.omega[:, 0]) < 0.5


def test_second_bag_is_another_vehicle_at_jittered_stamps(tmp_path):
    """The bag the fast path was not tuned on: stamps within ±5 % of a period of the 1 kHz grid,
    increasing, not on it; other samples than the unjittered bag's; it reads back through the
    replay's reader and gate exactly."""
    imu = bags.vehicle_imu(0.5, seed=31, jitter=0.05)
    grid = np.arange(imu.t.size) * 1e-3
    off = imu.t - grid
    assert np.all(np.diff(imu.t) > 0) and np.max(np.abs(off)) <= 0.05e-3 + 1e-15
    assert np.std(off) > 0.02e-3                       # really jittered
    plain = bags.vehicle_imu(0.5, seed=31)
    assert np.max(np.abs(imu.omega - plain.omega)) > 1e-4   # other times, other samples
    t, w, f = consumer.bag_samples(bags.cached_imu_bag(0.5, "mcap", seed=31, jitter=0.05))
    np.testing.assert_allclose(t, imu.t, atol=1e-9)
    np.testing.assert_array_equal(w, imu.omega)
    np.testing.assert_array_equal(f, imu.force)


def test_replay_row_goes_through_the_command_and_counts_every_message(tmp_path):
    path = bags.cached_imu_bag(0.3, "mcap")
    s = consumer.replay_once(path, tmp_path / "out", ("--output-rate", "100"))
    assert s["counts"]["in"] == 301 and s["counts"]["accepted"] == 301
    assert s["counts"]["out"] == 31                      # 100 Hz grid over 0.3 s, both ends
    assert s["real_time_factor"] > 0 and s["command_wall_s"] >= s["wall_time_s"]
    # the replay's CPU: this process's threads over the same span, at most every usable CPU busy
    from gyro_platform.engine.remote import compile_cpus
    assert 0 < s["cpu_time_s"] <= s["wall_time_s"] * compile_cpus() + 0.02


def test_cpu_ceiling_is_the_real_time_factor_the_cpus_allow(monkeypatch):
    """0.6 CPU s (median) for 120 s of data on 2 CPUs: no replay of it faster than ×400 here."""
    from gyro_platform.engine import remote

    monkeypatch.setattr(remote, "compile_cpus", lambda: 2)
    c = consumer.cpu_ceiling([0.7, 0.5, 0.6], 120.0)
    assert c == {"cpu_s": 0.6, "cpus": 2, "cpu_ceiling_rtf": pytest.approx(400.0)}
    row = consumer.Row("replay_1khz", "replay 1 kHz", "bag", rtf=250.0, us_per_sample=4.0, extra=c)
    assert "| CPU 0.60 s: ≤ ×400 on 2 CPUs |" in consumer.table([row])


def test_whole_command_row_reports_the_wall_and_the_figure_the_new_process_prints(tmp_path):
    """The subprocess run of the whole command: its wall time covers the replay the command
    timed, and the real-time factor is the one that command wrote (its first replay)."""
    path = bags.cached_imu_bag(0.3, "mcap")
    wall, printed = consumer.replay_subprocess(path, tmp_path / "sub", ("--output-rate", "100", "--no-plot"))
    summary = json.loads((tmp_path / "sub.summary.json").read_text())
    assert summary["counts"]["in"] == 301
    assert printed == summary["real_time_factor"] > 0 and 0 < summary["wall_time_s"] < wall


def test_sqlite_floor_inserts_every_row_the_replay_wrote(tmp_path):
    """The floor row re-inserts exactly the rows of the replay's output (inputs copied, 14
    output topics per instant, diagnostics), read from its .db3."""
    path = bags.cached_imu_bag(0.3, "sqlite3")
    s = consumer.replay_once(path, tmp_path / "out", ("--output-rate", "100"))
    wall, n = consumer.sqlite_floor(tmp_path / "out", repeats=1)
    assert n == s["output"]["messages"] == 301 + 14 * 31 + s["output"]["messages_by_topic"]["/diagnostics"]
    assert wall > 0
    row = consumer._floor_row(tmp_path / "out", repeats=1)
    assert row.extra["rows"] == n and "| SQLite alone" in consumer.table([row])


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_io_floor_writes_what_the_replay_writes(tmp_path, storage):
    """The I/O floor's output bag holds as many messages per topic as the replay's (inputs
    copied, the output topics at the 100 Hz instants, /diagnostics), on a bag with jittered stamps."""
    from rosbags.highlevel import AnyReader

    from gyro_platform.bench.floor import io_floor

    def counts(path):
        with AnyReader([path]) as r:
            return {c.topic: c.msgcount for c in r.connections if c.msgcount}

    path = bags.cached_imu_bag(0.5, storage, seed=31, jitter=0.05)
    s = consumer.replay_once(path, tmp_path / "replay", ("--output-rate", "100"))
    f = io_floor(path, tmp_path / "floor", None, 100.0)
    assert counts(tmp_path / "floor") == counts(tmp_path / "replay") == f["counts"]
    assert f["outputs"] == s["counts"]["out"] and f["inputs"] == s["counts"]["in"] == 501
    assert f["wall_s"] > 0 and f["duration_s"] == pytest.approx(s["duration_s"]) and f["cpu_s"] > 0
    row = consumer.Row("replay_1khz_x", "replay x", str(path), rtf=s["real_time_factor"], us_per_sample=1.0)
    consumer.add_floor(row, path, tmp_path, repeats=1)
    assert row.extra["replay_over_floor"] > 0 and "| replay ÷ floor" in consumer.table([row])
    assert row.extra["floor_cpu_ceiling_rtf"] > row.extra["floor_rtf"] * 0.9    # what its CPU allows, ≥ what it ran


def test_node_figure_publishes_on_the_default_grid():
    msgs = consumer._imu_objects(bags.cached_imu_bag(0.5, "mcap"), 400)
    r = consumer.node_us(msgs, repeats=1)
    assert r["internal_errors"] == 0
    assert r["published"] == 4                           # default output_rate 10 Hz over 0.4 s
    assert 0 < r["median_us"] <= r["p99_us"] <= r["max_us"]


def test_missing_husky_bag_is_a_row_saying_not_found(monkeypatch, tmp_path):
    monkeypatch.setattr(consumer, "husky_bag", lambda: (None, "not found"))
    row = consumer._husky_row(tmp_path, repeats=1, quick=True, whole=False)
    assert row.status == "not found" and row.ratio is None
    assert "| not found |" in consumer.table([row])


def test_short_copy_keeps_every_topic_and_only_the_first_seconds():
    path, why = bags.husky_bag()
    if path is None:
        pytest.skip(f"husky recording: {why}")
    from rosbags.rosbag2 import Reader

    short = bags.short_copy(path, 5.0)
    with Reader(path) as full, Reader(short) as cut:
        assert {c.topic for c in cut.connections} == {c.topic for c in full.connections}
        stamps = [ts for _, ts, _ in cut.messages()]
        assert stamps[0] == full.start_time and stamps[-1] <= full.start_time + 5_000_000_000
        n_full = sum(1 for _, ts, _ in full.messages() if ts <= full.start_time + 5_000_000_000)
    assert len(stamps) == n_full


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_generated_bag_names_its_file_after_its_folder(tmp_path, monkeypatch, storage):
    """A generated bench bag is written in a staging folder and renamed: its storage file is
    named after the bag (no hidden staging name), and nothing of the staging is left."""
    import numpy as np

    monkeypatch.setenv("GYRO_PLATFORM_BENCH_CACHE", str(tmp_path))
    t = np.arange(5) * 1e-3
    path = bags.write_imu_bag(tmp_path / "small", bags.VehicleImu(t, np.zeros((5, 3)), np.zeros((5, 3))), storage)
    files = sorted(p.name for p in path.iterdir())
    assert files == sorted(["metadata.yaml", f"small.{'db3' if storage == 'sqlite3' else 'mcap'}"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small"]


@pytest.mark.parametrize("value", ["0", "-3"])
def test_bench_refuses_non_positive_repeats(value, capsys):
    assert cli.main(["bench", "hotpath", "--repeats", value]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "--repeats must be between 1 and 1000" in err and "Traceback" not in err


def test_bench_refuses_an_unwritable_out_before_running(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert cli.main(["bench", "consumer", "--out", str(blocker / "results")]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "gyro-platform bench: error: --out " in err and "is a file, not a folder" in err and "Traceback" not in err


@pytest.fixture
def no_benchmark(monkeypatch):
    """Every benchmark runner fails the test if called: option checks must refuse first."""
    from gyro_platform.bench import command, peer_mujoco, roughness
    from gyro_platform.sweep import scaling

    def ran(*a, **k):
        raise AssertionError("a benchmark ran although its options are refused")

    for mod, names in ((command, ("consumer", "accuracy", "hard", "effects_cost", "hotpath")),
                       (peer_mujoco, ("peer",)), (roughness, ("roughness",)), (scaling, ("scaling",))):
        for name in names:
            monkeypatch.setattr(mod, name, ran)


@pytest.mark.parametrize("what", [[], ["consumer"], ["roughness"], ["peer"], ["accuracy"], ["effects"], ["hotpath"],
                                  ["hard"], ["sweep"]], ids=lambda w: w[0] if w else "default")
@pytest.mark.parametrize("value", ["0", "-1", "10001"])
def test_every_bench_refuses_bad_runs_before_writing(what, value, tmp_path, capsys, no_benchmark):
    out = tmp_path / "out"
    assert cli.main(["bench", *what, "--runs", value, "--out", str(out)]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err == f"gyro-platform bench: error: --runs must be between 1 and 10000, got {value}\n"
    assert not out.exists()


def test_bench_hard_refuses_an_unknown_case_naming_the_known_ones(tmp_path, capsys, no_benchmark):
    from gyro_platform.engine.hardcases import CASES

    out = tmp_path / "out"
    assert cli.main(["bench", "hard", "--case", "free_platform", "--case", "nope", "--out", str(out)]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith("gyro-platform bench: error: --case nope: unknown hard case; known: ")
    assert err.count("\n") == 1 and all(c.name in err for c in CASES) and "Traceback" not in err
    assert not out.exists()


def test_hard_table_refuses_an_unknown_case(tmp_path):
    from gyro_platform.bench.hard import hard

    with pytest.raises(ValueError, match="unknown case nope; known: carried_large_angles"):
        hard(tmp_path / "out", cases=["nope"])
    assert not (tmp_path / "out").exists()


def test_roughness_bench_writes_the_cost_of_vibration_at_equal_accuracy_and_how_far_it_holds(tmp_path, capsys):
    """``bench roughness --quick``: a sweep of tolerances, smooth beside vibrating (right-hand sides,
    steps, rejections, delivered error against the reference); three rows compare the inputs at the
    smooth input's delivered error (the vibrating work interpolated on its own sweep), and the grid
    of vibration amplitudes and frequencies; a vibration of 0.03 rad/s costs (almost) nothing more
    at any frequency, and every error stays below the asked rtol in rad; a parked vehicle (kinks
    every sample) costs more than the road at every row and is held to the same."""
    import json

    from gyro_platform.bench.roughness import cost_at_error, RTOLS, SWEEP

    out = tmp_path / "bench"
    assert cli.main(["bench", "roughness", "--quick", "--out", str(out)]) == 0
    doc = json.loads((out / "roughness.json").read_text())
    rows, cells, sweep = doc["rows"], doc["meta"]["grid"], doc["meta"]["sweep"]
    assert [r["rtol"] for r in rows] == list(RTOLS) and set(RTOLS) <= set(SWEEP)
    assert [p["rtol"] for p in sweep["smooth"]] == [p["rtol"] for p in sweep["vibrating"]] == list(SWEEP)
    for key in ("smooth", "vibrating"):                  # tighter tolerances cost more and deliver more
        rhs, err = ([p[f] for p in sweep[key]] for f in ("rhs", "error"))
        assert rhs[-1] > 2.0 * rhs[0] and err[-1] < 1e-3 * err[0]
        assert all(0 < p["error"] < p["rtol"] for p in sweep[key])
    curve = [(p["rhs"], p["error"]) for p in sweep["vibrating"]]
    for r in rows:
        assert 0 < r["smooth_error"] < r["rtol"] and 0 < r["vibrating_error"] < r["rtol"]
        assert r["ratio"] == pytest.approx(cost_at_error(curve, r["smooth_error"]) / r["smooth_rhs"])
        i = next(i for i, (_, e) in enumerate(curve) if e <= r["smooth_error"])   # the work lies in its bracket
        assert curve[max(i - 1, 0)][0] * (1 - 1e-12) <= r["vibrating_rhs_equal"] <= curve[i][0] * (1 + 1e-12)
    assert len(cells) == 16
    assert all(c["ratio"] <= 1.2 for c in cells if c["amplitude"] == 0.03)
    text = capsys.readouterr().out
    assert "at equal accuracy" in text and "How far it holds" in text
    still = doc["meta"]["parked"]               # the parked vehicle: kinks every sample, dearer
    assert [r["rtol"] for r in still] == list(RTOLS) and "A parked vehicle" in text
    assert all(0 < r["parked_error"] < r["rtol"] and r["same_rtol_ratio"] > 1.5 for r in still)
    md = (out / "roughness.md").read_text().splitlines()
    assert sum(line.startswith("|---") for line in md) == 3 and (out / "roughness.png").stat().st_size > 0


def test_work_at_an_error_is_read_off_the_sweep_between_its_bracketing_points():
    """``cost_at_error``: the loosest point's work where it already delivers, log-log between the two
    points around the target (exact on a power law), nan where the sweep never gets there."""
    import math

    from gyro_platform.bench.roughness import cost_at_error

    law = [(c, 1e-3 * c ** -4.0) for c in (3.0, 5.0, 9.0, 20.0)]      # error ∝ work⁻⁴, as RK4's
    for c in (3.7, 6.0, 15.0):
        assert cost_at_error(law, 1e-3 * c ** -4.0) == pytest.approx(c, rel=1e-12)
    assert cost_at_error(law, 1.0) == 3.0                              # the loosest point is enough
    assert math.isnan(cost_at_error(law, 1e-3 * 21.0 ** -4.0))       # beyond the tightest point
    assert cost_at_error([(3.0, 5e-7), (3.1, 5e-7), (4.2, 7e-11)], 1e-10) == pytest.approx(
        math.exp(math.log(3.1) + math.log(5e-7 / 1e-10) / math.log(5e-7 / 7e-11) * math.log(4.2 / 3.1)))


def test_a_roughness_row_the_vibrating_sweep_never_reaches_reads_not_reached():
    """The Markdown table names a row whose equal-accuracy work is nan (the vibrating input never
    delivered the smooth one's error) as not reached and ✗, not ×nan; a reached row keeps its ratio."""
    from gyro_platform.bench.roughness import RoughRow, table

    rows = [RoughRow(1e-8, "auto:rk4", 9.4, 13.2, 2.3, 3.4, 400, 147, 2.3e-13, 4.3e-12),
            RoughRow(1e-6, "auto:rk4", 4.0, 5.0, 1.0, 1.4, 69, 96, 1.3e-11, 1.4e-11, 5.2)]
    lines = table(rows, 10.0).splitlines()
    assert "13.20 / not reached | ✗ | ×1.40" in lines[-2] and "nan" not in lines[-2]
    assert "5.00 / 5.20 | ×1.30 | ×1.25" in lines[-1]


def test_headline_holds_this_runs_figures_to_their_bars_and_leaves_out_an_older_report(tmp_path, capsys):
    """The headline of ``gyro-platform bench``: each figure of the four section reports as a ratio
    beside its bar (✓/✗ computed, not copied), and a report older than the run (a section the
    run left out) not in it."""
    import json
    import os
    import time

    from gyro_platform.bench.headline import headline

    def put(stem, doc, age=0.0):
        p = tmp_path / f"{stem}.json"
        p.write_text(json.dumps(doc))
        if age:
            os.utime(p, (time.time() - age, time.time() - age))

    t0 = time.time() - 60
    put("coldstart", {"rows": [
        {"name": "compile", "what": "compile", "status": "ok", "cold_s": 60.0, "warm_s": 1.5, "extra": {}},
        {"name": "run_default", "what": "run default", "status": "ok", "cold_s": 60.0, "warm_s": 4.0,
         "extra": {"after_setup_s": 4.4, "cold_cpu_s": 100.0, "cpus": 2, "cold_cpu_bound_s": 50.0}},
        {"name": "node", "what": "node", "status": "ok", "cold_s": 5.0, "warm_s": 2.0, "extra": {}}]})
    put("consumer", {"rows": [
        {"name": "replay_1khz", "what": "replay 1 kHz", "status": "ok", "rtf": 250.0, "target": "replay_1khz",
         "us_per_sample": 4.0, "extra": {"replay_over_floor": 1.6, "floor_rtf": 400.0, "whole_command_rtf": 38.0,
                                         "cpu_s": 0.6, "cpus": 2, "cpu_ceiling_rtf": 400.0}},
        {"name": "replay_husky", "what": "replay husky", "status": "ok", "rtf": 520.0, "target": "replay_husky",
         "us_per_sample": 60.0, "extra": {"whole_command_rtf": 110.0, "new_process_rtf": 330.0}},
        {"name": "node_median", "what": "node (median)", "status": "ok", "rtf": None, "target": "node_median",
         "us_per_sample": 12.5, "extra": {}}]})
    put("roughness", {"rows": [{"rtol": 1e-6, "integrator": "auto:rk4", "ratio": 1.34, "smooth_rhs": 4.0,
                                "vibrating_rhs": 5.0, "smooth_error": 7e-11, "vibrating_error": 2e-10},
                               {"rtol": 1e-8, "integrator": "auto:rk4", "ratio": None, "smooth_rhs": 9.0,
                                "vibrating_rhs": 14.0, "smooth_error": 6e-12, "vibrating_error": 1e-11}]})
    put("peer", {"scenes": [{"scene": "ship", "comparison": [{"error_level": 1e-11, "ratio_kernel": 1.6,
                                                              "ratio_consumer": 1.1}]}]}, age=3600)
    rows = headline(tmp_path, since=t0)
    got = {r["figure"]: r["met"] for r in rows}
    assert got == {
        "set-up step `gyro-platform compile`, empty kernel cache": None,
        "run default: cold ÷ warm; after the set-up step ÷ warm": [False, True],     # ×15, ×1.1
        "node: cold ÷ warm": True,                                                   # ×2.5
        "replay 1 kHz: real-time ×; replay ÷ its I/O floor": [False, True],
        "replay husky: real-time ×": True, "node (median)": False,
        "vibrating ÷ smooth 1 kHz IMU, right-hand sides per sample at equal delivered accuracy, smooth at rtol "
        "1e-06 (auto:rk4)": True,
        "vibrating ÷ smooth 1 kHz IMU, right-hand sides per sample at equal delivered accuracy, smooth at rtol "
        "1e-08 (auto:rk4)": False}                                            # not reached: no ratio, ✗
    assert not any("MuJoCo" in f for f in got)                            # the peer report is older than the run
    text = (tmp_path / "headline.md").read_text()
    assert ("| run default: cold ÷ warm; after the set-up step ÷ warm | ×15.0 (60.0 s / 4.00 s, its CPU 100 s "
            "allows ≥ ×12.5 on 2 CPUs); ×1.1 | ≤ ×3 | ✗; ✓ |") in text
    assert ("| ×250 (whole command ×38) (CPU 0.60 s: ≤ ×400 on 2 CPUs); 1.60 (floor ×400) | ≥ ×500; ≤ ×2 "
            "| ✗; ✓ |") in text
    assert "| replay husky: real-time × | ×520 (new process: prints ×330, whole command ×110) | ≥ ×300 | ✓ |" in text
    assert "| node (median) | 12.5 µs | ≤ 10 µs | ✗ |" in text
    assert "| ×1.34 (at the same rtol ×1.25, errors 7.0e-11 / 2.0e-10 rad) | ≤ ×1.5 | ✓ |" in text
    assert "| not reached in the sweep (at the same rtol ×1.56, errors 6.0e-12 / 1.0e-11 rad) | ≤ ×1.5 | ✗ |" in text
    assert text in capsys.readouterr().out
