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

"""DDS discovery without multicast: when Cyclone's default SPDP cannot work, and what to use instead.

On a host where no up network interface supports multicast (e.g. a loopback-only network
namespace), :func:`default_discovery` gives the localhost unicast configuration of
rmw_cyclonedds' ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a hint for the ROS side.
Pure Python (interface flags from sysfs).
"""
from __future__ import annotations

import os

IFF_UP, IFF_LOOPBACK, IFF_MULTICAST = 0x1, 0x8, 0x1000
#: rmw_cyclonedds' configuration for ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, in Cyclone XML:
#: loopback only, no multicast, unicast discovery to localhost on the ports of participant
#: indices 0..32 — what both sides need on a host without a multicast-capable interface
LOCALHOST_DISCOVERY_XML = (  # noqa: Q000 (XML attributes in double quotes)
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General><Interfaces>'  # noqa: Q000
    '<NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast>'  # noqa: Q000
    '</General><Discovery><ParticipantIndex>auto</ParticipantIndex>'  # noqa: Q000
    '<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex><Peers><Peer address="localhost"/></Peers>'  # noqa: Q000
    '</Discovery></Domain></CycloneDDS>')  # noqa: Q000


def interface_flags(sys_class_net: str = "/sys/class/net") -> dict[str, int]:
    """Network interface name → kernel flags (IFF_*), read from sysfs (empty if unreadable)."""
    flags: dict[str, int] = {}
    try:
        names = os.listdir(sys_class_net)
    except OSError:
        return flags
    for name in names:
        try:
            with open(os.path.join(sys_class_net, name, "flags")) as f:
                flags[name] = int(f.read().strip(), 16)
        except (OSError, ValueError):
            continue
    return flags


def multicast_discovery_possible(flags: dict[str, int]) -> bool:
    """True when an up interface supports multicast (Cyclone's default SPDP then works)."""
    return any(f & IFF_UP and f & IFF_MULTICAST for f in flags.values())


def default_discovery(environ: dict[str, str], flags: dict[str, int]) -> tuple[str | None, str]:
    """(CYCLONEDDS_URI to use or None to keep Cyclone's default, one-line hint) for a node
    started without ``--cyclonedds-config``. An explicit ``CYCLONEDDS_URI`` is kept; on a host
    where no up interface supports multicast (e.g. a loopback-only network namespace whose
    ``lo`` lacks MULTICAST), Cyclone's default multicast discovery finds nobody, so the
    localhost unicast configuration of rmw_cyclonedds' LOCALHOST discovery range is used and
    the hint says what the ROS side must set to meet it."""
    if environ.get("CYCLONEDDS_URI", "").strip():
        return None, ""
    if not flags or multicast_discovery_possible(flags):
        return None, ""
    return LOCALHOST_DISCOVERY_XML, (
        "no network interface with multicast: using unicast discovery on 127.0.0.1 (participant indices "
        "0-32); ROS 2 nodes beside this one need the same: export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "
        "(rmw_cyclonedds) or CYCLONEDDS_URI=file://<share>/gyro_platform/config/cyclonedds_loopback.xml")


__all__ = ["IFF_UP", "IFF_LOOPBACK", "IFF_MULTICAST", "LOCALHOST_DISCOVERY_XML", "interface_flags",
           "multicast_discovery_possible", "default_discovery"]
