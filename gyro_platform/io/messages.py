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

"""ROS 2 message mapping of the platform (ROS-free: works on rosbags' and rclpy's classes).

Inputs are read duck-typed (same field names in rosbags and rclpy); outputs are built through a
:class:`MessageTypes` namespace, so the same code makes rosbags classes (bags, tests) and rclpy
classes (the node). Frames follow REP-103 (FLU, right-handed) and REP-145 (IMU data).

Topics (names relative to the node namespace, except ``/diagnostics``; copy this table to the README):

| topic | type | content, units | frame (header.frame_id) |
| --- | --- | --- | --- |
| `imu` (in) | `sensor_msgs/msg/Imu` | angular_velocity rad/s; linear_acceleration m/s² as specific force (+9.81 up at rest, REP-145); `angular_velocity_covariance[0] == -1`: sample rejected (`no_rate`); `linear_acceleration_covariance[0] == -1`: no specific force | sensor frame, rotated to `base_link` by the configured mounting |
| `twist` (in) | `geometry_msgs/msg/Twist` or `geometry_msgs/msg/TwistStamped` | angular part rad/s (linear part ignored; no specific force) | Twist: `base_link`; TwistStamped: header frame, rotated to `base_link` |
| `gimbal/joint_states` (out) | `sensor_msgs/msg/JointState` | gimbals `alpha4, beta5, beta7, alpha9, beta10`: position rad, velocity rad/s, effort = axial torque N m; then `mount_roll, mount_pitch, mount_yaw` (stabilised mode, intrinsic X-Y-Z base_link → platform): position rad, velocity rad/s, effort = servo torque about the joint axis N m; then `rotor6, rotor8, rotor11`: spin angle rad (wrapped), spin rate rad/s, motor torque N m. Never NaN; names = the URDF's moving joints | `""` (joint space) |
| `drift/angle` (out) | `geometry_msgs/msg/Vector3Stamped` | platform drift angle, rotation vector, rad | `platform` |
| `drift/rate` (out) | `geometry_msgs/msg/Vector3Stamped` | platform drift rate, rad/s | `platform` |
| `platform/attitude` (out) | `geometry_msgs/msg/QuaternionStamped` | platform attitude in its reference frame (inertial; local level with `earth_rate`), unit quaternion x, y, z, w | `platform_reference` |
| `platform/servo_torque` (out, stabilised mode) | `geometry_msgs/msg/Vector3Stamped` | servo (mount torquer) torque on the platform, N m | `platform` |
| `bearing/<name>/torque` (out, one per bearing: `support, gimbal4, gimbal5, gimbal7, gimbal9, gimbal10, rotor6, rotor8, rotor11`) | `geometry_msgs/msg/WrenchStamped` | torque = bearing reaction torque N m; force always 0: the model is torque-only (rotational dynamics about coincident gimbal centres), bearing forces are not computed | `BEARING_FRAMES[name]`: `platform, gyro_frame4, gyro_housing5, gyro_housing7, gyro_frame9, gyro_housing10, gyro_housing5, gyro_housing7, gyro_housing10` |
| `/diagnostics` (out) | `diagnostic_msgs/msg/DiagnosticArray` | statuses `gyro_platform: input` (time-base counters by reason, last reason, input rate Hz), `gyro_platform: platform` (`Outputs.status`), `gyro_platform: node` (counters, real-time margin, input lost; WARN on overload) and `gyro_platform: transport` (the transport's counters) — the same names on rclpy and on plain DDS | `""` |
| `/robot_description` (out, transient local) | `std_msgs/msg/String` | URDF of the platform (`gyro_platform.io.urdf`), generated from the parameters | - |
| `/tf`, `/tf_static` (out; DDS transport, under rclpy via robot_state_publisher) | `tf2_msgs/msg/TFMessage` | transforms of every joint of the URDF (`/tf_static`: fixed joints, transient local) | REP-105: `base_link` → platform → gimbals → rotors |

Output stamps are in the input's time base (the sample's header stamp, or its receive time when
the stamps are not set), see :mod:`gyro_platform.io.gate`.
"""  # noqa: E501 (the topic table: one row a line, as the README shows it)
from __future__ import annotations

import array
from dataclasses import dataclass
import importlib
import math
from typing import Any, Callable, Iterable, Mapping, NamedTuple, Sequence, TYPE_CHECKING

import numpy as np

from .blocks import bad_stamp_detail
from ..engine.outputs import (BEARING_FRAMES, BEARING_NAMES, C_ANG, C_AXIAL, C_BEAR, C_DRATE, C_DRIFT, C_MOTOR, C_MOUNT,
                              C_MRATE, C_QUAT, C_RATE, C_ROTOR, C_SERVO, C_T, GIMBAL_NAMES, MOUNT_NAMES, Outputs)

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

    from .blocks import RateBlock

# ---- names -------------------------------------------------------------------------------
IMU = "sensor_msgs/msg/Imu"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
JOINT_STATE = "sensor_msgs/msg/JointState"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"
QUATERNION_STAMPED = "geometry_msgs/msg/QuaternionStamped"
#: frame of the platform attitude: the platform's inertial reference (local level with earth_rate)
REFERENCE_FRAME = "platform_reference"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"

#: message types accepted as platform input
INPUT_TYPES: tuple[str, ...] = (IMU, TWIST, TWIST_STAMPED)
#: the vehicle frame (REP-105 ``base_link``, FLU)
VEHICLE_FRAME = "base_link"
#: frame of drift angle and drift rate
PLATFORM_FRAME = "platform"
HARDWARE_ID = "gyro_platform"


class TopicSpec(NamedTuple):
    """One row of the topic table above."""

    name: str
    type: str
    direction: str   # "in" | "out"
    units: str
    frame: str


def bearing_topic(name: str) -> str:
    """Topic of one bearing's reaction torque: ``bearing/<name>/torque``."""
    return f"bearing/{name}/torque"


TOPICS: tuple[TopicSpec, ...] = (
    TopicSpec("imu", IMU, "in", "rad/s; m/s² (specific force)", "sensor frame → base_link"),
    TopicSpec("twist", TWIST_STAMPED, "in", "rad/s (angular part)", "header frame → base_link"),
    TopicSpec("gimbal/joint_states", JOINT_STATE, "out", "rad, rad/s, N m", ""),
    TopicSpec("drift/angle", VECTOR3_STAMPED, "out", "rad", PLATFORM_FRAME),
    TopicSpec("drift/rate", VECTOR3_STAMPED, "out", "rad/s", PLATFORM_FRAME),
    TopicSpec("platform/attitude", QUATERNION_STAMPED, "out", "unit quaternion x, y, z, w", REFERENCE_FRAME),
    TopicSpec("platform/servo_torque", VECTOR3_STAMPED, "out", "N m (stabilised mode only)", PLATFORM_FRAME),
    *(TopicSpec(bearing_topic(b), WRENCH_STAMPED, "out", "N m", BEARING_FRAMES[b]) for b in BEARING_NAMES),
    TopicSpec("/diagnostics", DIAGNOSTIC_ARRAY, "out", "-", ""),
)


def resolve(name: str, namespace: str = "") -> str:
    """Absolute topic name of ``name`` in ``namespace`` ("" or "/" = root); absolute names stay."""
    if name.startswith("/"):
        return name
    ns = namespace.strip("/")
    return f"/{ns}/{name}" if ns else f"/{name}"


def output_topics(namespace: str = "") -> dict[str, str]:
    """Absolute output topic name → type, in ``namespace`` (root: ``/gimbal/joint_states`` …)."""
    return {resolve(s.name, namespace): s.type for s in TOPICS if s.direction == "out"}


# ---- type namespaces ---------------------------------------------------------------------
class MessageTypes:
    """Message classes by ROS type name (``'sensor_msgs/msg/JointState'``) plus the binding's
    float64[] constructor (rosbags wants numpy arrays, rclpy wants ``array.array('d')``)."""

    def __init__(self, lookup: Callable[[str], type], float_array: Callable[[Sequence[float]], Any]):
        self._lookup = lookup
        self._cache: dict[str, type] = {}
        self.float_array = float_array

    def __getitem__(self, name: str) -> type:
        cls = self._cache.get(name)
        if cls is None:
            cls = self._cache[name] = self._lookup(name)
        return cls

    @classmethod
    def rosbags(cls, typestore: Any = None) -> "MessageTypes":
        """rosbags classes of ``typestore`` (default: the ROS 2 Jazzy store)."""
        if typestore is None:
            typestore = jazzy_typestore()
        return cls(typestore.types.__getitem__, lambda v: np.asarray(v, dtype=np.float64))

    @classmethod
    def rclpy(cls) -> "MessageTypes":
        """Generated rclpy classes (imported lazily: ``sensor_msgs.msg.JointState`` …)."""

        def lookup(name: str) -> type:
            pkg, sub, typ = name.split("/")
            return getattr(importlib.import_module(f"{pkg}.{sub}"), typ)

        return cls(lookup, lambda v: array.array("d", (float(x) for x in v)))


_JAZZY = None


def jazzy_typestore():
    """The rosbags ROS 2 Jazzy typestore (cached)."""
    global _JAZZY
    if _JAZZY is None:
        from rosbags.typesys import get_typestore, Stores

        _JAZZY = get_typestore(Stores.ROS2_JAZZY)
    return _JAZZY


# ---- time ---------------------------------------------------------------------------------
def stamp_ns(stamp: Any) -> int:
    """``builtin_interfaces/Time`` → integer ns. ValueError when ``nanosec`` is outside
    [0, 1e9) (an invalid stamp, not a later time) or ``sec`` is negative
    (``blocks.bad_stamp_detail``)."""
    sec, nsec = int(stamp.sec), int(stamp.nanosec)
    bad = bad_stamp_detail(sec, nsec)
    if bad is not None:
        raise ValueError(bad)
    return sec * 1_000_000_000 + nsec


def header(types: MessageTypes, t_ns: int, frame_id: str = "") -> Any:
    """``std_msgs/Header`` at ``t_ns`` (ns; negative times are clamped to 0)."""
    sec, nsec = divmod(max(int(t_ns), 0), 1_000_000_000)
    time = types["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(nsec))
    return types["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


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
    """:class:`JointColumns` of every moving joint of the URDF (:mod:`gyro_platform.io.urdf`)
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


def _vector3(types: MessageTypes, v: Sequence[float]) -> Any:
    return types["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def vector3_stamped(v: Sequence[float], types: MessageTypes, t_ns: int, frame_id: str = PLATFORM_FRAME) -> Any:
    """``geometry_msgs/Vector3Stamped`` of a 3-vector."""
    return types[VECTOR3_STAMPED](header=header(types, t_ns, frame_id), vector=_vector3(types, v))


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
        wrench = types["geometry_msgs/msg/Wrench"](force=_vector3(types, (0.0, 0.0, 0.0)),
                                                   torque=_vector3(types, tq))
        res[name] = types[WRENCH_STAMPED](header=header(types, t_ns, BEARING_FRAMES[name]), wrench=wrench)
    return res


#: value types that are never a Mapping (spares the slow ABC check on the common values)
_PLAIN = frozenset({float, int, str, bool, type(None)})


def _fmt(v: Any) -> str:
    t = type(v)
    if t is float:
        return repr(v)
    if t is int or t is str:
        return str(v)
    if isinstance(v, (np.floating, np.integer)):
        return repr(v.item())
    if isinstance(v, Mapping):
        return ", ".join(f"{k}={_fmt(x)}" for k, x in v.items()) or "-"
    return str(v)


def _key_values(types: MessageTypes, items: Iterable[tuple[str, Any]]) -> list[Any]:
    kv = types["diagnostic_msgs/msg/KeyValue"]
    return [kv(key=str(k), value=_fmt(v)) for k, v in items]


def diagnostic_array(gate: Mapping[str, Any] | None, out: Outputs | None, types: MessageTypes,
                     t_ns: int, extra: Mapping[str, Any] | None = None) -> Any:
    """``diagnostic_msgs/DiagnosticArray`` with status "gyro_platform: input" (the gate
    snapshot: counts by reason, last reason, input rate Hz; WARN when the last input was
    dropped or a frame was taken as identity) and "gyro_platform: platform" (``out.status``
    plus ``extra``; ERROR if a value is not finite, STALE before any output)."""
    status_cls = types["diagnostic_msgs/msg/DiagnosticStatus"]
    statuses = []
    if gate is not None:
        level, message = status_cls.OK, "ok"
        if gate.get("last_action") == "drop":
            level, message = status_cls.WARN, f"last input dropped: {gate.get('last_reason')}"
        elif gate.get("notes", {}).get("identity_frame"):  # counted in the values; not a fault
            message = "ok (input frame without mounting taken as base_link)"
        statuses.append(status_cls(level=level, name="gyro_platform: input", message=message,
                                   hardware_id=HARDWARE_ID, values=_key_values(types, _flatten(gate))))
    items: list[tuple[str, Any]] = []
    if out is not None:
        items = [("t", out.t), *out.status.items()]
    items += list((extra or {}).items())
    if out is None:
        level, message = status_cls.STALE, "no output yet"
    elif all(math.isfinite(float(v)) for _, v in items if isinstance(v, (int, float, np.number))):
        level, message = status_cls.OK, "ok"
    else:
        level, message = status_cls.ERROR, "non-finite value"
    statuses.append(status_cls(level=level, name="gyro_platform: platform", message=message,
                               hardware_id=HARDWARE_ID, values=_key_values(types, items)))
    return types[DIAGNOSTIC_ARRAY](header=header(types, t_ns), status=statuses)


#: name of the transport's own diagnostic status (the same on rclpy and on plain DDS)
TRANSPORT_STATUS = f"{HARDWARE_ID}: transport"


def transport_status(types: MessageTypes, values: Mapping[str, Any], warn: str = "") -> Any:
    """``DiagnosticStatus`` ``gyro_platform: transport`` with the transport's counters; WARN
    with ``warn`` as its message when not empty, else OK."""
    cls = types["diagnostic_msgs/msg/DiagnosticStatus"]
    return cls(level=cls.WARN if warn else cls.OK, name=TRANSPORT_STATUS, message=warn or "ok",
               hardware_id=HARDWARE_ID, values=_key_values(types, values.items()))


def _flatten(d: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    res: list[tuple[str, Any]] = []
    for k, v in d.items():
        if type(v) not in _PLAIN and isinstance(v, Mapping):
            res += _flatten(v, f"{prefix}{k}.")
        else:
            res.append((f"{prefix}{k}", v))
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
STRING = "std_msgs/msg/String"


def tf_message(model: Any, positions: Mapping[str, float], types: MessageTypes, t_ns: int,
               frame_prefix: str = "", static: bool = False) -> Any:
    """``tf2_msgs/TFMessage`` of the joints of a :class:`gyro_platform.io.urdf.PlatformModel`: the
    fixed joints when ``static`` (for ``/tf_static``), else the moving ones at ``positions``
    (rad; for ``/tf``), as robot_state_publisher sends them: header frame = parent link,
    child frame = child link, both with ``frame_prefix``; translation m, rotation x, y, z, w."""
    T = types
    transforms = []
    for joint, xyz, quat in model.transforms(positions):
        if (joint.type == "fixed") != static:
            continue
        tf = T["geometry_msgs/msg/Transform"](
            translation=_vector3(T, xyz),
            rotation=T["geometry_msgs/msg/Quaternion"](x=float(quat[0]), y=float(quat[1]), z=float(quat[2]),
                                                       w=float(quat[3])))
        transforms.append(T["geometry_msgs/msg/TransformStamped"](
            header=header(T, t_ns, frame_prefix + joint.parent), child_frame_id=frame_prefix + joint.child,
            transform=tf))
    return T[TF_MESSAGE](transforms=transforms)


def string_message(text: str, types: MessageTypes) -> Any:
    """``std_msgs/String`` (``/robot_description``)."""
    return types[STRING](data=text)
