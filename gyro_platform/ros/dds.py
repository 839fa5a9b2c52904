"""ROS 2 on plain DDS: the node's second transport, without a ROS install.

Speaks the DDS wire format of ``rmw_cyclonedds_cpp`` through the ``cyclonedds`` Python package,
so the node joins a ROS 2 graph (``RMW_IMPLEMENTATION=rmw_cyclonedds_cpp``, same
``ROS_DOMAIN_ID``) and ROS 2 tools see its topics. Pieces:

* **Naming** (as rcl/rmw_cyclonedds): :func:`expand_topic_name` expands a relative name with the
  namespace, ``~`` with the node's namespace and name, ``{node}``/``{ns}`` substitutions, and
  validates the result as rcl does; :func:`dds_topic_name` prefixes ``rt`` (``/ns/imu`` →
  ``rt/ns/imu``); :func:`dds_type_name` gives ``sensor_msgs::msg::dds_::Imu_``.
* **Types** (:class:`IdlTypes`): ``cyclonedds.idl`` ``IdlStruct`` classes generated at run time
  from the field definitions of the rosbags ROS 2 Jazzy typestore (nested structs, fixed arrays,
  bounded/unbounded sequences and strings, ``builtin_interfaces/Time``), keyless, final, encoded
  as XCDR1 (= classic CDR, what rmw_cyclonedds sends), plus conversion both ways between
  rosbags message objects and the generated IDL objects — so the transport-independent core,
  which builds rosbags messages, is used unchanged. Byte identity with
  ``typestore.serialize_cdr`` is tested in ``test/test_dds.py``.
* **QoS** (:func:`dds_qos`): ``sensor_data`` (best effort, keep last 5, volatile) for the
  inputs, ``default`` (reliable, keep last 10, volatile) for the outputs, as the rclpy node; every
  endpoint forces data representation XCDR1 and carries rmw's ``typehash=RIHS01_…;`` user data.
* **Graph** (:class:`DdsNode`): one DomainParticipant per node (``ROS_DOMAIN_ID``; participant
  user data ``enclave=/;``), publishers and subscriptions on ROS names, and the
  ``ros_discovery_info`` announcement (``rmw_dds_common/ParticipantEntitiesInfo``) that lets
  ``ros2 node list`` show the node.
* **The platform node** (:class:`PlatformDdsNode`): the thin adapter around
  :class:`gyro_platform.ros.core.NodeCore` — inputs in, the core's (topic, message) pairs out,
  ``/diagnostics`` periodically (plus a ``gyro_platform: transport`` status, as the rclpy node), ``/robot_description`` and ``/tf_static`` (latched) and ``/tf`` (from the URDF of :mod:`gyro_platform.io.urdf`), ``~/reset``
  (``std_msgs/msg/Empty``) instead of the rclpy reset service, wall-clock jumps forwarded to
  the core.

Overload: the input reader keeps the last 5 samples (the sensor-data QoS), so a publisher faster
than the node cannot build a backlog (latency ≤ 5 samples' processing) nor grow memory: DDS
overwrites the oldest. DDS does not report such overwrites, so a second, data-less reader on
the input topic counts arrivals in C (as rejections of a KEEP_ALL reader with room for one
sample) and the node counts what it takes; the difference is reported as ``samples_lost`` in the
transport diagnostics and fed to the core's ``InputLoss`` (``gyro_platform: node`` WARN "input
overload" while it grows). No Python runs in Cyclone's threads (no listeners):
the node sleeps in a WaitSet.
"""
from __future__ import annotations

import os
import re
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable

import numpy as np

NS = 1_000_000_000

# =========================================================================================
# naming (rcl_expand_topic_name / rcl_validate_topic_name / rmw_cyclonedds_cpp conventions)
# =========================================================================================
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


# =========================================================================================
# discovery without multicast
# =========================================================================================
IFF_UP, IFF_LOOPBACK, IFF_MULTICAST = 0x1, 0x8, 0x1000
#: rmw_cyclonedds' configuration for ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, in Cyclone XML:
#: loopback only, no multicast, unicast discovery to localhost on the ports of participant
#: indices 0..32 — what both sides need on a host without a multicast-capable interface
LOCALHOST_DISCOVERY_XML = (
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General><Interfaces>'
    '<NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast>'
    '</General><Discovery><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex><Peers><Peer address="localhost"/></Peers>'
    '</Discovery></Domain></CycloneDDS>')


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


# =========================================================================================
# types: rosbags field definitions → cyclonedds IdlStruct classes, conversion both ways
# =========================================================================================
def _cyclone():
    """Lazy import of cyclonedds (an optional dependency: ``pip install .[dds]``)."""
    try:
        import cyclonedds.idl as idl
        import cyclonedds.idl.types as idl_types
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError(f"the DDS transport needs the 'cyclonedds' package (pip install 'gyro_platform[dds]'): {e}") from e
    return idl, idl_types


#: ROS primitive → (IDL type attribute of cyclonedds.idl.types, numpy dtype rosbags uses)
_PRIMITIVES: dict[str, tuple[str, str]] = {
    "bool": ("bool", "bool_"),
    "byte": ("byte", "int8"),      # IDL octet; rosbags keeps ROS byte as int8 (same bits)
    "char": ("uint8", "uint8"),    # ROS char is uint8 in IDL
    "int8": ("int8", "int8"),
    "uint8": ("uint8", "uint8"),
    "int16": ("int16", "int16"),
    "uint16": ("uint16", "uint16"),
    "int32": ("int32", "int32"),
    "uint32": ("uint32", "uint32"),
    "int64": ("int64", "int64"),
    "uint64": ("uint64", "uint64"),
    "float32": ("float32", "float32"),
    "float64": ("float64", "float64"),
}
_ONE_BYTE_UNSIGNED_IDL = ("byte", "char", "uint8")   # cyclonedds packs these arrays as bytes


class IdlTypes:
    """IDL classes for ROS message types, generated from a rosbags typestore, and conversions.

    ``idl_class(ros_type)`` → ``IdlStruct`` subclass named ``<pkg>::msg::dds_::<Type>_``;
    ``to_idl(msg)`` / ``from_idl(obj, ros_type)`` convert rosbags messages ↔ IDL objects;
    ``serialize(msg)`` / ``deserialize(data, ros_type)`` go through the IDL classes (XCDR1,
    little endian, 4-byte encapsulation header — the bytes rmw_cyclonedds sends).
    """

    def __init__(self, typestore: Any = None):
        if typestore is None:
            from ..io.messages import jazzy_typestore

            typestore = jazzy_typestore()
        self.typestore = typestore
        self._classes: dict[str, type] = {}
        self._to: dict[str, Callable[[Any], Any]] = {}
        self._from: dict[str, Callable[[Any], Any]] = {}
        self._lock = threading.RLock()

    # ---- classes ---------------------------------------------------------------------
    def fields(self, ros_type: str) -> list[tuple[str, Any]]:
        """rosbags field definitions ``[(name, (Nodetype, args)), …]`` of ``ros_type``."""
        try:
            return list(self.typestore.fielddefs[ros_type][1])
        except KeyError:
            raise KeyError(f"message type {ros_type!r} is not in the typestore") from None

    def idl_class(self, ros_type: str) -> type:
        """The generated ``IdlStruct`` class of ``ros_type`` (cached)."""
        with self._lock:
            cls = self._classes.get(ros_type)
            if cls is None:
                idl, _ = _cyclone()
                members = {name: self._idl_field_type(desc) for name, desc in self.fields(ros_type)}
                cls = idl.make_idl_struct(ros_type.split("/")[-1] + "_", dds_type_name(ros_type), members)
                # final extensibility, no key, no optional: XCDR1 is allowed and the default
                self._classes[ros_type] = cls
            return cls

    def _idl_field_type(self, desc: Any) -> Any:
        from rosbags.typesys.base import Nodetype

        _, T = _cyclone()
        kind, args = desc
        if kind == Nodetype.BASE:
            name, bound = args
            if name == "string":
                return T.bounded_str[bound] if bound else str
            if name not in _PRIMITIVES:
                raise TypeError(f"ROS primitive {name!r} has no IDL mapping")
            return bool if name == "bool" else getattr(T, _PRIMITIVES[name][0])
        if kind == Nodetype.NAME:
            return self.idl_class(args)
        if kind == Nodetype.ARRAY:
            sub, length = args
            return T.array[self._idl_field_type(sub), int(length)]
        if kind == Nodetype.SEQUENCE:
            sub, bound = args
            return T.sequence[self._idl_field_type(sub), int(bound)] if bound else T.sequence[self._idl_field_type(sub)]
        raise TypeError(f"field descriptor {desc!r} has no IDL mapping")

    # ---- rosbags → IDL ---------------------------------------------------------------
    def to_idl(self, msg: Any, ros_type: str | None = None) -> Any:
        """IDL object of a rosbags message (``ros_type`` defaults to ``msg.__msgtype__``)."""
        return self._to_fn(ros_type or msg.__msgtype__)(msg)

    def _to_fn(self, ros_type: str) -> Callable[[Any], Any]:
        with self._lock:
            fn = self._to.get(ros_type)
            if fn is None:
                cls = self.idl_class(ros_type)
                convs = [(name, self._to_field(desc)) for name, desc in self.fields(ros_type)]

                def fn(msg: Any, cls: type = cls, convs: list = convs) -> Any:
                    return cls(**{name: conv(getattr(msg, name)) for name, conv in convs})

                self._to[ros_type] = fn
            return fn

    def _to_field(self, desc: Any) -> Callable[[Any], Any]:
        from rosbags.typesys.base import Nodetype

        kind, args = desc
        if kind == Nodetype.BASE:
            name, _ = args
            if name == "string":
                return str
            if name in ("float32", "float64"):
                return float
            if name == "bool":
                return bool
            if name == "byte":
                return lambda v: int(v) & 0xFF
            return int
        if kind == Nodetype.NAME:
            return self._to_fn(args)
        sub, n = args
        skind, sargs = sub
        if skind == Nodetype.BASE and sargs[0] != "string":
            dtype = np.dtype(_PRIMITIVES[sargs[0]][1])
            if sargs[0] in _ONE_BYTE_UNSIGNED_IDL:
                if kind == Nodetype.ARRAY:   # cyclonedds: bytes for uint8/octet arrays
                    return lambda v, d=dtype: np.ascontiguousarray(v, dtype=d).view(np.uint8).tobytes()
                return lambda v, d=dtype: np.ascontiguousarray(v, dtype=d).view(np.uint8).tolist()
            return lambda v, d=dtype: np.asarray(v, dtype=d).tolist()
        conv = self._to_field(sub)
        return lambda v, c=conv: [c(x) for x in v]

    # ---- IDL → rosbags ---------------------------------------------------------------
    def from_idl(self, obj: Any, ros_type: str) -> Any:
        """rosbags message of an IDL object of ``ros_type``."""
        return self._from_fn(ros_type)(obj)

    def _from_fn(self, ros_type: str) -> Callable[[Any], Any]:
        with self._lock:
            fn = self._from.get(ros_type)
            if fn is None:
                cls = self.typestore.types[ros_type]
                convs = [(name, self._from_field(desc)) for name, desc in self.fields(ros_type)]

                def fn(obj: Any, cls: type = cls, convs: list = convs) -> Any:
                    return cls(**{name: conv(getattr(obj, name)) for name, conv in convs})

                self._from[ros_type] = fn
            return fn

    def _from_field(self, desc: Any) -> Callable[[Any], Any]:
        from rosbags.typesys.base import Nodetype

        kind, args = desc
        if kind == Nodetype.BASE:
            name, _ = args
            if name == "string":
                return str
            if name in ("float32", "float64"):
                return float
            if name == "bool":
                return bool
            if name == "byte":
                return lambda v: (int(v) + 128) % 256 - 128
            return int
        if kind == Nodetype.NAME:
            return self._from_fn(args)
        sub, _ = args
        skind, sargs = sub
        if skind == Nodetype.BASE and sargs[0] != "string":
            dtype = np.dtype(_PRIMITIVES[sargs[0]][1])
            if sargs[0] in _ONE_BYTE_UNSIGNED_IDL:
                return lambda v, d=dtype: (np.frombuffer(bytes(v), dtype=np.uint8) if isinstance(v, (bytes, bytearray))
                                           else np.asarray(v, dtype=np.uint8)).view(d).copy()
            return lambda v, d=dtype: np.asarray(v, dtype=d)
        conv = self._from_field(sub)
        return lambda v, c=conv: [c(x) for x in v]

    # ---- bytes -----------------------------------------------------------------------
    def serialize(self, msg: Any, ros_type: str | None = None) -> bytes:
        """CDR bytes (XCDR1, little endian, with the 4-byte encapsulation header) via IDL."""
        return self.to_idl(msg, ros_type).serialize(use_version_2=False)

    def deserialize(self, data: bytes, ros_type: str) -> Any:
        """rosbags message from CDR bytes (header included), decoded by the IDL class."""
        return self.from_idl(self.idl_class(ros_type).deserialize(data), ros_type)

    def type_hash(self, ros_type: str) -> str | None:
        """REP-2011 type hash ``RIHS01_<sha256>`` (what Jazzy's rmw puts in the user data)."""
        try:
            return self.typestore.hash_rihs01(ros_type)
        except Exception:  # noqa: BLE001 - older rosbags or a type without a hashable definition
            return None


# =========================================================================================
# QoS (the rclpy profiles the node uses, in DDS terms)
# =========================================================================================
@dataclass(frozen=True)
class QosProfile:
    """The ROS QoS of one endpoint: ``reliability`` best_effort|reliable, ``durability``
    volatile|transient_local, ``depth`` (keep last)."""

    reliability: str
    durability: str
    depth: int


SENSOR_DATA = QosProfile("best_effort", "volatile", 5)     # rclpy qos_profile_sensor_data
DEFAULT = QosProfile("reliable", "volatile", 10)           # rclpy default (depth 10)
DISCOVERY_INFO = QosProfile("reliable", "transient_local", 1)
TF = QosProfile("reliable", "volatile", 100)             # tf2_ros TransformBroadcaster / listener
LATCHED = QosProfile("reliable", "transient_local", 1)     # /tf_static, /robot_description (as robot_state_publisher)
PROFILES = {"sensor_data": SENSOR_DATA, "default": DEFAULT, "tf": TF, "latched": LATCHED}


def dds_qos(profile: QosProfile, user_data: bytes | None = None) -> Any:
    """cyclonedds ``Qos`` of a :class:`QosProfile`: reliability, durability, keep-last depth,
    data representation XCDR1 only, and ``user_data`` (rmw's ``typehash=…;``) if given."""
    from cyclonedds.core import Policy, Qos

    policies = [
        Policy.Reliability.Reliable(max_blocking_time=100_000_000) if profile.reliability == "reliable"
        else Policy.Reliability.BestEffort,
        Policy.Durability.TransientLocal if profile.durability == "transient_local" else Policy.Durability.Volatile,
        Policy.History.KeepLast(int(profile.depth)),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    ]
    if user_data:
        policies.append(Policy.Userdata(data=bytes(user_data)))
    return Qos(*policies)


def type_hash_user_data(type_hash: str | None) -> bytes | None:
    """rmw_dds_common's endpoint user data: ``typehash=RIHS01_…;``."""
    return f"typehash={type_hash};".encode() if type_hash else None


# =========================================================================================
# a ROS 2 node on DDS: participant, endpoints, graph announcement
# =========================================================================================
class DdsPublisher:
    """A writer on a ROS topic; ``publish(msg)`` takes a rosbags message."""

    def __init__(self, node: "DdsNode", topic: str, ros_type: str, profile: QosProfile):
        from cyclonedds.pub import DataWriter

        self.node, self.topic, self.ros_type, self.profile = node, topic, ros_type, profile
        self.dds_topic = node._topic(topic, ros_type)
        self.writer = DataWriter(node.participant, self.dds_topic,
                                 qos=dds_qos(profile, type_hash_user_data(node.types.type_hash(ros_type))))
        self._to = node.types._to_fn(ros_type)
        self.published = 0

    def publish(self, msg: Any) -> None:
        self.writer.write(self._to(msg))
        self.published += 1

    @property
    def matched(self) -> int:
        """Number of matched subscriptions right now."""
        return int(self.writer.get_publication_matched_status().current_count)

    @property
    def gid(self) -> bytes:
        return self.writer.guid.bytes


class DdsSubscription:
    """A reader on a ROS topic. ``take()`` returns ``[(rosbags message, SampleInfo)]``;
    :meth:`condition` gives a ReadCondition for a WaitSet (no Python listener: a listener
    runs Python, i.e. takes the GIL, for every arriving sample in Cyclone's receive thread,
    which under a flood throttles reception and builds a backlog in the socket buffer).

    ``count_arrivals``: a second, data-less reader on the same topic (KEEP_ALL with room for
    one sample, never read) counts every arriving sample in C as a rejection; with it,
    ``arrived`` is exact and ``lost`` = samples DDS overwrote in the keep-last queue before
    they were taken (arrived before a draining take and not taken: a lower bound while
    samples arrive, exact at rest).
    """

    def __init__(self, node: "DdsNode", topic: str, ros_type: str, profile: QosProfile,
                 count_arrivals: bool = False):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.sub import DataReader

        self.node, self.topic, self.ros_type, self.profile = node, topic, ros_type, profile
        self.dds_topic = node._topic(topic, ros_type)
        user_data = type_hash_user_data(node.types.type_hash(ros_type))
        self.reader = DataReader(node.participant, self.dds_topic, qos=dds_qos(profile, user_data))
        self.counter = None
        if count_arrivals:
            qos = dds_qos(profile, user_data)
            self.counter = DataReader(node.participant, self.dds_topic, qos=Qos(
                *(qos[k] for k in (Policy.Reliability, Policy.Durability, Policy.DataRepresentation, Policy.Userdata)
                  if k in qos),
                Policy.History.KeepAll,
                Policy.ResourceLimits(max_samples=1, max_instances=1, max_samples_per_instance=1)))
        self._from = node.types._from_fn(ros_type)
        self.taken = 0
        self.lost = 0
        self.undecodable = 0

    @property
    def arrived(self) -> int | None:
        """Samples that reached this participant (None without ``count_arrivals``)."""
        if self.counter is None:
            return None
        rejected = int(self.counter.get_sample_rejected_status().total_count)
        return rejected + 1 if (rejected or self.taken) else 0   # + the one the counter holds

    def condition(self) -> Any:
        """A ReadCondition that is triggered while samples wait in the queue."""
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState

        return ReadCondition(self.reader, SampleState.Any | ViewState.Any | InstanceState.Any)

    def take(self, n: int = 64) -> list[tuple[Any, Any]]:
        """Take up to ``n`` samples (oldest first) as rosbags messages with their SampleInfo.
        Samples are taken one by one, so one that cannot be decoded (a peer with another
        definition under the same type name) is counted in ``undecodable`` and skipped alone."""
        arrived = self.arrived            # each of these is taken below or was overwritten
        res = []
        for _ in range(n):
            try:
                got = self.reader.take(N=1)
            except Exception:  # noqa: BLE001 - undecodable CDR: the sample is gone, count it
                self.taken += 1
                self.undecodable += 1
                continue
            if not got:
                break
            s = got[0]
            self.taken += 1
            info = getattr(s, "sample_info", None)
            if info is None or not info.valid_data:   # instance state change (writer gone): no data
                continue
            try:
                res.append((self._from(s), info))
            except Exception:  # noqa: BLE001 - a conversion failure must not stop the node
                self.undecodable += 1
        else:
            return res                    # the queue may not be drained: no loss estimate now
        if arrived is not None:
            self.lost = max(self.lost, arrived - self.taken)
        return res

    @property
    def matched(self) -> int:
        """Number of matched publications right now."""
        return int(self.reader.get_subscription_matched_status().current_count)

    @property
    def gids(self) -> list[bytes]:
        return [self.reader.guid.bytes] + ([self.counter.guid.bytes] if self.counter is not None else [])


class DdsNode:
    """A ROS 2 node on plain DDS: ``name`` in ``namespace`` on ``domain_id`` (default
    ``ROS_DOMAIN_ID``). Create endpoints with :meth:`create_publisher` /
    :meth:`create_subscription` (ROS names, expanded as rclpy does); :meth:`close` deletes
    everything. The node announces itself on ``ros_discovery_info`` (as rmw_cyclonedds does)
    unless ``announce=False``."""

    def __init__(self, name: str, namespace: str = "/", domain_id: int | None = None,
                 types: IdlTypes | None = None, announce: bool = True):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.domain import DomainParticipant

        self.name = validate_node_name(name)
        self.namespace = normalize_namespace(namespace)
        self.domain_id = domain_id_from_env(domain_id)
        self.types = types or IdlTypes()
        self.participant = DomainParticipant(self.domain_id, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        self._topics: dict[str, Any] = {}
        self.publishers: list[DdsPublisher] = []
        self.subscriptions: list[DdsSubscription] = []
        self._announce = announce
        self._discovery_writer = None
        self.closed = False

    @property
    def fully_qualified_name(self) -> str:
        return f"{self.namespace.rstrip('/')}/{self.name}"

    def resolve(self, topic: str) -> str:
        """Fully qualified ROS name of ``topic`` for this node."""
        return expand_topic_name(topic, self.name, self.namespace)

    def _topic(self, ros_topic: str, ros_type: str) -> Any:
        from cyclonedds.topic import Topic

        name = dds_topic_name(ros_topic)
        t = self._topics.get(name)
        if t is None:
            t = self._topics[name] = Topic(self.participant, name, self.types.idl_class(ros_type))
        elif t.data_type is not self.types.idl_class(ros_type):
            raise TypeError(f"topic {ros_topic} already has type {t.get_type_name()} in this node")
        return t

    def create_publisher(self, ros_type: str, topic: str, profile: QosProfile = DEFAULT) -> DdsPublisher:
        pub = DdsPublisher(self, self.resolve(topic), ros_type, profile)
        self.publishers.append(pub)
        self.announce()
        return pub

    def create_subscription(self, ros_type: str, topic: str, profile: QosProfile = SENSOR_DATA,
                            count_arrivals: bool = False) -> DdsSubscription:
        sub = DdsSubscription(self, self.resolve(topic), ros_type, profile, count_arrivals)
        self.subscriptions.append(sub)
        self.announce()
        return sub

    # ---- ros_discovery_info -------------------------------------------------------------
    def announce(self) -> None:
        """Publish this participant's ``ParticipantEntitiesInfo`` (one node, its reader and writer
        GIDs) on ``ros_discovery_info``, as rmw_cyclonedds does after every graph change."""
        if not self._announce or self.closed:
            return
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        if self._discovery_writer is None:
            t = Topic(self.participant, DISCOVERY_TOPIC, self.types.idl_class(DISCOVERY_TYPE))
            # with the type hash in the user data, as rmw_cyclonedds' own ros_discovery_info
            # endpoints (else every ROS process warns "Failed to parse type hash … '(null)'")
            self._discovery_writer = DataWriter(self.participant, t, qos=dds_qos(
                DISCOVERY_INFO, type_hash_user_data(self.types.type_hash(DISCOVERY_TYPE))))
        T = self.types.typestore.types

        def gid(b: bytes) -> Any:
            return T["rmw_dds_common/msg/Gid"](data=np.frombuffer(bytes(b).ljust(16, b"\0")[:16], dtype=np.uint8).copy())

        node = T["rmw_dds_common/msg/NodeEntitiesInfo"](
            node_namespace=self.namespace, node_name=self.name,
            reader_gid_seq=[gid(g) for s in self.subscriptions for g in s.gids],
            writer_gid_seq=[gid(p.gid) for p in self.publishers])
        info = T[DISCOVERY_TYPE](gid=gid(self.participant.guid.bytes), node_entities_info_seq=[node])
        self._discovery_writer.write(self.types.to_idl(info, DISCOVERY_TYPE))

    def close(self) -> None:
        """Delete the participant and all its entities (idempotent)."""
        if self.closed:
            return
        self.closed = True
        try:
            if self._discovery_writer is not None:   # tell the graph the node is gone
                T = self.types.typestore.types
                info = T[DISCOVERY_TYPE](
                    gid=T["rmw_dds_common/msg/Gid"](data=np.frombuffer(self.participant.guid.bytes, np.uint8).copy()),
                    node_entities_info_seq=[])
                self._discovery_writer.write(self.types.to_idl(info, DISCOVERY_TYPE))
        except Exception:  # noqa: BLE001
            pass
        p = self.participant
        try:
            p.__del__()      # dds_delete of the participant deletes its whole entity tree
        except Exception:  # noqa: BLE001
            pass

    def __enter__(self) -> "DdsNode":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def zero_message(typestore: Any, ros_type: str) -> Any:
    """A rosbags message of ``ros_type`` with every number 0, strings empty, sequences empty."""
    from rosbags.typesys.base import Nodetype

    def value(desc: Any) -> Any:
        kind, args = desc
        if kind == Nodetype.BASE:
            name = args[0]
            return "" if name == "string" else False if name == "bool" else 0.0 if name.startswith("float") else 0
        if kind == Nodetype.NAME:
            return zero_message(typestore, args)
        sub, n = args
        if sub[0] == Nodetype.BASE and sub[1][0] != "string":
            return np.zeros(n if kind == Nodetype.ARRAY else 0, dtype=_PRIMITIVES[sub[1][0]][1])
        return [value(sub) for _ in range(n)] if kind == Nodetype.ARRAY else []

    return typestore.types[ros_type](**{name: value(d) for name, d in typestore.fielddefs[ros_type][1]})


def wait_matched(endpoints: Iterable[Any], timeout: float, count: int = 1, poll: float = 0.02) -> bool:
    """Wait until every endpoint (DdsPublisher/DdsSubscription) has ≥ ``count`` matches, at most
    ``timeout`` s. Returns whether they all matched."""
    endpoints = list(endpoints)
    deadline = time.monotonic() + timeout
    while True:
        if all(e.matched >= count for e in endpoints):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll)


# =========================================================================================
# the platform node on DDS: thin adapter around NodeCore
# =========================================================================================
class _ClockWatch:
    """Detects jumps of the wall clock (ROS time on a node without sim time) against the
    monotonic clock; ``check()`` → None or (``"backward"``|``"forward"``, jump ns)."""

    def __init__(self, threshold_ns: int = NS):
        self.threshold = threshold_ns
        self._offset = time.time_ns() - time.monotonic_ns()

    def check(self) -> tuple[str, int] | None:
        off = time.time_ns() - time.monotonic_ns()
        d, self._offset = off - self._offset, off
        if d <= -self.threshold:
            return "backward", d
        if d >= self.threshold:
            return "forward", d
        return None


class PlatformDdsNode:
    """The platform node on DDS, a thin adapter around :class:`gyro_platform.ros.core.NodeCore`:
    one subscription on the core's input topic (sensor-data QoS), one reliable publisher per
    output topic and ``/diagnostics`` every ``1 / diagnostics_rate`` s (the core's statuses plus
    ``gyro_platform: transport``), ``~/reset`` (``std_msgs/msg/Empty``) →
    ``core.reset("reset_topic")``, wall-clock jumps → ``core.on_clock_jump``.

    Receive times are the wall clock (``time.time_ns``), as an rclpy node's ROS time without
    sim time. Everything runs in the thread that calls :meth:`spin`, which sleeps in a DDS
    WaitSet (read conditions of its readers and a guard condition for :meth:`stop`): no Python
    runs in Cyclone's threads.
    """

    RESET_TOPIC = "~/reset"
    RESET_TYPE = "std_msgs/msg/Empty"
    TAKE_BATCH = 64

    def __init__(self, core: Any, node: DdsNode, *, diagnostics_period: float = 1.0,
                 log: Callable[[str], None] | None = None, reset_topic: bool = True,
                 robot_description: bool = True):
        from ..io.messages import DIAGNOSTIC_ARRAY

        self.core = core
        self.node = node
        self.log = log or (lambda s: None)
        self.diagnostics_period = float(diagnostics_period)
        from cyclonedds.core import GuardCondition, WaitSet

        self.stop_event = threading.Event()
        self.input = node.create_subscription(core.input_type, core.input_topic, SENSOR_DATA, count_arrivals=True)
        outputs = dict(core.output_topics())
        outputs["/diagnostics"] = DIAGNOSTIC_ARRAY
        #: topic as the core names it (relative to the namespace) → publisher
        self.publishers: dict[str, DdsPublisher] = {
            name: node.create_publisher(t, name, DEFAULT) for name, t in outputs.items()}
        self.reset_sub = (node.create_subscription(self.RESET_TYPE, self.RESET_TOPIC, DEFAULT)
                          if reset_topic else None)
        self.waitset = WaitSet(node.participant)
        self.guard = GuardCondition(node.participant)
        self._conditions = [self.input.condition()] + ([self.reset_sub.condition()] if self.reset_sub else [])
        for c in (*self._conditions, self.guard):
            self.waitset.attach(c)
        self.clock = _ClockWatch()
        self.processed = 0
        self.published = 0
        self.errors = 0
        self.resets = 0
        self.max_batch = 0
        self.last_error = ""
        self.unknown_topics: set[str] = set()
        self._lost_fed = 0
        self.model = None
        self.frame_prefix = core.config["frame_prefix"]
        if robot_description:
            self._setup_robot_description()

    def warm_up(self) -> None:
        """Compile/load the kernels and build the CDR encoders before the first real sample
        (:func:`gyro_platform.ros.command.warm_up`; outputs encoded, not sent), so that the
        first samples are not stalled (and dropped by the keep-last-5 input queue)."""
        from .command import warm_up

        def encode(topic: str, msg: Any) -> None:
            if topic in self.publishers:
                self.publishers[topic]._to(msg).serialize(use_version_2=False)

        try:
            warm_up(self.core, lambda: zero_message(self.node.types.typestore, self.core.input_type), encode)
            encode("/diagnostics", self.core.diagnostics(time.time_ns()))
        except Exception as e:  # noqa: BLE001 - warming up is an optimisation only
            self.log(f"warm-up skipped: {type(e).__name__}: {e}")

    @property
    def topics(self) -> dict[str, list[str]]:
        """Fully qualified ROS names of the node's endpoints: ``{"in": [...], "out": [...]}``."""
        ins = [self.input.topic] + ([self.reset_sub.topic] if self.reset_sub else [])
        return {"in": ins, "out": [p.topic for p in self.publishers.values()]}

    # ---- one pass -----------------------------------------------------------------------
    def poll(self) -> int:
        """Take and process everything queued now; returns the number of input samples."""
        jump = self.clock.check()
        if jump is not None:
            self.core.on_clock_jump(jump[0] == "backward", jump[1])
            self.log(f"wall clock jumped {jump[0]} by {jump[1] / NS:.3f} s; core told")
        if self.reset_sub is not None and self.reset_sub.take(self.TAKE_BATCH):
            self.core.reset("reset_topic")
            self.resets += 1
            self.log(f"reset requested on {self.reset_sub.topic}")
        batch = self.input.take(self.TAKE_BATCH)
        self.max_batch = max(self.max_batch, len(batch))
        for msg, _info in batch:
            self._process(msg, time.time_ns())
        lost = self.input.lost
        if lost > self._lost_fed:
            self.core.loss.on_transport_loss(lost - self._lost_fed, time.time_ns())
            self._lost_fed = lost
        return len(batch)

    # ---- robot description and TF ---------------------------------------------------
    def _setup_robot_description(self) -> None:
        """``/robot_description`` (URDF, transient local) and ``/tf_static`` (fixed joints)
        published once, latched; ``/tf`` (moving joints) with every JointState output."""
        from ..io.messages import STRING, TF_MESSAGE, string_message, tf_message
        from ..io.urdf import config_model, config_urdf

        self.model = config_model(self.core.config)
        self.publishers["robot_description"] = self.node.create_publisher(STRING, "robot_description", LATCHED)
        self.publishers["/tf_static"] = self.node.create_publisher(TF_MESSAGE, "/tf_static", LATCHED)
        self.publishers["/tf"] = self.node.create_publisher(TF_MESSAGE, "/tf", TF)
        self.publishers["robot_description"].publish(string_message(config_urdf(self.core.config), self.core.types))
        static = tf_message(self.model, {}, self.core.types, time.time_ns(), self.frame_prefix, static=True)
        if static.transforms:
            self.publishers["/tf_static"].publish(static)

    def _publish_tf(self, joint_state: Any) -> None:
        from ..io.messages import stamp_ns, tf_message

        positions = dict(zip(joint_state.name, (float(x) for x in joint_state.position)))
        msg = tf_message(self.model, positions, self.core.types, stamp_ns(joint_state.header.stamp), self.frame_prefix)
        self.publishers["/tf"].publish(msg)
        self.published += 1

    def _process(self, msg: Any, receive_ns: int) -> None:
        try:
            outs = self.core.on_message(msg, receive_ns)
        except Exception as e:  # noqa: BLE001 - the core does not raise; never die on input anyway
            self._error(f"core: {type(e).__name__}: {e}")
            return
        self.processed += 1
        if self.core.notices:
            for line in self.core.take_notices():
                self.log(line)
        for topic, out in outs or ():
            pub = self.publishers.get(topic)
            if pub is None:
                if topic not in self.unknown_topics:
                    self.unknown_topics.add(topic)
                    self.log(f"the core produced a message on {topic!r}, which has no publisher; ignored")
                continue
            try:
                pub.publish(out)
                self.published += 1
                if self.model is not None and topic == "gimbal/joint_states":
                    self._publish_tf(out)
            except Exception as e:  # noqa: BLE001 - e.g. a value out of range for its CDR type
                self._error(f"publish {pub.topic}: {type(e).__name__}: {e}")

    def _error(self, text: str) -> None:
        self.errors += 1
        if text != self.last_error:
            self.log(text)
        self.last_error = text

    # ---- diagnostics --------------------------------------------------------------------
    def transport_status(self) -> dict[str, Any]:
        """Counters of the DDS transport (the values of its diagnostic status)."""
        s = self.input
        d: dict[str, Any] = {
            "domain_id": self.node.domain_id, "input_topic": s.topic, "input_type": s.ros_type,
            "input_publishers_matched": s.matched, "samples_arrived": s.arrived or 0, "samples_taken": s.taken,
            "samples_lost": s.lost, "samples_undecodable": s.undecodable, "queue_depth": s.profile.depth,
            "max_batch": self.max_batch, "processed": self.processed, "published": self.published,
            "reset_requests": self.resets, "transport_errors": self.errors}
        if self.last_error:
            d["last_error"] = self.last_error
        return d

    def diagnostics(self) -> Any:
        """The core's DiagnosticArray (stamped now) plus ``gyro_platform: transport`` (the same
        status names as the rclpy node): WARN after a transport error. Lost input (samples DDS
        overwrote in the keep-last queue: the node is slower than its input) is fed to the
        core's ``InputLoss`` in :meth:`poll` and makes ``gyro_platform: node`` WARN."""
        from ..io.messages import transport_status

        arr = self.core.diagnostics(time.time_ns())
        warn = f"{self.errors} transport error(s); last: {self.last_error}" if self.errors else ""
        arr.status.append(transport_status(self.core.types,
                                           {"transport": "dds", **self.transport_status()}, warn))
        return arr

    def publish_diagnostics(self) -> None:
        try:
            self.publishers["/diagnostics"].publish(self.diagnostics())
        except Exception as e:  # noqa: BLE001
            self._error(f"diagnostics: {type(e).__name__}: {e}")

    # ---- the loop -----------------------------------------------------------------------
    def spin(self, duration: float | None = None) -> None:
        """Process inputs until :meth:`stop` (e.g. from a signal handler) or until ``duration`` s
        (monotonic) have passed. Diagnostics go out at the start, every period and at the end."""
        t_end = None if duration is None else time.monotonic() + float(duration)
        next_diag = time.monotonic()
        while not self.stop_event.is_set():
            now = time.monotonic()
            if t_end is not None and now >= t_end:
                break
            if now >= next_diag:
                self.publish_diagnostics()
                next_diag = now + self.diagnostics_period
            self.poll()
            wake_at = min(next_diag, now + 0.5, t_end if t_end is not None else next_diag)
            timeout = wake_at - time.monotonic()
            if timeout > 0 and not self.stop_event.is_set():
                self.waitset.wait(max(1, int(timeout * NS)))   # returns early when data waits
        self.publish_diagnostics()

    def stop(self) -> None:
        """Ask :meth:`spin` to return (safe from a signal handler or another thread). A signal
        handler runs when the WaitSet wait returns: within 0.5 s."""
        self.stop_event.set()
        try:
            self.guard.set(True)
        except Exception:  # noqa: BLE001 - already closed
            pass

    def close(self) -> None:
        self.node.close()
