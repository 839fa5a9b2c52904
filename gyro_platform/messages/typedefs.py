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

"""The ROS 2 Jazzy definitions of the message types this package reads and writes, and a small
rosbags typestore of them (:func:`core_typestore`).

rosbags' full Jazzy store (:func:`gyro_platform.messages.jazzy_typestore`) defines some
hundred types and costs ~0.14 s to import; a replay needs ~15 of them, the plain-DDS node ~20
(its TF, robot_description, reset and ROS graph discovery types too). ``DEFINITIONS`` holds
their ``.msg`` text as rosbags' Jazzy store generates it (one level each, constants included);
the store parsed from it gives the same message definitions, RIHS01 hashes, classes and CDR
bytes for these types as the full store (tested type by type against rosbags' Jazzy store).
"""
from __future__ import annotations

from typing import Any

#: the input types (Imu, Twist, TwistStamped), the output types, the plain-DDS node's own and what they contain
DEFINITIONS: dict[str, str] = {
    "sensor_msgs/msg/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n"),
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "geometry_msgs/msg/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/msg/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
    "geometry_msgs/msg/TwistStamped": "std_msgs/Header header\ngeometry_msgs/Twist twist\n",
    "sensor_msgs/msg/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"),
    "geometry_msgs/msg/Vector3Stamped": "std_msgs/Header header\ngeometry_msgs/Vector3 vector\n",
    "geometry_msgs/msg/QuaternionStamped": "std_msgs/Header header\ngeometry_msgs/Quaternion quaternion\n",
    "geometry_msgs/msg/WrenchStamped": "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n",
    "geometry_msgs/msg/Wrench": "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n",
    "diagnostic_msgs/msg/DiagnosticArray": "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n",
    "diagnostic_msgs/msg/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\n"
        "string hardware_id\ndiagnostic_msgs/KeyValue[] values\n"),
    "diagnostic_msgs/msg/KeyValue": "string key\nstring value\n",
    # the plain-DDS node's own topics: TF, robot_description, ~/reset, ROS graph discovery
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "geometry_msgs/msg/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"),
    "geometry_msgs/msg/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
    "std_msgs/msg/String": "string data\n",
    "std_msgs/msg/Empty": "",
    "rmw_dds_common/msg/ParticipantEntitiesInfo": (
        "rmw_dds_common/Gid gid\nrmw_dds_common/NodeEntitiesInfo[] node_entities_info_seq\n"),
    "rmw_dds_common/msg/NodeEntitiesInfo": (
        "string<=256 node_namespace\nstring<=256 node_name\nrmw_dds_common/Gid[] reader_gid_seq\n"
        "rmw_dds_common/Gid[] writer_gid_seq\n"),
    "rmw_dds_common/msg/Gid": "char[16] data\n",
}

_CORE = None


def core_typestore() -> Any:
    """A rosbags typestore of the types in :data:`DEFINITIONS` (built once, ~10 ms)."""
    global _CORE
    if _CORE is None:
        from rosbags.typesys import get_types_from_msg, get_typestore, Stores

        (first, text), *rest = DEFINITIONS.items()
        sep = "=" * 80 + "\n"
        combined = text + "".join(f"{sep}MSG: {name.replace('/msg/', '/')}\n{body}" for name, body in rest)
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(combined, first))
        _CORE = store
    return _CORE


_MSGDEFS: dict[str, str] = {}


def core_msgdef(msgtype: str) -> str:
    """The message definition text (``.msg``, dependencies appended) that rosbags writes for
    ``msgtype`` (a type of :data:`DEFINITIONS`) into a bag."""
    text = _MSGDEFS.get(msgtype)
    if text is None:
        text = _MSGDEFS[msgtype] = core_typestore().generate_msgdef(msgtype, ros_version=2)[0]
    return text


def has_type(msgtype: str) -> bool:
    """True when :func:`core_typestore` defines ``msgtype``."""
    return msgtype in DEFINITIONS
