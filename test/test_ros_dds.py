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

"""The plain-DDS transport (this venv, no ROS) against real rclpy nodes.

``gyro-platform node --transport dds`` runs in the interpreter running the tests (cyclonedds,
no rclpy); the probe (``ros_probe.py``) is an rclpy node in ROS's python on the same domain. It
publishes Imu and reads the outputs, ``/diagnostics``, ``/robot_description`` (transient local)
and TF through a ``tf2_ros.Buffer``: the wire format, QoS and names must be what rclpy expects.
"""
import math
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
from scipy.spatial.transform import Rotation

import rosenv
from rosenv import Proc
from tfcheck import assert_tf_matches_joint_states, tf_pairs, vehicle_attitudes

#: TF lookup (target, source): the attitude's frame from base_link, through the mount joints
REFERENCE = ("platform_reference", "base_link")

pytest.importorskip("cyclonedds", reason="the DDS transport needs the 'cyclonedds' package (pip install .[dds])")


@pytest.fixture(scope="module")
def dds_session(ros):
    with rosenv.domain_lock() as domain:
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), CYCLONEDDS_URI=rosenv.LOOPBACK_XML.as_uri(),
                   PYTHONUNBUFFERED="1")
        params = str(rosenv.REPO / "config" / "platform.yaml")
        cmd = [sys.executable, "-m", "gyro_platform", "node", "--transport", "dds", "--params-file", params]
        proc = Proc(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True))
        try:
            assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
            first = ros.probe({"latched": {"/robot_description": "std_msgs/msg/String"}, "settle": 3.0}, domain=domain)
            urdf = first["topics"]["/robot_description"][0]["data"]
            fixed = [(j.find("parent").get("link"), j.find("child").get("link"))
                     for j in ET.fromstring(urdf).iter("joint") if j.get("type") == "fixed"]
            report = ros.probe({
                "wait_subscriber": "/imu",
                "publish": {"topic": "/imu", "count": 200, "rate": 100.0, "w": [0.03, 0.01, 0.08]},
                "collect": {"/gimbal/joint_states": "sensor_msgs/msg/JointState",
                            "/drift/rate": "geometry_msgs/msg/Vector3Stamped",
                            "/bearing/rotor11/torque": "geometry_msgs/msg/WrenchStamped",
                            "/platform/attitude": "geometry_msgs/msg/QuaternionStamped",
                            "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray"},
                "settle": 2.0, "tf": [list(p) for p in tf_pairs(urdf) + fixed + [REFERENCE]]}, domain=domain)
        finally:
            code = proc.stop(signal.SIGINT)
    return report, urdf, fixed, code, proc.output


def test_rclpy_reads_the_outputs_of_the_dds_node(dds_session):
    report, _, _, code, log = dds_session
    js = report["topics"]["/gimbal/joint_states"]
    assert len(js) >= 10, log[-2000:]
    assert all(math.isfinite(x) for m in js for x in m["position"] + m["velocity"] + m["effort"])
    assert report["topics"]["/drift/rate"] and report["topics"]["/bearing/rotor11/torque"]
    assert all(m["header"]["frame_id"] == "gyro_housing10" for m in report["topics"]["/bearing/rotor11/torque"])
    names = {s["name"] for a in report["topics"]["/diagnostics"] for s in a["status"]}
    assert "gyro_platform: transport" in names and "gyro_platform: node" in names
    assert code == 0 and "Traceback" not in log


def test_tf_and_robot_description_of_the_dds_node_in_a_tf2_buffer(dds_session):
    report, urdf, fixed, _, _ = dds_session
    assert_tf_matches_joint_states(report, urdf, "/gimbal/joint_states")
    for parent, child in fixed:                          # /tf_static (transient local)
        tf = report["tf"][f"{parent}|{child}"]
        assert "error" not in tf, tf
        assert abs(math.hypot(*tf["rotation"]) - 1.0) < 1e-9
    # platform_reference (the attitude's frame) through the mount joints: the vehicle's attitude
    chain = report["tf"]["|".join(REFERENCE)]
    assert "error" not in chain, chain
    vehicle = vehicle_attitudes(report, urdf)[round(chain["stamp"], 9)]
    assert (Rotation.from_quat(chain["rotation"]).inv() * vehicle).magnitude() < 1e-9
