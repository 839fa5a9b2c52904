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

"""Outputs → ROS messages: JointState of gimbals, mount and rotors, drift Vector3Stamped,
attitude QuaternionStamped, bearing WrenchStamped, TF and robot description (built through a
:class:`~gyro_platform.messages.names.MessageTypes`: rosbags and rclpy classes alike). SI units, REP-103/105."""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, Sequence

import numpy as np

from .names import (bearing_topic, header, JOINT_STATE, MessageTypes, PLATFORM_FRAME, QUATERNION_STAMPED,
                    REFERENCE_FRAME, resolve, VECTOR3_STAMPED, WRENCH_STAMPED)
from ..engine.outputs import (BEARING_FRAMES, BEARING_NAMES, C_ANG, C_AXIAL, C_BEAR, C_DRATE, C_DRIFT, C_MOTOR, C_MOUNT,
                              C_MRATE, C_QUAT, C_RATE, C_ROTOR, C_SERVO, C_T, GIMBAL_NAMES, MOUNT_NAMES, Outputs)

# ---- outputs -----------------------------------------------------------------------------
#: continuous joints of the rotors 6, 8, 11 (housing → rotor), in JointState after the mount joints
ROTOR_JOINT_NAMES: tuple[str, ...] = ("rotor6", "rotor8", "rotor11")


def wrap_angle(x: float) -> float:
    """Angle wrapped to [-π, π) (rad)."""
    return (float(x) + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True, slots=True)
class JointColumns:
    """The numbers of ``sensor_msgs/JointState`` at K output instants: ``names`` (P), and
    ``position`` (K, P) rad, ``velocity`` and ``effort`` (K, V) rad/s and N m with V = P, or
    V = 0 when the outputs lack the mount rates (outputs built by an older producer)."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def mount_joint_efforts(mount_angles: np.ndarray, servo_torque: np.ndarray) -> np.ndarray:
    """Servo torque about each mount joint axis, ``Aᵀ τ`` with ``A`` =
    :func:`gyro_platform.physics.rotations.euler_xyz_axes` (intrinsic X-Y-Z chain), for
    (K, 3) angles rad and (K, 3) torques N m in platform axes → (K, 3) N m."""
    b, c = mount_angles[:, 1], mount_angles[:, 2]
    cb, sb, cc, sc = np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    s0, s1, s2 = servo_torque[:, 0], servo_torque[:, 1], servo_torque[:, 2]
    return np.stack([cb * cc * s0 - cb * sc * s1 + sb * s2, sc * s0 + cc * s1, s2.copy()], axis=1)


def rows_of(x: Any, k: int) -> np.ndarray:
    """``x`` as float64 (K, n) (a per-instant field of Outputs or OutputBlock)."""
    return np.asarray(x, dtype=np.float64).reshape(k, -1)


def joint_columns(src: Any) -> JointColumns:
    """:class:`JointColumns` of every moving joint of the URDF (:mod:`gyro_platform.ros.urdf`)
    from an ``Outputs`` (K = 1) or an ``OutputBlock`` (K instants; same field names, arrays
    with a leading K axis; ``rotor_rates`` (3,) in both): the one place these numbers are made.

    * gimbals ``alpha4 … beta10``: position rad, velocity rad/s, effort = applied axial torque N m;
    * mount joints ``mount_roll, mount_pitch, mount_yaw`` (stabilised mode; intrinsic X-Y-Z
      from ``base_link`` to ``platform``): position rad, velocity = angle rates rad/s, effort =
      servo torque about each joint axis N m (0 with the servo effect off);
    * rotors ``rotor6, rotor8, rotor11``: spin angle ``ω_r t`` of the ideal speed control,
      wrapped to [-π, π) (rad), spin rate rad/s, motor torque N m.

    Every value is finite for finite outputs. :func:`joint_values_of_row` is the scalar twin for one
    output row (the node's refill); the tests hold the two equal."""
    t = np.asarray(src.t, dtype=np.float64).reshape(-1)
    k = t.shape[0]
    names = list(GIMBAL_NAMES)
    pos, vel = [rows_of(src.gimbal_angles, k)], [rows_of(src.gimbal_rates, k)]
    eff = [rows_of(src.gimbal_axial_torques, k)]
    complete = True
    if src.mount_angles is not None:
        names += MOUNT_NAMES
        angles = rows_of(src.mount_angles, k)
        pos.append(angles)
        if src.mount_rates is None:
            complete = False
        else:
            vel.append(rows_of(src.mount_rates, k))
            servo = np.zeros((k, 3)) if src.servo_torque is None else rows_of(src.servo_torque, k)
            eff.append(mount_joint_efforts(angles, servo))
    if src.rotor_rates is not None:
        names += ROTOR_JOINT_NAMES
        w = np.asarray(src.rotor_rates, dtype=np.float64).reshape(1, 3)
        pos.append(np.mod(w * t[:, None] + math.pi, 2.0 * math.pi) - math.pi)   # = wrap_angle
        vel.append(np.broadcast_to(w, (k, 3)))
        eff.append(rows_of(src.motor_torques, k))
    if not complete:
        vel, eff = [np.zeros((k, 0))], [np.zeros((k, 0))]
    return JointColumns(tuple(names), np.concatenate(pos, axis=1), np.concatenate(vel, axis=1),
                        np.concatenate(eff, axis=1))


def joint_values_of_row(v: list[float], stabilised: bool) -> tuple[list[float], list[float], list[float]]:
    """Positions, velocities and efforts of :func:`joint_columns` for one output row as a list
    (``row.tolist()``, layout ``engine.outputs.C_*``; mount joints when ``stabilised``, rotors
    unless their rate is NaN): the same float operations in scalar Python, for the node's
    per-instant refill (a handful of numbers; numpy would cost more than the arithmetic)."""
    pos, vel, eff = v[C_ANG:C_ANG + 5], v[C_RATE:C_RATE + 5], v[C_AXIAL:C_AXIAL + 5]
    if stabilised:
        pos += v[C_MOUNT:C_MOUNT + 3]
        vel += v[C_MRATE:C_MRATE + 3]
        b, c = v[C_MOUNT + 1], v[C_MOUNT + 2]
        cb, sb, cc, sc = math.cos(b), math.sin(b), math.cos(c), math.sin(c)
        s0, s1, s2 = v[C_SERVO:C_SERVO + 3]
        eff += (cb * cc * s0 - cb * sc * s1 + sb * s2, sc * s0 + cc * s1, s2)     # mount_joint_efforts
    if v[C_ROTOR] == v[C_ROTOR]:
        w, t, pi = v[C_ROTOR:C_ROTOR + 3], v[C_T], math.pi
        pos += ((w[0] * t + pi) % (2.0 * pi) - pi, (w[1] * t + pi) % (2.0 * pi) - pi,
                (w[2] * t + pi) % (2.0 * pi) - pi)
        vel += w
        eff += v[C_MOTOR:C_MOTOR + 3]
    return pos, vel, eff


def joint_positions(out: Outputs) -> dict[str, float]:
    """Joint name → position (rad) of every moving joint of the URDF (see :func:`joint_columns`)."""
    cols = joint_columns(out)
    return dict(zip(cols.names, (float(x) for x in cols.position[0])))


def joint_state(out: Outputs, types: MessageTypes, t_ns: int) -> Any:
    """``sensor_msgs/JointState`` of every moving joint of the URDF, no NaN anywhere; the
    numbers of :func:`joint_columns` (velocity and effort empty, as the message definition
    allows, only when the outputs lack the mount rates; positions are always complete)."""
    cols = joint_columns(out)
    fa = types.float_array
    return types[JOINT_STATE](header=header(types, t_ns), name=list(cols.names), position=fa(cols.position[0]),
                              velocity=fa(cols.velocity[0]), effort=fa(cols.effort[0]))


def vector3(types: MessageTypes, v: Sequence[float]) -> Any:
    return types["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def vector3_stamped(v: Sequence[float], types: MessageTypes, t_ns: int, frame_id: str = PLATFORM_FRAME) -> Any:
    """``geometry_msgs/Vector3Stamped`` of a 3-vector."""
    return types[VECTOR3_STAMPED](header=header(types, t_ns, frame_id), vector=vector3(types, v))


def drift_angle(out: Outputs, types: MessageTypes, t_ns: int) -> Any:
    """Drift angle (rotation vector, rad) in frame ``platform``."""
    return vector3_stamped(out.drift_angle, types, t_ns)


def drift_rate(out: Outputs, types: MessageTypes, t_ns: int) -> Any:
    """Drift rate (rad/s) in frame ``platform``."""
    return vector3_stamped(out.drift_rate, types, t_ns)


def platform_attitude(out: Outputs, types: MessageTypes, t_ns: int) -> Any:
    """``geometry_msgs/QuaternionStamped``: the platform's attitude in its reference frame
    (``platform_reference``: inertial, or local level with ``earth_rate``), x, y, z, w."""
    q = out.platform_attitude
    quat = types["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))
    return types[QUATERNION_STAMPED](header=header(types, t_ns, REFERENCE_FRAME), quaternion=quat)


def bearing_wrenches(out: Outputs, types: MessageTypes, t_ns: int) -> dict[str, Any]:
    """Bearing name → ``geometry_msgs/WrenchStamped`` (torque N m in BEARING_FRAMES[name],
    force 0); bearings the outputs do not carry are left out."""
    res: dict[str, Any] = {}
    for name in BEARING_NAMES:
        tq = out.bearing_torques.get(name)
        if tq is None:
            continue
        wrench = types["geometry_msgs/msg/Wrench"](force=vector3(types, (0.0, 0.0, 0.0)),
                                                   torque=vector3(types, tq))
        res[name] = types[WRENCH_STAMPED](header=header(types, t_ns, BEARING_FRAMES[name]), wrench=wrench)
    return res


#: first column (layout ``engine.outputs.C_*``) of the numbers of each 3-vector or quaternion
#: output topic: what :func:`output_messages` puts in its Vector3 / torque / Quaternion
OUTPUT_COLUMNS: dict[str, int] = {"drift/angle": C_DRIFT, "drift/rate": C_DRATE, "platform/attitude": C_QUAT,
                                  "platform/servo_torque": C_SERVO,
                                  **{bearing_topic(b): C_BEAR + 3 * j for j, b in enumerate(BEARING_NAMES)}}


def output_messages(out: Outputs, types: MessageTypes, t_ns: int, namespace: str = "") -> list[tuple[str, Any]]:
    """All per-instant output messages as (topic, message): joint states, drift angle and rate,
    one wrench per bearing (diagnostics are separate: :func:`diagnostic_array`)."""
    res = [(resolve("gimbal/joint_states", namespace), joint_state(out, types, t_ns)),
           (resolve("drift/angle", namespace), drift_angle(out, types, t_ns)),
           (resolve("drift/rate", namespace), drift_rate(out, types, t_ns)),
           (resolve("platform/attitude", namespace), platform_attitude(out, types, t_ns))]
    if out.servo_torque is not None:
        res.append((resolve("platform/servo_torque", namespace),
                    vector3_stamped(out.servo_torque, types, t_ns, PLATFORM_FRAME)))
    res += [(resolve(bearing_topic(b), namespace), m) for b, m in bearing_wrenches(out, types, t_ns).items()]
    return res


# ---- TF and robot description (the DDS transport publishes these itself) --------------------
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
TF_TOPIC = "/tf"
STRING = "std_msgs/msg/String"


def tf_message(model: Any, positions: Mapping[str, float], types: MessageTypes, t_ns: int,
               frame_prefix: str = "", static: bool = False) -> Any:
    """``tf2_msgs/TFMessage`` of the joints of a :class:`gyro_platform.ros.urdf.PlatformModel`: the
    fixed joints when ``static`` (for ``/tf_static``), else the moving ones at ``positions``
    (rad; for ``/tf``), as robot_state_publisher sends them: header frame = parent link,
    child frame = child link, both with ``frame_prefix``; translation m, rotation x, y, z, w."""
    T = types
    transforms = []
    for joint, xyz, quat in model.transforms(positions):
        if (joint.type == "fixed") != static:
            continue
        tf = T["geometry_msgs/msg/Transform"](
            translation=vector3(T, xyz),
            rotation=T["geometry_msgs/msg/Quaternion"](x=float(quat[0]), y=float(quat[1]), z=float(quat[2]),
                                                       w=float(quat[3])))
        transforms.append(T["geometry_msgs/msg/TransformStamped"](
            header=header(T, t_ns, frame_prefix + joint.parent), child_frame_id=frame_prefix + joint.child,
            transform=tf))
    return T[TF_MESSAGE](transforms=transforms)


def reference_tf(attitude: Any, types: MessageTypes, frame_prefix: str = "") -> Any:
    """``tf2_msgs/TFMessage`` putting ``platform_reference`` (the frame of ``platform/attitude``)
    in the TF tree, from an attitude ``QuaternionStamped`` (:func:`platform_attitude`): parent
    ``platform`` (whose parent is ``base_link`` through the URDF), child ``platform_reference``,
    both with ``frame_prefix``; rotation the attitude's conjugate (the reference's axes in the
    platform's), translation 0 m (the model is rotational), the attitude's stamp."""
    T = types
    q = attitude.quaternion
    tf = T["geometry_msgs/msg/Transform"](
        translation=vector3(T, (0.0, 0.0, 0.0)),
        rotation=T["geometry_msgs/msg/Quaternion"](x=-q.x, y=-q.y, z=-q.z, w=q.w))
    head = header(T, 0, frame_prefix + PLATFORM_FRAME)
    head.stamp = attitude.header.stamp
    return T[TF_MESSAGE](transforms=[T["geometry_msgs/msg/TransformStamped"](
        header=head, child_frame_id=frame_prefix + REFERENCE_FRAME, transform=tf)])


def string_message(text: str, types: MessageTypes) -> Any:
    """``std_msgs/String`` (``/robot_description``)."""
    return types[STRING](data=text)
