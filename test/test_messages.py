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

"""Message mapping: inputs (Imu/Twist/TwistStamped → base_link), outputs (CDR round trips)."""
from __future__ import annotations

import array
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_platform import messages as m
from gyro_platform.engine.outputs import BEARING_FRAMES, BEARING_NAMES, GIMBAL_NAMES, MOUNT_NAMES, Outputs
from gyro_platform.messages import names
from gyro_platform.physics.rotations import euler_xyz_axes

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
TYPES = m.MessageTypes.rosbags()
STORE = m.jazzy_typestore()
T = STORE.types


def make_outputs(mount: bool = True, t: float = 1.25) -> Outputs:
    rng = np.random.default_rng(7)
    return Outputs(
        t=t,
        gimbal_angles=rng.normal(size=5) * 1e-3,
        gimbal_rates=rng.normal(size=5) * 1e-2,
        gimbal_axial_torques=rng.normal(size=5) * 1e-4,
        platform_rate=rng.normal(size=3) * 1e-5,
        platform_attitude=np.array([0.0, 0.0, 0.0, 1.0]),
        drift_angle=np.array([1e-6, -2e-6, 3e-6]),
        drift_rate=np.array([4e-8, -5e-8, 6e-8]),
        bearing_torques={b: rng.normal(size=3) * 1e-3 for b in BEARING_NAMES},
        motor_torques=np.zeros(3),
        mount_angles=rng.normal(size=3) * 0.1 if mount else None,
        mount_rates=rng.normal(size=3) * 1e-3 if mount else None,
        servo_torque=rng.normal(size=3) * 1e-2 if mount else None,
        rotor_rates=np.array([2513.0, -2400.0, 2600.0]),
        status={"gimbal_lock_margin": 1.4, "steps": 12.0},
    )


def imu(wx=0.0, wy=0.0, wz=0.0, *, frame="base_link", sec=10, nanosec=5, cov_w=0.0, cov_a=0.0,
        acc=(0.0, 0.0, 9.81)):
    cov_w9 = np.zeros(9)
    cov_w9[0] = cov_w
    cov_a9 = np.zeros(9)
    cov_a9[0] = cov_a
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=T["geometry_msgs/msg/Vector3"](x=wx, y=wy, z=wz),
        angular_velocity_covariance=cov_w9,
        linear_acceleration=T["geometry_msgs/msg/Vector3"](x=acc[0], y=acc[1], z=acc[2]),
        linear_acceleration_covariance=cov_a9,
    )


def roundtrip(msg):
    raw = STORE.serialize_cdr(msg, msg.__msgtype__)
    back = STORE.deserialize_cdr(raw, msg.__msgtype__)
    assert STORE.serialize_cdr(back, msg.__msgtype__) == raw
    return back


# ---- outputs ------------------------------------------------------------------------------
def test_every_output_message_round_trips_through_cdr():
    out = make_outputs()
    t_ns = 1_700_000_000_123_456_789
    msgs = m.output_messages(out, TYPES, t_ns) + [("/diagnostics", m.diagnostic_array(
        {"received": 3, "dropped_by_reason": {"over_rate": 1}, "last_action": "accept"}, out, TYPES, t_ns))]
    expected_types = m.output_topics()
    assert [t for t, _ in msgs] == list(expected_types)          # every output topic, table order
    for topic, msg in msgs:
        assert msg.__msgtype__ == expected_types[topic]
        back = roundtrip(msg)
        assert m.stamp_ns(back.header.stamp) == t_ns               # exact ns, no float rounding

    by_topic = dict(msgs)
    q = by_topic["/platform/attitude"]
    assert q.header.frame_id == "platform_reference"
    np.testing.assert_array_equal([q.quaternion.x, q.quaternion.y, q.quaternion.z, q.quaternion.w],
                                  out.platform_attitude)
    st = by_topic["/platform/servo_torque"]
    assert st.header.frame_id == "platform"
    np.testing.assert_array_equal([st.vector.x, st.vector.y, st.vector.z], out.servo_torque)

    js = roundtrip(m.joint_state(out, TYPES, t_ns))
    assert js.name == [*GIMBAL_NAMES, *MOUNT_NAMES, *m.ROTOR_JOINT_NAMES]
    for arr in (js.position, js.velocity, js.effort):
        assert len(arr) == len(js.name) and np.all(np.isfinite(arr))
    np.testing.assert_array_equal(js.position[:8], np.r_[out.gimbal_angles, out.mount_angles])
    np.testing.assert_array_equal(js.velocity[:8], np.r_[out.gimbal_rates, out.mount_rates])
    np.testing.assert_array_equal(js.effort[:5], out.gimbal_axial_torques)
    # mount effort: the servo torque's generalised force on the X-Y-Z joint axes (virtual work:
    # τ · ω_rel = Σ effort_i rate_i for any joint rates)
    rates = np.array([0.3, -0.2, 0.7])
    omega_rel = euler_xyz_axes(out.mount_angles) @ rates
    assert js.effort[5:8] @ rates == pytest.approx(out.servo_torque @ omega_rel, rel=1e-12)
    # rotors: ideal speed control, angle = rate · t wrapped to [-π, π)
    np.testing.assert_allclose(np.cos(js.position[8:]), np.cos(out.rotor_rates * out.t), atol=1e-9)
    np.testing.assert_allclose(np.sin(js.position[8:]), np.sin(out.rotor_rates * out.t), atol=1e-9)
    assert np.all(np.abs(js.position[8:]) <= math.pi)
    np.testing.assert_array_equal(js.velocity[8:], out.rotor_rates)

    for name, w in m.bearing_wrenches(out, TYPES, t_ns).items():
        w = roundtrip(w)
        assert w.header.frame_id == BEARING_FRAMES[name]
        assert (w.wrench.force.x, w.wrench.force.y, w.wrench.force.z) == (0.0, 0.0, 0.0)
        np.testing.assert_array_equal([w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z],
                                      out.bearing_torques[name])

    for fn, vec in ((m.drift_angle, out.drift_angle), (m.drift_rate, out.drift_rate)):
        v = roundtrip(fn(out, TYPES, t_ns))
        assert v.header.frame_id == "platform"
        np.testing.assert_array_equal([v.vector.x, v.vector.y, v.vector.z], vec)


@pytest.mark.parametrize("mount", [True, False])
@pytest.mark.parametrize("t", [0.0, 1.25, 3.7e4])
def test_joint_values_of_one_output_row_equal_joint_columns(mount, t):
    """The node's scalar refill (``joint_values_of_row`` on ``row.tolist()``) gives the numbers
    of ``joint_columns`` (numpy): mount joints in stabilised mode, rotor spin angles wrapped at
    large t, and no rotors when their rate is NaN."""
    from gyro_platform.engine.outputs import C_ROTOR, OutputBlock

    out = make_outputs(mount=mount, t=t)
    row = OutputBlock.stack([out]).rows[0]
    for rotors in (True, False):
        if not rotors:
            row[C_ROTOR:C_ROTOR + 3] = np.nan
            out.rotor_rates = None
        cols = m.joint_columns(out)
        pos, vel, eff = m.joint_values_of_row(row.tolist(), mount)
        for got, want in ((pos, cols.position[0]), (vel, cols.velocity[0]), (eff, cols.effort[0])):
            assert len(got) == len(want) == len(cols.names)
            assert all(type(x) is float for x in got)
            np.testing.assert_allclose(got, want, rtol=1e-15, atol=1e-300)


def test_output_columns_hold_what_output_messages_publish():
    """``OUTPUT_COLUMNS`` names, per vector topic, the row columns whose numbers
    ``output_messages`` puts into the message."""
    from gyro_platform.engine.outputs import OutputBlock

    out = make_outputs()
    v = OutputBlock.stack([out]).rows[0].tolist()
    msgs = dict(m.output_messages(out, TYPES, 7, ""))
    assert {t.lstrip("/") for t in msgs} - {"gimbal/joint_states"} == set(m.OUTPUT_COLUMNS)
    for topic, c in m.OUTPUT_COLUMNS.items():
        msg = msgs["/" + topic]
        if topic == "platform/attitude":
            q = msg.quaternion
            assert [q.x, q.y, q.z, q.w] == v[c:c + 4]
        else:
            vec = msg.wrench.torque if topic.startswith("bearing/") else msg.vector
            assert [vec.x, vec.y, vec.z] == v[c:c + 3]


def test_joint_state_without_mount_rates_leaves_velocity_and_effort_empty():
    out = make_outputs()
    out.mount_rates = None                              # an Outputs from an older producer
    js = m.joint_state(out, TYPES, 5)
    assert len(js.position) == len(js.name) == 11 and np.all(np.isfinite(js.position))
    assert len(js.velocity) == 0 and len(js.effort) == 0   # "all arrays … same size, or empty"


def test_joint_state_without_mount_and_missing_bearings():
    out = make_outputs(mount=False)
    del out.bearing_torques["rotor8"]
    js = roundtrip(m.joint_state(out, TYPES, 5))
    assert js.name == [*GIMBAL_NAMES, *m.ROTOR_JOINT_NAMES]
    assert len(js.position) == len(js.velocity) == len(js.effort) == 8
    assert np.all(np.isfinite(js.velocity)) and np.all(np.isfinite(js.effort))
    assert "rotor8" not in m.bearing_wrenches(out, TYPES, 5)


def test_diagnostics_levels_and_values():
    S = T["diagnostic_msgs/msg/DiagnosticStatus"]
    gate = {"received": 4, "dropped_by_reason": {"non_finite": 1}, "last_action": "drop",
            "last_reason": "non_finite", "input_rate_hz": 30.0}
    d = roundtrip(m.diagnostic_array(gate, None, TYPES, 1))
    inp, plat = d.status
    assert inp.level == S.WARN and "non_finite" in inp.message
    assert {kv.key: kv.value for kv in inp.values}["dropped_by_reason.non_finite"] == "1"
    assert plat.level == S.STALE                              # no output yet
    out = make_outputs()
    d = roundtrip(m.diagnostic_array({**gate, "last_action": "accept"}, out, TYPES, 1))
    assert [s.level for s in d.status] == [S.OK, S.OK]
    assert {kv.key: kv.value for kv in d.status[1].values}["gimbal_lock_margin"] == "1.4"
    out.status["gimbal_lock_margin"] = math.nan
    assert roundtrip(m.diagnostic_array(None, out, TYPES, 1)).status[0].level == S.ERROR


def test_header_stamp_is_exact_and_clamped():
    h = m.header(TYPES, 1_432_235_498_025_043_042, "x")
    assert (h.stamp.sec, h.stamp.nanosec, h.frame_id) == (1_432_235_498, 25_043_042, "x")
    assert (m.header(TYPES, -5).stamp.sec, m.header(TYPES, -5).stamp.nanosec) == (0, 0)


def test_topic_table_lists_every_topic():
    outs = m.output_topics()
    assert len(outs) == 5 + len(BEARING_NAMES) + 1
    assert outs["/platform/attitude"] == "geometry_msgs/msg/QuaternionStamped"
    assert outs["/diagnostics"] == "diagnostic_msgs/msg/DiagnosticArray"
    assert m.output_topics("/robot1/")["/robot1/bearing/rotor11/torque"] == "geometry_msgs/msg/WrenchStamped"
    assert "/diagnostics" in m.output_topics("robot1")          # absolute name stays
    for spec in m.TOPICS:
        name = "bearing/<name>/torque" if spec.name.startswith("bearing/") else spec.name
        assert f"`{name}`" in names.__doc__ and f"`{spec.type}`" in names.__doc__
    for b, f in BEARING_FRAMES.items():
        assert b in names.__doc__ and f in names.__doc__


def test_rclpy_namespace_uses_array_d():
    fa = m.MessageTypes.rclpy().float_array([1, 2.5, math.nan])
    assert isinstance(fa, array.array) and fa.typecode == "d" and fa[1] == 2.5


# ---- inputs -------------------------------------------------------------------------------
def test_imu_covariance_rules():
    r = m.reading_from_msg(imu(0.1, 0.2, 0.3, acc=(1.0, 2.0, 3.0)))
    assert isinstance(r, m.Reading)
    np.testing.assert_array_equal(r.omega, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(r.specific_force, [1.0, 2.0, 3.0])   # covariance 0 = unknown, still data
    assert r.stamp_ns == 10_000_000_005 and r.frame_id == "base_link" and not r.identity_assumed

    r = m.reading_from_msg(imu(0.1, cov_a=-1.0))
    assert isinstance(r, m.Reading) and r.specific_force is None          # accel not reported
    np.testing.assert_array_equal(r.omega, [0.1, 0.0, 0.0])

    r = m.reading_from_msg(imu(0.1, cov_w=-1.0))
    assert isinstance(r, m.Rejected) and r.reason == "no_rate" and r.stamp_ns == 10_000_000_005

    r = m.reading_from_msg(imu(0.1, cov_w=-0.5))                          # only exactly -1 means "absent"
    assert isinstance(r, m.Reading)


# robot_localization's README: static_transform_publisher 0 -0.3 0.52 -1.570796327 0 1.570796327 base_link imu_link
# (yaw, pitch, roll) = (-pi/2, 0, pi/2): R = Rz(-pi/2) Rx(pi/2)
def _husky_matrix() -> np.ndarray:
    rz = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # Rz(-90°)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])   # Rx(+90°)
    return rz @ rx


def test_mounting_rotation_maps_imu_link_axes_to_base_link():
    q = Rotation.from_matrix(_husky_matrix()).as_quat()                   # x, y, z, w
    for spec in (list(q), (math.pi / 2, 0.0, -math.pi / 2)):              # quaternion or roll, pitch, yaw
        mount = m.Mounting({"imu_link": spec}, unknown_frame="reject")
        r = m.reading_from_msg(imu(1.0, 0.0, 0.0, frame="imu_link", acc=(0.0, 9.81, 0.0)), mount)
        np.testing.assert_allclose(r.omega, [0.0, -1.0, 0.0], atol=1e-12)   # about imu x = about base -y
        np.testing.assert_allclose(r.specific_force, [0.0, 0.0, 9.81], atol=1e-12)  # gravity up
        r = m.reading_from_msg(imu(0.0, 0.0, 2.0, frame="imu_link"), mount)
        np.testing.assert_allclose(r.omega, [-2.0, 0.0, 0.0], atol=1e-12)   # about imu z = about base -x
    frame, rot = m.Mounting.parse_spec("imu_link=1.5707963267948966,0,-1.5707963267948966")
    assert frame == "imu_link"
    np.testing.assert_allclose(rot.as_matrix(), _husky_matrix(), atol=1e-12)
    with pytest.raises(ValueError, match="unit quaternion"):
        m.Mounting({"imu_link": (0.0, 0.0, 0.0, 2.0)})
    with pytest.raises(ValueError, match="FRAME="):
        m.Mounting.parse_spec("0,0,0,1")


def test_unknown_frame_policies():
    msg = imu(0.5, frame="somewhere")
    r = m.reading_from_msg(msg, m.Mounting(unknown_frame="reject"))
    assert isinstance(r, m.Rejected) and r.reason == "unknown_frame" and "somewhere" in r.detail
    r = m.reading_from_msg(msg, m.Mounting(unknown_frame="identity"))
    assert isinstance(r, m.Reading) and r.identity_assumed
    np.testing.assert_array_equal(r.omega, [0.5, 0.0, 0.0])


def test_twist_and_twist_stamped():
    v3 = T["geometry_msgs/msg/Vector3"]
    tw = T["geometry_msgs/msg/Twist"](linear=v3(x=9.0, y=9.0, z=9.0), angular=v3(x=0.1, y=0.2, z=0.3))
    r = m.reading_from_msg(tw, m.Mounting(unknown_frame="reject"))      # no header: base_link
    assert r.stamp_ns is None and r.specific_force is None and r.frame_id == "base_link"
    np.testing.assert_array_equal(r.omega, [0.1, 0.2, 0.3])
    ts = T["geometry_msgs/msg/TwistStamped"](header=m.header(TYPES, 2_000_000_001, "imu_link"), twist=tw)
    r = m.reading_from_msg(ts, m.Mounting({"imu_link": (0.0, 0.0, math.pi / 2)}))  # yaw 90°
    np.testing.assert_allclose(r.omega, [-0.2, 0.1, 0.3], atol=1e-12)
    assert r.stamp_ns == 2_000_000_001


def test_duck_typed_rclpy_like_messages():
    """rclpy messages have the same fields but no ``__msgtype__`` and plain sequences."""
    ns = SimpleNamespace
    msg = ns(header=ns(stamp=ns(sec=3, nanosec=7), frame_id="base_link"),
             angular_velocity=ns(x=1.0, y=2.0, z=3.0), angular_velocity_covariance=array.array("d", [0.0] * 9),
             linear_acceleration=ns(x=0.0, y=0.0, z=9.8),
             linear_acceleration_covariance=array.array("d", [-1.0] + [0.0] * 8))
    r = m.reading_from_msg(msg)
    assert isinstance(r, m.Reading) and r.specific_force is None and r.stamp_ns == 3_000_000_007
    assert m.message_kind(ns(linear=msg.angular_velocity, angular=msg.angular_velocity)) == m.TWIST
    bad = m.reading_from_msg(ns(header=ns(stamp=ns(sec=1, nanosec=0), frame_id=""), angular_velocity=None,
                                angular_velocity_covariance=[0.0] * 9))
    assert isinstance(bad, m.Rejected) and bad.reason == "bad_message"
    assert m.reading_from_msg(object()).reason == "bad_message"


def test_other_types_are_rejected_by_name():
    v3 = T["geometry_msgs/msg/Vector3"]
    twist = T["geometry_msgs/msg/Twist"](linear=v3(x=0.0, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=1.0))
    odom = T["nav_msgs/msg/Odometry"](
        header=m.header(TYPES, 1, "odom"), child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                             orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
            covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))
    r = m.reading_from_msg(odom)
    assert isinstance(r, m.Rejected) and r.reason == "bad_message" and "nav_msgs/msg/Odometry" in r.detail
    assert m.type_name(odom) == "nav_msgs/msg/Odometry" and m.type_name(SimpleNamespace()) is None


def test_real_husky_imu_gravity_maps_to_base_link_up():
    """First 300 samples of the husky recording: mean specific force in base_link ≈ (0, 0, +9.8)."""
    bag = BAGS / "robot_localization_husky_test1"
    if not bag.exists():
        pytest.skip(f"real recording absent: {bag}")
    from rosbags.highlevel import AnyReader
    mount = m.Mounting({"imu_link": (math.pi / 2, 0.0, -math.pi / 2)}, unknown_frame="reject")
    forces = []
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/imu/data"]
        for i, (c, _, raw) in enumerate(reader.messages(conns)):
            r = m.reading_from_msg(reader.deserialize(raw, c.msgtype), mount)
            assert isinstance(r, m.Reading) and r.frame_id == "imu_link"
            forces.append(r.specific_force)
            if i == 299:
                break
    mean = np.mean(forces, axis=0)
    assert mean[2] > 9.6 and abs(mean[0]) < 0.5 and abs(mean[1]) < 0.5
