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

"""The chunked pipeline against the per-message path (the reference, ``engine="per_message"``):
identical output bags (every topic's records, byte for byte: stamps, values, order), the same
counts and gate figures, on generated 1 kHz bags full of faults, across chunk boundaries, on
the shared recordings, through simulator failures and interrupts."""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from gyro_platform import messages as m
from gyro_platform import replay as rp
from gyro_platform.physics.options import ModelOptions
from gyro_platform.pipeline.gate_rules import GateConfig
from gyro_platform.pipeline.grid import grid_index, grid_indices, new_slots
from gyro_platform.replay.stats import LineFit, PlotSeries, Stats
from imubag import raw_by_topic

JAZZY = get_typestore(Stores.ROS2_JAZZY)
T = JAZZY.types
S = 1_000_000_000
T0 = 1_700_000_000 * S
BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
ROOT = Path(__file__).resolve().parents[1]


def imu(stamp_ns: int, w, frame="base_link", cov_w=0.0, cov_a=0.0, f=(0.0, 0.0, 9.81)) -> bytes:
    cw, ca = np.zeros(9), np.zeros(9)
    cw[0], ca[0] = cov_w, cov_a
    msg = T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp_ns // S, nanosec=stamp_ns % S),
                                        frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
        angular_velocity=T["geometry_msgs/msg/Vector3"](x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=cw,
        linear_acceleration=T["geometry_msgs/msg/Vector3"](x=f[0], y=f[1], z=f[2]),
        linear_acceleration_covariance=ca)
    return bytes(JAZZY.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def vehicle_rate(t: float) -> tuple[float, float, float]:
    """A vehicle rocking about all axes (rad/s)."""
    return (0.3 * math.sin(2.1 * t), 0.2 * math.sin(1.3 * t + 0.5), 0.1 * math.cos(0.7 * t))


def faulty_stream(seconds: float = 3.0, rate: float = 1000.0) -> list[tuple[int, bytes]]:
    """(receive ns, CDR) of a 1 kHz Imu stream with every kind of fault: drops of each reason,
    a gap (reset), a loop (jump back), a frame without mounting, rows without specific force."""
    dt = int(S / rate)
    rows, t, rx = [], T0, T0                   # header stamps loop; the receive clock does not
    n = int(seconds * rate)
    for i in range(n):
        w = vehicle_rate((t - T0) / S)
        k = i % 97
        raw = {11: lambda: imu(0, w),                                     # zero_stamp
               23: lambda: imu(t - 5 * dt, w),                            # backward_stamp
               31: lambda: imu(t, (math.nan, 0.0, 0.0)),                  # non_finite
               37: lambda: imu(t, (50.0, 0.0, 0.0)),                      # over_rate
               41: lambda: imu(t, w, cov_w=-1.0),                         # no_rate
               43: lambda: b"\x00\x01\x00\x00garbage",                    # bad_message
               47: lambda: imu(t, w, frame="elsewhere"),                  # frame without mounting
               53: lambda: imu(t, w, cov_a=-1.0),                         # no specific force
               }.get(k, lambda: imu(t, w))()
        rows.append((rx, raw))
        t += dt
        rx += dt
        if i == n // 3:
            t += 2 * S                                                    # gap > max_gap: reset
            rx += 2 * S
        if i == 2 * n // 3:
            t -= 2 * S                                                    # loop: jump back, reset
    return rows


def write_bag(path: Path, rows, storage: str = "sqlite3", topic: str = "/imu") -> Path:
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=JAZZY)
        other = w.add_connection("/odom_twist", "geometry_msgs/msg/Twist", typestore=JAZZY)
        tw = bytes(JAZZY.serialize_cdr(T["geometry_msgs/msg/Twist"](
            linear=T["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
            angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)), "geometry_msgs/msg/Twist"))
        for j, (ts, raw) in enumerate(rows):
            w.write(conn, ts, raw)
            if j % 50 == 0:
                w.write(other, ts + 1, tw)
    return path


def both(bag: Path, tmp: Path, **cfg) -> dict[str, tuple[dict, dict]]:
    """Replay ``bag`` with both engines; engine -> (summary, records by topic)."""
    res = {}
    for engine in ("per_message", "chunked"):
        out = tmp / f"out_{engine}"
        s = rp.replay(bag, out, rp.ReplayConfig(progress=False, plot=False, engine=engine, **cfg))
        res[engine] = (s, raw_by_topic(out))
    return res


def assert_same(res: dict[str, tuple[dict, dict]]) -> None:
    (s_ref, ref), (s, got) = res["per_message"], res["chunked"]
    assert sorted(got) == sorted(ref)
    for topic in ref:
        assert len(got[topic]) == len(ref[topic]), topic
        assert got[topic] == ref[topic], f"{topic}: records differ"
    for key in ("counts", "gate", "output", "simulated", "no_usable_input"):
        if key == "output":
            ref = {k: v for k, v in s_ref[key].items() if k != "bag"}
            assert {k: v for k, v in s[key].items() if k != "bag"} == ref
        else:
            assert s[key] == s_ref[key], key
    assert list(s["counts"]["simulator"]) == list(s_ref["counts"]["simulator"])    # key order (diagnostics)
    assert s["simulator"]["errors"] == s_ref["simulator"]["errors"]
    assert s["simulator"]["stats"]["n_samples"] == s_ref["simulator"]["stats"]["n_samples"]
    assert s["ranges"] == s_ref["ranges"] and s["non_finite_outputs"] == s_ref["non_finite_outputs"]
    d, d_ref = s["drift"], s_ref["drift"]
    assert d.keys() == d_ref.keys()
    if "drift_rate_rad_s" in d:
        for ax in "xyz":
            assert d["drift_rate_rad_s"][ax] == pytest.approx(d_ref["drift_rate_rad_s"][ax], rel=1e-9, abs=1e-15)


# ---- generated 1 kHz bags -------------------------------------------------------------------
@pytest.mark.parametrize("storage,output_rate,chunk_rows,diag", [
    ("sqlite3", 100.0, 7, 1.0), ("mcap", None, 4096, 25.0), ("sqlite3", 3.0, 333, 7.0)])
def test_generated_faulty_bag_identical_to_per_message(tmp_path, storage, output_rate, chunk_rows, diag):
    bag = write_bag(tmp_path / "in", faulty_stream(1.2), storage)
    res = both(bag, tmp_path, output_rate=output_rate, chunk_rows=chunk_rows, diagnostics_rate=diag,
               mounting=m.Mounting(unknown_frame="identity"))
    s = res["chunked"][0]
    # the faults are there (the comparison covers them)
    assert set(s["counts"]["dropped_by_reason"]) >= {"zero_stamp", "backward_stamp", "non_finite", "over_rate",
                                                     "no_rate", "bad_message"}
    assert s["counts"]["resets_by_reason"] == {"gap": 1, "jump_back": 1}
    assert s["counts"]["notes"]["identity_frame"] > 0
    assert s["counts"]["accepted"] == s["simulated"] > 0 and not s["no_usable_input"]
    assert_same(res)


def test_unknown_frame_rejected_and_specific_force_effects(tmp_path):
    """unknown_frame="reject" and an effect that needs the specific force: rows without it
    are refused by the simulator (``rejected``) on both paths alike."""
    bag = write_bag(tmp_path / "in", faulty_stream(0.6), "mcap")
    opts = ModelOptions(effects=frozenset(ModelOptions().effects) | {"mass_unbalance"})
    res = both(bag, tmp_path, output_rate=50.0, chunk_rows=64, options=opts,
               mounting=m.Mounting(unknown_frame="reject"))
    s = res["chunked"][0]
    assert s["counts"]["dropped_by_reason"]["unknown_frame"] > 0
    assert s["counts"]["simulator"]["rejected"] > 0
    refused = s["counts"]["dropped_by_reason"].get("refused", 0)         # a gate that takes refusals back
    assert s["simulated"] == s["counts"]["accepted"] - s["counts"]["simulator"]["rejected"] + refused
    assert_same(res)


def test_simulation_error_restarts_like_per_message(tmp_path):
    """An integrator that cannot meet its tolerance on some intervals (rk4, one substep, a
    tight tolerance, a vehicle rate that jumps): each failing sample restarts the simulator
    (counted ``restarted``, outputs before it kept) exactly as on the per-message path."""
    rows, t = [], T0
    for i in range(400):
        w = (8.0 if (i // 40) % 2 else -8.0, 0.5, 0.0)
        rows.append((t, imu(t, w)))
        t += S // 1000
    bag = write_bag(tmp_path / "in", rows)
    opts = ModelOptions(integrator="rk4", rtol=1e-9, atol=1e-12, max_substeps=1)
    res = both(bag, tmp_path, output_rate=200.0, chunk_rows=128, options=opts)
    s = res["chunked"][0]
    assert s["counts"]["simulator"].get("restarted", 0) > 0, s["counts"]["simulator"]
    assert s["simulator"]["errors"]
    assert_same(res)


def unbounded_force_gate() -> GateConfig:
    """A gate that lets every specific force through: no finite bound can (the norm of 1e200 m/s²
    overflows), and GateConfig refuses a bound of inf, so it is set after the check."""
    gate = GateConfig()
    object.__setattr__(gate, "max_specific_force", math.inf)
    return gate


def test_failed_outputs_like_per_message(tmp_path):
    """A finite but absurd specific force (1e200 m/s², anisoelastic on; let through the gate's
    ``max_specific_force``, which drops it by default): the outputs of that instant are not
    finite and the next interval cannot be integrated. On the first sample, right after a reset
    and in mid-run, each such instant is counted ``output_failed`` and the simulation goes on
    exactly as on the per-message path (the chunked path raised an AttributeError here, on the
    first sample of a run)."""
    bad, rows, t = (1e200, 5e199, -1e200), [], T0
    for i in range(300):
        rows.append((t, imu(t, vehicle_rate((t - T0) / S), f=bad if i in (0, 150, 151, 222) else (0.0, 0.0, 9.81))))
        t += S // 1000
        if i == 149:
            t += 2 * S                                                    # gap: a reset at row 150
    bag = write_bag(tmp_path / "in", rows, "mcap")
    opts = ModelOptions(effects=frozenset(ModelOptions().effects) | {"anisoelastic"}, fidelity="full")
    res = both(bag, tmp_path, output_rate=None, chunk_rows=64, options=opts,
               gate=unbounded_force_gate())
    sim = res["chunked"][0]["counts"]["simulator"]
    assert sim["output_failed"] == 4 and sim["restarted"] > 0 and sim["reset"] == 1, sim
    assert_same(res)


# ---- the shared recordings ------------------------------------------------------------------
def need(bag: Path) -> None:
    if not bag.exists():
        pytest.skip(f"real recording absent: {bag}")


def test_cabrillo_identical_every_sample(tmp_path):
    bag = BAGS / "cabrillo_rov_bno085_imu"
    need(bag)
    assert_same(both(bag, tmp_path, output_rate=None))


def test_husky_identical_with_mounting(tmp_path):
    bag = BAGS / "robot_localization_husky_test1"
    need(bag)
    mount = m.Mounting({"imu_link": (math.pi / 2, 0.0, -math.pi / 2)}, unknown_frame="reject")
    assert_same(both(bag, tmp_path, output_rate=2.0, mounting=mount, chunk_rows=1000))


# ---- pieces ---------------------------------------------------------------------------------
@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-10**12, 10**12), min_size=1, max_size=40), st.integers(-10**12, 10**12),
       st.sampled_from([1.0, 3.0, 10.0, 100.0, 0.7, 1000.0, 33.333]))
def test_grid_indices_are_grid_index(ts, origin, rate):
    got = grid_indices(np.array(ts, dtype=np.int64), origin, rate)
    assert got.tolist() == [grid_index(t, origin, rate) for t in ts]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-50, 50), min_size=1, max_size=30), st.one_of(st.none(), st.integers(-50, 50)))
def test_new_slots_is_the_running_due(slots, last):
    ref, cur = [], last
    for s in slots:
        ref.append(cur is None or s > cur)
        if ref[-1]:
            cur = s
    assert new_slots(np.array(slots, dtype=np.int64), last).tolist() == ref


def test_stats_from_blocks_equal_per_output():
    """Stats.add_block == Stats.add per output (ranges, non-finite counts, drift slope)."""
    from gyro_platform.engine.inputs import RateSample
    from gyro_platform.engine.outputs import OutputBlock
    from gyro_platform.engine.simulator import Simulator

    sim = Simulator()
    outs = []
    for i in range(60):
        sim.push(RateSample.of(i * 0.01, vehicle_rate(i * 0.01)))
        outs.append(sim.outputs())
    outs[17].bearing_torques["support"][1] = math.nan                   # a non-finite column
    a, b = Stats(), Stats()
    for i, o in enumerate(outs):
        a.add(o, new_segment=i == 30)
    b.add_block(OutputBlock.stack(outs[:13]), False)
    b.add_block(OutputBlock.stack(outs[13:30]), False)
    b.add_block(OutputBlock.stack(outs[30:]), True)
    assert b.ranges() == a.ranges() and b.non_finite == a.non_finite == {"support_torque_y_N_m": 1}
    assert b.n == a.n
    da, db = a.drift(), b.drift()
    assert db["final_drift_angle_rad"] == da["final_drift_angle_rad"]
    assert db["fit_outputs"] == da["fit_outputs"] == 30
    for ax in "xyz":
        assert db["drift_rate_rad_s"][ax] == pytest.approx(da["drift_rate_rad_s"][ax], rel=1e-9, abs=1e-18)


def test_line_fit_many_equals_streaming():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.001, 0.1, 200))
    y = np.column_stack([2.5 * t + rng.normal(0, 0.01, 200), -t, np.ones(200)])
    a, b = LineFit(), LineFit()
    for ti, yi in zip(t, y):
        a.add(ti, yi)
    b.add_many(t[:77], y[:77])
    b.add_many(t[77:], y[77:])
    assert b.slope() == pytest.approx(a.slope(), rel=1e-10, abs=1e-12) and b.n == a.n and b.span == a.span
    assert b.slope() == pytest.approx([2.5, -1.0, 0.0], abs=0.01)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 5), st.lists(st.integers(0, 40), max_size=12))
def test_plot_series_buckets_hold_every_outputs_extremes(half_cap, sizes):
    """PlotSeries: add_block keeps the buckets K calls of add keep, and each bucket holds the
    minimum and maximum over exactly its ``stride`` outputs (brute force over all of them),
    however the outputs arrive; at most ``cap`` buckets."""
    from gyro_platform.engine.outputs import OutputBlock
    from gyro_platform.replay.stats import plot_columns

    cap = 2 * half_cap
    outs = _outputs(sum(sizes))
    a, b, n = PlotSeries(cap), PlotSeries(cap), 0
    for k in sizes:
        for o in outs[n:n + k]:
            a.add(o)
        if k:
            b.add_block(OutputBlock.stack(outs[n:n + k]))
        n += k
        assert (a.stride, a.n, a.nb) == (b.stride, b.n, b.nb) and b.nb <= cap
        for x, y in zip(a.columns(), b.columns()):
            assert np.array_equal(x, y)
        if n:
            m = plot_columns(OutputBlock.stack(outs[:n]))
            t = np.array([o.t for o in outs[:n]])
            edges = np.arange(0, n, b.stride)
            assert len(edges) == b.nb
            tb, lo, hi = b.columns()
            assert np.array_equal(lo, np.minimum.reduceat(m, edges, axis=0))
            assert np.array_equal(hi, np.maximum.reduceat(m, edges, axis=0))
            assert np.array_equal(tb, t[edges]) and np.array_equal(b.t_last[:b.nb], t[np.r_[edges[1:], n] - 1])
            assert np.array_equal(b.last, m[-1])


def test_plot_series_summary_is_the_recorders_over_every_output():
    """The replay's ``recorder`` figures from a PlotSeries thinned 64-fold equal
    ``Recorder.summary`` over all outputs (maxima, final values; the drift rate of the
    replay's own least-squares fit), and the plot strokes span every output's range."""
    from gyro_platform.engine.outputs import OutputBlock
    from gyro_platform.reports.recording import Recorder

    outs = _outputs(500)
    ps, stats, rec = PlotSeries(8), Stats(), Recorder()
    for i in range(0, 500, 70):
        blk = OutputBlock.stack(outs[i:i + 70])
        ps.add_block(blk)
        stats.add_block(blk, i == 0)
    for o in outs:
        rec.append(o)
    assert ps.stride == 64
    got, want = ps.summary(stats.drift_fit()), rec.summary()
    for key in ("n_outputs", "t_start", "duration", "max_abs_gimbal_angle", "final_gimbal_angle",
                "max_abs_bearing_torque", "max_abs_motor_torque", "max_abs_servo_torque",
                "final_drift_angle", "max_abs_drift_angle", "drift_fit_start"):
        assert got[key] == pytest.approx(want[key], rel=1e-12, abs=1e-300), key
    for key in ("drift_rate", "drift_rate_deg_per_h"):
        assert got[key] == pytest.approx(want[key], rel=1e-6), key
    data, full = ps.plot_data(), rec.plot_data()
    assert len(data.t_rel) == 2 * ps.nb and data.t_rel[-1] <= full.t_rel[-1]
    for x, y in ((data.gimbal_angles, full.gimbal_angles), (data.drift_angle, full.drift_angle),
                 (data.bearings["gimbal10"], full.bearings["gimbal10"]), (data.servo_torque, full.servo_torque)):
        assert np.array_equal(x.min(axis=0), y.min(axis=0)) and np.array_equal(x.max(axis=0), y.max(axis=0))


_OUTS: list = []


def _outputs(n: int) -> list:
    """n distinct outputs of a real simulator (cached)."""
    from gyro_platform.engine.inputs import RateSample
    from gyro_platform.engine.simulator import Simulator

    if len(_OUTS) < n:
        sim = Simulator()
        _OUTS.clear()
        for i in range(max(n, 500)):
            sim.push(RateSample.of(i * 0.01, vehicle_rate(i * 0.01)))
            _OUTS.append(sim.outputs())
    return _OUTS[:n]


# ---- interrupts: what is counted is what was simulated --------------------------------------
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_at_a_chunk_boundary_with_consistent_counts(tmp_path, sig):
    rows = faulty_stream(30.0)
    bag = write_bag(tmp_path / "in", rows, "sqlite3")
    # an expensive model (rk4, 500 substeps per 1 ms sample) keeps the replay running for a while
    scene = tmp_path / "slow.yaml"
    scene.write_text("name: slow\nmode: stabilised\nintegrator: rk4\nmax_step: 2.0e-6\nduration: 30.0\n"
                     "sample_rate: 100.0\noutput_rate: 100.0\nmotion: {type: constant, omega: [0.0, 0.0, 0.1]}\n")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # the same replay of the same bag first, with a cheap step bound (the same kernels: they are
    # typed on the model and the method, not on max_step), so that every kernel the slow replay
    # runs (the per-sample one after its resets too) is compiled: a signal during a compile stops
    # the replay before any sample is simulated, which is right but not what this test looks at
    warm = tmp_path / "warm.yaml"
    warm.write_text(scene.read_text().replace("max_step: 2.0e-6", "max_step: 1.0e-3"))
    subprocess.run([sys.executable, "-m", "gyro_platform", "replay", str(bag), "--out", str(tmp_path / "warm_out"),
                    "--quiet", "--no-plot", "--scene", str(warm)], cwd=ROOT, env=env, capture_output=True, timeout=600)
    proc = subprocess.Popen([sys.executable, "-m", "gyro_platform", "replay", str(bag), "--out", str(out),
                             "--quiet", "--no-plot", "--scene", str(scene)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    summary = Path(str(out) + ".summary.json")
    deadline = time.monotonic() + 120
    while not any(out.glob("*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(2.0)                                                       # into the loop
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.skip("the replay finished before the signal arrived")
    assert proc.returncode == (143 if sig == signal.SIGTERM else 130) and "Traceback" not in err, err
    s = json.loads(summary.read_text())
    assert s["error"] == ("terminated" if sig == signal.SIGTERM else "interrupted")
    assert s["interrupted_by"] == signal.Signals(sig).name
    c = s["counts"]
    assert 0 < c["in"] < len(rows)
    assert c["accepted"] == s["simulated"] == sum(v for k, v in c["simulator"].items()
                                                  if k in ("pushed", "reset", "restarted"))
    assert c["accepted"] + c["dropped"] == c["in"]
    got = raw_by_topic(out)                                                   # closed and readable
    assert len(got["/gimbal/joint_states"]) == c["out"] == s["output"]["outputs"]
    assert len(got["/imu"]) == c["in"] and len(got["/imu"]) + len(got["/odom_twist"]) == s["input"]["messages"]


def test_nothing_simulated_is_said_in_the_summary(tmp_path):
    """Every sample reaches the simulator without the specific force an effect needs: none
    can be simulated; the summary says so (``no_usable_input``, a warning), no outputs."""
    rows = [(T0 + i * S // 100, imu(T0 + i * S // 100, (0.0, 0.0, 0.1), cov_a=-1.0)) for i in range(50)]
    bag = write_bag(tmp_path / "in", rows)
    opts = ModelOptions(effects=frozenset(ModelOptions().effects) | {"mass_unbalance"})
    res = both(bag, tmp_path, output_rate=None, options=opts)
    s = res["chunked"][0]
    assert s["no_usable_input"] is True and s["simulated"] == 0 and s["counts"]["out"] == 0
    assert s["warnings"] and ("could be simulated" in s["warnings"][0] or "accepted" in s["warnings"][0])
    assert "/gimbal/joint_states" not in res["chunked"][1]
    assert_same(res)
