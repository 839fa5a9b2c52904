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

"""The small typestore of the types the package reads and writes (``messages.typedefs``) is rosbags'
Jazzy store for those types: the same message definitions, RIHS01 hashes, fields and CDR bytes."""
from __future__ import annotations

import numpy as np
import pytest

from gyro_platform import messages as m
from gyro_platform.messages.typedefs import core_typestore, DEFINITIONS, has_type

JAZZY = m.jazzy_typestore()
CORE = core_typestore()


@pytest.mark.parametrize("msgtype", sorted(DEFINITIONS))
def test_core_types_are_jazzys(msgtype):
    assert has_type(msgtype)
    assert CORE.generate_msgdef(msgtype, ros_version=2) == JAZZY.generate_msgdef(msgtype, ros_version=2)
    assert CORE.hash_rihs01(msgtype) == JAZZY.hash_rihs01(msgtype)
    assert CORE.get_msgdef(msgtype).fields == JAZZY.get_msgdef(msgtype).fields


def test_every_topic_type_is_a_core_type():
    assert {s.type for s in m.TOPICS} <= set(DEFINITIONS)
    assert not has_type("nav_msgs/msg/Odometry")


def test_core_messages_serialise_as_jazzys():
    """A diagnostic array and an Imu built from the core classes give Jazzy's bytes, and the
    Jazzy store reads them back."""
    gate = {"received": 3, "accepted": 2, "dropped_by_reason": {"gap": 1}, "last_action": "drop",
            "last_reason": "gap", "input_rate_hz": 1000.0}
    raws = []
    for store in (CORE, JAZZY):
        types = m.MessageTypes.rosbags(store)
        msg = m.diagnostic_array(gate, None, types, 1_700_000_000_123_456_789, {"outputs": 7})
        raws.append(bytes(store.serialize_cdr(msg, m.DIAGNOSTIC_ARRAY)))
    assert raws[0] == raws[1]
    back = JAZZY.deserialize_cdr(raws[0], m.DIAGNOSTIC_ARRAY)
    assert back.status[0].name == "gyro_platform: input" and back.header.stamp.nanosec == 123_456_789
    imu = CORE.types[m.IMU](header=m.header(m.MessageTypes.rosbags(CORE), 5, "imu_link"),
                            orientation=CORE.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                            orientation_covariance=np.zeros(9),
                            angular_velocity=CORE.types["geometry_msgs/msg/Vector3"](x=0.1, y=0.2, z=0.3),
                            angular_velocity_covariance=np.zeros(9),
                            linear_acceleration=CORE.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
                            linear_acceleration_covariance=np.zeros(9))
    assert bytes(CORE.serialize_cdr(imu, m.IMU)) == bytes(JAZZY.serialize_cdr(imu, m.IMU))


def test_a_bag_with_rosbags_definitions_decodes_with_the_core_store(tmp_path):
    """A connection whose definition is the text rosbags writes is decoded with the core store
    (no parsing); any other text gets a store of its own."""
    from types import SimpleNamespace

    from rosbags.interfaces import MessageDefinition, MessageDefinitionFormat

    from gyro_platform.bags.reader import typestore_for
    from gyro_platform.messages.typedefs import core_msgdef

    text = JAZZY.generate_msgdef(m.IMU, ros_version=2)[0]
    assert core_msgdef(m.IMU) == text
    conn = SimpleNamespace(msgtype=m.IMU, msgdef=MessageDefinition(MessageDefinitionFormat.MSG, text))
    assert typestore_for(conn) is CORE
    other = SimpleNamespace(msgtype=m.IMU, msgdef=MessageDefinition(MessageDefinitionFormat.MSG, "# comment\n" + text))
    store = typestore_for(other)
    assert store is not CORE and store.get_msgdef(m.IMU).fields == CORE.get_msgdef(m.IMU).fields
    # no definition (bags recorded before Iron): Jazzy's, from the core store for its types only
    for fmt, data in ((MessageDefinitionFormat.NONE, ""), (MessageDefinitionFormat.MSG, "")):
        bare = SimpleNamespace(msgtype=m.TWIST_STAMPED, msgdef=MessageDefinition(fmt, data))
        assert typestore_for(bare) is CORE
    odom = SimpleNamespace(msgtype="nav_msgs/msg/Odometry", msgdef=MessageDefinition(MessageDefinitionFormat.NONE, ""))
    assert typestore_for(odom) is JAZZY
