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

"""ros — the platform as a ROS 2 node, on rclpy or on plain DDS.

Holds the parameter schema (``parameters``), the validated configuration and params files
(``config``), the transport-independent node core (``core``), its warm-up (``warmup``) and its
input-loss count (``overload``), the rclpy node (``node``, the only module that imports rclpy), the
plain-DDS transport (``dds``; its naming ``dds_names``, discovery ``dds_discovery``, types and QoS
``dds_types``; cyclonedds), the ``gyro-platform node`` command (``command``), the launch file's
argument logic (``launch_setup``) and the URDF generated from the parameters (``urdf``, for
``/robot_description`` and TF). May import everything below it (``replay``, ``pipeline``,
``scenes``, ``bags``, ``messages``, ``reports``, ``engine``, ``physics``, ``errors``, ``signals``,
``filesystem``); nothing imports it but ``cli`` and ``bench``.
"""
