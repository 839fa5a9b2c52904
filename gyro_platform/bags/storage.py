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

* sqlite3 (:class:`BatchedSqlite3`): rosbags' schema, written through ``apsw`` (the SQLite
  binding rosbags reads with) with ``SQLITE_PAGE_SIZE`` pages, its timestamp index made at close
  (a killed run's ``.db3`` has none: readers sort); rows buffered and written with
  ``executemany`` in one transaction per commit (rollback journal, no cache spill: no page of an
  open transaction reaches the ``.db3`` before its commit; a failed commit is rolled back);
* MCAP (:class:`BatchedMcap`): rosbags' records byte for byte, the open chunk kept as a list of
  pieces, chunk and message index records built with numpy and written in one go when the chunk
  closes (1 MiB as rosbags); a failed write cuts the file back to the last complete chunk;
* both commit at least every ``COMMIT_ROWS`` messages, ``COMMIT_SECONDS`` of wall time or
  ``COMMIT_BYTES`` (sqlite3; MCAP: its chunk size) of message data, and
  every append is all-or-nothing even when a Ctrl-C lands inside it;
* YAML (``metadata.yaml``, QoS) through libyaml (:mod:`.yaml_dump`).

The classes are module-level mixins; :func:`storage_classes` and :func:`writer_class` put them
in front of rosbags' ``Sqlite3Writer``, ``McapWriter`` and ``Writer`` on first use (rosbags is
imported lazily: ~80 ms that ``--help`` does not pay). What of rosbags' internals they rely on,
and why, is listed in :mod:`gyro_platform.bags`.
"""
from __future__ import annotations

from functools import lru_cache
from io import BytesIO
import os
from pathlib import Path
import re
import sqlite3
import struct
import time
from typing import Any, Sequence

import apsw
import numpy as np

from .fast import mcap_records
from .rows import (as_bytes_list, channel_groups, cut_rows, fixed_width, id_counts, id_runs, payload_bytes, seg_lens,
                   segments)
from .yaml_dump import fast_yaml
from ..messages.blocks import RawRows, readonly, row_lens
from ..signals import deferred_signals

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


# ---- sqlite3 --------------------------------------------------------------------------------
class BatchedSqlite3:
    """The sqlite3 storage writer in front of rosbags' ``Sqlite3Writer`` (its ``SQLITE_SCHEMA``,
    ``add_msgtype``/``add_connection`` on ``self.cursor``), through ``apsw``; messages batched with
    ``executemany`` in transactions committed every ``COMMIT_ROWS`` rows / ``COMMIT_SECONDS`` s."""

    def __init__(self, path: Path, compression: Any) -> None:
        from rosbags.rosbag2 import CompressionMode, WriterError

        if compression == CompressionMode.STORAGE:
            raise WriterError("SQLITE3 writer does not support storage-side compression.")
        self.path = path / f"{path.name}.db3"
        # apsw: explicit transactions only; usable from the writer thread of
        # OutputBag.batched (one user at a time: a write is waited for before the next call)
        self.conn = apsw.Connection(str(self.path))
        self.conn.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")     # before the first table
        # rollback journal (a failed or killed transaction is undone; the .db3 alone holds
        # every committed row); no cache spill: nothing of an open transaction reaches the
        # .db3 before its commit; no fsync, from the schema on (SQLite's default syncs each
        # CREATE TABLE: 5-100 ms of a replay's start, waiting for the disk's pending writes)
        self.conn.execute("PRAGMA cache_spill=OFF")
        self.conn.execute("PRAGMA synchronous=OFF")
        # rosbags' schema; its timestamp index made at close, over all rows at once (an
        # index kept up to date row by row costs a quarter of the replay's sqlite3 time)
        self.index_sql = _INDEX_RE.search(self.SQLITE_SCHEMA).group(0)
        self.conn.execute(self.SQLITE_SCHEMA.replace(self.index_sql, ""))
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
        alone holds more (a failed transaction is rolled back; the ones before it stay). From
        the moment the rows leave the pending list until they are committed a Ctrl-C/SIGTERM
        waits (on the main thread; a writer thread gets no signals): one landing in between
        lost them (1300 of 20 000 rows, once in a CI run)."""
        with deferred_signals():
            self._commit()

    def _commit(self) -> None:
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
        cuts = sorted(bounds)
        for a, b in zip(cuts[:-1], cuts[1:]):
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
        starts, ends = id_runs(cids)
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


def _rollback(conn: Any) -> None:
    try:
        conn.execute("ROLLBACK")
    except SQLITE_ERRORS:
        pass


# ---- MCAP -----------------------------------------------------------------------------------
_MSG_HEADER = np.dtype([("op", "u1"), ("len", "<u8"), ("cid", "<u2"), ("seq", "<u4"), ("log", "<u8"),
                        ("pub", "<u8")])
assert _MSG_HEADER.itemsize == 31


class BatchedMcap:
    """The MCAP storage writer in front of rosbags' ``McapWriter`` (its header, schema, channel
    and summary records; its ``bio``, ``chunk``, ``chunks``, ``channel_stats`` and message times
    kept as it keeps them), byte for byte, with messages appended in batches; each chunk is
    flushed to the file when closed (1 MiB, or ``COMMIT_ROWS`` / ``COMMIT_SECONDS``)."""

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
        by_seg = [seg_lens(seg) for seg in segs]
        lens = (by_seg[0] if len(segs) == 1 else np.concatenate(by_seg)) + 31   # record: 1 + 8 + 22 + data
        n = len(lens)
        seg_at = np.cumsum([0] + [len(sl) for sl in by_seg])      # first row of each segment
        start = 0
        while start < n:
            base = self.chunk.bio.tell()
            ends = base + np.cumsum(lens[start:])
            # rosbags closes the chunk after the first message that takes it past 1 MiB
            over = int(np.searchsorted(ends, MCAP_CHUNK_BYTES, side="right"))
            stop = start + min(over + 1, n - start)
            part = segs if (start, stop) == (0, n) else cut_rows(segs, seg_at, start, stop)
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
            data = fixed_width(seg, lens[a:a + m] - 31)
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
        groups = channel_groups(cids)
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
        # the chunk index record's body (rosbags' write_uint64/write_uint32/write_string, packed)
        idx = BytesIO()
        idx.write(struct.pack("<QQQQI", self.chunk.message_start_time, self.chunk.message_end_time, chunk_start,
                              chunk_end - chunk_start, len(offsets) * 10))
        for cid, o in offsets:
            idx.write(struct.pack("<HQ", cid, o))
        idx.write(struct.pack("<QI", pos - chunk_end, len(comp)) + comp)
        idx.write(struct.pack("<QQ", len(compressed), len(data)))
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


# ---- the Writer and the classes on rosbags' ---------------------------------------------------
class BatchedWriter:
    """rosbags' ``Writer`` on the batched storages (see :func:`writer_class`), with ``write_rows``
    (counts kept right) and its YAML dumped by :func:`.yaml_dump.fast_yaml`."""

    def write(self, connection: Any, timestamp: int, data: Any) -> None:
        self.write_rows(np.array([connection.id]), np.array([timestamp], np.int64), [data])

    def add_connection(self, *args: Any, **kw: Any) -> Any:
        with fast_yaml():
            return super().add_connection(*args, **kw)

    def close(self) -> None:
        with fast_yaml():
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


@lru_cache(maxsize=None)
def storage_classes() -> tuple[type, type]:
    """(sqlite3, MCAP) storage writer classes: the batched mixins on rosbags' storage writers
    (made once, on first use: rosbags is imported here)."""
    from rosbags.rosbag2.storage_mcap import McapWriter
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

    class FastSqlite3(BatchedSqlite3, Sqlite3Writer):
        """:class:`BatchedSqlite3` on rosbags' ``Sqlite3Writer`` (its schema and connection records)."""

    class FastMcap(BatchedMcap, McapWriter):
        """:class:`BatchedMcap` on rosbags' ``McapWriter`` (its header, schema, channel and summary records)."""

    return FastSqlite3, FastMcap


@lru_cache(maxsize=None)
def writer_class() -> type:
    """rosbags' ``Writer`` with :class:`BatchedWriter` in front and the batched storages as its
    plugins (made once, on first use)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    sqlite_cls, mcap_cls = storage_classes()

    class FastWriter(BatchedWriter, Writer):
        """rosbags' ``Writer`` writing through :class:`BatchedSqlite3` / :class:`BatchedMcap`."""

        STORAGE_PLUGINS = {StoragePlugin.SQLITE3: sqlite_cls, StoragePlugin.MCAP: mcap_cls}

    return FastWriter
