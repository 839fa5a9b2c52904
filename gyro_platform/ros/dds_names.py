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

"""ROS names on DDS, as rcl and rmw_cyclonedds spell them: expansion, validation, DDS topic and
type names, the domain id.

:func:`expand_topic_name` expands a relative name with the namespace, ``~`` with the node's
namespace and name, ``{node}``/``{ns}`` substitutions, and validates the result as rcl does;
:func:`dds_topic_name` prefixes ``rt`` (``/ns/imu`` → ``rt/ns/imu``); :func:`dds_type_name`
gives ``sensor_msgs::msg::dds_::Imu_``; :func:`domain_id_from_env` reads ``ROS_DOMAIN_ID``.
Pure Python (no cyclonedds needed).
"""
from __future__ import annotations

import os
import re

#: rmw_cyclonedds topic prefixes: topics, service requests, service replies
ROS_TOPIC_PREFIX = "rt"
ROS_SERVICE_REQUEST_PREFIX = "rq"
ROS_SERVICE_REPLY_PREFIX = "rr"
DISCOVERY_TOPIC = "ros_discovery_info"
DISCOVERY_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"
#: ROS_DOMAIN_ID range Cyclone DDS accepts (ROS recommends 0–101 and 215–232 on Linux)
MAX_DOMAIN_ID = 232

_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_NODE_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_FULL_NAME_RE = re.compile(rf"^(/{_TOKEN})+$|^/$")


class NameError_(ValueError):
    """An invalid node name, namespace or topic name (the message says why)."""


def validate_node_name(name: str) -> str:
    """rmw_validate_node_name: letters, digits, underscores, not starting with a digit."""
    if not isinstance(name, str) or not _NODE_NAME_RE.match(name):
        raise NameError_(f"invalid node name {name!r}: use letters, digits and '_', not starting with a digit")
    return name


def normalize_namespace(namespace: str | None) -> str:
    """rcl normalisation of a node namespace: ``""``/``None`` → ``/``, a leading ``/`` is added,
    a trailing one removed; then validated (tokens of letters, digits and ``_``, none starting
    with a digit, no ``//``)."""
    ns = (namespace or "").strip()
    if not ns or ns == "/":
        return "/"
    if not ns.startswith("/"):
        ns = "/" + ns
    ns = ns.rstrip("/")
    if not _FULL_NAME_RE.match(ns):
        raise NameError_(f"invalid namespace {namespace!r}: tokens of letters, digits and '_' separated "
                         "by single '/', none starting with a digit")
    return ns


def expand_topic_name(name: str, node_name: str, namespace: str = "/") -> str:
    """Fully qualified ROS name of ``name`` for a node ``node_name`` in ``namespace``, as
    rclpy/rcl expand it: absolute names stay, relative names get the namespace, ``~`` is the
    node's own name space (``/ns/node``), ``{node}`` and ``{ns}``/``{namespace}`` are
    substituted. Raises :class:`NameError_` for names rcl rejects."""
    validate_node_name(node_name)
    ns = normalize_namespace(namespace)
    if not isinstance(name, str) or not name:
        raise NameError_("topic name must not be empty")
    node_fq = f"{ns.rstrip('/')}/{node_name}"
    if name.startswith("~"):
        if name != "~" and not name.startswith("~/"):
            raise NameError_(f"invalid topic name {name!r}: '~' must be followed by '/' or stand alone")
        name = node_fq + name[1:]
    for key, value in (("{node}", node_name), ("{ns}", ns), ("{namespace}", ns)):
        name = name.replace(key, value)
    if "{" in name or "}" in name:
        raise NameError_(f"invalid topic name {name!r}: unknown substitution")
    if not name.startswith("/"):
        name = f"{ns.rstrip('/')}/{name}"
    if name.startswith("//"):    # "{ns}/x" in the root namespace
        name = name[1:]
    if name.endswith("/") or "//" in name or not _FULL_NAME_RE.match(name) or name == "/":
        raise NameError_(f"invalid topic name {name!r}: tokens of letters, digits and '_' separated by "
                         "single '/', none starting with a digit, no trailing '/'")
    return name


def dds_topic_name(ros_name: str, prefix: str = ROS_TOPIC_PREFIX) -> str:
    """DDS topic of a fully qualified ROS topic: ``/ns/imu`` → ``rt/ns/imu``."""
    if not ros_name.startswith("/"):
        raise NameError_(f"{ros_name!r} is not a fully qualified ROS name (expand it first)")
    return prefix + ros_name


def ros_topic_name(dds_name: str) -> str | None:
    """Inverse of :func:`dds_topic_name` for ROS topics (``rt/...``); None for other DDS topics."""
    return dds_name[len(ROS_TOPIC_PREFIX):] if dds_name.startswith(ROS_TOPIC_PREFIX + "/") else None


def dds_type_name(ros_type: str) -> str:
    """``sensor_msgs/msg/Imu`` → ``sensor_msgs::msg::dds_::Imu_`` (rosidl_typesupport DDS naming)."""
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"ROS type name {ros_type!r}: expected package/msg/Type")
    pkg, sub, typ = parts
    return f"{pkg}::{sub}::dds_::{typ}_"


def ros_type_name(dds_type: str) -> str | None:
    """Inverse of :func:`dds_type_name`; None when ``dds_type`` is not of that form."""
    m = re.fullmatch(r"(\w+)::(\w+)::dds_::(\w+)_", dds_type)
    return f"{m[1]}/{m[2]}/{m[3]}" if m else None


def domain_id_from_env(value: int | str | None = None) -> int:
    """The DDS domain: ``value`` if given, else ``ROS_DOMAIN_ID``, else 0 (as rmw). Validated."""
    raw = value if value is not None else os.environ.get("ROS_DOMAIN_ID", "").strip() or 0
    try:
        dom = int(raw)
    except (TypeError, ValueError):
        raise ValueError(f"ROS_DOMAIN_ID = {raw!r} is not an integer") from None
    if not 0 <= dom <= MAX_DOMAIN_ID:
        raise ValueError(f"ROS_DOMAIN_ID = {dom} outside 0..{MAX_DOMAIN_ID}")
    return dom


__all__ = ["NameError_", "validate_node_name", "normalize_namespace", "expand_topic_name", "dds_topic_name",
           "ros_topic_name", "dds_type_name", "ros_type_name", "domain_id_from_env", "ROS_TOPIC_PREFIX",
           "ROS_SERVICE_REQUEST_PREFIX", "ROS_SERVICE_REPLY_PREFIX", "DISCOVERY_TOPIC", "DISCOVERY_TYPE",
           "MAX_DOMAIN_ID"]
