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

"""Input messages → readings: sensor mountings (frame → rotation into ``base_link``), the
``Reading``/``Rejected`` of one Imu, Twist or TwistStamped message (duck-typed: rosbags and rclpy
classes alike). Rates rad/s, specific force m/s², frames per REP-103/145."""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Iterable, Mapping, TYPE_CHECKING

import numpy as np

from .names import IMU, INPUT_TYPES, stamp_ns, TWIST, TWIST_STAMPED, VEHICLE_FRAME

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

    from .blocks import RateBlock

# ---- mounting ----------------------------------------------------------------------------


class Mounting:
    """Sensor mountings: ``frame_id`` → rotation of the sensor frame in ``base_link``.

    A rotation ``q`` (quaternion x, y, z, w — the ``base_link → frame`` TF rotation) maps a
    vector given in the sensor frame to the vehicle frame: ``v_base = R(q) v_sensor``.
    ``base_link`` is the identity. ``unknown_frame`` says what to do with other frame ids:
    ``"identity"`` (use them as if aligned with base_link; flagged so it can be counted) or
    ``"reject"`` (the sample is rejected with reason ``unknown_frame``).
    """

    UNKNOWN_POLICIES = ("identity", "reject")

    def __init__(self, frames: Mapping[str, Any] | None = None, *, vehicle_frame: str = VEHICLE_FRAME,
                 unknown_frame: str = "identity"):
        if unknown_frame not in self.UNKNOWN_POLICIES:
            raise ValueError(f"unknown_frame = {unknown_frame!r}; allowed: {', '.join(self.UNKNOWN_POLICIES)}")
        self.vehicle_frame = vehicle_frame
        self.unknown_frame = unknown_frame
        self._rot: dict[str, Rotation | None] = {vehicle_frame: None}      # None: identity
        self._mat: dict[str, np.ndarray] = {vehicle_frame: np.eye(3)}
        self._rows: dict[str, tuple[float, ...] | None] = {vehicle_frame: None}   # None: identity
        for frame, rot in (frames or {}).items():
            self.add(frame, rot)

    def add(self, frame_id: str, rotation: Any) -> None:
        """Set the mounting of ``frame_id``: a Rotation, a quaternion (x, y, z, w) or roll,
        pitch, yaw (rad, fixed axes x-y-z, i.e. R = Rz(yaw) Ry(pitch) Rx(roll), as in URDF)."""
        self._rot[frame_id] = r = as_rotation(rotation)
        self._mat[frame_id] = m = r.as_matrix()
        self._rows[frame_id] = None if np.array_equal(m, np.eye(3)) else tuple(float(x) for x in m.reshape(9))

    def frames(self) -> dict[str, tuple[float, float, float, float]]:
        """Configured frames → quaternion (x, y, z, w)."""
        return {f: (0.0, 0.0, 0.0, 1.0) if r is None else tuple(float(x) for x in r.as_quat())
                for f, r in self._rot.items()}

    def matrix(self, frame_id: str) -> np.ndarray | None:
        """3×3 matrix sensor → vehicle, or None when the frame is unknown (whatever the policy)."""
        return self._mat.get(frame_id)

    def rotate(self, frame_id: str, v: tuple[float, float, float]) -> tuple[float, float, float] | None:
        """``v`` (sensor frame ``frame_id``) in the vehicle frame, as Python floats (None when
        the frame is unknown). Identity mountings return ``v`` unchanged."""
        try:
            m = self._rows[frame_id]
        except KeyError:
            return None
        return v if m is None else _mul(m, v)

    def rotate_block(self, rb: "RateBlock") -> "RateBlock":
        """The rows of ``rb`` in the vehicle frame (a new block; ``rb`` is not changed), row by
        row what :func:`reading_from_msg` does: omega and force rotated by the mounting of their
        ``frame_id`` (same float operations as :meth:`rotate`, so bit-identical); rows without a
        header (Twist) take the vehicle frame; usable rows of an unknown frame are flagged in
        ``identity`` (policy ``identity``: values kept) or rejected ``unknown_frame``
        (policy ``reject``). Rows already rejected are left as they are."""
        from .blocks import RateBlock, REJECT_UNKNOWN_FRAME

        n = len(rb)
        omega, force = rb.omega.copy(), rb.force.copy()
        frames = list(rb.frame_id)
        reject, detail = rb.reject.copy(), dict(rb.detail)
        identity = np.zeros(n, bool)
        no_header = ~rb.has_header
        if no_header.any():
            for i in np.flatnonzero(no_header).tolist():
                frames[i] = self.vehicle_frame
        usable = reject == 0
        for frame, idx in _group(frames).items():
            if frame in self._rows:
                m = self._rows[frame]
                if m is not None:
                    for arr in (omega, force):
                        x, y, z = arr[idx, 0], arr[idx, 1], arr[idx, 2]
                        arr[idx] = np.stack([m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z,
                                             m[6] * x + m[7] * y + m[8] * z], axis=1)
                continue
            rows = idx[usable[idx]]
            if self.unknown_frame == "reject":
                reject[rows] = REJECT_UNKNOWN_FRAME
                text = f"no mounting configured for frame_id {frame!r}"
                for i in rows.tolist():
                    detail[i] = text
            else:
                identity[rows] = True
        return RateBlock(rb.stamp_ns, rb.has_header, frames, omega, force, rb.has_force, reject, detail, identity)

    @staticmethod
    def parse_spec(spec: str) -> tuple[str, Rotation]:
        """``"imu_link=qx,qy,qz,qw"`` or ``"imu_link=roll,pitch,yaw"`` (rad) → (frame, Rotation)."""
        frame, sep, values = spec.partition("=")
        if not sep or not frame.strip():
            raise ValueError(f"mounting {spec!r}: expected FRAME=qx,qy,qz,qw or FRAME=roll,pitch,yaw")
        try:
            nums = [float(x) for x in values.replace(" ", "").split(",") if x]
        except ValueError:
            raise ValueError(f"mounting {spec!r}: values must be numbers") from None
        return frame.strip(), as_rotation(nums)

    @staticmethod
    def parse_specs(specs: Iterable[str], vehicle_frame: str = VEHICLE_FRAME) -> dict[str, Rotation]:
        """Every :meth:`parse_spec` of ``specs`` → frame → Rotation. ValueError for a frame given
        twice (which one was meant?) and for the vehicle frame itself, which is the identity by
        definition (a mounting for it would rotate every base_link reading and every Twist)."""
        frames: dict[str, Rotation] = {}
        for spec in specs:
            frame, rot = Mounting.parse_spec(spec)
            if frame == vehicle_frame:
                raise ValueError(f"mounting {spec!r}: {vehicle_frame} is the vehicle frame itself (the identity); "
                                 "mount the sensor's own frame_id")
            if frame in frames:
                raise ValueError(f"mounting {spec!r}: frame {frame!r} is mounted twice")
            frames[frame] = rot
        return frames


def _group(frames: list[str]) -> dict[str, np.ndarray]:
    """frame id → indices of its rows (one group without a Python loop when all rows agree)."""
    if not frames:
        return {}
    first = frames[0]
    if frames.count(first) == len(frames):
        return {first: np.arange(len(frames))}
    groups: dict[str, list[int]] = {}
    for i, f in enumerate(frames):
        groups.setdefault(f, []).append(i)
    return {f: np.asarray(ix) for f, ix in groups.items()}


def as_rotation(value: Any) -> Rotation:
    """Rotation from a Rotation, a unit quaternion (x, y, z, w) or roll, pitch, yaw (rad)."""
    from scipy.spatial.transform import Rotation  # here: 0.2 s of import a replay without mounting skips

    if isinstance(value, Rotation):
        return value
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.size == 4:
        n = float(np.linalg.norm(v))
        if not math.isfinite(n) or abs(n - 1.0) > 1e-6:
            raise ValueError(f"mounting quaternion {v.tolist()} is not a unit quaternion (norm {n:.9g})")
        return Rotation.from_quat(v)  # scalar-last (x, y, z, w)
    if v.size == 3 and np.all(np.isfinite(v)):
        return Rotation.from_euler("xyz", v)  # extrinsic x, y, z = Rz(yaw) Ry(pitch) Rx(roll)
    raise ValueError(f"mounting {value!r}: expected a quaternion (x, y, z, w) or roll, pitch, yaw")


# ---- inputs ------------------------------------------------------------------------------
Vec3 = tuple[float, float, float]


@dataclass(slots=True)
class Reading:
    """Rates of one message, rotated into the vehicle frame (not yet timed; the gate does that).

    ``omega`` rad/s and ``specific_force`` m/s² (or None), vehicle axes, as 3-tuples of Python
    floats (any 3-sequence is accepted by the gate); ``stamp_ns`` the header stamp (ns; 0 =
    not set) or None when the type has no header; ``identity_assumed`` when the frame was
    unknown and taken as base_link.
    """

    omega: Vec3
    specific_force: Vec3 | None
    stamp_ns: int | None
    frame_id: str
    identity_assumed: bool = False


@dataclass(slots=True)
class Rejected:
    """A message that cannot give a rate sample: ``reason`` (``no_rate``, ``unknown_frame``,
    ``bad_message``) and a human-readable ``detail``."""

    reason: str
    detail: str
    stamp_ns: int | None = None
    frame_id: str = ""


def _vec3(v: Any) -> Vec3:
    return (float(v.x), float(v.y), float(v.z))


def type_name(msg: Any) -> str | None:
    """ROS type name of a message: rosbags ``__msgtype__``, or from an rclpy class
    (``sensor_msgs.msg._imu.Imu`` → ``sensor_msgs/msg/Imu``); None if neither."""
    name = getattr(msg, "__msgtype__", None)
    if isinstance(name, str):
        return name
    parts = type(msg).__module__.split(".")
    if len(parts) >= 2 and parts[1] == "msg":
        return f"{parts[0]}/msg/{type(msg).__name__}"
    return None


_KIND_BY_CLASS: dict[type, str | None] = {}


def message_kind(msg: Any) -> str | None:
    """``IMU``, ``TWIST_STAMPED``, ``TWIST`` or None: by type name when known (other types,
    e.g. nav_msgs/Odometry, are None; cached per class), else by the fields (duck typing)."""
    cls = type(msg)
    try:
        return _KIND_BY_CLASS[cls]
    except (KeyError, TypeError):
        pass
    name = type_name(msg)
    if name is not None:
        kind = name if name in INPUT_TYPES else None
        try:
            _KIND_BY_CLASS[cls] = kind
        except TypeError:
            pass
        return kind
    if hasattr(msg, "angular_velocity") and hasattr(msg, "header"):
        return IMU
    if hasattr(msg, "twist") and hasattr(msg, "header"):
        return TWIST_STAMPED
    if hasattr(msg, "angular") and hasattr(msg, "linear"):
        return TWIST
    return None


def reading_from_msg(msg: Any, mounting: Mounting | None = None) -> Reading | Rejected:
    """Imu / Twist / TwistStamped → :class:`Reading` in base_link, or :class:`Rejected`. Never raises.

    Imu: ``angular_velocity_covariance[0] == -1`` (sensor_msgs: "not reported") → rejected
    ``no_rate``; ``linear_acceleration_covariance[0] == -1`` → ``specific_force`` None. A
    stamp with ``nanosec`` outside [0, 1e9) or a negative ``sec`` → rejected ``bad_message``. Values are passed
    through as they are (NaN/Inf and range are the gate's job). Pure Python floats: no numpy
    call per message.
    """
    mounting = mounting if mounting is not None else _DEFAULT_MOUNTING
    stamp: int | None = None
    frame = ""
    try:
        kind = _KIND_BY_CLASS.get(type(msg), False)
        if kind is False:
            kind = message_kind(msg)
        if kind is None:
            return Rejected("bad_message", f"unsupported message type {type_name(msg) or type(msg).__name__}")
        if kind == TWIST:
            v = msg.angular
            omega, force, frame = (float(v.x), float(v.y), float(v.z)), None, mounting.vehicle_frame
        else:
            h = msg.header
            frame = str(h.frame_id)
            stamp = stamp_ns(h.stamp)
            if kind == TWIST_STAMPED:
                v = msg.twist.angular
                omega, force = (float(v.x), float(v.y), float(v.z)), None
            else:
                if float(msg.angular_velocity_covariance[0]) == -1.0:
                    return Rejected("no_rate", "angular_velocity_covariance[0] = -1 (rate not reported)",
                                    stamp, frame)
                v = msg.angular_velocity
                omega = (float(v.x), float(v.y), float(v.z))
                if float(msg.linear_acceleration_covariance[0]) == -1.0:
                    force = None
                else:
                    v = msg.linear_acceleration
                    force = (float(v.x), float(v.y), float(v.z))
    except (AttributeError, TypeError, ValueError, IndexError, OverflowError) as e:
        return Rejected("bad_message", f"malformed message: {e}", stamp, frame)
    rows = mounting._rows
    if frame in rows:
        m = rows[frame]
        if m is not None:
            omega = _mul(m, omega)
            if force is not None:
                force = _mul(m, force)
        return Reading(omega, force, stamp, frame, False)
    if mounting.unknown_frame == "reject":
        return Rejected("unknown_frame", f"no mounting configured for frame_id {frame!r}", stamp, frame)
    return Reading(omega, force, stamp, frame, True)


def _mul(m: tuple[float, ...], v: Vec3) -> Vec3:
    """Row-major 3×3 ``m`` times ``v`` (the float operations of :meth:`Mounting.rotate_block`)."""
    x, y, z = v
    return (m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z, m[6] * x + m[7] * y + m[8] * z)


_DEFAULT_MOUNTING = Mounting()
