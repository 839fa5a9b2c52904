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

"""The node core without ROS: rosbags Jazzy messages in, (topic, message) pairs out.

Drives :class:`gyro_platform.ros.core.NodeCore` the way the rclpy node and the DDS adapter do —
one message per call with its receive time — with scripted rate samples at 1 kHz and 100 Hz,
and checks the published topics, types, stamps and values against the physics (spec O6, O9b),
the handling of bad input (counted, never raised), live parameters, resets and the config files.
Callback timing uses a fake clock (25 µs per callback), so no assertion depends on wall time.
"""
from __future__ import annotations

from dataclasses import fields
import itertools
import math
from pathlib import Path
import subprocess
import sys

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from gyro_platform.messages import jazzy_typestore, MessageTypes, stamp_ns
from gyro_platform.physics.params import NAV1, PlatformParams
from gyro_platform.ros import parameters as P
from gyro_platform.ros.config import NodeConfig, parameter_defaults
from gyro_platform.ros.core import NodeCore
from gyro_platform.ros.parameters import ConfigError

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "config" / "scenes").glob("*.yaml"))
TYPES = MessageTypes.rosbags()
T = jazzy_typestore().types
BASE = 1_700_000_000 * 10**9            # ns, a bag-like epoch stamp
MS = 10**6
L11 = NAV1.L[2]                         # N m s, rotor 11
Q10 = 1e-4                              # N m, bias torque on beta10
DRIFT = -Q10 / L11                      # rad/s, spec O9(b): −1.98944e-3


# ---- message builders (rosbags Jazzy classes) ---------------------------------------------
def _stamp(t_ns: int):
    sec, nsec = divmod(int(t_ns), 10**9)
    return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _v3(v):
    return T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def imu(t_ns: int, w=(0.0, 0.0, 0.0), acc=(0.0, 0.0, 9.81), frame="base_link", cov_w=0.0, cov_a=0.0):
    cw, ca = np.zeros(9), np.zeros(9)
    cw[0], ca[0] = cov_w, cov_a
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=_stamp(t_ns), frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9), angular_velocity=_v3(w), angular_velocity_covariance=cw,
        linear_acceleration=_v3(acc), linear_acceleration_covariance=ca)


def twist(w):
    return T["geometry_msgs/msg/Twist"](linear=_v3((0, 0, 0)), angular=_v3(w))


def twist_stamped(t_ns: int, w, frame="base_link"):
    return T["geometry_msgs/msg/TwistStamped"](header=T["std_msgs/msg/Header"](stamp=_stamp(t_ns), frame_id=frame),
                                               twist=twist(w))


def make_core(**params) -> NodeCore:
    """A core from ros__parameters (nested dicts allowed), timed by a fake clock: 25 µs per callback."""
    return NodeCore(NodeConfig.from_ros_params(params), TYPES, clock_ns=itertools.count(0, 25_000).__next__)


def statuses(arr) -> dict[str, tuple[int, str, dict[str, str]]]:
    return {s.name: (s.level, s.message, {kv.key: kv.value for kv in s.values}) for s in arr.status}


STABILISED_BIAS = {"effects": ["rotor_gyroscopic", "coriolis", "servo", "bias_torque"],
                   "physics": {"bias_torque": [0.0, 0.0, 0.0, 0.0, Q10]}}


# =========================================================================================
# scenarios
# =========================================================================================
def test_stabilised_bias_torque_drift_at_1khz_every_sample_published():
    """O9(b) through the node: Q10 = 1e-4 N m drags the platform at Ω3 = −Q10/L11."""
    core = make_core(output_rate=0.0, **STABILISED_BIAS)
    expected_topics = core.output_topics()
    t, drift_z, rate_z = [], [], []
    for k in range(1001):
        stamp = BASE + k * MS
        out = core.on_message(imu(stamp), stamp + 200_000)        # received 0.2 ms after its stamp
        assert [topic for topic, _ in out] == list(expected_topics)
        for topic, m in out:
            assert m.__msgtype__ == expected_topics[topic]
            head = m.transforms[0].header if topic == "/tf" else m.header
            assert stamp_ns(head.stamp) == stamp                     # the sample's own time, exact ns
        d = dict(out)
        assert d["drift/angle"].header.frame_id == "platform"
        assert d["bearing/gimbal4/torque"].header.frame_id == "gyro_frame4"
        assert list(d["gimbal/joint_states"].name[:5]) == ["alpha4", "beta5", "beta7", "alpha9", "beta10"]
        t.append(k * 1e-3)
        drift_z.append(d["drift/angle"].vector.z)
        rate_z.append(d["drift/rate"].vector.z)
    t, drift_z, rate_z = map(np.asarray, (t, drift_z, rate_z))
    late = t >= 0.5                      # after the servo transient; 1 kHz resolves the 122 Hz nutation
    assert DRIFT == pytest.approx(-1.98944e-3, rel=1e-5)
    assert np.polyfit(t[late], drift_z[late], 1)[0] == pytest.approx(DRIFT, rel=1e-4)
    assert np.mean(rate_z[late]) == pytest.approx(DRIFT, rel=2e-3)
    snap = core.snapshot()
    assert snap["accepted"] == 1001 and snap["dropped"] == 0 and snap["outputs_published"] == 1001
    assert snap["simulator"] == {"pushed": 1001}


def test_carried_free_gyro_at_100hz_twist_stamped_outputs_on_a_10hz_grid():
    """O6: a free gyro keeps its direction, so under Ω2 = 0.5 rad/s alpha4 = −0.5 t."""
    core = make_core(mode="carried", input_type="twist_stamped", output_rate=10.0)
    assert core.input_topics() == {"twist": "geometry_msgs/msg/TwistStamped"}
    published = []
    for k in range(401):                                          # 4 s at 100 Hz
        stamp = BASE + k * 10 * MS
        out = core.on_message(twist_stamped(stamp, (0.0, 0.5, 0.0)), stamp)
        if out:
            js = dict(out)["gimbal/joint_states"]
            published.append(k)
            assert stamp_ns(js.header.stamp) == stamp
            assert js.position[0] == pytest.approx(-0.5 * k * 0.01, abs=1e-9)
            assert np.max(np.abs(np.asarray(js.position[1:5]))) < 1e-9
            # carried: no mount joints
            assert list(js.name) == ["alpha4", "beta5", "beta7", "alpha9", "beta10", "rotor6", "rotor8", "rotor11"]
    assert published == list(range(0, 401, 10))                   # first sample, then one per 0.1 s slot


def test_twist_without_header_is_timed_by_the_receive_clock():
    core = make_core(mode="carried", input_type="twist", output_rate=0.0)
    for k in range(101):
        rx = BASE + k * 10 * MS
        out = core.on_message(twist((0.0, 0.5, 0.0)), rx)
        js = dict(out)["gimbal/joint_states"]
        assert stamp_ns(js.header.stamp) == rx
    assert js.position[0] == pytest.approx(-0.5, abs=1e-9)
    snap = core.gate.snapshot()
    assert snap["time_source"] == "receive" and snap["notes"]["receive_time"] == 101
    # without a receive time there is no time: dropped as no_time, never raised
    assert core.on_message(twist((0.0, 0.5, 0.0)), None) == []
    assert core.gate.snapshot()["dropped_by_reason"] == {"no_time": 1}


def test_sensor_mounting_rotates_the_input_into_the_vehicle_frame():
    core = make_core(mode="carried", output_rate=0.0, sensor_mountings=["imu_link=0.0,0.0,1.5707963267948966"],
                     unknown_frame="reject")
    core.on_message(imu(BASE, w=(0.5, 0.0, 0.0), frame="imu_link"), BASE)
    np.testing.assert_allclose(core.gate.last.sample.omega, [0.0, 0.5, 0.0], atol=1e-12)   # yaw 90°: x → y
    core.on_message(imu(BASE + MS, w=(0.5, 0.0, 0.0), frame="camera_link"), BASE + MS)
    assert core.gate.snapshot()["dropped_by_reason"] == {"unknown_frame": 1}


def test_a_namespaced_robots_prefixed_frames_take_their_mountings():
    """With ``frame_prefix`` robot1/ (what the launch file sets for namespace robot1) the drivers
    stamp robot1/imu_link and robot1/base_link: the mounting of imu_link applies, base_link is
    the vehicle frame; unprefixed names still work. Before, both were taken as base_link (the
    rotation dropped) and, with unknown_frame reject, dropped."""
    core = make_core(mode="carried", output_rate=0.0, frame_prefix="robot1/", unknown_frame="reject",
                     sensor_mountings=["imu_link=0.0,0.0,1.5707963267948966"])
    for k, frame in enumerate(("robot1/imu_link", "imu_link")):
        core.on_message(imu(BASE + k * MS, w=(0.5, 0.0, 0.0), frame=frame), BASE + k * MS)
        np.testing.assert_allclose(core.gate.last.sample.omega, [0.0, 0.5, 0.0], atol=1e-12)   # yaw 90°
    for k, frame in enumerate(("robot1/base_link", "base_link"), start=2):
        core.on_message(imu(BASE + k * MS, w=(0.5, 0.0, 0.0), frame=frame), BASE + k * MS)
        np.testing.assert_allclose(core.gate.last.sample.omega, [0.5, 0.0, 0.0], atol=1e-12)
    core.on_message(imu(BASE + 4 * MS, frame="robot2/imu_link"), BASE + 4 * MS)
    assert core.gate.snapshot()["dropped_by_reason"] == {"unknown_frame": 1}


def test_unmounted_frames_are_named_up_to_sixteen_and_cut_to_64_characters():
    """500 frame ids without mounting and one of 100 000 characters: 17 lines, not 501, and a
    diagnostics value of bounded size (it was 104 390 characters, republished every second)."""
    core = make_core(output_rate=0.0)
    frames = ["x" * 100_000] + [f"f{i}" for i in range(500)]
    for k, frame in enumerate(frames):
        core.on_message(imu(BASE + k * MS, frame=frame), BASE + k * MS)
    notices = core.take_notices()
    assert len(notices) == 17 and "more than 16" in notices[-1] and max(map(len, notices)) < 200
    snap = core.snapshot(BASE + len(frames) * MS)
    assert len(snap["frames_taken_as_base_link"]) < 16 * 70 and snap["frames_taken_as_base_link"].endswith("…")
    assert sum(map(len, snap["input_frames"])) < 17 * 70


def test_an_input_slower_than_max_gap_restarts_at_every_sample_and_the_node_warns():
    """gate.max_gap 5 ms against a 100 Hz input for 21 s: every sample restarts the simulation, which never
    integrates; the node said OK. Now it WARNs, and the gap restarts are said in a line, at most
    one per 10 s of receive time (with the count of those not said)."""
    core = make_core(output_rate=0.0, gate={"max_gap": 0.005})
    for k in range(2100):
        core.on_message(imu(BASE + k * 10 * MS), BASE + k * 10 * MS)
    assert core.resets["gap"] == 2099
    level, message, _ = statuses(core.diagnostics(BASE + 2099 * 10 * MS))["gyro_platform: node"]
    assert level == 1 and "restarting repeatedly" in message and "gate.max_gap" in message
    lines = [n for n in core.take_notices() if "input gap" in n]
    assert len(lines) == 3 and "more since the last line" in lines[1]
    steady = make_core(output_rate=0.0)
    for k in range(300):
        steady.on_message(imu(BASE + k * 10 * MS), BASE + k * 10 * MS)
    assert statuses(steady.diagnostics(BASE + 299 * 10 * MS))["gyro_platform: node"][0] == 0


def test_unknown_frame_taken_as_identity_is_one_notice_and_a_count_not_a_warning():
    core = make_core(mode="carried", output_rate=0.0)            # unknown_frame: identity (default)
    for k in range(5):
        out = core.on_message(imu(BASE + k * MS, w=(0.5, 0.0, 0.0), frame="imu_link"), BASE + k * MS)
    np.testing.assert_allclose(core.gate.last.sample.omega, [0.5, 0.0, 0.0], atol=1e-12)
    notices = core.take_notices()
    assert len(notices) == 1 and "imu_link" in notices[0] and core.take_notices() == []
    diag = dict(out)["/diagnostics"] if "/diagnostics" in dict(out) else core.diagnostics(BASE + 5 * MS)
    level, message, values = statuses(diag)["gyro_platform: input"]
    assert level == 0 and "base_link" in message                 # OK, said once; counted below
    assert values["notes.identity_frame"] == "5"


@pytest.mark.parametrize("mode", ["stabilised", "carried"])
def test_tf_puts_platform_reference_where_the_vehicle_attitude_says(mode):
    """``/tf`` carries ``platform`` → ``platform_reference`` (the frame of ``platform/attitude``),
    so TF chains base_link → platform (the mount joints or the mounting) → platform_reference:
    under a constant body rate w (rad/s) for t s that chain is the vehicle's attitude in the
    reference, ``exp(t w×)`` (the reference is base_link's axes at the first sample; whatever the
    mounting, here 30° of yaw: the platform starts at its mounting)."""
    from scipy.spatial.transform import Rotation

    from gyro_platform.ros.urdf import config_model

    mounting = [0.0, 0.0, math.sin(math.pi / 12), math.cos(math.pi / 12)]
    core = make_core(mode=mode, output_rate=100.0, frame_prefix="r1/", physics={"mounting": mounting})
    model = config_model(core.config)
    w = np.array([0.05, -0.02, 0.1]) * 5.0
    worst = 0.0
    for k in range(1001):
        for topic, m in core.on_message(imu(BASE + k * MS, w=w), BASE + k * MS):
            if topic == "gimbal/joint_states":
                base_platform = model.link_rotations(dict(zip(m.name, m.position)))["platform"]
            elif topic == "/tf":
                (tf,) = m.transforms
                assert (tf.header.frame_id, tf.child_frame_id) == ("r1/platform", "r1/platform_reference")
                assert stamp_ns(tf.header.stamp) == BASE + k * MS and tf.transform.translation.x == 0.0
                r = tf.transform.rotation
                platform_reference = Rotation.from_quat([r.x, r.y, r.z, r.w])
                base_reference = base_platform * platform_reference      # reference axes in base_link's
                worst = max(worst, (base_reference * Rotation.from_rotvec(w * k * 1e-3)).magnitude())
    assert k == 1000 and worst < 1e-12, worst


def test_frame_prefix_is_put_before_every_output_frame():
    core = make_core(output_rate=0.0, frame_prefix="robot1/")
    d = dict(core.on_message(imu(BASE), BASE))
    assert d["drift/rate"].header.frame_id == "robot1/platform"
    assert d["bearing/rotor11/torque"].header.frame_id == "robot1/gyro_housing10"
    assert d["gimbal/joint_states"].header.frame_id == ""          # joint space has no frame


# =========================================================================================
# bad input: counted, never raised
# =========================================================================================
def test_bad_input_is_counted_by_reason_and_never_raises():
    core = make_core(output_rate=0.0, unknown_frame="reject")

    def good(k):
        return core.on_message(imu(BASE + k * MS), BASE + k * MS)
    for k in range(5):
        assert good(k)
    bad = [
        imu(BASE + 5 * MS, w=(math.nan, 0.0, 0.0)),              # non_finite
        imu(BASE + 5 * MS, acc=(0.0, math.inf, 9.81)),           # non_finite (specific force)
        imu(BASE + 5 * MS, w=(100.0, 0.0, 0.0)),                 # over_rate (> 35 rad/s)
        imu(BASE + 5 * MS, acc=(1e20, 0.0, 9.81)),               # over_specific_force (> 2000 m/s²)
        imu(0),                                                  # zero_stamp
        imu(BASE + 2 * MS),                                      # backward_stamp (2 ms back)
        imu(BASE + 4 * MS),                                      # repeated_stamp
        imu(BASE + 5 * MS, frame="nowhere"),                     # unknown_frame
        imu(BASE + 5 * MS, cov_w=-1.0),                          # no_rate
        "not a message",                                         # bad_message
        T["std_msgs/msg/Header"](stamp=_stamp(BASE), frame_id=""),   # bad_message (wrong type)
    ]
    for m in bad:
        assert core.on_message(m, BASE + 5 * MS) == []
    assert good(6)                                               # still integrating afterwards
    assert core.on_message(imu(BASE + 3 * 10**9), BASE + 3 * 10**9)          # gap 3 s > max_gap: reset
    assert core.on_message(imu(BASE - 60 * 10**9), BASE + 3 * 10**9 + MS)  # looped bag: jump back, reset
    snap = core.snapshot()
    assert snap["dropped_by_reason"] == {"non_finite": 2, "over_rate": 1, "over_specific_force": 1, "zero_stamp": 1,
                                         "backward_stamp": 1, "repeated_stamp": 1, "unknown_frame": 1, "no_rate": 1,
                                         "bad_message": 2}
    assert snap["stamp_anomalies"] == {"zero_stamp": 1, "backward_stamp": 1, "repeated_stamp": 1, "gap": 1,
                                       "jump_back": 1}
    assert snap["resets_by_reason"] == {"gap": 1, "jump_back": 1}
    assert snap["internal_errors"] == 0
    st = statuses(core.diagnostics(BASE + 4 * 10**9))
    level, _, values = st["gyro_platform: input"]
    assert values["dropped_by_reason.over_rate"] == "1" and values["resets_by_reason.jump_back"] == "1"
    assert st["gyro_platform: node"][2]["dropped_by_reason.bad_message"] == "2"


@pytest.mark.parametrize("sec,nanosec", [(None, 1_500_000_000), (None, 1_000_000_000), (None, -1), (-1, 500_000_000)])
def test_stamp_with_nanosec_out_of_range_is_a_bad_message_not_a_time_jump(sec, nanosec):
    """``nanosec = 1.5e9`` is not 1.5 s later, nor ``sec = -1`` a jump back: the message is
    dropped (bad_message), the time base and the output grid are untouched (issue 17: it lost
    14 rows and sent t backwards; a negative stamp reset the node twice)."""
    core = make_core(output_rate=10.0)
    published = {k: bool(core.on_message(imu(BASE + k * MS), BASE + k * MS)) for k in range(150)}
    bad = imu(BASE + 150 * MS)
    bad.header.stamp.nanosec = nanosec
    if sec is not None:
        bad.header.stamp.sec = sec
    assert core.on_message(bad, BASE + 150 * MS) == []
    assert core.gate.last.reason == "bad_message"
    assert ("sec = -1 is negative" if sec else "nanosec") in core.gate.last.detail
    assert core.gate.last_stamp_ns == BASE + 149 * MS
    published.update({k: bool(core.on_message(imu(BASE + k * MS), BASE + k * MS)) for k in range(151, 400)})
    assert [k for k, p in published.items() if p] == [0, 100, 200, 300]       # the 10 Hz grid goes on
    assert core.snapshot()["resets"] == 0


@pytest.mark.parametrize("force", [1e20, 1e160, 1e300])
def test_an_absurd_specific_force_is_dropped_and_the_simulation_goes_on(force):
    """One finite but absurd specific force in a carried run with the anisoelastic effect: it is
    dropped (``over_specific_force``) and α4 goes on at −0.5 rad/s · t. It was accepted; the
    integration failed and the simulator restarted from zero twice (1e20), or the exponential
    step's scaling loop halved an infinite norm for ever and the node hung (1e160)."""
    core = make_core(mode="carried", output_rate=0.0, effects=["defaults", "anisoelastic"])
    last = None
    for k in range(30):
        out = core.on_message(imu(BASE + k * 10 * MS, w=(0.0, 0.5, 0.0), acc=(force if k == 10 else 0.0, 0.0, 9.81)),
                              BASE + k * 10 * MS)
        last = dict(out).get("gimbal/joint_states", last)
    snap = core.snapshot()
    assert snap["dropped_by_reason"] == {"over_specific_force": 1} and snap["resets"] == 0
    assert last.position[0] == pytest.approx(-0.5 * 0.29, rel=1e-6)


def test_the_matrix_exponential_of_a_non_finite_matrix_is_nan_not_an_endless_loop():
    """``_expm_small`` scales by halving the norm until ≤ 1/8: an infinite norm never got there
    (the node hung at 99 % CPU). Run in a child process so that the old behaviour fails the
    test instead of hanging it."""
    code = ("import numpy as np; from gyro_platform.engine.integrators.exponential import _expm_small;"
            "W = np.eye(3); W[0, 1] = np.inf; E = _expm_small(W); print(bool(np.isnan(E).all()));"
            "W[0, 1] = np.nan; print(not bool(np.isfinite(_expm_small(W)).all()))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       cwd=Path(__file__).resolve().parents[1])
    assert p.stdout.split() == ["True", "True"], p.stderr


def test_sample_without_the_needed_specific_force_is_dropped_before_it_advances_the_gate():
    """mass_unbalance needs the specific force: an Imu that does not report it is dropped by the
    gate (``no_specific_force``, WARN), and the next valid sample — even at the same stamp — is
    accepted (the dropped one did not advance the time base)."""
    core = make_core(output_rate=0.0, effects=["defaults", "mass_unbalance"])
    assert core.on_message(imu(BASE), BASE)
    assert core.on_message(imu(BASE + MS, cov_a=-1.0), BASE + MS) == []
    assert core.snapshot()["dropped_by_reason"] == {"no_specific_force": 1}
    level, message, _ = statuses(core.diagnostics(BASE + 2 * MS))["gyro_platform: input"]
    assert level == 1 and "no_specific_force" in message
    assert core.on_message(imu(BASE + MS), BASE + MS)
    assert core.gate.last.reason == "ok" and core.snapshot()["simulator"] == {"pushed": 2, "dropped": 1}


def test_a_sample_the_simulator_refuses_rolls_the_gate_back():
    """A gate that does not know what the simulator needs accepts the sample; the simulator
    refuses it; the pipeline rolls the gate back (``refused``), so the next sample at the same
    stamp is not dropped as repeated_stamp and the run does not diverge."""
    from gyro_platform.engine.simulator import Simulator
    from gyro_platform.messages import reading_from_msg
    from gyro_platform.pipeline.gate import TimeGate
    from gyro_platform.pipeline.gate_rules import GateConfig
    from gyro_platform.pipeline.stream import Pipeline

    cfg = NodeConfig.from_ros_params({"effects": ["defaults", "mass_unbalance"]})
    pipe = Pipeline(Simulator(cfg.params, cfg.options), TimeGate(GateConfig()), 0.0)
    assert pipe.offer(reading_from_msg(imu(BASE)), BASE).outcome == "pushed"
    step = pipe.offer(reading_from_msg(imu(BASE + MS, cov_a=-1.0)), BASE + MS)
    assert step.outcome == "rejected" and pipe.gate.last.reason == "refused"
    assert pipe.gate.last_stamp_ns == BASE
    assert pipe.offer(reading_from_msg(imu(BASE + MS)), BASE + MS).outcome == "pushed"
    assert pipe.sim.n_samples == 2 and pipe.gate.snapshot()["dropped_by_reason"] == {"refused": 1}


LANE_STEPS = [MS] * 12 + [0, -MS // 2, 2_000 * MS, -3_000 * MS, 7 * MS]
LANE_VALUES = [0.1] * 12 + [math.nan, math.inf, 40.0, 20.0, -25.0]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(draws=st.lists(st.tuples(st.sampled_from(LANE_STEPS), st.sampled_from(LANE_VALUES),
                                st.integers(0, 2), st.sampled_from([True] * 4 + [False]), st.booleans()),
                      min_size=1, max_size=50),
       needs_f=st.booleans(), tight=st.booleans(), rate=st.sampled_from([0.0, 100.0]), with_rx=st.booleans())
def test_pipeline_offer_through_the_plain_lane_equals_the_general_path(draws, needs_f, tight, rate, with_rx):
    """``Pipeline.offer`` (plain readings: ``offer_plain`` + ``Simulator.push_plain``, no objects)
    against ``apply(gate.offer(...))`` for every reading: the same steps (decision, outcome,
    output slot), and in the end a bit-identical state, the same statistics, outcomes and gate.
    Drawn: repeated, backward, gapped and jumping-back stamps, NaN/Inf/over-rate values, large
    rates that a tight rk4 budget cannot integrate (``restarted``/``rejected``), samples without
    the specific force a model needs (the simulator refuses: ``rejected``, gate rolled back)."""
    from gyro_platform.engine.simulator import Simulator
    from gyro_platform.messages import Reading
    from gyro_platform.physics.options import ModelOptions
    from gyro_platform.pipeline.gate import TimeGate
    from gyro_platform.pipeline.gate_rules import GateConfig
    from gyro_platform.pipeline.stream import Pipeline

    opts = ModelOptions(effects=ModelOptions().effects | ({"mass_unbalance"} if needs_f else set()),
                        **({"integrator": "rk4", "rtol": 1e-8, "atol": 1e-11, "max_substeps": 4} if tight else {}))
    pipes = [Pipeline(Simulator(options=opts), TimeGate(GateConfig()), rate) for _ in range(2)]
    lane, ref = pipes
    stamp = BASE
    for i, (step, v, which, has_f, identity) in enumerate(draws):
        stamp += step
        w = [0.1, -0.2, 0.05]
        w[which] = v
        reading = Reading(tuple(w), (0.0, 0.0, 9.81) if has_f else None, stamp, "base_link", identity)
        rx = BASE + i * MS if with_rx else None
        a = lane.offer(reading, rx)
        b = ref.apply(ref.gate.offer(reading, rx))
        assert (a.outcome, a.emit, a.stamp_ns, a.source) == (b.outcome, b.emit, b.stamp_ns, b.source)
        da, db = a.decision, b.decision
        assert (da.action, da.reason, da.stamp_ns, da.source, da.detail) == \
               (db.action, db.reason, db.stamp_ns, db.source, db.detail)
        if db.sample is not None:
            assert da.sample.t == db.sample.t and da.sample.omega.tolist() == db.sample.omega.tolist()
    assert lane.sim.y.tobytes() == ref.sim.y.tobytes()
    assert lane.sim.stats == ref.sim.stats and lane.outcomes == ref.outcomes
    assert (lane.slot, lane.new_segment) == (ref.slot, ref.new_segment)
    assert lane.gate.snapshot() == ref.gate.snapshot() and lane.gate._undo == ref.gate._undo


def test_gimbal_lock_proximity_is_reported():
    core = make_core(mode="carried", input_type="twist_stamped", output_rate=10.0)   # full fidelity: no singularity
    for k in range(221):                                          # beta10 = −0.7 t → −1.54 rad at 2.2 s
        core.on_message(twist_stamped(BASE + k * 10 * MS, (0.7, 0.0, 0.0)), BASE + k * 10 * MS)
    level, message, values = statuses(core.diagnostics(BASE + 2210 * MS))["gyro_platform: node"]
    assert float(values["gimbal_lock_margin"]) == pytest.approx(abs(math.cos(0.7 * 2.2)), abs=1e-6)
    assert level == 1 and "gimbal lock" in message


# =========================================================================================
# diagnostics
# =========================================================================================
def test_diagnostics_content_levels_and_cdr_round_trip():
    core = make_core(output_rate=0.0)
    st = statuses(core.diagnostics(BASE))
    assert set(st) == {"gyro_platform: input", "gyro_platform: platform", "gyro_platform: node"}
    assert st["gyro_platform: node"][0] == 3 and st["gyro_platform: platform"][0] == 3      # STALE: no input
    for k in range(200):
        core.on_message(imu(BASE + k * MS), BASE + k * MS)
    arr = core.diagnostics(BASE + 200 * MS)
    assert stamp_ns(arr.header.stamp) == BASE + 200 * MS
    store = jazzy_typestore()
    raw = store.serialize_cdr(arr, arr.__msgtype__)
    assert store.serialize_cdr(store.deserialize_cdr(raw, arr.__msgtype__), arr.__msgtype__) == raw
    st = statuses(arr)
    level, message, v = st["gyro_platform: node"]
    assert (level, message) == (0, "ok")
    for key in ("input_rate_hz", "input_period_ms", "callback_time_mean_ms", "callback_time_max_ms",
                "real_time_margin", "integrator", "integrator_steps", "integrator_error_estimate_max",
                "gimbal_lock_margin", "resets", "outputs_published", "since_last_input_s"):
        assert key in v, key
    assert float(v["input_rate_hz"]) == pytest.approx(1000.0)
    # real-time margin = 1 − callback time / input period; the fake clock makes it 1 − 25 µs / 1 ms
    assert float(v["real_time_margin"]) == pytest.approx(0.975)
    # auto rule: NAV-1 nutation 808.6 rad/s × 1 ms = 0.81 < 1.5 (RK4 stable with margin) → rk4
    # auto: primary rk4, exprb fallback
    assert int(v["integrator_steps"]) == 199 and v["integrator"] == "auto:rk4+exprb"
    assert float(st["gyro_platform: platform"][2]["gimbal_lock_margin"]) > 0.99
    # nothing for longer than max_gap: STALE
    assert statuses(core.diagnostics(BASE + 5 * 10**9))["gyro_platform: node"][0] == 3


def test_real_time_margin_goes_negative_when_callbacks_outlast_the_input_period():
    core = NodeCore(NodeConfig.from_ros_params({"output_rate": 0.0}), TYPES,
                    clock_ns=itertools.count(0, 1_500_000).__next__)        # 1.5 ms per callback at 1 kHz
    for k in range(50):
        core.on_message(imu(BASE + k * MS), BASE + k * MS)
    assert core.real_time_margin() == pytest.approx(-0.5)
    level, message, _ = statuses(core.diagnostics(BASE + 50 * MS))["gyro_platform: node"]
    assert level == 2 and "behind real time" in message


# =========================================================================================
# parameters
# =========================================================================================
def test_live_parameter_changes_apply_at_once():
    core = make_core(output_rate=0.0, **STABILISED_BIAS)
    for k in range(100):
        core.on_message(imu(BASE + k * MS), BASE + k * MS)
    # output rate: 0 (every sample) → 100 Hz
    assert core.set_parameters({"output_rate": 100.0}) == (True, "")
    n = sum(bool(core.on_message(imu(BASE + k * MS), BASE + k * MS)) for k in range(100, 200))
    assert n == 10
    # gate limit: 40 rad/s is over the default 35 rad/s, accepted after raising max_rate
    assert core.on_message(imu(BASE + 200 * MS, w=(40.0, 0.0, 0.0)), BASE + 200 * MS) == []
    assert core.set_parameters({"gate.max_rate": 50.0}) == (True, "")
    core.on_message(imu(BASE + 201 * MS, w=(40.0, 0.0, 0.0)), BASE + 201 * MS)
    assert core.gate.last.reason == "ok"
    # effects and servo gains rebuild the model; the integration goes on from the same state
    t_before, q_before = core.sim.t, core.sim.y.copy()
    ok, reason = core.set_parameters({"effects": ["rotor_gyroscopic", "coriolis", "servo"],
                                      "physics.servo_kp": 1000.0})
    assert (ok, reason) == (True, "")
    assert "bias_torque" not in core.sim.options.effects and core.sim.params.servo_kp == 1000.0
    assert core.sim.t == t_before and np.array_equal(core.sim.y, q_before)
    assert core.on_message(imu(BASE + 210 * MS), BASE + 210 * MS)
    assert core.snapshot()["parameter_changes"] == 3


@pytest.mark.parametrize("changes, named, says", [
    ({"output_rate": -1.0}, "output_rate", "outside the allowed range"),
    ({"output_rate": 20}, "output_rate", "write 20.0"),
    ({"gate.max_gap": 0.0}, "gate.max_gap", "outside the allowed range"),
    ({"gate.on_gap": "ignore"}, "gate.on_gap", "allowed: reset, integrate"),
    ({"effects": ["warp_drive"]}, "effects", "not allowed"),
    ({"effects": ["defaults", "none"]}, "effects", "only entry"),
    ({"physics.servo_limit": 0.0}, "physics.servo_limit", "outside the allowed range"),
    ({"sensor_mountings": ["imu_link=1,2"]}, "sensor_mountings", "quaternion"),
    ({"mode": "carried"}, "mode", "read-only"),
    ({"physics.rotor_speed": [1.0, 2.0, 3.0]}, "physics.rotor_speed", "read-only"),
    ({"scene": "coning"}, "scene", "read-only"),
    ({"no_such_parameter": 1.0}, "no_such_parameter", "unknown parameter"),
])
def test_bad_or_read_only_parameter_changes_are_refused_with_a_reason(changes, named, says):
    core = make_core(output_rate=5.0)
    before = core.config
    ok, reason = core.set_parameters({"gate.max_rate": 20.0, **changes})    # atomic: nothing applied
    assert not ok
    assert f"'{named}'" in reason and says in reason
    assert core.config is before and core.gate.config.max_rate == 35.0


def test_unchanged_read_only_value_is_accepted():
    core = make_core()
    assert core.set_parameters({"mode": "stabilised", "output_rate": 5.0}) == (True, "")


def test_effect_needing_specific_force_is_refused_on_a_twist_input():
    core = make_core(input_type="twist")
    ok, reason = core.set_parameters({"effects": ["defaults", "anisoelastic"]})
    assert not ok and "'effects'" in reason and "specific force" in reason
    with pytest.raises(ConfigError, match="specific force"):
        NodeConfig.from_ros_params({"input_type": "twist_stamped", "effects": ["defaults", "mass_unbalance"]})


@pytest.mark.parametrize("params, named", [
    ({"output_rat": 5.0}, "output_rat"),
    ({"gate": {"max_gapp": 1.0}}, "gate.max_gapp"),
    ({"output_rate": "fast"}, "output_rate"),
    ({"input_type": "odometry"}, "input_type"),
    ({"physics": {"rotor_C": [1.0, 1.0]}}, "physics.rotor_C"),
    ({"physics": {"rotor_C": [5.0e-5, 5.0e-5, 5.0e-5]}}, "physics.rotor_C"),     # C > 2A: not a rigid body
    ({"physics": {"mounting": [0.0, 0.0, 0.0, 2.0]}}, "physics.mounting"),
    ({"mode": "carried", "effects": ["defaults", "servo"]}, "effects"),           # servo needs stabilised
    ({"scene": "no_such_scene"}, "scene"),
    ({"reset_on_clock_jump": 1}, "reset_on_clock_jump"),
    ({"physics": {"servo_kp": True}}, "physics.servo_kp"),                       # a bool is not a double
    ({"physics": {"bias_torque": [[0.0, 0.0], [0.0, 0.0, 0.0]]}}, "physics.bias_torque"),   # not flattened
    ({"effects": [["servo"]]}, "effects"),
    ({"fidelity": "precession", "physics": {"rotor_speed": [0.0, 2500.0, 2500.0]}}, "fidelity"),  # L6 = 0: det G_R = 0
    ({"physics": {"rotor_C": [0.0, 2.0e-5, 2.0e-5]}}, "physics.rotor_C"),     # no polar inertia: no gyro at all
    ({"fidelity": "precession", "physics": {"rotor_speed": [2500.0, 2500.0, 0.0]}}, "fidelity"),
    # a traceback before: names rcl refuses, the node's own topics as input
    ({"imu_topic": "bad topic"}, "imu_topic"),
    ({"imu_topic": ""}, "imu_topic"),
    ({"imu_topic": "drift/angle"}, "imu_topic"),
    ({"input_type": "twist", "twist_topic": "gimbal/joint_states"}, "twist_topic"),
    ({"imu_topic": "/tf"}, "imu_topic"),
    # accepted before, then every sample dropped: a Twist has no header stamp
    ({"input_type": "twist", "gate": {"time_source": "header"}}, "gate.time_source"),
    # accepted before: base_link re-mounted (every reading rotated), a frame mounted twice (last won)
    ({"sensor_mountings": ["base_link=0.0,0.0,1.5707963267948966"]}, "sensor_mountings"),
    ({"sensor_mountings": ["imu_link=0.0,0.0,1.0", "imu_link=0.0,0.0,2.0"]}, "sensor_mountings"),
])
def test_config_errors_name_the_parameter(params, named):
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_ros_params(params)
    assert e.value.parameter == named and f"'{named}'" in str(e.value)


def test_a_range_refusal_shows_bounds_that_exclude_the_value():
    """1.5708 rad was refused as outside [-1.5708, 1.5708]: the bounds are shown exactly."""
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_ros_params({"physics": {"latitude": 1.5708}})
    assert "1.5708 rad is outside the allowed range [-1.5707963267948966, 1.5707963267948966]" in str(e.value)
    with pytest.raises(ConfigError, match=r"20000 Hz is outside the allowed range \[0, 10000\]"):
        NodeConfig.from_ros_params({"output_rate": 20000.0})


def test_unknown_key_suggests_the_closest_name_and_ros_keys_are_accepted():
    with pytest.raises(ConfigError, match="did you mean 'output_rate'"):
        NodeConfig.from_ros_params({"output_rat": 5.0})
    cfg = NodeConfig.from_ros_params({"use_sim_time": True, "qos_overrides": {"/imu": {"subscription": {"depth": 5}}},
                                      "diagnostic_updater": {"period": 1.0}})
    assert cfg.values == parameter_defaults()


# =========================================================================================
# reset and clock jumps
# =========================================================================================
def test_reset_restarts_the_simulation_and_the_time_base():
    core = make_core(mode="carried", input_type="twist_stamped", output_rate=0.0)
    for k in range(101):
        core.on_message(twist_stamped(BASE + k * 10 * MS, (0.0, 0.5, 0.0)), BASE + k * 10 * MS)
    assert core.sim.outputs().gimbal_angles[0] == pytest.approx(-0.5)
    core.reset("service")
    later = BASE + 50 * 10**9
    js = dict(core.on_message(twist_stamped(later, (0.0, 0.5, 0.0)), later))["gimbal/joint_states"]
    assert js.position[0] == 0.0 and stamp_ns(js.header.stamp) == later
    assert core.gate.last.reason == "start"
    assert core.snapshot()["resets_by_reason"] == {"service": 1}
    assert core.snapshot()["last_reset_reason"] == "service"


def _published(out) -> dict[str, list[float]]:
    """Every number of one output instant by topic (messages are reused between calls)."""
    res = {}
    for topic, m in out:
        if topic == "gimbal/joint_states":
            res[topic] = [*m.position, *m.velocity, *m.effort, stamp_ns(m.header.stamp)]
        elif topic.startswith("bearing/"):
            t = m.wrench.torque
            res[topic] = [t.x, t.y, t.z, stamp_ns(m.header.stamp)]
        elif topic == "platform/attitude":
            q = m.quaternion
            res[topic] = [q.x, q.y, q.z, q.w, stamp_ns(m.header.stamp)]
        elif topic == "/tf":
            (t,) = m.transforms
            r = t.transform.rotation
            res[topic] = [r.x, r.y, r.z, r.w, stamp_ns(t.header.stamp)]
        else:
            v = m.vector
            res[topic] = [v.x, v.y, v.z, stamp_ns(m.header.stamp)]
    return res


def test_reused_output_messages_equal_freshly_built_ones_at_every_instant():
    """The core refills one set of message objects; at every instant they carry exactly what
    ``messages.output_messages`` builds from the same outputs (also across a live change of
    the effects, and with a frame prefix)."""
    from gyro_platform.messages import output_messages, reference_tf

    core = make_core(output_rate=0.0, frame_prefix="r1/", effects=["rotor_gyroscopic", "coriolis"])
    rng = np.random.default_rng(7)
    for k in range(60):
        if k == 30:
            assert core.set_parameters({"effects": ["rotor_gyroscopic", "coriolis", "servo"]})[0]
        t = BASE + k * MS
        out = core.on_message(imu(t, rng.normal(scale=0.3, size=3)), t)
        ref = [(topic.lstrip("/"), m) for topic, m in output_messages(core.last_out, TYPES, t)]
        (tf_topic, tf), out = out[-1], out[:-1]
        assert tf_topic == "/tf" and tf.transforms[0].header.frame_id == "r1/platform"
        assert tf.transforms[0].child_frame_id == "r1/platform_reference"
        fresh_tf = reference_tf(dict(ref)["platform/attitude"], TYPES, "r1/")
        assert _published([(tf_topic, tf)]) == _published([(tf_topic, fresh_tf)])
        assert [topic for topic, _ in out] == [topic for topic, _ in ref]
        assert _published(out) == _published(ref)
        assert all(m.header.frame_id in ("", "r1/" + r.header.frame_id) for (_, m), (_, r) in zip(out, ref))


@pytest.mark.parametrize("how", ["gap", "jump_back", "service"])
def test_every_reset_is_a_fresh_start_of_the_core(how):
    """After a reset (a gap or a jump back in the stamps, or ~/reset) the core publishes exactly
    what a fresh core fed the same messages publishes: state, input, time origin (rotor spin
    angles), output grid (10 Hz) and input-loss window all start again (issue 17)."""
    rng = np.random.default_rng(3)
    w = rng.normal(scale=0.3, size=(700, 3))
    a = np.array([0.0, 0.0, 9.81]) + rng.normal(scale=0.5, size=(700, 3))
    before = [BASE + 7_300_000 + k * MS for k in range(400)]            # grid phase differs from after
    start = {"gap": before[-1] + 3 * 10**9, "jump_back": BASE - 20 * 10**9, "service": before[-1] + 10 * MS}[how]
    after = [start + k * MS for k in range(300)]
    params = dict(output_rate=10.0, **STABILISED_BIAS)
    core, fresh = make_core(**params), make_core(**params)
    for k, t in enumerate(before):
        core.on_message(imu(t, w[k], a[k]), t)
    if how == "service":
        core.reset("service")
    got, want = [], []
    for k, t in enumerate(after):
        got.append(_published(core.on_message(imu(t, w[400 + k], a[400 + k]), t)))
        want.append(_published(fresh.on_message(imu(t, w[400 + k], a[400 + k]), t)))
    assert sum(bool(g) for g in got) == 3                             # t = 0, 0.1, 0.2 s after the reset
    assert got == want
    assert core.snapshot()["resets_by_reason"] == {how: 1}
    assert core.snapshot()["input_lost"] == fresh.snapshot()["input_lost"] == 0


@pytest.mark.parametrize("enabled", [True, False])
def test_clock_jump_back_resets_when_enabled(enabled):
    core = make_core(mode="carried", input_type="twist", output_rate=0.0, reset_on_clock_jump=enabled)
    for k in range(101):
        core.on_message(twist((0.0, 0.5, 0.0)), BASE + k * 10 * MS)
    core.on_clock_jump(False, 5 * 10**9)                          # forward: never a reset
    core.on_clock_jump(True, -60 * 10**9)                         # looped bag: /clock back 60 s
    assert core.snapshot()["clock_jumps"] == {"forward": 1, "back": 1}
    js = dict(core.on_message(twist((0.0, 0.5, 0.0)), BASE - 59 * 10**9))["gimbal/joint_states"]
    if enabled:
        assert core.snapshot()["resets_by_reason"] == {"clock_jump_back": 1}
        assert js.position[0] == 0.0                              # a fresh start at the new time
    else:
        # no reset from the clock; the gate still sees the time jump back and restarts itself
        assert core.snapshot()["resets_by_reason"] == {"jump_back": 1}


# =========================================================================================
# configuration files, scenes, docs
# =========================================================================================
def test_platform_yaml_loads_and_documents_every_parameter():
    path = ROOT / "config" / "platform.yaml"
    cfg = NodeConfig.from_yaml(path)
    assert cfg.values == parameter_defaults()
    text = path.read_text()
    for p in P.PARAMETERS:
        key = p.name.rpartition(".")[2]
        assert f" {key}: " in text or f"# {key}: " in text, p.name
    for key in ("output_rate", "mode", "effects"):               # scene keys stay commented out
        assert f"\n    # {key}: " in text


def test_params_file_sections_merge_wildcard_then_node(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    output_rate: 5.0\n    gate:\n      max_gap: 2.0\n"
                 "/robot1/gyro_platform_node:\n  ros__parameters:\n    output_rate: 25.0\n"
                 "other_node:\n  ros__parameters:\n    whatever: 1\n")
    cfg = NodeConfig.from_yaml(f)
    assert cfg["output_rate"] == 25.0 and cfg.gate.max_gap == 2.0
    f.write_text("/**:\n  ros__parameters:\n    output_rate: 5\n")
    with pytest.raises(ConfigError, match=r"'output_rate'.*write 5.0"):
        NodeConfig.from_yaml(f)


def test_params_file_reads_exponent_numbers_as_doubles_as_rcl_does(tmp_path):
    """rcl reads a plain ``1e2`` or ``1.0e3`` as a double (strtod); YAML 1.1 (PyYAML) reads it
    as text. The plain-DDS node (``build_config``) reads it as rcl does; a quoted one stays text."""
    import argparse

    from gyro_platform.ros.command import build_config

    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    output_rate: 1.0e3\n    gate:\n      max_gap: 1e2\n"
                 "    physics:\n      latitude: -2.5E-3\n      bias_torque: [1e-4, 0.0, 0.0, 0.0, 0.0]\n"
                 "      servo_kp: 1500.0\n")
    cfg, _ = build_config(argparse.Namespace(params_file=str(f), scene=""), P.NODE_NAME)
    assert cfg["output_rate"] == 1000.0 and cfg.gate.max_gap == 100.0
    assert cfg["physics.latitude"] == -2.5e-3 and cfg["physics.bias_torque"][0] == 1e-4
    f.write_text("/**:\n  ros__parameters:\n    output_rate: '1e3'\n")
    with pytest.raises(ConfigError, match=r"'output_rate'.*expected a double, got str '1e3'"):
        build_config(argparse.Namespace(params_file=str(f), scene=""), P.NODE_NAME)
    f.write_text("/**:\n  ros__parameters:\n    output_rate: 5\n")      # an integer stays an integer
    with pytest.raises(ConfigError, match=r"'output_rate'.*write 5.0"):
        build_config(argparse.Namespace(params_file=str(f), scene=""), P.NODE_NAME)


@pytest.mark.parametrize("text, says", [
    ("/**:\n  ros__parameters: [1, 2]\n", "must be a mapping"),
    ("/**:\n  ros__parameters: 3\n", "must be a mapping"),
    ("/**:\n  ros__parameters: text\n", "must be a mapping"),
    ("- 1\n- 2\n", "mapping of node names"),
    ("/**: [1]\n", "has no 'ros__parameters'"),
    ("? [1, 2]\n: 3\n", "unhashable key"),
    ("/**:\n  ros__parameters:\n    physics: {servo_kp: true}\n", "expected a double"),
    ("/**:\n  ros__parameters:\n    fidelity: precession\n    physics: {rotor_speed: [0.0, 2500.0, 2500.0]}\n",
     "zero spin momentum"),
])
def test_bad_params_files_give_one_line_naming_the_file(tmp_path, text, says):
    f = tmp_path / "p.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_yaml(f)
    assert says in str(e.value) and str(f) in str(e.value) and "\n" not in str(e.value)


def test_node_scene_with_a_repeated_key_is_refused_in_one_line(tmp_path):
    f = tmp_path / "dup.yaml"
    f.write_text("duration: 2\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\noutput_rate: 5.0\noutput_rate: 50.0\n")
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_ros_params({"scene": str(f)})
    assert str(e.value) == ("parameter 'scene': scene 'dup.yaml': not valid YAML: line 4:1: duplicate key "
                            "'output_rate' (first at line 3:1)")


def test_precession_with_a_rotor_at_rest_is_refused_at_node_start(tmp_path):
    """The refusal a scene gives: ``gyro-platform node`` exits 2 with one line before it joins
    any transport (no traceback)."""
    f = tmp_path / "p.yaml"
    f.write_text(
        "/**:\n  ros__parameters:\n    fidelity: precession\n    physics: {rotor_speed: [0.0, 2500.0, 2500.0]}\n"
    )
    r = subprocess.run([sys.executable, "-m", "gyro_platform", "node", "--transport", "dds", "--params-file", str(f)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    assert "zero spin momentum" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("scene_file", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_file_configures_the_node(scene_file):
    from gyro_platform.scenes.schema import load_scene

    scene = load_scene(scene_file)
    for name in (str(scene_file), scene_file.stem):               # by path and by name
        cfg = NodeConfig.from_ros_params({"scene": name})
        assert cfg.options == scene.options
        assert cfg.params == scene.params
        assert cfg["output_rate"] == scene.output_rate
    core = NodeCore(cfg, TYPES)
    for k in range(3):
        stamp = BASE + k * 10 * MS
        core.on_message(imu(stamp, w=(0.01, -0.02, 0.005)), stamp)
    snap = core.snapshot()
    assert snap["accepted"] == 3 and snap["simulator"].get("pushed") == 3 and snap["internal_errors"] == 0


def test_explicit_parameters_override_the_scene():
    cfg = NodeConfig.from_ros_params({"scene": "default", "output_rate": 50.0, "physics": {"servo_kp": 1000.0}})
    assert cfg["output_rate"] == 50.0 and cfg.params.servo_kp == 1000.0
    assert cfg.params.bias_torque == (0.0, 0.0, 0.0, 0.0, 1.0e-7)          # from the scene
    assert "bias_torque" in cfg.options.effects


def test_every_platform_parameter_is_a_documented_node_parameter():
    for f in fields(PlatformParams):
        assert f.name in P.PHYSICS_DOCS, f"document PlatformParams.{f.name} in parameters.PHYSICS_DOCS"
        assert P.SPECS[P.PHYSICS_PREFIX + f.name].read_only == (f.name not in P.LIVE_PHYSICS)
    for p in P.PARAMETERS:
        assert p.description and p.default is not None
        assert p.coerce(p.default) == p.default                    # every default passes its own checks


def test_docs_carry_the_current_parameter_and_topic_tables():
    doc = (ROOT / "README.md").read_text()
    hint = ("README.md is stale: paste gyro_platform.ros.parameters.parameters_markdown() / topics_markdown() "
            "between its <!-- parameters --> / <!-- topics --> markers")
    assert P.parameters_markdown() in doc, hint
    assert P.topics_markdown() in doc, hint


def test_importing_the_package_and_core_does_not_import_rclpy():
    code = ("import sys, gyro_platform, gyro_platform.ros.core, gyro_platform.messages; "
            "assert 'rclpy' not in sys.modules; print('ok')")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr


def test_node_module_without_rclpy_fails_with_a_clear_import_error():
    try:
        import rclpy  # noqa: F401
    except ImportError:
        pass
    else:
        pytest.skip("rclpy is installed here")
    with pytest.raises(ImportError, match="rclpy"):
        import gyro_platform.ros.node  # noqa: F401
