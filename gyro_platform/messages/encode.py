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

"""CDR bytes of the per-instant output messages for K instants at once (issue 12 fast path).

:func:`encode_outputs` makes exactly the messages :func:`gyro_platform.messages.output_messages`
makes (joint states, drift angle and rate, attitude, servo torque, one wrench per bearing),
byte-identical to rosbags ``serialize_cdr`` of them, without building message objects: each
topic has a fixed layout (its frame id and, for JointState, its joint names are constant), so
a template of one message is tiled K times and the stamps and float64 fields are written into
it as array columns. CDR (XCDR1, little endian, 4-byte encapsulation header ``00 01 00 00``),
alignment relative to the end of the encapsulation header, as rosbags and Fast DDS write it.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import struct
from typing import Any

import numpy as np

from . import names as msgs
from .outputs import joint_columns, rows_of
from ..engine.outputs import BEARING_FRAMES, BEARING_NAMES

_HEAD = b"\x00\x01\x00\x00"      # CDR_LE encapsulation, options 0
NS = 1_000_000_000
_INT32_MAX = 2 ** 31 - 1


@dataclass(frozen=True)
class Layout:
    """One message layout: ``template`` (bytes of a message with zero stamp and values),
    ``fields``: byte offset of each float64 column group (in order of the value arrays)."""

    template: np.ndarray          # uint8 (L,)
    fields: tuple[int, ...]


class _Builder:
    """Appends CDR primitives with XCDR1 alignment; records where float64 groups start."""

    def __init__(self) -> None:
        self.buf = bytearray(_HEAD)
        self.fields: list[int] = []

    def _align(self, n: int) -> None:
        self.buf += bytes((-(len(self.buf) - 4)) % n)

    def u32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", v)

    def string(self, s: str) -> None:
        data = s.encode() + b"\x00"
        self.u32(len(data))
        self.buf += data

    def header(self, frame_id: str) -> None:
        self.u32(0)          # stamp.sec (offset 4: written per row)
        self.u32(0)          # stamp.nanosec (offset 8)
        self.string(frame_id)

    def f64(self, n: int) -> None:
        """``n`` float64 (a fixed group, e.g. a Vector3), values written per row."""
        self._align(8)
        self.fields.append(len(self.buf))
        self.buf += bytes(8 * n)

    def f64_seq(self, n: int) -> None:
        """``float64[]`` of length ``n`` (no alignment of the elements when empty)."""
        self.u32(n)
        if n:
            self.f64(n)
        else:
            self.fields.append(len(self.buf))

    def layout(self) -> Layout:
        return Layout(np.frombuffer(bytes(self.buf), np.uint8), tuple(self.fields))


@lru_cache(maxsize=256)
def stamped_layout(frame_id: str, groups: tuple[int, ...]) -> Layout:
    """A ``Header`` with ``frame_id`` then fixed float64 groups of the given sizes
    (Vector3Stamped: (3,), QuaternionStamped: (4,), WrenchStamped: (3, 3))."""
    b = _Builder()
    b.header(frame_id)
    for n in groups:
        b.f64(n)
    return b.layout()


@lru_cache(maxsize=64)
def joint_state_layout(names: tuple[str, ...], n_vel: int) -> Layout:
    """``sensor_msgs/JointState`` with frame ``""``, ``names``, P positions, ``n_vel``
    velocities and efforts."""
    b = _Builder()
    b.header("")
    b.u32(len(names))
    for n in names:
        b.string(n)
    b.f64_seq(len(names))
    b.f64_seq(n_vel)
    b.f64_seq(n_vel)
    return b.layout()


def stamp_columns(stamps_ns: Any) -> tuple[np.ndarray, np.ndarray]:
    """``builtin_interfaces/Time`` (sec int32, nanosec uint32) of int64 stamps (ns; negative
    clamped to 0 as :func:`gyro_platform.messages.header` does). ValueError past 2038."""
    ns = np.maximum(np.asarray(stamps_ns, dtype=np.int64).reshape(-1), 0)
    sec, nsec = np.divmod(ns, NS)
    if sec.size and int(sec.max()) > _INT32_MAX:
        raise ValueError(f"stamp {int(ns.max())} ns does not fit builtin_interfaces/Time (int32 seconds)")
    return sec.astype("<i4"), nsec.astype("<u4")


def fill(layout: Layout, sec: np.ndarray, nsec: np.ndarray, values: list[np.ndarray]) -> list[bytes]:
    """K messages of ``layout``: stamps and the float64 groups ``values`` ((K, n) each)."""
    rows = fill_rows(layout, sec, nsec, values)
    return rows.view(f"V{rows.shape[1]}").ravel().tolist()     # one bytes object per row (NULs kept)


def fill_rows(layout: Layout, sec: np.ndarray, nsec: np.ndarray, values: list[np.ndarray]) -> np.ndarray:
    """:func:`fill` as a uint8 array (K, message size): row i is message i's bytes."""
    k = sec.shape[0]
    size = layout.template.shape[0]
    rows = np.empty((k, size), np.uint8)
    rows[:] = layout.template
    rows[:, 4:8].view("<i4")[:, 0] = sec
    rows[:, 8:12].view("<u4")[:, 0] = nsec
    for off, v in zip(layout.fields, values):
        n = v.shape[1]
        if n:
            rows[:, off:off + 8 * n].view("<f8")[:] = v
    return rows


def _prefixed(prefix: str, frame_id: str) -> str:
    """Frame id with the node's ``frame_prefix`` (empty ids stay empty, as the node does)."""
    return prefix + frame_id if frame_id else frame_id


def encode_outputs(block: Any, stamps_ns: Any, namespace: str = "", frame_prefix: str = "",
                   arrays: bool = False) -> list[tuple[str, Any]]:
    """(absolute topic, CDR bytes of its K messages) for every per-instant output topic, in
    the order of :func:`gyro_platform.messages.output_messages`, from an ``OutputBlock``
    (arrays over K instants, see :mod:`gyro_platform.engine.outputs`) and the K header stamps
    (int64 ns). ``namespace`` resolves the topic names; ``frame_prefix`` is put before every
    non-empty frame id. Byte-identical to rosbags ``serialize_cdr`` of those messages.
    ``arrays``: each topic's messages as one uint8 array (K, size) (:func:`fill_rows`;
    a topic's messages all have one size) instead of K bytes objects."""
    make = fill_rows if arrays else fill
    sec, nsec = stamp_columns(stamps_ns)
    k = sec.shape[0]
    if np.asarray(block.t).reshape(-1).shape[0] != k:
        raise ValueError(f"{k} stamps for {np.asarray(block.t).size} output instants")
    res: list[tuple[str, Any]] = []
    cols = joint_columns(block)
    res.append((msgs.resolve("gimbal/joint_states", namespace),
                make(joint_state_layout(cols.names, cols.velocity.shape[1]), sec, nsec,
                     [cols.position, cols.velocity, cols.effort])))
    platform = _prefixed(frame_prefix, msgs.PLATFORM_FRAME)
    vec3 = stamped_layout(platform, (3,))
    res.append((msgs.resolve("drift/angle", namespace), make(vec3, sec, nsec, [rows_of(block.drift_angle, k)])))
    res.append((msgs.resolve("drift/rate", namespace), make(vec3, sec, nsec, [rows_of(block.drift_rate, k)])))
    res.append((msgs.resolve("platform/attitude", namespace),
                make(stamped_layout(_prefixed(frame_prefix, msgs.REFERENCE_FRAME), (4,)), sec, nsec,
                     [rows_of(block.platform_attitude, k)])))
    if block.servo_torque is not None:
        res.append((msgs.resolve("platform/servo_torque", namespace),
                    make(vec3, sec, nsec, [rows_of(block.servo_torque, k)])))
    torques = _bearing_torques(block, k)
    zeros = np.zeros((k, 3))
    for name in BEARING_NAMES:
        tq = torques.get(name)
        if tq is None:
            continue
        layout = stamped_layout(_prefixed(frame_prefix, BEARING_FRAMES[name]), (3, 3))
        res.append((msgs.resolve(msgs.bearing_topic(name), namespace), make(layout, sec, nsec, [zeros, tq])))
    return res


def _bearing_torques(block: Any, k: int) -> dict[str, np.ndarray]:
    """Bearing name → (K, 3) N m: from a (K, 9, 3) array in BEARING_NAMES order (OutputBlock)
    or a name → array mapping (``Outputs``, bearings it lacks left out)."""
    bt = block.bearing_torques
    if isinstance(bt, dict):
        return {n: rows_of(v, k) for n, v in bt.items()}
    arr = np.asarray(bt, dtype=np.float64).reshape(k, len(BEARING_NAMES), 3)
    return {n: arr[:, i, :] for i, n in enumerate(BEARING_NAMES)}


__all__ = ["encode_outputs", "stamp_columns", "fill", "fill_rows", "stamped_layout", "joint_state_layout", "Layout"]
