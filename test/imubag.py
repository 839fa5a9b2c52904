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

"""Imu recordings for the tests, written with rosbags (Jazzy typestore, rosbag2 version 8), and
the raw rows of a bag by topic."""
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader, Writer
from rosbags.typesys import get_typestore, Stores

T0_NS = 1000 * 10**9


def write_imu_bag(path: Path, n: int, rate_hz: float, w=(0.02, 0.0, 0.1), stamped: bool = True) -> None:
    """``n`` Imu on /imu at bag times ``T0 + k / rate_hz``; header stamps the same, or 0 when not
    ``stamped`` (a recording without stamps: the node times it by /clock with use_sim_time)."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    Imu, Header, Time, Vec3, Quat = (ts.types[t] for t in (
        "sensor_msgs/msg/Imu", "std_msgs/msg/Header", "builtin_interfaces/msg/Time",
        "geometry_msgs/msg/Vector3", "geometry_msgs/msg/Quaternion"))
    cov = np.zeros(9)
    with Writer(path, version=8) as writer:
        conn = writer.add_connection("/imu", Imu.__msgtype__, typestore=ts)
        for k in range(n):
            t = T0_NS + int(round(k * 1e9 / rate_hz))
            s = t if stamped else 0
            m = Imu(header=Header(stamp=Time(sec=s // 10**9, nanosec=s % 10**9), frame_id="base_link"),
                    orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=cov,
                    angular_velocity=Vec3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=cov,
                    linear_acceleration=Vec3(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=cov)
            writer.write(conn, t, ts.serialize_cdr(m, Imu.__msgtype__))


def raw_by_topic(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Topic → (bag time ns, serialised bytes) of every message of ``bag``, in bag order."""
    res: dict[str, list] = {}
    with Reader(bag) as r:
        for c, ts, raw in r.messages():
            res.setdefault(c.topic, []).append((ts, bytes(raw)))
    return res
