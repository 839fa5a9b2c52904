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

"""Message payloads of a write batch in segments (:class:`Rows`) and the numpy helpers the
storage writers (:mod:`.storage`) cut, count and group them with."""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..messages.blocks import RawRows, row_lens


class Rows:
    """Message payloads of a batch in segments, in order: each a 2-D uint8 array (one message
    per row, all of its width: what :func:`gyro_platform.messages.encode.encode_outputs` makes with
    ``arrays=True``) or a sequence of bytes. ``len`` is the number of messages."""

    __slots__ = ("segments", "n")

    def __init__(self, segments: Sequence[Any]):
        self.segments = list(segments)
        self.n = sum(len(s) for s in self.segments)

    def __len__(self) -> int:
        return self.n


def segments(raws: Any) -> list[Any]:
    """The segments of ``raws`` (a :class:`Rows` or one sequence of bytes)."""
    return raws.segments if isinstance(raws, Rows) else [raws]


def as_bytes_list(raws: Any) -> list[Any]:
    """``raws`` (a :class:`Rows` or a sequence of bytes) as one list of bytes-like objects."""
    res: list[Any] = []
    for seg in segments(raws):
        res += _seg_list(seg)
    return res


def payload_bytes(raws: Any) -> int:
    """Total payload size of ``raws`` (bytes)."""
    return sum(int(seg_lens(seg).sum()) for seg in segments(raws))


def _seg_list(seg: Any) -> list[Any]:
    if isinstance(seg, np.ndarray):
        return seg.view(f"V{seg.shape[1]}").ravel().tolist() if seg.shape[1] else [b""] * len(seg)
    if isinstance(seg, RawRows):
        return seg.tolist()
    return seg if isinstance(seg, list) else list(seg)


def seg_lens(seg: Any) -> np.ndarray:
    if isinstance(seg, np.ndarray):
        return np.full(len(seg), seg.shape[1], np.int64)
    return row_lens(seg)


def fixed_width(seg: Any, lens: np.ndarray) -> np.ndarray | None:
    """``seg`` as a 2-D uint8 array when its messages all have one size, else None."""
    if isinstance(seg, np.ndarray):
        return seg
    if len(lens) and lens[0] == lens[-1] and not np.any(lens != lens[0]):
        return np.frombuffer(b"".join(seg), np.uint8).reshape(len(seg), int(lens[0]))
    return None


def cut_rows(segs: list[Any], seg_at: np.ndarray, a: int, b: int) -> list[Any]:
    """Rows ``a:b`` of the concatenation of ``segs`` as segments (``seg_at``: the first row of
    each segment, then the total)."""
    res = []
    first = int(np.searchsorted(seg_at, a, side="right")) - 1
    last = int(np.searchsorted(seg_at, b, side="left"))
    for i in range(max(first, 0), min(last, len(segs))):
        at = int(seg_at[i])
        lo, hi = max(a - at, 0), min(b - at, int(seg_at[i + 1]) - at)
        if lo < hi:
            res.append(segs[i][lo:hi])
    return res


def id_runs(cids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends of the runs of equal ids in ``cids`` (non-empty)."""
    if cids[0] == cids[-1] and not np.any(cids != cids[0]):
        return np.zeros(1, np.int64), np.array([len(cids)], np.int64)
    cuts = np.flatnonzero(cids[1:] != cids[:-1]) + 1
    return np.concatenate(([0], cuts)), np.concatenate((cuts, [len(cids)]))


def channel_groups(cids: np.ndarray) -> list[tuple[int, Any]]:
    """(id, rows: a slice or an index array) per id of ``cids`` (non-empty), ids in order of
    first appearance, rows in order: runs of equal ids as slices when there are few of them."""
    starts, ends = id_runs(cids)
    if len(starts) <= 16:
        return [(int(cids[a]), slice(a, b)) for a, b in zip(starts.tolist(), ends.tolist())]
    ids, first = np.unique(cids, return_index=True)
    order = np.argsort(cids, kind="stable")
    bounds = np.searchsorted(cids[order], ids)
    parts = np.split(order, bounds[1:])
    return [(int(ids[i]), parts[i]) for i in np.argsort(first).tolist()]


def id_counts(cids: np.ndarray) -> list[tuple[int, int]]:
    """(id, number of rows) of every id in ``cids`` (int64 >= 0), in increasing id order."""
    if not len(cids):
        return []
    if cids[0] == cids[-1] and not np.any(cids != cids[0]):
        return [(int(cids[0]), len(cids))]
    bc = np.bincount(cids)
    nz = np.flatnonzero(bc)
    return list(zip(nz.tolist(), bc[nz].tolist()))
