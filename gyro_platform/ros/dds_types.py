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

"""ROS message types and QoS on DDS: IDL classes from the rosbags typestore, conversions, QoS.

* :class:`IdlTypes`: ``cyclonedds.idl`` ``IdlStruct`` classes generated at run time from the
  field definitions of the rosbags ROS 2 Jazzy typestore (nested structs, fixed arrays,
  bounded/unbounded sequences and strings, ``builtin_interfaces/Time``), keyless, final, encoded
  as XCDR1 (= classic CDR, what rmw_cyclonedds sends), plus conversion both ways between
  rosbags message objects and the generated IDL objects — so the transport-independent core,
  which builds rosbags messages, is used unchanged. Byte identity with
  ``typestore.serialize_cdr`` is tested in ``test/test_dds.py``.
* QoS (:class:`QosProfile`, :func:`dds_qos`): ``sensor_data`` (best effort, keep last 5,
  volatile) for the inputs, ``default`` (reliable, keep last 10, volatile) for the outputs, as
  the rclpy node; every endpoint forces data representation XCDR1 and carries rmw's
  ``typehash=RIHS01_…;`` user data (:func:`type_hash_user_data`).
* :func:`zero_message`: a rosbags message with every field zero (warm-up samples).

cyclonedds is an optional dependency, imported lazily (:func:`import_cyclonedds`).
"""
from __future__ import annotations

from dataclasses import dataclass
import threading
from typing import Any, Callable

import numpy as np

from .dds_names import dds_type_name


# =========================================================================================
# types: rosbags field definitions → cyclonedds IdlStruct classes, conversion both ways
# =========================================================================================
def import_cyclonedds():
    """``(cyclonedds.idl, cyclonedds.idl.types)``, imported lazily (an optional dependency:
    ``pip install .[dds]``); ImportError with the install hint when it is missing."""
    try:
        import cyclonedds.idl as idl
        import cyclonedds.idl.types as idl_types
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError(
            f"the DDS transport needs the 'cyclonedds' package (pip install 'gyro_platform[dds]'): {e}"
        ) from e
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


def _scalar_conv(name: str, byte: Callable[[Any], int]) -> Callable[[Any], Any]:
    """Converter of one value of the ROS primitive ``name`` between rosbags and IDL objects;
    ``byte``: the one for ``byte`` (int8 in rosbags, an octet in IDL: it differs by direction)."""
    if name == "string":
        return str
    if name in ("float32", "float64"):
        return float
    if name == "bool":
        return bool
    return byte if name == "byte" else int


class IdlTypes:
    """IDL classes for ROS message types, generated from a rosbags typestore, and conversions.

    ``idl_class(ros_type)`` → ``IdlStruct`` subclass named ``<pkg>::msg::dds_::<Type>_``;
    ``to_idl(msg)`` / ``from_idl(obj, ros_type)`` convert rosbags messages ↔ IDL objects;
    ``serialize(msg)`` / ``deserialize(data, ros_type)`` go through the IDL classes (XCDR1,
    little endian, 4-byte encapsulation header — the bytes rmw_cyclonedds sends).
    """

    def __init__(self, typestore: Any = None):
        if typestore is None:
            from ..messages import jazzy_typestore

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
                idl, _ = import_cyclonedds()
                members = {name: self._idl_field_type(desc) for name, desc in self.fields(ros_type)}
                cls = idl.make_idl_struct(ros_type.split("/")[-1] + "_", dds_type_name(ros_type), members)
                # final extensibility, no key, no optional: XCDR1 is allowed and the default
                self._classes[ros_type] = cls
            return cls

    def _idl_field_type(self, desc: Any) -> Any:
        from rosbags.interfaces import Nodetype

        _, T = import_cyclonedds()
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
        return self.to_idl_fn(ros_type or msg.__msgtype__)(msg)

    def to_idl_fn(self, ros_type: str) -> Callable[[Any], Any]:
        """The converter rosbags message → IDL object of ``ros_type`` (built once, cached)."""
        return self._converter(self._to, ros_type, self.idl_class, self._to_field)

    def _converter(self, cache: dict, ros_type: str, target: Callable[[str], type],
                   field_conv: Callable[[Any], Callable[[Any], Any]]) -> Callable[[Any], Any]:
        """Cached field-by-field converter of ``ros_type`` into ``target(ros_type)`` objects."""
        with self._lock:
            fn = cache.get(ros_type)
            if fn is None:
                cls = target(ros_type)
                convs = [(name, field_conv(desc)) for name, desc in self.fields(ros_type)]

                def fn(obj: Any, cls: type = cls, convs: list = convs) -> Any:
                    return cls(**{name: conv(getattr(obj, name)) for name, conv in convs})

                cache[ros_type] = fn
            return fn

    def _to_field(self, desc: Any) -> Callable[[Any], Any]:
        from rosbags.interfaces import Nodetype

        kind, args = desc
        if kind == Nodetype.BASE:
            return _scalar_conv(args[0], lambda v: int(v) & 0xFF)        # IDL octet: 0…255
        if kind == Nodetype.NAME:
            return self.to_idl_fn(args)
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
        return self.from_idl_fn(ros_type)(obj)

    def from_idl_fn(self, ros_type: str) -> Callable[[Any], Any]:
        """The converter IDL object → rosbags message of ``ros_type`` (built once, cached)."""
        return self._converter(self._from, ros_type, self.typestore.types.__getitem__, self._from_field)

    def _from_field(self, desc: Any) -> Callable[[Any], Any]:
        from rosbags.interfaces import Nodetype

        kind, args = desc
        if kind == Nodetype.BASE:
            return _scalar_conv(args[0], lambda v: (int(v) + 128) % 256 - 128)     # rosbags byte: int8
        if kind == Nodetype.NAME:
            return self.from_idl_fn(args)
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


__all__ = ["IdlTypes", "QosProfile", "SENSOR_DATA", "DEFAULT", "DISCOVERY_INFO", "TF", "LATCHED", "PROFILES",
           "dds_qos", "type_hash_user_data", "zero_message", "import_cyclonedds"]
