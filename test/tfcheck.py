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

"""TF against joint states, for the ROS tests: the URDF's moving joints and the check that the
TF of each equals its joint origin turned about its axis by the published JointState position."""
import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation


def stamp(m):
    """Header stamp of a message dict, s."""
    return m["header"]["stamp"]["sec"] + m["header"]["stamp"]["nanosec"] * 1e-9


def moving_joints(urdf: str):
    """(name, parent, child, origin Rotation, axis) of every non-fixed joint, in document order."""
    out = []
    for j in ET.fromstring(urdf).iter("joint"):
        if j.get("type") == "fixed":
            continue
        o = j.find("origin")
        rpy = [float(x) for x in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
        axis = np.array([float(x) for x in j.find("axis").get("xyz").split()])
        out.append((j.get("name"), j.find("parent").get("link"), j.find("child").get("link"),
                    Rotation.from_euler("xyz", rpy), axis))
    return out


def link_rotation(urdf: str, positions: dict, link: str) -> Rotation:
    """Forward kinematics of the URDF: rotation base → ``link`` (child axes to base axes) with
    the moving joints at ``positions`` (rad; the fixed ones at their origins)."""
    parent_joint = {j.find("child").get("link"): j for j in ET.fromstring(urdf).iter("joint")}
    rot = Rotation.identity()
    while link in parent_joint:
        j = parent_joint[link]
        o = j.find("origin")
        rpy = [float(x) for x in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
        r = Rotation.from_euler("xyz", rpy)
        if j.get("type") != "fixed":
            axis = np.array([float(x) for x in j.find("axis").get("xyz").split()])
            r = r * Rotation.from_rotvec(positions[j.get("name")] * axis)
        rot = r * rot
        link = j.find("parent").get("link")
    return rot


def vehicle_attitudes(report, urdf: str, prefix: str = "") -> dict:
    """Stamp (s, rounded to ns) → the vehicle's attitude in ``platform_reference`` (base_link axes
    to reference axes) at every instant with both a JointState and a platform attitude: the
    attitude times the inverse of base_link → platform (the URDF at the joint positions)."""
    att = {round(stamp(m), 9): m["quaternion"] for m in report["topics"][f"{prefix}/platform/attitude"]}
    res = {}
    for m in report["topics"][f"{prefix}/gimbal/joint_states"]:
        q = att.get(round(stamp(m), 9))
        if q is not None:
            platform = link_rotation(urdf, dict(zip(m["name"], m["position"])), "platform")
            res[round(stamp(m), 9)] = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]) * platform.inv()
    return res


def tf_pairs(urdf: str, prefix: str = ""):
    """(parent, child) frame pairs of the moving joints, with the TF frame prefix."""
    return [(prefix + p, prefix + c) for _, p, c, _, _ in moving_joints(urdf)]


def assert_tf_matches_joint_states(report, urdf: str, joint_states: str, prefix: str = ""):
    """Every moving joint's TF (probe report) = origin · rot(axis, q) of the JointState of its stamp."""
    by_stamp = {round(stamp(m), 9): dict(zip(m["name"], m["position"])) for m in report["topics"][joint_states]}
    joints = moving_joints(urdf)
    assert joints
    for name, parent, child, origin, axis in joints:
        tf = report["tf"][f"{prefix}{parent}|{prefix}{child}"]
        assert "error" not in tf, tf
        q = by_stamp[round(tf["stamp"], 9)][name]
        expected = origin * Rotation.from_rotvec(q * axis)
        got = Rotation.from_quat(tf["rotation"])
        assert (got.inv() * expected).magnitude() < 1e-6, f"{name}: TF differs from origin * rot(axis, {q})"
