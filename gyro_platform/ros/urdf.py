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

"""URDF of the platform, generated from its parameters (ROS-free), and the joint transforms for TF.

Frames (REP-105, REP-103 FLU) and joints; joint names equal the ``JointState`` names the node
publishes (:func:`gyro_platform.messages.joint_state`):

* ``base_link`` (vehicle) → ``platform``: carried mode: fixed joint ``platform_mount`` with the
  ``mounting`` rotation; stabilised mode: the mount joints ``mount_roll`` (x), ``mount_pitch``
  (y), ``mount_yaw`` (z), intrinsic X-Y-Z as the mount angles are output, through the links
  ``mount_roll_link`` and ``mount_pitch_link``; the first joint's origin carries ``mounting``,
  so ``R_base,platform = R(mounting) Rx(roll) Ry(pitch) Rz(yaw)``;
* unit A: ``platform`` → ``gyro_frame4`` (``alpha4``, +y) → ``gyro_housing5`` (``beta5``, +z)
  and ``gyro_housing7`` (``beta7``, −z); unit B: ``platform`` → ``gyro_frame9`` (``alpha9``,
  +z) → ``gyro_housing10`` (``beta10``, +x) — the axes of ``model.GIMBAL_AXES``, all continuous
  (the model has no gimbal stops);
* rotors: ``gyro_housing5`` → ``gyro_rotor6`` (``rotor6``, +x), ``gyro_housing7`` →
  ``gyro_rotor8`` (``rotor8``, −x), ``gyro_housing10`` → ``gyro_rotor11`` (``rotor11``, +y),
  continuous (``model.SPIN_AXES``).

In the normal position (all angles 0) every body's axes are parallel to the platform's (spec 2).
The model is rotational only (gimbal centres coincide; translations do not enter the
dynamics), so the joint *positions* are a schematic layout for display: unit A on the left
(+y) half of the platform top, unit B on the right, housings 5 and 7 side by side along the
α4 axis. Sizes follow the parameters: each body is drawn as the uniform box (rotors: the solid
cylinder) of the density :data:`DENSITY` whose principal moments are the body's, so a heavier
body is drawn larger; the ``<inertial>`` moments are the parameters themselves, the masses are
those of the equivalent solids (the model has no masses except ``gyro_mass``).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Mapping, Sequence, TYPE_CHECKING
import xml.etree.ElementTree as ET

import numpy as np

from .. import quaternions
from ..engine.outputs import GIMBAL_NAMES, MOUNT_NAMES
from ..physics.model import GIMBAL_AXES, SPIN_AXES
from ..physics.params import NO_POLAR_INERTIA, ParameterError, PlatformParams

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

#: densities of the equivalent solids (kg/m³): aluminium frames and housings, steel rotors
DENSITY = {"structure": 2700.0, "rotor": 7850.0}
ROBOT_NAME = "gyro_platform"
BASE_FRAME = "base_link"
PLATFORM_FRAME = "platform"
ROTOR_JOINTS = ("rotor6", "rotor8", "rotor11")
#: child link of each gimbal joint (alpha4, beta5, beta7, alpha9, beta10) and its parent
GIMBAL_LINKS = (("platform", "gyro_frame4"), ("gyro_frame4", "gyro_housing5"), ("gyro_frame4", "gyro_housing7"),
                ("platform", "gyro_frame9"), ("gyro_frame9", "gyro_housing10"))
ROTOR_LINKS = (("gyro_housing5", "gyro_rotor6"), ("gyro_housing7", "gyro_rotor8"), ("gyro_housing10", "gyro_rotor11"))
MOUNT_LINKS = ((BASE_FRAME, "mount_roll_link"), ("mount_roll_link", "mount_pitch_link"),
               ("mount_pitch_link", PLATFORM_FRAME))
MOUNT_AXES = np.eye(3)


@dataclass(frozen=True)
class Joint:
    """One URDF joint: ``T_parent,child(q) = Trans(xyz) Rot(quat) Rot(axis, q)`` (URDF semantics)."""

    name: str
    type: str                                   # fixed | continuous | revolute
    parent: str
    child: str
    xyz: tuple[float, float, float]             # m, parent axes
    quat: tuple[float, float, float, float]     # x, y, z, w: rotation of the joint frame in the parent
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    limits: tuple[float, float] | None = None   # rad, revolute only

    def quaternion(self, q: float = 0.0) -> np.ndarray:
        """Rotation parent → child (maps child-axes vectors to parent axes) at position ``q`` rad,
        as a unit quaternion (x, y, z, w)."""
        r = quaternions.normalized(self.quat)
        if self.type == "fixed":
            return r
        return quaternions.mul(r, quaternions.from_rotvec(np.asarray(self.axis, float) * float(q)))

    def rotation(self, q: float = 0.0) -> Rotation:
        """:meth:`quaternion` as SciPy's ``Rotation``."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_quat(self.quaternion(q))


@dataclass(frozen=True)
class Visual:
    """A link's geometry: ``box`` (size x, y, z m) or ``cylinder`` (radius, length m, along
    ``axis``), a colour and the inertia drawn from (mass kg, 3×3 tensor kg m² in link axes)."""

    kind: str
    size: tuple[float, ...]
    axis: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    mass: float
    inertia: np.ndarray


@dataclass(frozen=True)
class PlatformModel:
    """Links (name → visual, None for massless mount links), joints parents-first."""

    links: dict[str, Visual | None]
    joints: tuple[Joint, ...]

    @property
    def moving_joints(self) -> list[str]:
        return [j.name for j in self.joints if j.type != "fixed"]

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    def transforms(self, positions: Mapping[str, float]) -> list[tuple[Joint, np.ndarray, np.ndarray]]:
        """(joint, translation m, quaternion x, y, z, w) parent → child of every joint, moving
        joints at ``positions`` (rad; missing ones at 0)."""
        res = []
        for j in self.joints:
            q = float(positions.get(j.name, 0.0)) if j.type != "fixed" else 0.0
            res.append((j, np.asarray(j.xyz, float), j.quaternion(q)))
        return res

    def link_rotations(self, positions: Mapping[str, float]) -> dict[str, Rotation]:
        """Forward kinematics: rotation base_link → link (child axes to base axes) of every link."""
        from scipy.spatial.transform import Rotation

        rot = {BASE_FRAME: Rotation.identity()}
        for j in self.joints:
            q = float(positions.get(j.name, 0.0)) if j.type != "fixed" else 0.0
            rot[j.child] = rot[j.parent] * j.rotation(q)
        return rot


# =========================================================================================
# sizes from inertia
# =========================================================================================
def equivalent_box(moments: Sequence[float], density: float) -> tuple[tuple[float, float, float], float]:
    """Sides (m) and mass (kg) of the uniform box of ``density`` with principal moments
    ``moments`` (kg m²): ``I_x = m (b² + c²)/12`` … Moments violating the triangle inequality
    (not a rigid body) are clamped to a thin plate."""
    Ix, Iy, Iz = (float(x) for x in moments)
    s = np.array([Iy + Iz - Ix, Ix + Iz - Iy, Ix + Iy - Iz]) * 6.0        # m a², m b², m c²
    s = np.maximum(s, 1e-3 * max(float(np.max(s)), 1e-30))
    abc = (float(np.prod(s)) / density ** 3) ** 0.2                       # (abc)^5 = Π s / ρ³
    mass = density * abc
    sides = tuple(float(x) for x in np.sqrt(s / mass))
    return sides, mass


def equivalent_cylinder(C: float, A: float, density: float) -> tuple[float, float, float]:
    """Radius (m), length (m) and mass (kg) of the solid cylinder of ``density`` with axial
    moment ``C = m r²/2`` and equatorial moment ``A = m (3 r² + h²)/12`` (kg m²). ``2A ≤ C``
    (a disc flatter than any solid cylinder) gives a thin disc of length r/10. ``C ≤ 0`` is
    refused (ParameterError, as ``PlatformParams`` refuses it: no such rotor)."""
    C, A = float(C), float(A)
    if not C > 0.0:
        raise ParameterError(f"rotor_C = {C:g}: {NO_POLAR_INERTIA}")
    h2_m = max(12.0 * A - 6.0 * C, 0.0)                                   # m h²
    if h2_m <= 1e-3 * C:
        # thin disc: m = ρ π r² (r/10), C = m r²/2 → r^5 = 20 C / (ρ π)
        r = (20.0 * C / (density * math.pi)) ** 0.2
        m = density * math.pi * r ** 3 / 10.0
        return r, r / 10.0, m
    m = (2.0 * math.pi * density * C * math.sqrt(h2_m)) ** 0.4           # m^(5/2) = 2πρ C √(m h²)
    return math.sqrt(2.0 * C / m), math.sqrt(h2_m / m), m


def _box_visual(moments: Sequence[float], rgba, tensor: np.ndarray | None = None) -> Visual:
    sides, mass = equivalent_box(moments, DENSITY["structure"])
    return Visual("box", sides, (0.0, 0.0, 1.0), rgba, mass,
                  np.diag(np.asarray(moments, float)) if tensor is None else tensor)


def _rotor_visual(C: float, A: float, axis: np.ndarray) -> Visual:
    r, h, m = equivalent_cylinder(C, A, DENSITY["rotor"])
    a = np.abs(axis)
    inertia = np.diag(A + (C - A) * a)          # C about the spin axis, A across it
    return Visual("cylinder", (r, h), tuple(float(x) for x in axis), (0.75, 0.75, 0.8, 1.0), m, inertia)


# =========================================================================================
# the model
# =========================================================================================
def platform_model(p: PlatformParams, stabilised: bool) -> PlatformModel:
    """Links and joints of the platform for parameters ``p`` (see the module docstring)."""
    P = np.asarray(p.platform_tensor, float)
    links: dict[str, Visual | None] = {BASE_FRAME: None}
    links[PLATFORM_FRAME] = _box_visual(np.diag(P), (0.55, 0.6, 0.65, 1.0), tensor=P)
    links["gyro_frame4"] = _box_visual(p.frame4, (0.2, 0.45, 0.8, 0.35))
    links["gyro_housing5"] = _box_visual(p.housing5, (0.9, 0.55, 0.1, 0.6))
    links["gyro_housing7"] = _box_visual(p.housing7, (0.9, 0.55, 0.1, 0.6))
    links["gyro_frame9"] = _box_visual(p.frame9, (0.2, 0.7, 0.35, 0.35))
    links["gyro_housing10"] = _box_visual(p.housing10, (0.9, 0.55, 0.1, 0.6))
    for (host, rotor), C, A, s in zip(ROTOR_LINKS, p.rotor_C, p.rotor_A, SPIN_AXES):
        links[rotor] = _rotor_visual(C, A, s)

    top = links[PLATFORM_FRAME].size[2] / 2.0
    plat_y = links[PLATFORM_FRAME].size[1]
    f4, f9 = links["gyro_frame4"].size, links["gyro_frame9"].size
    h5, h7 = links["gyro_housing5"].size, links["gyro_housing7"].size
    d57 = 0.5 * (h5[1] + h7[1]) * 0.6                       # housings 5 / 7 apart along the α4 axis (y)
    origins = {
        "alpha4": (0.0, plat_y / 4.0, top + f4[2] / 2.0),
        "beta5": (0.0, d57, 0.0),
        "beta7": (0.0, -d57, 0.0),
        "alpha9": (0.0, -plat_y / 4.0, top + f9[2] / 2.0),
        "beta10": (0.0, 0.0, 0.0),
    }
    ident = (0.0, 0.0, 0.0, 1.0)
    mounting = tuple(float(x) for x in quaternions.normalized(p.mounting))
    joints: list[Joint] = []
    if stabilised:
        limits = ((-math.pi, math.pi), (-math.pi / 2, math.pi / 2), (-math.pi, math.pi))
        for k, (name, (parent, child)) in enumerate(zip(MOUNT_NAMES, MOUNT_LINKS)):
            links.setdefault(child, None)
            joints.append(Joint(name, "revolute", parent, child, (0.0, 0.0, 0.0), mounting if k == 0 else ident,
                                tuple(MOUNT_AXES[k]), limits[k]))
    else:
        joints.append(Joint("platform_mount", "fixed", BASE_FRAME, PLATFORM_FRAME, (0.0, 0.0, 0.0), mounting))
    for name, (parent, child), axis in zip(GIMBAL_NAMES, GIMBAL_LINKS, GIMBAL_AXES):
        joints.append(Joint(name, "continuous", parent, child, origins[name], ident, tuple(float(x) for x in axis)))
    for name, (parent, child), axis in zip(ROTOR_JOINTS, ROTOR_LINKS, SPIN_AXES):
        joints.append(Joint(name, "continuous", parent, child, (0.0, 0.0, 0.0), ident, tuple(float(x) for x in axis)))
    # links in parents-first order: base, (mount links), platform, then by joint order
    order = [BASE_FRAME] + [j.child for j in joints]
    return PlatformModel({n: links[n] for n in order}, tuple(joints))


# =========================================================================================
# URDF text
# =========================================================================================
def _f(x: float) -> str:
    return repr(float(x))


def _vec(v: Sequence[float]) -> str:
    return " ".join(_f(x) for x in v)


def _rpy(quat: Sequence[float]) -> str:
    """URDF rpy (fixed axes x-y-z: R = Rz(y) Ry(p) Rx(r)) of a quaternion."""
    return _vec(quaternions.as_euler_xyz(quat))


def _cylinder_rpy(axis: Sequence[float]) -> str:
    """rpy turning the URDF cylinder (along z) onto ``axis``."""
    a = np.abs(np.asarray(axis, float))
    if a[0] > 0.5:
        return _vec((0.0, math.pi / 2, 0.0))
    if a[1] > 0.5:
        return _vec((math.pi / 2, 0.0, 0.0))
    return _vec((0.0, 0.0, 0.0))


def to_urdf(model: PlatformModel, name: str = ROBOT_NAME, effort_limit: float = 1.0) -> str:
    """URDF XML text of ``model`` (links with box/cylinder visuals and inertials, joints)."""
    robot = ET.Element("robot", name=name)
    colours: dict[tuple, str] = {}
    for link_name, vis in model.links.items():
        link = ET.SubElement(robot, "link", name=link_name)
        if vis is None:
            continue
        key = tuple(round(c, 3) for c in vis.rgba)
        material_name = colours.setdefault(key, f"{ROBOT_NAME}_colour{len(colours)}")
        visual = ET.SubElement(link, "visual")
        rpy = _cylinder_rpy(vis.axis) if vis.kind == "cylinder" else "0.0 0.0 0.0"
        ET.SubElement(visual, "origin", xyz="0.0 0.0 0.0", rpy=rpy)
        geom = ET.SubElement(visual, "geometry")
        if vis.kind == "box":
            ET.SubElement(geom, "box", size=_vec(vis.size))
        else:
            ET.SubElement(geom, "cylinder", radius=_f(vis.size[0]), length=_f(vis.size[1]))
        mat = ET.SubElement(visual, "material", name=material_name)
        ET.SubElement(mat, "color", rgba=_vec(vis.rgba))
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz="0.0 0.0 0.0", rpy="0.0 0.0 0.0")
        ET.SubElement(inertial, "mass", value=_f(vis.mass))
        I = vis.inertia
        ET.SubElement(inertial, "inertia", ixx=_f(I[0, 0]), ixy=_f(I[0, 1]), ixz=_f(I[0, 2]),
                      iyy=_f(I[1, 1]), iyz=_f(I[1, 2]), izz=_f(I[2, 2]))
    for j in model.joints:
        joint = ET.SubElement(robot, "joint", name=j.name, type=j.type)
        ET.SubElement(joint, "parent", link=j.parent)
        ET.SubElement(joint, "child", link=j.child)
        ET.SubElement(joint, "origin", xyz=_vec(j.xyz), rpy=_rpy(j.quat))
        if j.type != "fixed":
            ET.SubElement(joint, "axis", xyz=_vec(j.axis))
        if j.type == "revolute":
            lo, hi = j.limits or (-math.pi, math.pi)
            ET.SubElement(joint, "limit", lower=_f(lo), upper=_f(hi), effort=_f(effort_limit), velocity=_f(100.0))
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def platform_urdf(p: PlatformParams, stabilised: bool, name: str = ROBOT_NAME) -> str:
    """The URDF text of the platform with parameters ``p`` in the given mode."""
    return to_urdf(platform_model(p, stabilised), name, effort_limit=float(p.servo_limit))


def config_model(config) -> PlatformModel:
    """:class:`PlatformModel` of a node configuration (``ros.config.NodeConfig``: its ``params``
    and ``options.mode``)."""
    return platform_model(config.params, config.options.mode == "stabilised")


def config_urdf(config) -> str:
    """URDF text of a node configuration (``ros.config.NodeConfig``; what the node and the launch
    file publish)."""
    return platform_urdf(config.params, config.options.mode == "stabilised")
