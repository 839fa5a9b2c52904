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

"""URDF and TF of the platform against the model's own kinematics (gyro_platform.ros.urdf).

The URDF is parsed with urdf_parser_py (urdfdom-py, what ROS tools use) and its forward
kinematics is computed here from the parsed origins and axes (independently of urdf.py);
it must agree with the body tree of the equations of motion (model.platform_tree and the
tree.kinematics kernel), with the simulator's own attitudes (mount joints), and with the
TF messages the DDS transport sends.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_platform import messages as m
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.outputs import GIMBAL_NAMES, MOUNT_NAMES
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.model import GIMBAL_AXES, platform_tree, SPIN_AXES
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import PlatformParams
from gyro_platform.physics.tree import kinematics, REVOLUTE, ROOT, rot_axis
from gyro_platform.ros import urdf as U

urdf_parser = pytest.importorskip("urdf_parser_py.urdf", reason="urdf_parser_py (pip install urdf-parser-py)")

TYPES = m.MessageTypes.rosbags()
#: a non-trivial mounting and unequal bodies, so that a swapped axis or size shows
PARAMS = PlatformParams(mounting=tuple(Rotation.from_euler("xyz", [0.3, -0.2, 0.5]).as_quat()),
                        frame9=(9e-5, 7e-5, 5e-5), housing10=(3.5e-5, 2e-5, 2.8e-5))
BODY_LINK = {"platform": "platform", "frame4": "gyro_frame4", "housing5": "gyro_housing5",
             "housing7": "gyro_housing7", "frame9": "gyro_frame9", "housing10": "gyro_housing10"}


def parsed(stabilised: bool = True, p: PlatformParams = PARAMS):
    return urdf_parser.URDF.from_xml_string(U.platform_urdf(p, stabilised))


def urdf_fk(robot, positions: dict[str, float]) -> dict[str, np.ndarray]:
    """Rotation matrices base_link → link from the parsed URDF (origin rpy, then axis rotation)."""
    R = {robot.get_root(): np.eye(3)}
    pending = list(robot.joints)
    while pending:
        for j in list(pending):
            if j.parent in R:
                rpy = j.origin.rpy if j.origin is not None else [0, 0, 0]
                Rj = Rotation.from_euler("xyz", rpy).as_matrix()      # URDF: Rz(y) Ry(p) Rx(r)
                if j.type != "fixed":
                    Rj = Rj @ Rotation.from_rotvec(np.asarray(j.axis) * positions[j.name]).as_matrix()
                R[j.child] = R[j.parent] @ Rj
                pending.remove(j)
    return R


@pytest.mark.parametrize("stabilised", [True, False])
def test_urdf_tree_and_joint_names(stabilised):
    robot = parsed(stabilised)
    assert robot.get_root() == "base_link"
    parent = {j.child: j.parent for j in robot.joints}
    tree = platform_tree(PARAMS, root_dynamic=stabilised)
    for i, body in enumerate(tree.names[1:], start=1):                # same tree as the dynamics
        assert parent[BODY_LINK[body]] == BODY_LINK[tree.names[tree.parent[i]]]
    for (host, rotor) in U.ROTOR_LINKS:
        assert parent[rotor] == host
    chain = (
        ["platform", "mount_pitch_link", "mount_roll_link", "base_link"] if stabilised else ["platform", "base_link"]
    )
    assert [chain[0]] + [parent[c] for c in chain[:-1]] == chain       # REP-105: base_link → platform
    moving = [j.name for j in robot.joints if j.type != "fixed"]
    # joint names are exactly the JointState names of the node's outputs (same order)
    sim = Simulator(PARAMS, ModelOptions.make("stabilised" if stabilised else "carried", "linear"))
    sim.push(RateSample.of(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81)))
    sim.push(RateSample.of(0.01, (0.01, 0.0, 0.0), (0.0, 0.0, 9.81)))
    js = m.joint_state(sim.outputs(), TYPES, 1)
    assert sorted(moving) == sorted(js.name)
    assert list(js.name) == [*GIMBAL_NAMES, *(MOUNT_NAMES if stabilised else ()), *U.ROTOR_JOINTS]
    for j in robot.joints:
        if j.type == "revolute":
            assert j.limit is not None and j.limit.lower < 0 < j.limit.upper


def test_joint_axes_are_the_model_axes():
    robot = parsed()
    joints = {j.name: j for j in robot.joints}
    for name, axis in zip(GIMBAL_NAMES, GIMBAL_AXES):
        np.testing.assert_array_equal(joints[name].axis, axis)
        assert joints[name].type == "continuous"
    for name, axis in zip(U.ROTOR_JOINTS, SPIN_AXES):
        np.testing.assert_array_equal(joints[name].axis, axis)
    for name, axis in zip(MOUNT_NAMES, np.eye(3)):
        np.testing.assert_array_equal(joints[name].axis, axis)


def test_the_trees_rotations_and_rates_are_scipys_about_any_axis():
    """``rot_axis`` and a chain of revolute joints about random unit axes (the kernels' one
    Rodrigues formula, indexed in place): R_parent,child = SciPy's rotation of the axis·angle
    vector, and each body's rate = R_childᵀ ω_parent + q̇ n, to 1e-15; the velocity Jacobian's
    columns reproduce the rates."""
    rng = np.random.default_rng(38)
    for _ in range(20):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        th = rng.uniform(-math.pi, math.pi)
        out = np.zeros((3, 3))
        rot_axis(n, th, out)
        np.testing.assert_allclose(out, Rotation.from_rotvec(n * th).as_matrix(), rtol=0, atol=1e-15)
    nb = 4
    axes = rng.normal(size=(nb, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    parent = np.array([-1, 0, 1, 1], dtype=np.int64)                 # a root, a joint, two children
    jtype = np.array([ROOT, REVOLUTE, REVOLUTE, REVOLUTE], dtype=np.int64)
    qidx = np.array([-1, 0, 1, 2], dtype=np.int64)
    vidx = qidx.copy()
    q, v, w0 = rng.uniform(-2, 2, 3), rng.normal(size=3), rng.normal(size=3)
    R, w, J = np.zeros((nb, 3, 3)), np.zeros((nb, 3)), np.zeros((nb, 3, 3))
    kinematics(parent, jtype, axes, qidx, vidx, False, q, v, w0, R, w, J)
    np.testing.assert_array_equal(R[0], np.eye(3))
    np.testing.assert_array_equal(w[0], w0)
    for i in range(1, nb):
        Ri = Rotation.from_rotvec(axes[i] * q[qidx[i]]).as_matrix()
        np.testing.assert_allclose(R[i], Ri, rtol=0, atol=1e-15)
        np.testing.assert_allclose(w[i], Ri.T @ w[parent[i]] + v[vidx[i]] * axes[i], rtol=0, atol=1e-14)
        np.testing.assert_allclose(J[i] @ v, w[i] - _root_part(R, parent, i, w0),
                                   rtol=0, atol=1e-14)


def _root_part(R, parent, i, w0):
    """The prescribed root rate seen in body i's axes (the affine part of ω_i = J_i v + …)."""
    chain = []
    while i > 0:
        chain.append(i)
        i = parent[i]
    x = np.asarray(w0, float)
    for k in reversed(chain):
        x = R[k].T @ x
    return x


def test_forward_kinematics_equals_the_body_tree():
    """R_platform,body from the URDF = the product of the tree kernel's R_parent,child."""
    robot = parsed()
    tree = platform_tree(PARAMS, root_dynamic=True)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 5)
        mount = rng.uniform(-1.0, 1.0, 3)
        pos = {**dict(zip(GIMBAL_NAMES, q)), **dict(zip(MOUNT_NAMES, mount)),
               **dict(zip(U.ROTOR_JOINTS, rng.uniform(-3, 3, 3)))}
        Rk = np.zeros((tree.nb, 3, 3))
        kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, tree.root_dynamic, q,
                   np.zeros(tree.nv), np.zeros(3), Rk, np.zeros((tree.nb, 3)), np.zeros((tree.nb, 3, tree.nv)))
        R_tree = {0: np.eye(3)}
        for i in range(1, tree.nb):
            R_tree[i] = R_tree[tree.parent[i]] @ Rk[i]
        R = urdf_fk(robot, pos)
        R_base_P = R["platform"]
        for i, body in enumerate(tree.names):
            np.testing.assert_allclose(R_base_P.T @ R[BODY_LINK[body]], R_tree[i], atol=1e-12)
        for (host, rotor), s, name in zip(U.ROTOR_LINKS, SPIN_AXES, U.ROTOR_JOINTS):
            np.testing.assert_allclose(R[host].T @ R[rotor], Rotation.from_rotvec(s * pos[name]).as_matrix(),
                                       atol=1e-12)
        # the implementation's own FK (used for /tf) agrees with the parsed URDF
        own = U.platform_model(PARAMS, True).link_rotations(pos)
        for link, Rl in R.items():
            np.testing.assert_allclose(own[link].as_matrix(), Rl, atol=1e-12)


def run_stabilised(T: float = 0.6, hz: float = 200.0, rate=(0.4, -0.3, 0.5)):
    """Stabilised platform on a vehicle turning at ``rate`` (rad/s, base axes): outputs and the
    simulator's (R_IB, R_IP) at each sample."""
    sim = Simulator(PARAMS, ModelOptions.make("stabilised", "full", integrator="dop853", rtol=1e-10, atol=1e-12))
    res = []
    for k in range(int(T * hz) + 1):
        sim.push(RateSample.of(k / hz, rate, (0.0, 0.0, 9.81)))
        res.append((sim.outputs(), *sim.attitude_matrices()))
    return res


def test_mount_joints_reproduce_the_platform_attitude_in_base_link():
    """URDF FK at the published mount angles = the simulated vehicle → platform rotation."""
    robot = parsed()
    for out, R_IB, R_IP in run_stabilised()[::20]:
        pos = m.joint_positions(out)
        np.testing.assert_allclose(urdf_fk(robot, pos)["platform"], R_IB.T @ R_IP, atol=1e-9)


def test_mount_rates_are_the_derivative_of_the_mount_angles():
    res = run_stabilised(hz=400.0)
    t = np.array([o.t for o, _, _ in res])
    a = np.unwrap(np.array([o.mount_angles for o, _, _ in res]), axis=0)
    rates = np.array([o.mount_rates for o, _, _ in res])
    assert np.max(np.abs(rates)) > 0.2                                 # the vehicle turns under the platform
    fd = (a[2:] - a[:-2]) / (t[2:] - t[:-2])[:, None]                  # central differences, O(h²)
    np.testing.assert_allclose(rates[1:-1], fd, atol=2e-4)


def test_inertials_are_the_parameters_and_visuals_reproduce_them():
    robot = parsed()
    links = {l.name: l for l in robot.links}
    P = PARAMS.platform_tensor
    I = links["platform"].inertial.inertia
    np.testing.assert_array_equal([I.ixx, I.iyy, I.izz, I.ixy, I.ixz, I.iyz],
                                  [P[0, 0], P[1, 1], P[2, 2], P[0, 1], P[0, 2], P[1, 2]])
    for body, moments in (("gyro_frame9", PARAMS.frame9), ("gyro_housing10", PARAMS.housing10)):
        link = links[body]
        I = link.inertial.inertia
        assert [I.ixx, I.iyy, I.izz] == list(moments)
        a, b, c = link.visual.geometry.size
        mass = link.inertial.mass
        assert mass == pytest.approx(U.DENSITY["structure"] * a * b * c, rel=1e-12)
        np.testing.assert_allclose(
            [mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12], moments, rtol=1e-12
        )
    rotors = ("gyro_rotor6", "gyro_rotor8", "gyro_rotor11")
    for rotor, C, A, s in zip(rotors, PARAMS.rotor_C, PARAMS.rotor_A, SPIN_AXES):
        cyl = links[rotor].visual.geometry
        mass = links[rotor].inertial.mass
        assert mass == pytest.approx(U.DENSITY["rotor"] * math.pi * cyl.radius ** 2 * cyl.length, rel=1e-12)
        assert mass * cyl.radius ** 2 / 2 == pytest.approx(C, rel=1e-12)
        assert mass * (3 * cyl.radius ** 2 + cyl.length ** 2) / 12 == pytest.approx(A, rel=1e-12)
        # the cylinder (URDF z) is turned onto the spin axis
        Rv = Rotation.from_euler("xyz", links[rotor].visual.origin.rpy).as_matrix()
        assert abs(abs(Rv[:, 2] @ s) - 1.0) < 1e-12


def test_bigger_inertia_draws_a_bigger_body():
    small = {l.name: l for l in parsed(p=PARAMS).links}
    big = {l.name: l for l in parsed(p=PARAMS.with_(frame4=tuple(32 * x for x in PARAMS.frame4))).links}
    # moments × 32 at equal density: every side × 2 (I ∝ ρ L⁵)
    np.testing.assert_allclose(np.array(big["gyro_frame4"].visual.geometry.size),
                               2 * np.array(small["gyro_frame4"].visual.geometry.size), rtol=1e-12)


def test_tf_messages_compose_to_the_model_rotations():
    """The DDS transport's /tf (moving joints) and /tf_static (fixed joints), chained from
    base_link, give the model's rotations; frames carry the prefix."""
    for stabilised in (True, False):
        model = U.platform_model(PARAMS, stabilised)
        robot = parsed(stabilised)
        rng = np.random.default_rng(11)
        pos = {n: float(x) for n, x in zip(model.moving_joints, rng.uniform(-1, 1, len(model.moving_joints)))}
        dyn = m.tf_message(model, pos, TYPES, 5_000_000_123, "robot1/")
        sta = m.tf_message(model, pos, TYPES, 5_000_000_123, "robot1/", static=True)
        assert len(dyn.transforms) == len(model.moving_joints)
        assert len(sta.transforms) == len(model.joints) - len(model.moving_joints)
        R = {"robot1/base_link": np.eye(3)}
        edges = {t.child_frame_id: t for t in [*dyn.transforms, *sta.transforms]}
        while len(R) < len(edges) + 1:
            for child, t in edges.items():
                if t.header.frame_id in R and child not in R:
                    q = t.transform.rotation
                    R[child] = R[t.header.frame_id] @ Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
        expected = urdf_fk(robot, pos)
        assert {k.removeprefix("robot1/") for k in R} == set(expected)
        for link, Rl in expected.items():
            np.testing.assert_allclose(R["robot1/" + link], Rl, atol=1e-12)
        assert all(t.header.stamp.sec == 5 and t.header.stamp.nanosec == 123 for t in dyn.transforms)
