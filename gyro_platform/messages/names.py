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
| `/robot_description` (out, transient local) | `std_msgs/msg/String` | URDF of the platform (`gyro_platform.ros.urdf`), generated from the parameters | - |
| `/tf`, `/tf_static` (out; DDS transport, under rclpy via robot_state_publisher) | `tf2_msgs/msg/TFMessage` | transforms of every joint of the URDF (`/tf_static`: fixed joints, transient local) | REP-105: `base_link` → platform → gimbals → rotors |
| `/tf` (out; the node on both transports, with `platform/attitude`) | `tf2_msgs/msg/TFMessage` | `platform` → `platform_reference`: the attitude's conjugate, translation 0 | puts the attitude's frame in the TF tree |

Output stamps are in the input's time base (the sample's header stamp, or its receive time when
the stamps are not set), see :mod:`gyro_platform.pipeline.gate`.
"""  # noqa: E501 (the topic table: one row a line, as the README shows it)
from __future__ import annotations

import array
import importlib
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from .blocks import bad_stamp_detail
from ..engine.outputs import BEARING_FRAMES, BEARING_NAMES

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
#: input frame_ids named one by one in log lines, summaries and diagnostics (more are counted
#: together), each cut to ``FRAME_NAME_CHARS`` characters (``frame_label``)
FRAMES_NAMED = 16
FRAME_NAME_CHARS = 64


def frame_label(frame: str) -> str:
    """An input frame_id as a log line, a summary or the diagnostics names it: at most
    ``FRAME_NAME_CHARS`` characters (a 100 000-character frame_id made a 104 kB diagnostics value)."""
    return frame if len(frame) <= FRAME_NAME_CHARS else frame[:FRAME_NAME_CHARS - 1] + "…"


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

        return cls(lookup, lambda v: array.array("d", v))      # floats, a list or a numpy array


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
