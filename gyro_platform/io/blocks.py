"""Array blocks flowing through the fast path (issue 12 contract): one block = one chunk of rows.

* :class:`RowChunk` — raw bag rows as :meth:`gyro_platform.io.bag_reader.InputBag.chunks` yields
  them (rosbags connection id, record time ns, CDR bytes), in bag order.
* :class:`RateBlock` — the input rows decoded (:func:`gyro_platform.io.decode.decode_rates`):
  per row what :func:`gyro_platform.io.messages.reading_from_msg` gives for one message, as arrays
  (rad/s, m/s², sensor frame until ``Mounting.rotate_block`` turns them into base_link).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np

#: reasons of ``RateBlock.reject`` (value = 1 + index; 0 = usable reading); the names of
#: :class:`gyro_platform.io.messages.Rejected` reasons
REJECT_REASONS: tuple[str, ...] = ("no_rate", "unknown_frame", "bad_message")
REJECT_OK = 0
REJECT_NO_RATE, REJECT_UNKNOWN_FRAME, REJECT_BAD_MESSAGE = 1, 2, 3

Raw = Union[bytes, memoryview]


@dataclass(slots=True)
class RowChunk:
    """``N`` bag rows in bag order (record-time order as rosbags reads them).

    ``conn_id``: int64 (N,) rosbags ``Connection.id`` of each row; ``ts``: int64 (N,) record
    (receive) time ns; ``raws``: the CDR bytes of each row (N)."""

    conn_id: np.ndarray
    ts: np.ndarray
    raws: list[Raw]

    def __len__(self) -> int:
        return len(self.raws)

    @classmethod
    def empty(cls) -> "RowChunk":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), [])

    def take(self, mask_or_idx: np.ndarray) -> "RowChunk":
        """The rows selected by a boolean mask or an index array, in order."""
        idx = np.flatnonzero(mask_or_idx) if np.asarray(mask_or_idx).dtype == bool else np.asarray(mask_or_idx)
        return RowChunk(self.conn_id[idx], self.ts[idx], [self.raws[i] for i in idx.tolist()])


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
