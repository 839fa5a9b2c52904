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

"""``ros2 launch gyro_platform platform.launch.py`` on real ROS 2 Jazzy, checked from outside.

The package is built into a colcon workspace (``--symlink-install``, conftest ``ros_ws``) and
launched as a user does, with launch arguments; a probe node (``ros_probe.py``, rclpy, in ROS's
python) publishes rate samples and records every output topic, ``/robot_description``, the
diagnostics and TF looked up through a ``tf2_ros.Buffer``. Checked: every documented output
topic carries finite values with the documented frame ids and the input's stamps; the TF of
every moving joint equals its joint origin turned by the published JointState position;
``/robot_description`` parses and its moving joints are the JointState names; each launch
argument does what it says (namespace, frame_prefix, scene, input_type, input_topic,
output_rate, robot_state_publisher:=false); Ctrl-C of ``ros2 launch`` exits 0 without a
traceback.
"""
import math
import signal
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import rosenv
from tfcheck import assert_tf_matches_joint_states, moving_joints, stamp, tf_pairs, vehicle_attitudes

BEARINGS = ("support", "gimbal4", "gimbal5", "gimbal7", "gimbal9", "gimbal10", "rotor6", "rotor8", "rotor11")
#: documented output topics (README, topic table) → (type, frame_id)
OUTPUTS = {
    "gimbal/joint_states": ("sensor_msgs/msg/JointState", ""),
    "drift/angle": ("geometry_msgs/msg/Vector3Stamped", "platform"),
    "drift/rate": ("geometry_msgs/msg/Vector3Stamped", "platform"),
    "platform/attitude": ("geometry_msgs/msg/QuaternionStamped", "platform_reference"),
    "platform/servo_torque": ("geometry_msgs/msg/Vector3Stamped", "platform"),
    **{f"bearing/{b}/torque": ("geometry_msgs/msg/WrenchStamped", f) for b, f in zip(BEARINGS, (
        "platform", "gyro_frame4", "gyro_housing5", "gyro_housing7", "gyro_frame9", "gyro_housing10",
        "gyro_housing5", "gyro_housing7", "gyro_housing10"))},
}
LAUNCH = "ros2 launch gyro_platform platform.launch.py"
#: TF lookups (target, source) of the attitude's frame: from platform, and through the mount joints
REFERENCE_TF = [("platform_reference", "platform"), ("platform_reference", "base_link")]
#: the gimbal axes of the model (spec PHYSICS.md; docs/ros.md): unit A α4 about +y, β5 about +z,
#: β7 about −z; unit B α9 about +z, β10 about +x (in the parent frames at zero angles)
GIMBAL_AXES = {"alpha4": (0.0, 1.0, 0.0), "beta5": (0.0, 0.0, 1.0), "beta7": (0.0, 0.0, -1.0),
               "alpha9": (0.0, 0.0, 1.0), "beta10": (1.0, 0.0, 0.0)}


def numbers(d):
    """Every number in a message dict (nested), as floats."""
    if isinstance(d, dict):
        return [x for v in d.values() for x in numbers(v)]
    if isinstance(d, list):
        return [x for v in d for x in numbers(v)]
    return [float(d)] if isinstance(d, (int, float)) and not isinstance(d, bool) else []


def launch_and_probe(ws, domain, args: str, spec: dict, ready="ready:"):
    """Launch with ``args``, wait for the node's ready line, run the probe; (report, launch
    exit code, launch output)."""
    proc = ws.start(f"{LAUNCH} {args}", domain=domain)
    try:
        assert proc.wait_for(ready, rosenv.READY_TIMEOUT), f"no {ready!r} line:\n{proc.output[-4000:]}"
        report = ws.ros.probe(spec, domain=domain)
    finally:
        code = proc.stop(signal.SIGINT)
    return report, code, proc.output


def spec_for(ns="", kind="imu", topic="/imu", count=150, rate=100.0, tf=(), frame_id="base_link",
             w=(0.05, -0.02, 0.1)):
    prefix = f"/{ns}" if ns else ""
    collect = {f"{prefix}/{t}": typ for t, (typ, _) in OUTPUTS.items()}
    collect[f"{prefix}/gimbal/joint_states"] = "sensor_msgs/msg/JointState"
    collect["/diagnostics"] = "diagnostic_msgs/msg/DiagnosticArray"
    return {"wait_subscriber": topic, "publish": {"topic": topic, "type": kind, "rate": rate, "count": count,
                                                  "w": list(w), "frame_id": frame_id},
            "collect": collect, "latched": {f"{prefix}/robot_description": "std_msgs/msg/String"},
            "settle": 1.5, "tf": [list(p) for p in tf]}


@pytest.fixture(scope="module")
def default_launch(ros_ws, tmp_path_factory):
    """The launch file with output_rate:=50.0 and 150 Imu at 100 Hz; TF of every moving joint."""
    with rosenv.domain_lock() as domain:
        # first launch: learn the URDF's joints, then look every moving one up in TF
        urdf_report, _, _ = launch_and_probe(ros_ws, domain, "output_rate:=50.0", spec_for(count=20))
        urdf = urdf_report["topics"]["/robot_description"][0]["data"]
        report, code, out = launch_and_probe(ros_ws, domain, "output_rate:=50.0",
                                             spec_for(tf=tf_pairs(urdf) + REFERENCE_TF))
    return report, code, out, urdf


def test_every_output_topic_is_finite_with_its_frame_and_the_input_stamps(default_launch):
    report, _, _, _ = default_launch
    for topic, (_, frame) in OUTPUTS.items():
        msgs = report["topics"][f"/{topic}"]
        assert len(msgs) >= 40, f"/{topic}: {len(msgs)} messages for 1.5 s of input at output_rate 50"
        assert all(m["header"]["frame_id"] == frame for m in msgs), topic
        assert all(math.isfinite(x) for m in msgs for x in numbers(m)), topic
        t = [stamp(m) for m in msgs]
        assert all(b > a for a, b in zip(t, t[1:])), f"{topic}: stamps not increasing"
    js = report["topics"]["/gimbal/joint_states"]
    t = np.array([stamp(m) for m in js])
    # the 50 Hz output grid on the sample time (the input stamps are wall-clock 'now')
    assert np.median(np.diff(t)) == pytest.approx(0.02, abs=1e-6)
    att = report["topics"]["/platform/attitude"]
    assert all(abs(math.hypot(*m["quaternion"].values()) - 1.0) < 1e-9 for m in att)


def test_tf_of_every_moving_joint_equals_the_joint_state(default_launch):
    report, _, _, urdf = default_launch
    assert_tf_matches_joint_states(report, urdf, "/gimbal/joint_states")


def test_platform_reference_is_in_tf_at_the_vehicle_attitude(default_launch):
    """The frame of /platform/attitude is in TF (the node's /tf: platform → platform_reference):
    looked up from platform it is the attitude of the same stamp, and from base_link (through
    robot_state_publisher's mount joints) the vehicle's attitude the outputs give; between two
    instants that attitude turns by exp(Δt w×) under the probe's constant body rate w."""
    report, _, _, urdf = default_launch
    att = {round(stamp(m), 9): m["quaternion"] for m in report["topics"]["/platform/attitude"]}
    direct, chain = (report["tf"][f"{target}|{source}"] for target, source in REFERENCE_TF)
    assert "error" not in direct and "error" not in chain, (direct, chain)
    q = att[round(direct["stamp"], 9)]
    assert (Rotation.from_quat(direct["rotation"]).inv() * Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]])
            ).magnitude() < 1e-9
    assert direct["translation"] == [0.0, 0.0, 0.0]
    vehicle = vehicle_attitudes(report, urdf)
    assert (Rotation.from_quat(chain["rotation"]).inv() * vehicle[round(chain["stamp"], 9)]).magnitude() < 1e-9
    first, last = min(vehicle), max(vehicle)
    w = np.array(spec_for()["publish"]["w"])
    assert last - first > 1.0
    turned = vehicle[first].inv() * vehicle[last]
    # 1e-7: the stamps are float seconds since 1970 here (~2e-7 s apart), w ~0.1 rad/s
    assert (turned.inv() * Rotation.from_rotvec(w * (last - first))).magnitude() < 1e-7


def test_robot_description_joints_are_the_joint_state_names(default_launch):
    report, _, _, urdf = default_launch
    names = report["topics"]["/gimbal/joint_states"][0]["name"]
    joints = [j[0] for j in moving_joints(urdf)]
    assert sorted(joints) == sorted(names) and len(set(names)) == len(names)
    assert set(names) >= {"alpha4", "beta5", "beta7", "alpha9", "beta10", "rotor6", "rotor8", "rotor11"}
    axes = {name: tuple(axis) for name, _, _, _, axis in moving_joints(urdf)}
    for name, axis in GIMBAL_AXES.items():
        assert axes[name] == axis, f"{name}: axis {axes[name]}, the model's is {axis}"


def test_ctrl_c_of_ros2_launch_exits_0_without_a_traceback(default_launch):
    _, code, out, _ = default_launch
    assert code == 0, out[-3000:]
    assert "Traceback" not in out, out[-3000:]


def test_diagnostics_report_the_taken_inputs(default_launch):
    report, _, _, _ = default_launch
    names = {s["name"] for a in report["topics"]["/diagnostics"] for s in a["status"]}
    assert {"gyro_platform: input", "gyro_platform: node", "gyro_platform: platform"} <= names


def test_namespace_twist_stamped_and_output_rate_arguments(ros_ws, domain):
    """namespace:=robot1 puts every topic under /robot1 and prefixes every frame 'robot1/';
    input_type:=twist_stamped on input_topic:=/vehicle/twist drives it; output_rate:=20.0."""
    spec = spec_for(ns="robot1", kind="twist_stamped", topic="/vehicle/twist", count=150,
                    tf=[("robot1/base_link", "robot1/platform")])
    report, code, out = launch_and_probe(
        ros_ws, domain, "namespace:=robot1 input_type:=twist_stamped input_topic:=/vehicle/twist "
                        "output_rate:=20.0", spec)
    assert code == 0
    for topic, (_, frame) in OUTPUTS.items():
        msgs = report["topics"][f"/robot1/{topic}"]
        assert msgs, f"/robot1/{topic}: nothing"
        assert all(m["header"]["frame_id"] == (f"robot1/{frame}" if frame else "") for m in msgs), topic
    t = np.array([stamp(m) for m in report["topics"]["/robot1/drift/angle"]])
    assert np.median(np.diff(t)) == pytest.approx(0.05, abs=1e-6)
    assert 15 <= len(t) <= 40          # 1.5 s of input at 20 Hz
    assert "error" not in report["tf"]["robot1/base_link|robot1/platform"]
    assert report["topics"]["/robot1/robot_description"]


def test_twist_input_frame_prefix_and_no_robot_state_publisher(ros_ws, domain):
    """input_type:=twist (no stamps: receive time), frame_prefix:=sim/, robot_state_publisher:=false:
    outputs come with 'sim/' frames and nothing publishes /robot_description."""
    spec = spec_for(kind="twist", topic="/twist", count=100)
    report, code, out = launch_and_probe(
        ros_ws, domain, "input_type:=twist frame_prefix:=sim/ robot_state_publisher:=false", spec)
    assert code == 0
    att = report["topics"]["/platform/attitude"]
    assert att and all(m["header"]["frame_id"] == "sim/platform_reference" for m in att)
    assert report["topics"]["/robot_description"] == []
    assert "robot_state_publisher" not in out


def test_scene_argument_sets_the_model(ros_ws, domain):
    """scene:=rate_step_shock (a carried platform): the node says so and its JointState has the gimbals and
    rotors but no mount joints (the default scene is stabilised: three mount joints more)."""
    spec = spec_for(count=100)
    report, code, out = launch_and_probe(ros_ws, domain, "scene:=rate_step_shock output_rate:=50.0", spec)
    assert code == 0
    assert "carried/" in out and "scene rate_step_shock" in out, out[-2000:]
    js = report["topics"]["/gimbal/joint_states"]
    assert js and all(math.isfinite(x) for m in js for x in m["position"])
    assert js[0]["name"] == ["alpha4", "beta5", "beta7", "alpha9", "beta10", "rotor6", "rotor8", "rotor11"]


def test_a_bad_launch_argument_is_one_error_line_and_a_failed_launch(ros_ws, domain):
    """A bringup that includes the launch file must see it fail: one ERROR line, exit 1, nothing
    started (it logged at INFO and exited 0, so the vehicle ran without its platform)."""
    proc = ros_ws.start(f"{LAUNCH} output_rate:=-5.0", domain=domain)
    code = proc.popen.wait(120)
    out = proc.output
    proc.stop()
    errors = [ln for ln in out.splitlines() if "[ERROR]" in ln]
    assert len(errors) == 1 and "not started" in errors[0] and "output_rate" in errors[0], out
    assert code == 1 and "Traceback" not in out and "process started" not in out


@pytest.mark.parametrize("bad, says", [
    ("ros__parameters: [1, 2]\n", "params file"),      # rcl cannot parse it
    (None, "params file"),                              # the file does not exist
])
def test_a_params_file_rcl_cannot_read_is_one_line_and_exit_2(ros_ws, domain, tmp_path, bad, says):
    """rcl parses ``--params-file`` in ``rclpy.init``: its RCLError was a traceback (exit 1)."""
    path = tmp_path / "bad.yaml"
    if bad is not None:
        path.write_text(f"gyro_platform_node:\n  {bad}")
    exe = ros_ws.root / "install" / "gyro_platform" / "lib" / "gyro_platform" / "platform_node"
    p = ros_ws.run(f"{exe} --ros-args --params-file {path}", domain=domain, timeout=120)
    out = p.stdout + p.stderr
    assert p.returncode == 2 and "Traceback" not in out, out[-3000:]
    lines = [ln for ln in out.splitlines() if "cannot start" in ln]
    assert len(lines) == 1 and says in lines[0] and "./src/" not in lines[0], out[-3000:]


def test_a_parameter_the_node_does_not_have_is_said_not_ignored_silently(ros_ws, domain, tmp_path):
    """``-p input_topic:=…`` (the launch argument's name, not the parameter's) and a misspelt key in
    the params file: rclpy ignores both without a word, and the node ran on /imu. Now one WARN line
    each, naming the parameter meant; the node starts as before and ROS's own parameters are quiet."""
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    output_rte: 5.0\n    use_sim_time: false\n")
    exe = ros_ws.root / "install" / "gyro_platform" / "lib" / "gyro_platform" / "platform_node"
    proc = ros_ws.start(f"{exe} --ros-args -p input_topic:=/vehicle/imu --params-file {path}", domain=domain)
    try:
        assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
    finally:
        code = proc.stop(signal.SIGINT)
    warned = [ln for ln in proc.output.splitlines() if "[WARN]" in ln and "not one of this node's" in ln]
    assert len(warned) == 2, proc.output[-3000:]
    assert "'input_topic'" in warned[0] and "imu_topic" in warned[0]
    assert "'output_rte'" in warned[1] and "'output_rate'" in warned[1]
    assert code == 0 and "Traceback" not in proc.output


@pytest.mark.parametrize("after", [0.5, 0.9, 1.5])
def test_ctrl_c_while_the_node_starts_is_a_quiet_exit_0(ros_ws, domain, after):
    """SIGINT to the node's process group while numba and rclpy load (as ``ros2 launch`` sends
    it twice when a bringup is aborted): exit 0 and no traceback (it was a KeyboardInterrupt
    traceback through ``import numba``, exit −2 or 1). Not covered: the first ~0.3 s, spent in
    the console script setuptools writes (it looks its entry point up in the installed
    distributions' metadata before any of this package runs)."""
    exe = ros_ws.root / "install" / "gyro_platform" / "lib" / "gyro_platform" / "platform_node"
    proc = ros_ws.start(str(exe), domain=domain)
    time.sleep(after)
    code = proc.stop(signal.SIGINT)
    out = proc.output
    assert code == 0 and "Traceback" not in out, (after, code, out[-3000:])
