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

"""rosbags' rosbag2 ``Writer`` with a batched, bounded, fault-aware message path (used by
:class:`gyro_platform.bags.writer.OutputBag`; the files are those rosbags writes).

* sqlite3 (:class:`FastSqlite3` in :func:`storage_classes`): rosbags' schema, written through
  ``apsw`` (the SQLite binding rosbags reads with) with ``SQLITE_PAGE_SIZE`` pages, its timestamp
  index made at close (a killed run's ``.db3`` has none: readers sort); rows buffered
  and written with ``executemany`` in one transaction per commit (rollback journal, no cache
  spill: no page of an open transaction reaches the ``.db3`` before its commit; a failed commit
  is rolled back);
* MCAP (``FastMcap``): rosbags' records byte for byte, the open chunk kept as a list of pieces,
  chunk and message index records built with numpy and written in one go when the chunk closes
  (1 MiB as rosbags); a failed write cuts the file back to the last complete chunk;
* both commit at least every ``COMMIT_ROWS`` messages, ``COMMIT_SECONDS`` of wall time or
  ``COMMIT_BYTES`` (sqlite3; MCAP: its chunk size) of message data, and
  every append is all-or-nothing even when a Ctrl-C lands inside it;
* YAML (``metadata.yaml``, QoS) through libyaml: the text ruamel writes for rosbags, up to
  line breaking, ~50x faster.
"""
from __future__ import annotations

from contextlib import contextmanager
from io import BytesIO
import os
from pathlib import Path
import re
import sqlite3
import struct
import time
from typing import Any, Iterator, Sequence

import apsw
import numpy as np

from .fast import mcap_records
from ..messages.blocks import RawRows, readonly, row_lens

#: commit bound: a chunk is committed after this many messages …
COMMIT_ROWS = 100_000
#: … or this much wall time (s) since the last commit, whichever comes first
COMMIT_SECONDS = 1.0
#: … or (sqlite3) this many bytes of message data pending: a kill or a full disk loses at most
#: this much of the newest data (the MCAP bound is its chunk size)
COMMIT_BYTES = 2 ** 19
#: MCAP chunk size at which rosbags' writer (and this one) closes a chunk (bytes)
MCAP_CHUNK_BYTES = 2 ** 20
#: page size of the output ``.db3`` (bytes; SQLite's default is 4096; any reader reads any size):
#: 288k replay rows of 194 bytes insert in 0.43 s with the standard ``sqlite3`` module and 4 KiB
#: pages, 0.23 s with apsw and 16 KiB (0.21 s with 64 KiB, but then the empty schema alone takes
#: 384 KiB of a small disk)
SQLITE_PAGE_SIZE = 16384
#: rows per sqlite3 INSERT statement (one multi-row ``VALUES`` list: ~2x fewer µs per row
#: than one statement per row; the same rows in the same order)
SQLITE_ROWS_PER_INSERT = 128

#: rosbags' ``CREATE INDEX`` statement in its sqlite3 schema (made at close, see FastSqlite3)
_INDEX_RE = re.compile(r"CREATE INDEX [^;]*;")
#: what SQLite raises, through either binding (the standard module, apsw)
SQLITE_ERRORS = (sqlite3.Error, apsw.Error)


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
    return sum(int(_seg_lens(seg).sum()) for seg in segments(raws))


def _seg_list(seg: Any) -> list[Any]:
    if isinstance(seg, np.ndarray):
        return seg.view(f"V{seg.shape[1]}").ravel().tolist() if seg.shape[1] else [b""] * len(seg)
    if isinstance(seg, RawRows):
        return seg.tolist()
    return seg if isinstance(seg, list) else list(seg)


def _seg_lens(seg: Any) -> np.ndarray:
    if isinstance(seg, np.ndarray):
        return np.full(len(seg), seg.shape[1], np.int64)
    return row_lens(seg)


def _fixed(seg: Any, lens: np.ndarray) -> np.ndarray | None:
    """``seg`` as a 2-D uint8 array when its messages all have one size, else None."""
    if isinstance(seg, np.ndarray):
        return seg
    if len(lens) and lens[0] == lens[-1] and not np.any(lens != lens[0]):
        return np.frombuffer(b"".join(seg), np.uint8).reshape(len(seg), int(lens[0]))
    return None


def _cut(segs: list[Any], seg_at: np.ndarray, a: int, b: int) -> list[Any]:
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


def _runs(cids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends of the runs of equal ids in ``cids`` (non-empty)."""
    if cids[0] == cids[-1] and not np.any(cids != cids[0]):
        return np.zeros(1, np.int64), np.array([len(cids)], np.int64)
    cuts = np.flatnonzero(cids[1:] != cids[:-1]) + 1
    return np.concatenate(([0], cuts)), np.concatenate((cuts, [len(cids)]))


def _channel_groups(cids: np.ndarray) -> list[tuple[int, Any]]:
    """(id, rows: a slice or an index array) per id of ``cids`` (non-empty), ids in order of
    first appearance, rows in order: runs of equal ids as slices when there are few of them."""
    starts, ends = _runs(cids)
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


def insert_rows(cursor: Any, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
    """``INSERT INTO messages`` of the rows in order, ``SQLITE_ROWS_PER_INSERT`` per statement."""
    n, r = len(raws), SQLITE_ROWS_PER_INSERT
    flat: list[Any] = [None] * (3 * n)
    flat[0::3] = cids.tolist()
    flat[1::3] = ts.tolist()
    flat[2::3] = raws
    m = n - n % r
    if m:
        many = "INSERT INTO messages (topic_id, timestamp, data) VALUES " + ",".join(["(?, ?, ?)"] * r)
        cursor.executemany(many, (flat[3 * a:3 * (a + r)] for a in range(0, m, r)))
    if n > m:
        cursor.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)",
                           (flat[3 * a:3 * a + 3] for a in range(m, n)))

# ---- storage writers: rosbags' with a batched, bounded, fault-aware message path -------------


def storage_classes():
    from rosbags.rosbag2.storage_mcap import McapWriter
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

    class FastSqlite3(Sqlite3Writer):
        """rosbags' sqlite3 storage (its schema) through ``apsw``; messages batched with
        ``executemany`` in transactions committed every ``COMMIT_ROWS`` rows / ``COMMIT_SECONDS`` s."""

        def __init__(self, path: Path, compression: Any) -> None:
            from rosbags.rosbag2.writer import CompressionMode, WriterError

            if compression == CompressionMode.STORAGE:
                raise WriterError("SQLITE3 writer does not support storage-side compression.")
            self.path = path / f"{path.name}.db3"
            # apsw: explicit transactions only; usable from the writer thread of
            # OutputBag.batched (one user at a time: a write is waited for before the next call)
            self.conn = apsw.Connection(str(self.path))
            self.conn.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")     # before the first table
            # rosbags' schema; its timestamp index made at close, over all rows at once (an
            # index kept up to date row by row costs a quarter of the replay's sqlite3 time)
            self.index_sql = _INDEX_RE.search(self.SQLITE_SCHEMA).group(0)
            self.conn.execute(self.SQLITE_SCHEMA.replace(self.index_sql, ""))
            # rollback journal (a failed or killed transaction is undone; the .db3 alone holds
            # every committed row); no cache spill: nothing of an open transaction reaches the
            # .db3 before its commit
            self.conn.execute("PRAGMA cache_spill=OFF")
            self.conn.execute("PRAGMA synchronous=OFF")
            self.cursor = self.conn.cursor()
            self.pending: list[tuple[np.ndarray, np.ndarray, Sequence[Any]]] = []
            self.n_pending = 0
            self.bytes_pending = 0
            self.last_commit = time.monotonic()
            self.committed: dict[int, list[int]] = {}   # cid -> [count, first ts, last ts]
            self.dirty = False

        def write(self, connection: Any, timestamp: int, data: Any) -> None:
            self.write_rows(np.array([connection.id]), np.array([timestamp], np.int64), [data])

        def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
            self.pending.append((cids, ts, raws))
            self.n_pending += len(raws)
            self.bytes_pending += payload_bytes(raws)
            if (self.n_pending >= COMMIT_ROWS or self.bytes_pending >= COMMIT_BYTES
                    or time.monotonic() - self.last_commit >= COMMIT_SECONDS):
                self.commit()

        def commit(self) -> None:
            """Write the pending rows in transactions of at most ``COMMIT_BYTES`` of data each,
            cut between write calls (a call's rows all in or all out), inside a call only when it
            alone holds more (a failed transaction is rolled back; the ones before it stay)."""
            parts, self.pending, self.n_pending, self.bytes_pending = self.pending, [], 0, 0
            self.last_commit = time.monotonic()
            if not parts:
                return
            cids = np.concatenate([p[0] for p in parts])
            ts = np.concatenate([p[1] for p in parts])
            raws = [r for p in parts for r in as_bytes_list(p[2])]
            lens = row_lens(raws)
            bounds, acc, row = {0, len(raws)}, 0, 0
            for p in parts:
                k = len(p[1])
                size = int(lens[row:row + k].sum())
                if acc and acc + size > COMMIT_BYTES:
                    bounds.add(row)
                    acc = 0
                if size > COMMIT_BYTES:             # one call larger than a transaction: cut inside
                    ends = np.cumsum(lens[row:row + k])
                    cuts = np.searchsorted(ends, np.arange(COMMIT_BYTES, int(ends[-1]), COMMIT_BYTES), side="right")
                    bounds.update(row + int(c) for c in cuts.tolist() if 0 < c < k)
                    bounds.add(row + k)
                    acc = 0
                else:
                    acc += size
                row += k
            bounds = sorted(bounds)
            for a, b in zip(bounds[:-1], bounds[1:]):
                self._transaction(cids[a:b], ts[a:b], raws[a:b])

        def _transaction(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
            self.dirty = True        # stays set if anything below is cut short (error, Ctrl-C)
            try:
                self.cursor.execute("BEGIN")
                insert_rows(self.cursor, cids, ts, raws)
                self.cursor.execute("COMMIT")
            except BaseException:
                if self.conn.in_transaction:
                    _rollback(self.conn)
                raise
            starts, ends = _runs(cids)
            for a, b in zip(starts.tolist(), ends.tolist()):
                sel = ts[a:b]
                cur = self.committed.setdefault(int(cids[a]), [0, 2 ** 63 - 1, 0])
                cur[0] += b - a
                cur[1], cur[2] = min(cur[1], int(sel.min())), max(cur[2], int(sel.max()))
            self.dirty = False

        def settle(self) -> None:
            """Commit what is pending (before the counts are taken for the metadata)."""
            self.commit()

        def stored(self) -> tuple[dict[int, int], int, int]:
            """(count by connection id, first, last record time ns) of the rows the file holds:
            counted as committed, or asked from the file after a commit was cut short."""
            if self.dirty:
                rows = self.conn.execute("SELECT topic_id, count(*), min(timestamp), max(timestamp) "
                                         "FROM messages GROUP BY topic_id").fetchall()
                self.committed = {r[0]: list(r[1:]) for r in rows}
                self.dirty = False
            live = [v for v in self.committed.values() if v[0]]
            return ({c: v[0] for c, v in self.committed.items()}, min((v[1] for v in live), default=2 ** 63 - 1),
                    max((v[2] for v in live), default=0))

        def close(self, version: int, metadata: str) -> None:
            self.commit()
            try:
                self.conn.execute(self.index_sql)
            except SQLITE_ERRORS:       # disk full: readers sort without it (ros2 bag reindex adds it)
                pass
            try:
                self.cursor.execute("INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)",
                                    (version, metadata))
            except SQLITE_ERRORS:       # disk full: the metadata row is optional (metadata.yaml is not)
                pass
            self.conn.close()      # (no PRAGMA optimize: its ANALYZE costs ~1 µs per row, readers need none)

        def drop_pending(self) -> None:
            self.pending, self.n_pending = [], 0

        def abort(self) -> None:
            self.drop_pending()
            try:
                _rollback(self.conn)
            finally:
                self.conn.close()

    class FastMcap(McapWriter):
        """rosbags' MCAP storage, byte for byte, with messages appended in batches; each chunk
        is flushed to the file when closed (1 MiB, or ``COMMIT_ROWS`` / ``COMMIT_SECONDS``)."""

        def __init__(self, path: Path, compression: Any) -> None:
            super().__init__(path, compression)
            self.bio.flush()
            self.bio = _WholeWrites(self.bio.detach())   # unbuffered: a failed write is seen at once
            self.chunk.bio = _Pieces()
            self._index: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
            self._rows = 0
            self._opened = time.monotonic()
            self._snaps = [self._snapshot()]    # state after each complete chunk (the first: none)

        def _snapshot(self) -> tuple:
            return (self.bio.tell(), len(self.chunks), dict(self.channel_stats), self.message_start_time,
                    self.message_end_time)

        def write(self, connection: Any, timestamp: int, data: Any) -> None:
            self.write_rows(np.array([connection.id]), np.array([timestamp], np.int64), [data])

        def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Any) -> None:
            """Rows (payloads: a sequence of bytes or a :class:`Rows`) appended to the open
            chunk, which is closed where rosbags closes it (after the message that takes it
            past 1 MiB)."""
            segs = segments(raws)
            seg_lens = [_seg_lens(seg) for seg in segs]
            lens = (seg_lens[0] if len(segs) == 1 else np.concatenate(seg_lens)) + 31   # record: 1 + 8 + 22 + data
            n = len(lens)
            seg_at = np.cumsum([0] + [len(sl) for sl in seg_lens])      # first row of each segment
            start = 0
            while start < n:
                base = self.chunk.bio.tell()
                ends = base + np.cumsum(lens[start:])
                # rosbags closes the chunk after the first message that takes it past 1 MiB
                over = int(np.searchsorted(ends, MCAP_CHUNK_BYTES, side="right"))
                stop = start + min(over + 1, n - start)
                part = segs if (start, stop) == (0, n) else _cut(segs, seg_at, start, stop)
                self._append(cids[start:stop], ts[start:stop], part, lens[start:stop], base)
                start = stop
                if self.chunk.bio.tell() > MCAP_CHUNK_BYTES:
                    self.close_chunk()
            if self._rows >= COMMIT_ROWS or (self._rows and time.monotonic() - self._opened >= COMMIT_SECONDS):
                self.close_chunk()

        def _append(self, cids: np.ndarray, ts: np.ndarray, segs: list[Any], lens: np.ndarray,
                    base: int) -> None:
            k = len(lens)
            hdr = np.zeros(k, dtype=_MSG_HEADER)
            hdr["op"] = 0x05
            hdr["len"] = lens - 9
            hdr["cid"] = cids
            hdr["log"] = ts
            hdr["pub"] = ts
            parts: list[Any] = []
            a = 0
            for seg in segs:
                m = len(seg)
                if isinstance(seg, RawRows):     # one piece, built from the buffer the payloads lie in
                    parts.append(mcap_records(hdr[a:a + m].view(np.uint8).reshape(m, 31), readonly(seg.buf), seg.beg,
                                              seg.end))
                    a += m
                    continue
                data = _fixed(seg, lens[a:a + m] - 31)
                if data is not None:     # one piece: records of one size as rows of one array
                    rec = np.empty((m, 31 + data.shape[1]), np.uint8)
                    rec[:, :31] = hdr[a:a + m].view(np.uint8).reshape(m, 31)
                    rec[:, 31:] = data
                    parts.append(rec)
                else:
                    pieces: list[Any] = [None] * (2 * m)
                    pieces[0::2] = hdr[a:a + m].view("V31").tolist()
                    pieces[1::2] = seg
                    parts += pieces
                a += m
            offsets = base + np.concatenate(([0], np.cumsum(lens[:-1])))
            groups = _channel_groups(cids)
            lo, hi = int(ts.min()), int(ts.max())
            buf = self.chunk.bio
            saved = (dict(self.channel_stats), {c: len(v) for c, v in self._index.items()},
                     self.message_start_time, self.message_end_time, self.chunk.message_start_time,
                     self.chunk.message_end_time, self._rows, buf.mark())
            try:                 # all or nothing, even when a Ctrl-C lands in between
                buf.extend(parts, int(lens.sum()))
                # per channel in order of first appearance (as rosbags' dict), rows in order
                for c, rows in groups:
                    t_c = ts[rows]
                    self._index.setdefault(c, []).append((t_c, offsets[rows]))
                    self.channel_stats[c] += len(t_c)
                self.message_start_time = min(lo, self.message_start_time)
                self.message_end_time = max(hi, self.message_end_time)
                self.chunk.message_start_time = min(lo, self.chunk.message_start_time)
                self.chunk.message_end_time = max(hi, self.chunk.message_end_time)
                self._rows += k
            except BaseException:
                stats, lens_, *times, self._rows, mark = saved
                self.channel_stats = stats
                (self.message_start_time, self.message_end_time, self.chunk.message_start_time,
                 self.chunk.message_end_time) = times
                self._index = {c: v[:lens_[c]] for c, v in self._index.items() if c in lens_}
                buf.reset(mark)
                raise

        def close_chunk(self) -> None:
            """rosbags' chunk, message index and chunk index records (vectorised), written to
            the file in one go (chunk CRC 0 and no compression, as rosbags and rosbag2 write)."""
            from rosbags.rosbag2.storage_mcap import write_string, write_uint32, write_uint64

            if not self.chunk.bio.tell():
                return
            data = self.chunk.bio.getvalue()
            compressed = self.compressor(data)
            comp = self.compression.encode()
            head = struct.pack("<BQQQQI", 0x06, 8 + 8 + 8 + 4 + 4 + len(comp) + 8 + len(compressed),
                               self.chunk.message_start_time, self.chunk.message_end_time, len(data), 0)
            head += struct.pack("<I", len(comp)) + comp + struct.pack("<Q", len(compressed))
            chunk_start = self.bio.tell()
            chunk_end = chunk_start + len(head) + len(compressed)
            out = []
            offsets: list[tuple[int, int]] = []
            pos = chunk_end
            for cid, parts in self._index.items():
                offsets.append((cid, pos))
                ts = np.concatenate([p[0] for p in parts])
                off = np.concatenate([p[1] for p in parts])
                pairs = np.empty((len(ts), 2), "<u8")
                pairs[:, 0], pairs[:, 1] = ts, off
                rec = struct.pack("<BQHI", 0x07, 6 + 16 * len(ts), cid, 16 * len(ts)) + pairs.tobytes()
                out.append(rec)
                pos += len(rec)
            idx = BytesIO()
            write_uint64(idx, self.chunk.message_start_time)
            write_uint64(idx, self.chunk.message_end_time)
            write_uint64(idx, chunk_start)
            write_uint64(idx, chunk_end - chunk_start)
            write_uint32(idx, len(offsets) * 10)
            for cid, o in offsets:
                idx.write(struct.pack("<HQ", cid, o))
            write_uint64(idx, pos - chunk_end)
            write_string(idx, self.compression)
            write_uint64(idx, len(compressed))
            write_uint64(idx, len(data))
            saved = (self.chunk, self._index, self._rows, self._opened, len(self.chunks), len(self._snaps))
            try:                 # all or nothing, even when a Ctrl-C lands in between
                self.bio.write(head)
                self.bio.write(compressed)
                self.bio.write(b"".join(out))
                self.chunks.append(idx)
                self._new_chunk()
                self._snaps.append(self._snapshot())
            except BaseException:
                self.chunk, self._index, self._rows, self._opened, nc, ns = saved
                del self.chunks[nc:], self._snaps[ns:]
                self.bio.seek(chunk_start)
                self.bio.truncate()
                raise

        def settle(self) -> None:
            pass

        def stored(self) -> tuple[dict[int, int], int, int]:
            return dict(self.channel_stats), self.message_start_time, self.message_end_time

        def close(self, version: int, metadata: str) -> None:
            super().close(version, metadata)     # its bio.close() only flushes: kept open on failure
            self.bio.raw.close()

        def abort(self) -> None:
            self.bio.raw.close()

        def _new_chunk(self) -> None:
            from rosbags.rosbag2.storage_mcap import PendingChunk

            self.chunk = PendingChunk(2 ** 63 - 1, 0, _Pieces(), {})
            self._index = {}
            self._rows = 0
            self._opened = time.monotonic()

        def drop_pending(self) -> None:
            """After a failed write: forget the open chunk and cut the file back to the end of
            the last complete chunk (its counts restored), ready for the summary."""
            pos, nchunks, stats, lo, hi = self._snaps[-1]
            self._new_chunk()
            del self.chunks[nchunks:]
            self.channel_stats = dict(stats)
            self.message_start_time, self.message_end_time = lo, hi
            self.bio.seek(pos)
            self.bio.truncate()

        def drop_last_chunk(self) -> bool:
            """Free room for the summary by cutting the last complete chunk; False if none."""
            if len(self._snaps) < 2:
                return False
            self._snaps.pop()
            self.drop_pending()
            return True

    return FastSqlite3, FastMcap


class _Pieces:
    """The open MCAP chunk as a list of byte strings (joined once when the chunk is written):
    ``write``/``tell`` for rosbags' record writers, ``extend`` for batches."""

    def __init__(self) -> None:
        self.parts: list[Any] = []
        self.size = 0

    def write(self, data: Any) -> int:
        data = bytes(data)
        self.parts.append(data)
        self.size += len(data)
        return len(data)

    def extend(self, parts: list[Any], size: int) -> None:
        self.parts += parts
        self.size += size

    def tell(self) -> int:
        return self.size

    def getvalue(self) -> bytes:
        return b"".join(self.parts)

    def mark(self) -> tuple[int, int]:
        return len(self.parts), self.size

    def reset(self, mark: tuple[int, int]) -> None:
        del self.parts[mark[0]:]
        self.size = mark[1]


class _WholeWrites:
    """An unbuffered file whose ``write`` writes everything or raises OSError (a short write,
    e.g. at RLIMIT_FSIZE, is retried so the error surfaces); ``close`` is left to the owner."""

    def __init__(self, raw: Any):
        self.raw = raw

    def write(self, data: Any) -> int:
        mv = memoryview(data).cast("B")
        n = len(mv)
        while mv:
            k = self.raw.write(mv)
            if not k:
                raise OSError(28, os.strerror(28))
            mv = mv[k:]
        return n

    def tell(self) -> int:
        return self.raw.tell()

    def seek(self, pos: int) -> int:
        return self.raw.seek(pos)

    def truncate(self) -> int:
        return self.raw.truncate()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


_MSG_HEADER = np.dtype([("op", "u1"), ("len", "<u8"), ("cid", "<u2"), ("seq", "<u4"), ("log", "<u8"),
                        ("pub", "<u8")])
assert _MSG_HEADER.itemsize == 31


def _rollback(conn: Any) -> None:
    try:
        conn.execute("ROLLBACK")
    except SQLITE_ERRORS:
        pass


_PLAIN = re.compile(r"[A-Za-z_/][A-Za-z0-9_/.\-]*")
#: words PyYAML would read back as booleans or null (YAML 1.1): quoted, so not on the fast path
_RESERVED = {w for v in ("yes", "no", "true", "false", "on", "off", "null") for w in (v, v.title(), v.upper())}


def _scalar(v: Any) -> str | None:
    """The plain text PyYAML writes for ``v``, or None where it would quote, fold or format it."""
    if v is None:
        return "null"
    if v is True or v is False:
        return "true" if v else "false"
    if type(v) is int:
        return str(v)
    if type(v) is str:
        if v == "":
            return "''"
        if _PLAIN.fullmatch(v) and v not in _RESERVED:
            return v
    return None


def block_yaml(data: dict) -> str | None:
    """``yaml.dump(data, CSafeDumper, default_flow_style=False, sort_keys=True)`` for a bag's
    metadata made of mappings, lists of scalars or mappings, ints, booleans, None and plain
    names (tested equal); None for anything else (the caller dumps with PyYAML). PyYAML's
    representer walks every node in Python (~12 ms for the metadata of 15 topics)."""
    out: list[str] = []

    def mapping(d: dict, ind: int, first: str | None) -> bool:
        for n, k in enumerate(sorted(d)):
            key = _scalar(k) if type(k) is str else None
            if key is None:
                return False
            head = first if n == 0 and first is not None else " " * ind
            if not value(head + key + ":", d[k], ind):
                return False
        return True

    def value(head: str, v: Any, ind: int) -> bool:
        if isinstance(v, dict) and v:
            out.append(head)
            return mapping(v, ind + 2, None)
        if isinstance(v, list) and v:
            out.append(head)
            for item in v:
                if isinstance(item, dict) and item:
                    if not mapping(item, ind + 2, " " * ind + "- "):
                        return False
                else:
                    text = _scalar(item) if not isinstance(item, (dict, list)) else ("{}" if item == {} else None)
                    if text is None:
                        return False
                    out.append(" " * ind + "- " + text)
            return True
        text = "{}" if v == {} and isinstance(v, dict) else "[]" if v == [] and isinstance(v, list) else _scalar(v)
        if text is None:
            return False
        out.append(head + " " + text)
        return True

    if not isinstance(data, dict) or not data or not mapping(data, 0, None):
        return None
    return "\n".join(out) + "\n"


class _LibYaml:
    """Stand-in for ruamel's ``YAML(typ='safe')`` inside rosbags' writer: the same text
    (sorted keys, block style; tested equal) from libyaml, ~50x faster (ruamel takes ~0.3 s to
    dump the metadata of a bag with 16 topics). Texts of small values (a connection's QoS
    profiles, the same for every output topic) are kept: each dump walks PyYAML's Python
    representer (~0.5 ms)."""

    _memo: dict[str, str] = {}
    MEMO_KEY_CHARS = 2000       # values whose repr is longer (the bag's metadata) are not kept

    def __init__(self, typ: str = "safe"):
        self.default_flow_style = False

    def dump(self, data: Any, stream: Any) -> None:
        import yaml

        text = block_yaml(data) if isinstance(data, dict) and not self.default_flow_style else None
        if text is None:
            key = repr(data) + repr(self.default_flow_style)
            small = len(key) <= self.MEMO_KEY_CHARS
            text = self._memo.get(key) if small else None
            if text is None:
                dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
                text = yaml.dump(data, Dumper=dumper, default_flow_style=self.default_flow_style, sort_keys=True)
                if small and len(self._memo) < 256:
                    self._memo[key] = text
        stream.write(text)


@contextmanager
def _fast_yaml() -> Iterator[None]:
    """rosbags' writer module dumping YAML with :class:`_LibYaml` for the block's duration."""
    import rosbags.rosbag2.writer as mod

    old, mod.YAML = mod.YAML, _LibYaml
    try:
        yield
    finally:
        mod.YAML = old


_WRITER_CLS = None


def writer_class():
    """rosbags' ``Writer`` on the batched storages, with ``write_rows`` (counts kept right)."""
    global _WRITER_CLS
    if _WRITER_CLS is None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        sqlite_cls, mcap_cls = storage_classes()

        class FastWriter(Writer):
            STORAGE_PLUGINS = {StoragePlugin.SQLITE3: sqlite_cls, StoragePlugin.MCAP: mcap_cls}

            def write(self, connection: Any, timestamp: int, data: Any) -> None:
                self.write_rows(np.array([connection.id]), np.array([timestamp], np.int64), [data])

            def add_connection(self, *args: Any, **kw: Any) -> Any:
                with _fast_yaml():
                    return super().add_connection(*args, **kw)

            def close(self) -> None:
                with _fast_yaml():
                    super().close()

            def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Any) -> None:
                """Rows on connection ids ``cids`` (int64) at record times ``ts`` (int64 ns);
                payloads a sequence of bytes or a :class:`Rows`."""
                if not len(raws):
                    return
                self.storage.write_rows(cids, ts, raws)
                for cid, cnt in id_counts(cids):
                    self.counts[cid] += cnt
                self.min_timestamp = min(int(ts.min()), self.min_timestamp)
                self.max_timestamp = max(int(ts.max()), self.max_timestamp)

            def counts_from_storage(self) -> None:
                """Counts and first/last record times of what the file holds (the metadata's)."""
                counts, self.min_timestamp, self.max_timestamp = self.storage.stored()
                self.counts = {c.id: counts.get(c.id, 0) for c in self.connections}

        _WRITER_CLS = FastWriter
    return _WRITER_CLS
