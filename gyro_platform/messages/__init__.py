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

"""messages — ROS 2 messages of the platform, ROS-free (rosbags' and rclpy's classes alike).

Holds the names (``names``: message types, frames, the topic table, ``MessageTypes``, stamps and
headers), input messages → readings (``inputs``: sensor mounting, ``Reading``/``Rejected``),
outputs → messages (``outputs``: JointState, drift, attitude, bearing wrenches, TF, robot
description), ``/diagnostics`` (``diagnostics``), the array blocks of the fast path (``blocks``:
RowChunk, RateBlock), the vectorised input decoder (``decode``), the output encoder (``encode``)
and the Jazzy definitions of the types read and written (``typedefs``: a small typestore). This
``__init__`` re-exports the names of ``names``, ``inputs``, ``outputs`` and ``diagnostics``.
May import ``physics`` (jit), the engine's public records (``engine.inputs``, ``engine.outputs``)
and ``errors``.
"""
from .diagnostics import diagnostic_array, flatten, key_values, TRANSPORT_STATUS, transport_status
from .inputs import as_rotation, message_kind, Mounting, Reading, reading_from_msg, Rejected, type_name, Vec3
from .names import (bearing_topic, DIAGNOSTIC_ARRAY, frame_label, FRAME_NAME_CHARS, FRAMES_NAMED, HARDWARE_ID,
                    header, IMU, INPUT_TYPES, jazzy_typestore,
                    JOINT_STATE, MessageTypes, output_topics, PLATFORM_FRAME, QUATERNION_STAMPED, REFERENCE_FRAME,
                    resolve, stamp_ns, TOPICS, TopicSpec, TWIST, TWIST_STAMPED, VECTOR3_STAMPED, VEHICLE_FRAME,
                    WRENCH_STAMPED)
from .outputs import (bearing_wrenches, drift_angle, drift_rate, joint_columns, joint_positions, joint_state,
                      joint_values_of_row, JointColumns, mount_joint_efforts, OUTPUT_COLUMNS, output_messages,
                      platform_attitude, reference_tf, ROTOR_JOINT_NAMES, rows_of, STRING, string_message,
                      TF_MESSAGE, tf_message, TF_TOPIC, vector3, vector3_stamped, wrap_angle)

__all__ = ["diagnostic_array", "flatten", "key_values", "TRANSPORT_STATUS", "transport_status", "as_rotation",
           "message_kind", "Mounting", "Reading", "reading_from_msg", "Rejected", "type_name", "Vec3", "bearing_topic",
           "DIAGNOSTIC_ARRAY", "frame_label", "FRAME_NAME_CHARS", "FRAMES_NAMED", "HARDWARE_ID", "header", "IMU",
           "INPUT_TYPES", "jazzy_typestore", "JOINT_STATE",
           "MessageTypes", "output_topics", "PLATFORM_FRAME", "QUATERNION_STAMPED", "REFERENCE_FRAME", "resolve",
           "stamp_ns", "TOPICS", "TopicSpec", "TWIST", "TWIST_STAMPED", "VECTOR3_STAMPED", "VEHICLE_FRAME",
           "WRENCH_STAMPED", "bearing_wrenches", "drift_angle", "drift_rate", "joint_columns", "joint_positions",
           "joint_state", "joint_values_of_row", "JointColumns", "mount_joint_efforts", "OUTPUT_COLUMNS",
           "output_messages", "platform_attitude", "reference_tf", "ROTOR_JOINT_NAMES", "rows_of", "STRING",
           "string_message", "TF_MESSAGE", "tf_message", "TF_TOPIC", "vector3", "vector3_stamped", "wrap_angle"]
