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

"""Array blocks flowing through the fast path (issue 12 contract): one block = one chunk of rows.

* :class:`RowChunk` — raw bag rows as :meth:`gyro_platform.bags.reader.InputBag.chunks` yields
  them (rosbags connection id, record time ns, CDR bytes), in bag order; the CDR bytes as a
  list of ``bytes`` or as :class:`RawRows` (payloads in place in one buffer: an MCAP chunk's).
* :class:`RateBlock` — the input rows decoded (:func:`gyro_platform.messages.decode.decode_rates`):
  per row what :func:`gyro_platform.messages.reading_from_msg` gives for one message, as arrays
  (rad/s, m/s², sensor frame until ``Mounting.rotate_block`` turns them into base_link).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np

#: reasons of ``RateBlock.reject`` (value = 1 + index; 0 = usable reading); the names of
#: :class:`gyro_platform.messages.Rejected` reasons
REJECT_REASONS: tuple[str, ...] = ("no_rate", "unknown_frame", "bad_message")
REJECT_NO_RATE, REJECT_UNKNOWN_FRAME, REJECT_BAD_MESSAGE = 1, 2, 3

Raw = Union[bytes, memoryview]


class RawRows:
    """``N`` payloads in place in one byte buffer: row ``i`` is ``buf[beg[i]:end[i]]`` (e.g. the
    message records of a decompressed MCAP chunk), without a Python object per row. A sequence
    of ``bytes``: ``len``, ``rows[i]`` (bytes), ``rows[a:b]`` and ``rows[index array]`` (RawRows
    on the same buffer), iteration; :meth:`lens`, :meth:`tolist`."""

    __slots__ = ("buf", "beg", "end")

    def __init__(self, buf: np.ndarray, beg: np.ndarray, end: np.ndarray):
        self.buf, self.beg, self.end = buf, beg, end

    def __len__(self) -> int:
        return len(self.beg)

    def __getitem__(self, k):
        if isinstance(k, (slice, np.ndarray, list)):
            return RawRows(self.buf, self.beg[k], self.end[k])
        return self.buf[int(self.beg[k]):int(self.end[k])].tobytes()

    def __iter__(self):
        buf = self.buf
        return (buf[a:b].tobytes() for a, b in zip(self.beg.tolist(), self.end.tolist()))

    def lens(self) -> np.ndarray:
        """Payload sizes (bytes), int64."""
        return self.end - self.beg

    def tolist(self) -> list[bytes]:
        return list(self)

    @classmethod
    def concat(cls, parts: list["RawRows"]) -> "RawRows":
        """One RawRows of the rows of ``parts`` in order (the buffers joined when they differ)."""
        if len(parts) == 1 or all(p.buf is parts[0].buf for p in parts):
            return cls(parts[0].buf, np.concatenate([p.beg for p in parts]), np.concatenate([p.end for p in parts]))
        bufs, begs, ends, off = [], [], [], 0
        for p in parts:                 # each part's span of its buffer, no more
            lo, hi = (int(p.beg.min()), int(p.end.max())) if len(p) else (0, 0)
            bufs.append(p.buf[lo:hi])
            begs.append(p.beg - lo + off)
            ends.append(p.end - lo + off)
            off += hi - lo
        return cls(np.concatenate(bufs), np.concatenate(begs), np.concatenate(ends))


def readonly(buf: np.ndarray) -> np.ndarray:
    """``buf`` as a read-only array (a view if it is writable): the byte buffers handed to the
    compiled kernels are always read-only, so that each kernel compiles for one signature
    (``np.frombuffer(bytes)`` is read-only, a decompressed chunk writable)."""
    if not buf.flags.writeable:
        return buf
    v = buf.view()
    v.flags.writeable = False
    return v


def row_lens(raws) -> np.ndarray:
    """Payload sizes (bytes, int64) of a list of bytes or a :class:`RawRows`."""
    return raws.lens() if isinstance(raws, RawRows) else np.fromiter(map(len, raws), np.int64, len(raws))


def take_rows(raws, idx: np.ndarray):
    """Rows ``idx`` (int array) of a list of bytes or a :class:`RawRows`, in that order."""
    if isinstance(raws, RawRows):
        return raws[idx]
    return [raws[i] for i in idx.tolist()]


def concat_rows(parts: list) -> "list | RawRows":
    """Rows of ``parts`` (lists of bytes or :class:`RawRows`) in order: a list when all are lists."""
    parts = [p for p in parts if len(p)] or parts[:1]
    if not parts:
        return []
    if all(isinstance(p, RawRows) for p in parts):
        return RawRows.concat(parts)
    if not any(isinstance(p, RawRows) for p in parts):
        return [r for p in parts for r in p] if len(parts) > 1 else list(parts[0])
    return [r for p in parts for r in (p.tolist() if isinstance(p, RawRows) else p)]


def bad_stamp_detail(sec: int, nanosec: int) -> str | None:
    """Detail of a message rejected ``bad_message`` because its header stamp is not a valid
    ``builtin_interfaces/Time``: ``nanosec`` must be in [0, 1e9) (issue 17: not a later time)
    and ``sec`` not negative (before 1970: not a time a ROS clock gives); None when valid."""
    if not 0 <= nanosec < 1_000_000_000:
        return f"header.stamp.nanosec = {nanosec} is not in [0, 1e9) (invalid stamp)"
    if sec < 0:
        return f"header.stamp.sec = {sec} is negative (invalid stamp)"
    return None


@dataclass(slots=True)
class RowChunk:
    """``N`` bag rows in bag order (record-time order as rosbags reads them).

    ``conn_id``: int64 (N,) rosbags ``Connection.id`` of each row; ``ts``: int64 (N,) record
    (receive) time ns; ``raws``: the CDR bytes of each row (N; a list or :class:`RawRows`)."""

    conn_id: np.ndarray
    ts: np.ndarray
    raws: "list[Raw] | RawRows"

    def __len__(self) -> int:
        return len(self.raws)

    @classmethod
    def empty(cls) -> "RowChunk":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), [])

    def take(self, mask_or_idx: np.ndarray) -> "RowChunk":
        """The rows selected by a boolean mask or an index array, in order."""
        idx = np.flatnonzero(mask_or_idx) if np.asarray(mask_or_idx).dtype == bool else np.asarray(mask_or_idx)
        return RowChunk(self.conn_id[idx], self.ts[idx], take_rows(self.raws, idx))


@dataclass(slots=True)
class RateBlock:
    """Decoded input rows, one per message of the input topic.

    * ``stamp_ns`` int64 (N,): header stamp ns (0 = not set; Twist: 0); ``has_header`` bool (N,)
      (False for Twist);
    * ``frame_id`` list[str] (N) (Twist: ""; after ``rotate_block`` Twist rows carry the vehicle frame);
    * ``omega`` float64 (N, 3) rad/s; ``force`` float64 (N, 3) m/s² specific force (0 where
      ``has_force`` is False); ``has_force`` bool (N,): Imu with ``linear_acceleration_covariance[0] != -1``;
    * ``reject`` int8 (N,): 0 = usable, else 1 + index into :data:`REJECT_REASONS`;
      ``detail``: row → text for rejected rows;
    * ``identity`` bool (N,): frame without mounting taken as base_link (set by ``rotate_block``).
    """

    stamp_ns: np.ndarray
    has_header: np.ndarray
    frame_id: list[str]
    omega: np.ndarray
    force: np.ndarray
    has_force: np.ndarray
    reject: np.ndarray
    detail: dict[int, str] = field(default_factory=dict)
    identity: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.identity is None:
            self.identity = np.zeros(len(self.frame_id), bool)

    def __len__(self) -> int:
        return len(self.frame_id)

    @classmethod
    def zeros(cls, n: int) -> "RateBlock":
        """``n`` rows, all fields zero / empty / not rejected (to be filled by a decoder)."""
        return cls(np.zeros(n, np.int64), np.zeros(n, bool), [""] * n, np.zeros((n, 3)), np.zeros((n, 3)),
                   np.zeros(n, bool), np.zeros(n, np.int8), {}, np.zeros(n, bool))

    def reject_reason(self, i: int) -> str | None:
        """Reason name of row ``i`` or None when it is usable."""
        r = int(self.reject[i])
        return None if r == 0 else REJECT_REASONS[r - 1]

    def set_reject(self, i: int, reason: str, detail: str) -> None:
        """Mark row ``i`` rejected for ``reason`` (a name of :data:`REJECT_REASONS`)."""
        self.reject[i] = 1 + REJECT_REASONS.index(reason)
        self.detail[i] = detail

    @classmethod
    def concat(cls, blocks: list["RateBlock"]) -> "RateBlock":
        """One block of the rows of ``blocks`` in order (details renumbered)."""
        if not blocks:
            return cls.zeros(0)
        detail: dict[int, str] = {}
        off = 0
        for b in blocks:
            detail.update({off + k: v for k, v in b.detail.items()})
            off += len(b)
        return cls(np.concatenate([b.stamp_ns for b in blocks]), np.concatenate([b.has_header for b in blocks]),
                   [f for b in blocks for f in b.frame_id], np.concatenate([b.omega for b in blocks]),
                   np.concatenate([b.force for b in blocks]), np.concatenate([b.has_force for b in blocks]),
                   np.concatenate([b.reject for b in blocks]), detail,
                   np.concatenate([b.identity for b in blocks]))
