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

"""The rclpy node, driven through topics (ROS 2 Jazzy needed; skipped elsewhere).

Each test starts ``PlatformNode`` in-process with ``config/platform.yaml`` (``--params-file``)
plus per-test overrides, publishes scripted rate samples from a driver node, waits until the
platform node has taken each one, and checks the published outputs with the same expectations
as the ROS-free ``test_node_core.py`` (spec O6, O9b). Stamps are scripted, so nothing depends on
wall-clock timing except the waits (which have generous timeouts).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip(
    "rclpy", reason="rclpy is not installed (ROS 2 Jazzy needed); the same behaviour is tested ROS-free in "
                    "test_node_core.py")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import TwistStamped, Vector3, Vector3Stamped  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from gyro_platform.ros.node import PlatformNode  # noqa: E402
from gyro_platform.physics.params import NAV1  # noqa: E402

PARAMS = Path(__file__).resolve().parents[1] / "config" / "platform.yaml"
BASE = 1_700_000_000 * 10**9
MS = 10**6
Q10 = 1e-4
DRIFT = -Q10 / NAV1.L[2]                 # rad/s, −1.98944e-3
RELIABLE_DEEP = QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE)


def stamp(t_ns: int) -> Time:
    sec, nsec = divmod(int(t_ns), 10**9)
    return Time(sec=sec, nanosec=nsec)


def ns(t: Time) -> int:
    return t.sec * 10**9 + t.nanosec


def imu(t_ns: int, w=(0.0, 0.0, 0.0)) -> Imu:
    m = Imu(header=Header(stamp=stamp(t_ns), frame_id="base_link"))
    m.angular_velocity = Vector3(x=float(w[0]), y=float(w[1]), z=float(w[2]))
    m.linear_acceleration = Vector3(x=0.0, y=0.0, z=9.81)
    return m


def twist_stamped(t_ns: int, w) -> TwistStamped:
    m = TwistStamped(header=Header(stamp=stamp(t_ns), frame_id="base_link"))
    m.twist.angular = Vector3(x=float(w[0]), y=float(w[1]), z=float(w[2]))
    return m


class Harness:
    """The platform node, a driver node publishing the input, and subscriptions to the outputs."""

    def __init__(self, context: Context, msg_type: type = Imu, input_topic: str = "imu", **overrides):
        self.node = PlatformNode(context=context, cli_args=["--ros-args", "--params-file", str(PARAMS)],
                                 parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.driver = Node("scenario_driver", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.driver)
        self.pub = self.driver.create_publisher(msg_type, input_topic, qos_profile_sensor_data)
        self.got: dict[str, list] = {"gimbal/joint_states": [], "drift/angle": [], "drift/rate": [],
                                     "/diagnostics": []}
        for topic, typ in (("gimbal/joint_states", JointState), ("drift/angle", Vector3Stamped),
                           ("drift/rate", Vector3Stamped), ("/diagnostics", DiagnosticArray)):
            self.driver.create_subscription(typ, topic, self.got[topic].append, RELIABLE_DEEP)
        self.wait(lambda: self.pub.get_subscription_count() > 0
                  and self.node._pubs["gimbal/joint_states"].get_subscription_count() > 0, what="discovery")

    def wait(self, cond, timeout: float = 20.0, what: str = "condition") -> None:
        end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > end:
                raise AssertionError(f"timed out waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def send(self, msg) -> None:
        """Publish one input and wait until the platform node has taken it."""
        n = self.node.core.received
        self.pub.publish(msg)
        self.wait(lambda: self.node.core.received > n, what="the node to take the input")

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.driver.destroy_node()


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def harness(context):
    made = []

    def make(**kw) -> Harness:
        h = Harness(context, **kw)
        made.append(h)
        return h

    yield make
    for h in made:
        h.close()


def test_bias_torque_drift_through_topics_at_1khz(harness):
    h = harness(effects=["rotor_gyroscopic", "coriolis", "servo", "bias_torque"],
                **{"physics.bias_torque": [0.0, 0.0, 0.0, 0.0, Q10], "output_rate": 0.0})
    stamps = [BASE + k * MS for k in range(1001)]
    for s in stamps:
        h.send(imu(s))
    h.wait(lambda: len(h.got["drift/angle"]) == 1001 and len(h.got["drift/rate"]) == 1001, what="1001 outputs")
    assert [ns(m.header.stamp) for m in h.got["drift/angle"]] == stamps
    assert all(m.header.frame_id == "platform" for m in h.got["drift/angle"])
    t = np.array([(ns(m.header.stamp) - BASE) * 1e-9 for m in h.got["drift/angle"]])
    z = np.array([m.vector.z for m in h.got["drift/angle"]])
    late = t >= 0.5
    assert np.polyfit(t[late], z[late], 1)[0] == pytest.approx(DRIFT, rel=1e-4)
    assert np.mean([m.vector.z for m in h.got["drift/rate"]][500:]) == pytest.approx(DRIFT, rel=2e-3)


def test_carried_free_gyro_through_topics_at_100hz(harness):
    h = harness(msg_type=TwistStamped, input_topic="twist", mode="carried", input_type="twist_stamped",
                output_rate=10.0)
    for k in range(401):
        h.send(twist_stamped(BASE + k * 10 * MS, (0.0, 0.5, 0.0)))
    h.wait(lambda: len(h.got["gimbal/joint_states"]) == 41, what="41 joint states")
    for i, js in enumerate(h.got["gimbal/joint_states"]):
        assert ns(js.header.stamp) == BASE + i * 100 * MS          # the 10 Hz grid of sample times
        assert js.position[0] == pytest.approx(-0.5 * i * 0.1, abs=1e-9)
        assert list(js.name) == ["alpha4", "beta5", "beta7", "alpha9", "beta10", "rotor6", "rotor8", "rotor11"]


def test_bad_input_is_counted_and_the_node_goes_on(harness):
    h = harness(output_rate=0.0)
    h.send(imu(BASE))
    h.send(imu(BASE + MS, w=(math.nan, 0.0, 0.0)))
    h.send(imu(0))
    h.send(imu(BASE + 2 * MS, w=(100.0, 0.0, 0.0)))
    h.send(imu(BASE + 3 * MS))
    h.wait(lambda: len(h.got["gimbal/joint_states"]) == 2, what="2 outputs")
    assert h.node.core.snapshot()["dropped_by_reason"] == {"non_finite": 1, "zero_stamp": 1, "over_rate": 1}


def test_parameters_have_descriptors_and_are_validated(harness):
    h = harness()
    d = h.node.describe_parameter("output_rate")
    assert d.floating_point_range[0].from_value == 0.0 and not d.read_only and "Hz" in d.description
    assert h.node.describe_parameter("mode").read_only
    assert h.node.describe_parameter("physics.servo_kp").floating_point_range
    res = h.node.set_parameters([Parameter("output_rate", value=-1.0)])[0]
    assert not res.successful                                   # rclpy's range check
    res = h.node.set_parameters([Parameter("mode", value="carried")])[0]
    assert not res.successful and "read-only" in res.reason
    res = h.node.set_parameters([Parameter("effects", value=["warp_drive"])])[0]
    assert not res.successful and "'effects'" in res.reason       # the core's check
    res = h.node.set_parameters([Parameter("output_rate", value=50.0), Parameter("gate.max_rate", value=20.0)])
    assert all(r.successful for r in res)
    assert h.node.core.config["output_rate"] == 50.0 and h.node.core.gate.config.max_rate == 20.0


def test_scene_parameter_sets_the_model(harness):
    h = harness(scene="coning")
    assert h.node.get_parameter("output_rate").value == 20.0      # the scene's output rate
    assert h.node.core.config.options.mode == "stabilised"


def test_reset_service(harness):
    h = harness()
    h.send(imu(BASE))
    client = h.driver.create_client(Trigger, "/gyro_platform_node/reset")
    h.wait(lambda: client.service_is_ready(), what="the reset service")
    future = client.call_async(Trigger.Request())
    h.wait(future.done, what="the reset response")
    assert future.result().success
    assert h.node.core.snapshot()["resets_by_reason"] == {"service": 1}


def test_clock_jump_back_resets(harness, context):
    h = harness(use_sim_time=True)
    clock_pub = h.driver.create_publisher(Clock, "/clock", 10)
    h.wait(lambda: clock_pub.get_subscription_count() > 0, what="the node's /clock subscription")
    clock_pub.publish(Clock(clock=stamp(BASE + 100 * 10**9)))
    h.wait(lambda: h.node.get_clock().now().nanoseconds == BASE + 100 * 10**9, what="sim time")
    clock_pub.publish(Clock(clock=stamp(BASE + 10 * 10**9)))      # ros2 bag play --loop starts over
    h.wait(lambda: h.node.core.snapshot()["clock_jumps"].get("back") == 1, what="the jump callback")
    assert h.node.core.snapshot()["resets_by_reason"] == {"clock_jump_back": 1}


def test_diagnostics_are_published(harness):
    h = harness()
    h.send(imu(BASE))
    h.wait(lambda: any(s.name.endswith("node") for a in h.got["/diagnostics"] for s in a.status),
           timeout=10.0, what="/diagnostics")
    names = {s.name for a in h.got["/diagnostics"] for s in a.status}
    assert any(n.endswith("input") for n in names) and any(n.endswith("platform") for n in names)
    assert names == {"gyro_platform: input", "gyro_platform: platform", "gyro_platform: node",
                     "gyro_platform: transport"}                  # the same names as the DDS transport


def test_every_parameter_has_a_value_for_param_dump(harness):
    """GetParameters (``ros2 param dump``) answers for every declared parameter: none is unset."""
    h = harness()
    names = h.node.list_parameters([], 10).names
    assert "sensor_mountings" in names and "physics.servo_kp" in names
    for name in names:
        assert h.node.get_parameter(name).type_ != Parameter.Type.NOT_SET, name
    p = h.node.get_parameter("sensor_mountings")
    assert p.type_ == Parameter.Type.STRING_ARRAY and list(p.value) == []
    for spec_name in ("physics.latitude", "physics.earth_rate", "physics.gyro_mass", "gate.max_gap"):
        assert h.node.describe_parameter(spec_name).floating_point_range, spec_name


def test_joint_state_is_finite_and_matches_the_urdf(harness):
    from gyro_platform.ros.urdf import config_model

    h = harness()
    for k in range(3):
        h.send(imu(BASE + k * 10 * MS, w=(0.1, -0.2, 0.3)))
    h.wait(lambda: h.got["gimbal/joint_states"], what="a JointState")
    js = h.got["gimbal/joint_states"][-1]
    assert sorted(js.name) == sorted(config_model(h.node.core.config).moving_joints)
    for arr in (js.position, js.velocity, js.effort):
        assert len(arr) == len(js.name) and all(math.isfinite(x) for x in arr)


def test_lost_input_turns_the_node_status_warn(harness):
    """Every third stamp of a 100 Hz stream missing: counted as stamp gaps, status WARN."""
    h = harness()
    for k in range(60):
        if k % 3 != 2:
            h.send(imu(BASE + k * 10 * MS))
    snap = h.node.core.snapshot()
    assert snap["input_lost_stamp_gaps"] >= 15                 # all but the first few (period not yet known)
    n = len(h.got["/diagnostics"])
    h.wait(lambda: len(h.got["/diagnostics"]) > n, timeout=5.0, what="/diagnostics")
    node = [s for s in h.got["/diagnostics"][-1].status if s.name == "gyro_platform: node"][0]
    assert node.level == node.WARN and "overload" in node.message


def test_a_publisher_of_another_type_on_the_input_is_said(harness):
    """A Twist publisher on the Imu input (or TwistStamped where Twist is taken: Jazzy stacks are
    moving to it) never matches, and DDS raises no event for it: the node said only 'no input
    yet'. Now /diagnostics names the other type (WARN when no publisher is of the input's type)."""
    from geometry_msgs.msg import Twist

    h = harness()
    h.driver.create_publisher(Twist, "imu", 10)
    h.driver.destroy_publisher(h.pub)

    def warned():
        for a in h.got["/diagnostics"]:
            st = {s.name: s for s in a.status}
            values = {v.key: v.value for v in st["gyro_platform: transport"].values}
            node = st["gyro_platform: node"]
            if values.get("input_publishers_other_types") == "geometry_msgs/msg/Twist" and node.level != node.OK:
                return "geometry_msgs/msg/Twist" in node.message and "sensor_msgs/msg/Imu" in node.message
        return False
    h.wait(warned, timeout=15.0, what="a WARN naming the Twist publisher")
