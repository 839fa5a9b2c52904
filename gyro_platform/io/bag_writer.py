"""The output rosbag2 bag (version 9, sqlite3 or mcap): input connections copied byte for
byte plus the simulator's output topics, offered with the rclpy default QoS.

rosbags' ``Writer`` makes the connections, the sqlite3 schema (rosbag2 Jazzy, schema version 4:
``schema``, ``metadata``, ``topics``, ``message_definitions``, ``messages``), the MCAP schemas
and channels (profile ``ros2``, encodings ``ros2msg``/``ros2idl``, channel metadata
``offered_qos_profiles``) and ``metadata.yaml``; only the per-message write is replaced by a
batched one (:meth:`OutputBag.write_many`, :meth:`OutputBag.copy_chunk`) whose files are
those rosbags writes (tested field by field; MCAP byte for byte).

What survives a fault (issue 17):

* the output is committed in bounded chunks: sqlite3 transactions (rollback journal) and MCAP
  chunks are written to the file at least every
  ``COMMIT_ROWS`` messages or ``COMMIT_SECONDS`` of wall time (MCAP also every 1 MiB chunk), so
  a SIGKILL or power cut loses at most the last chunk; the readable part has no
  ``metadata.yaml`` and is read by ``InputBag``'s salvage;
* ``close()`` defers SIGINT/SIGTERM until the index and ``metadata.yaml`` are written (a second
  Ctrl-C is taken after it);
* a full disk (``ENOSPC``, ``EFBIG``, sqlite3 "database or disk is full") while writing or
  closing: the bag is cut back to the last complete chunk, closed with index and metadata
  counting what it holds, and :class:`~gyro_platform.errors.OutputWriteError` names the file
  and the error. :func:`check_writable` checks output paths before a run starts.
"""
from __future__ import annotations

import atexit
import os
import signal
import sqlite3
import struct
import sys
import tempfile
import threading
import time
from contextlib import contextmanager
from io import BytesIO
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np

from ..errors import OutputWriteError
from . import messages as msgs
from .bag_paths import rosbags_api

#: commit bound: a chunk is committed after this many messages …
COMMIT_ROWS = 100_000
#: … or this much wall time (s) since the last commit, whichever comes first
COMMIT_SECONDS = 1.0
#: MCAP chunk size at which rosbags' writer (and this one) closes a chunk (bytes)
MCAP_CHUNK_BYTES = 2 ** 20


def default_qos() -> list:
    """QoS offered by the output publishers: reliable, volatile, keep last 10 (rclpy default)."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                    QosTime)

    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]


# ---- path checks ---------------------------------------------------------------------------
def check_writable(files: Iterable[str | Path] = (), new_dirs: Iterable[str | Path] = ()) -> None:
    """Check before a run that outputs can be created: ``files`` (written or replaced, e.g. a
    summary) must not be directories; ``new_dirs`` (e.g. an output bag) must not exist; the
    nearest existing ancestor of each must be a directory in which a file can be created
    (probed, so read-only file systems and permissions are caught whoever runs).
    Raises :class:`OutputWriteError` naming the path and the reason."""
    for p in map(Path, files):
        if p.is_dir():
            raise OutputWriteError(f"{p}: is a directory; cannot write the file there")
        if p.exists() and not os.access(p, os.W_OK):
            raise OutputWriteError(f"{p}: exists and is not writable")
        _check_parent(p)
    for p in map(Path, new_dirs):
        if p.exists():
            raise OutputWriteError(f"{p}: exists already (nothing is overwritten)")
        _check_parent(p)


def _check_parent(p: Path) -> None:
    anc = p.absolute().parent
    while not anc.exists():
        anc = anc.parent
    if not anc.is_dir():
        raise OutputWriteError(f"{p}: {anc} is a file, not a directory")
    try:
        fd, probe = tempfile.mkstemp(prefix=".gyro_platform_probe_", dir=anc)
    except OSError as e:
        raise OutputWriteError(f"{p}: cannot create files in {anc}: {_err(e)}") from None
    os.close(fd)
    os.unlink(probe)


def _err(e: BaseException) -> str:
    """One-line text of an OSError / sqlite3 error (``[Errno 28] No space left on device``)."""
    if isinstance(e, OSError) and e.errno is not None:
        return f"[Errno {e.errno}] {e.strerror or os.strerror(e.errno)}"
    return f"{type(e).__name__}: {e}"


#: what a full disk or an unwritable file looks like from the storage writers
WRITE_ERRORS = (OSError, sqlite3.Error)


@contextmanager
def signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM held back while the block runs, then handed to the handlers that
    were in place (a Ctrl-C raises KeyboardInterrupt after the block; a SIGTERM with the
    default action then ends the process). Only the main thread can do this; elsewhere the
    block just runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        got.append(signum)

    old = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for s in dict.fromkeys(got):
            h = old[s]
            if callable(h):
                h(s, None)
            elif h == signal.SIG_DFL:
                os.kill(os.getpid(), s)


# ---- storage writers: rosbags' with a batched, bounded, fault-aware message path -------------
def _storage_classes():
    from rosbags.rosbag2.storage_mcap import McapWriter
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

    class FastSqlite3(Sqlite3Writer):
        """rosbags' sqlite3 storage; messages batched with ``executemany`` in transactions
        committed every ``COMMIT_ROWS`` rows / ``COMMIT_SECONDS`` s."""

        def __init__(self, path: Path, compression: Any) -> None:
            super().__init__(path, compression)
            self.conn.commit()
            self.conn.isolation_level = None          # explicit transactions only
            # rollback journal (a failed or killed transaction is undone; the .db3 alone holds
            # every committed row); no cache spill: nothing of an open transaction reaches the
            # .db3 before its commit
            self.conn.execute("PRAGMA cache_spill=OFF")
            self.conn.execute("PRAGMA synchronous=NORMAL")
            self.cursor = self.conn.cursor()
            self.pending: list[tuple[np.ndarray, np.ndarray, Sequence[Any]]] = []
            self.n_pending = 0
            self.last_commit = time.monotonic()
            self.committed: dict[int, list[int]] = {}   # cid -> [count, first ts, last ts]
            self.dirty = False

        def write(self, connection: Any, timestamp: int, data: Any) -> None:
            self.write_rows(np.array([connection.id]), np.array([timestamp], np.int64), [data])

        def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
            self.pending.append((cids, ts, raws))
            self.n_pending += len(raws)
            if self.n_pending >= COMMIT_ROWS or time.monotonic() - self.last_commit >= COMMIT_SECONDS:
                self.commit()

        def commit(self) -> None:
            """Write the pending rows in one transaction (rolled back on failure)."""
            parts, self.pending, self.n_pending = self.pending, [], 0
            self.last_commit = time.monotonic()
            if not parts:
                return
            cids = np.concatenate([p[0] for p in parts])
            ts = np.concatenate([p[1] for p in parts])
            raws = [r for p in parts for r in p[2]] if len(parts) > 1 else parts[0][2]
            self.dirty = True        # stays set if anything below is cut short (error, Ctrl-C)
            try:
                self.cursor.execute("BEGIN")
                self.cursor.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)",
                                        zip(cids.tolist(), ts.tolist(), raws))
                self.cursor.execute("COMMIT")
            except BaseException:
                if self.conn.in_transaction:
                    _rollback(self.conn)
                raise
            for cid in np.unique(cids).tolist():
                sel = ts[cids == cid]
                cur = self.committed.setdefault(cid, [0, 2 ** 63 - 1, 0])
                cur[0] += len(sel)
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
                self.cursor.execute("INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)",
                                    (version, metadata))
            except sqlite3.Error:       # disk full: the metadata row is optional (metadata.yaml is not)
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

        def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
            n = len(raws)
            start = 0
            lens = np.fromiter(map(len, raws), np.int64, n) + 31       # record: 1 + 8 + 22 + data
            while start < n:
                base = self.chunk.bio.tell()
                ends = base + np.cumsum(lens[start:])
                # rosbags closes the chunk after the first message that takes it past 1 MiB
                over = int(np.searchsorted(ends, MCAP_CHUNK_BYTES, side="right"))
                stop = start + min(over + 1, n - start)
                self._append(cids[start:stop], ts[start:stop], raws[start:stop], lens[start:stop], base)
                start = stop
                if self.chunk.bio.tell() > MCAP_CHUNK_BYTES:
                    self.close_chunk()
            if self._rows >= COMMIT_ROWS or (self._rows and time.monotonic() - self._opened >= COMMIT_SECONDS):
                self.close_chunk()

        def _append(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any], lens: np.ndarray,
                    base: int) -> None:
            k = len(raws)
            hdr = np.zeros(k, dtype=_MSG_HEADER)
            hdr["op"] = 0x05
            hdr["len"] = lens - 9
            hdr["cid"] = cids
            hdr["log"] = ts
            hdr["pub"] = ts
            parts: list[Any] = [None] * (2 * k)
            parts[0::2] = hdr.view("V31").tolist()
            parts[1::2] = raws
            offsets = base + np.concatenate(([0], np.cumsum(lens[:-1])))
            if np.all(cids == cids[0]):
                groups = [(int(cids[0]), ts, offsets)]
            else:                # per channel, in order of first appearance (as rosbags' dict)
                _, first = np.unique(cids, return_index=True)
                groups = [(c, ts[cids == c], offsets[cids == c]) for c in cids[np.sort(first)].tolist()]
            ucid, cnt = np.unique(cids, return_counts=True)
            lo, hi = int(ts.min()), int(ts.max())
            buf = self.chunk.bio
            saved = (dict(self.channel_stats), {c: len(v) for c, v in self._index.items()},
                     self.message_start_time, self.message_end_time, self.chunk.message_start_time,
                     self.chunk.message_end_time, self._rows, buf.mark())
            try:                 # all or nothing, even when a Ctrl-C lands in between
                buf.extend(parts, int(lens.sum()))
                for c, t, o in groups:
                    self._index.setdefault(c, []).append((t, o))
                for c, n in zip(ucid.tolist(), cnt.tolist()):
                    self.channel_stats[c] += n
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


def _rollback(conn: sqlite3.Connection) -> None:
    try:
        conn.execute("ROLLBACK")
    except sqlite3.Error:
        pass


class _LibYaml:
    """Stand-in for ruamel's ``YAML(typ='safe')`` inside rosbags' writer: the same text
    (sorted keys, block style; tested equal) from libyaml, ~50x faster (ruamel takes ~0.3 s to
    dump the metadata of a bag with 16 topics)."""

    def __init__(self, typ: str = "safe"):
        self.default_flow_style = False

    def dump(self, data: Any, stream: Any) -> None:
        import yaml

        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
        stream.write(yaml.dump(data, Dumper=dumper, default_flow_style=self.default_flow_style, sort_keys=True))


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


def _writer_class():
    """rosbags' ``Writer`` on the batched storages, with ``write_rows`` (counts kept right)."""
    global _WRITER_CLS
    if _WRITER_CLS is None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        sqlite_cls, mcap_cls = _storage_classes()

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

            def write_rows(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
                """Rows on connection ids ``cids`` (int64) at record times ``ts`` (int64 ns)."""
                if not len(raws):
                    return
                self.storage.write_rows(cids, ts, raws)
                for cid, cnt in zip(*np.unique(cids, return_counts=True)):
                    self.counts[int(cid)] += int(cnt)
                self.min_timestamp = min(int(ts.min()), self.min_timestamp)
                self.max_timestamp = max(int(ts.max()), self.max_timestamp)

            def counts_from_storage(self) -> None:
                """Counts and first/last record times of what the file holds (the metadata's)."""
                counts, self.min_timestamp, self.max_timestamp = self.storage.stored()
                self.counts = {c.id: counts.get(c.id, 0) for c in self.connections}

        _WRITER_CLS = FastWriter
    return _WRITER_CLS


# ---- the output bag --------------------------------------------------------------------------
class OutputBag:
    """rosbag2 version-9 writer that copies input connections and adds the output topics.

    Writes raise :class:`OutputWriteError` (the bag is then already closed, readable, with
    what it held before the failure)."""

    def __init__(self, path: Path, storage: str):
        from rosbags.rosbag2 import StoragePlugin

        self.path = Path(path)
        self.storage = storage
        plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
        self.writer = _writer_class()(self.path, version=9, storage_plugin=plugin)
        try:
            self.writer.open()
        except WRITE_ERRORS as e:
            raise OutputWriteError(f"{self.path}: cannot create the output bag: {_err(e)}") from None
        self._copies: dict[int, Any] = {}     # input connection id -> output connection
        self._by_key: dict[tuple, Any] = {}
        self._outs: dict[str, Any] = {}
        self._lut = np.zeros(1, np.int64)     # input connection id -> output id (0: not copied)
        self.skipped: dict[str, str] = {}     # input topics that could not be copied -> why
        self.closed = False
        self.error: str | None = None
        atexit.register(self._close_at_exit)

    @property
    def counts(self) -> dict[str, int]:
        """Messages written by topic (topics with at least one)."""
        res: dict[str, int] = {}
        for c in self.writer.connections:
            n = self.writer.counts.get(c.id, 0)
            if n:
                res[c.topic] = res.get(c.topic, 0) + n
        return res

    # ---- connections ---------------------------------------------------------------------
    def copy_connection(self, conn: Any, store: Any) -> Any | None:
        """Output connection for an input connection (same topic, type, definition, QoS)."""
        if conn.id in self._copies:
            return self._copies[conn.id]
        key = (conn.topic, conn.msgtype, conn.ext.serialization_format, tuple(conn.ext.offered_qos_profiles))
        out = self._by_key.get(key)
        if out is None:
            out = self._guard(lambda: self._add_copy(conn, store))
            if out is not None:
                self._by_key[key] = out
        self._copies[conn.id] = out
        if conn.id >= len(self._lut):
            self._lut = np.concatenate([self._lut, np.zeros(conn.id + 1 - len(self._lut), np.int64)])
        self._lut[conn.id] = 0 if out is None else out.id
        return out

    def _add_copy(self, conn: Any, store: Any) -> Any | None:
        rb = rosbags_api()
        msgdef, digest = None, None
        if conn.msgdef.format != rb["MsgDefFormat"].NONE and conn.msgdef.data:
            msgdef = conn.msgdef.data
            digest = conn.digest or None
            if digest is None:
                try:
                    digest = store.hash_rihs01(conn.msgtype)
                except Exception:
                    digest = None
        if msgdef is None or digest is None:
            jazzy = msgs.jazzy_typestore()
            if conn.msgtype not in jazzy.fielddefs:
                self.skipped[conn.topic] = f"type {conn.msgtype} has no definition in the bag nor in Jazzy"
                return None
            msgdef, _ = jazzy.generate_msgdef(conn.msgtype, ros_version=2)
            digest = jazzy.hash_rihs01(conn.msgtype)
        return self.writer.add_connection(conn.topic, conn.msgtype, msgdef=msgdef, rihs01=digest,
                                          serialization_format=conn.ext.serialization_format,
                                          offered_qos_profiles=conn.ext.offered_qos_profiles)

    def add_output(self, topic: str, msgtype: str) -> None:
        """Add an output topic; an input topic of the same name and type is shared (/diagnostics)."""
        shared = next((c for c in self._copies.values() if c is not None and c.topic == topic
                       and c.msgtype == msgtype), None)
        self._outs[topic] = shared or self._guard(lambda: self.writer.add_connection(
            topic, msgtype, typestore=msgs.jazzy_typestore(), offered_qos_profiles=default_qos()))

    def output_connection(self, topic: str) -> Any:
        """The output connection of an output topic added with :meth:`add_output`."""
        return self._outs[topic]

    # ---- messages --------------------------------------------------------------------------
    def write_raw(self, out_conn: Any, ts: int, raw: bytes) -> None:
        """Write CDR bytes on an output connection at record time ``ts`` (ns)."""
        self.write_many(out_conn, np.array([ts], np.int64), [raw])

    def write_msg(self, topic: str, ts: int, msg: Any) -> None:
        """Serialise a Jazzy message and write it on output topic ``topic`` at ``ts`` (ns)."""
        raw = msgs.jazzy_typestore().serialize_cdr(msg, msg.__msgtype__)
        self.write_raw(self._outs[topic], ts, raw)

    def write_many(self, out_conn: Any, ts: Any, raws: Sequence[Any]) -> None:
        """Write K messages (CDR bytes) on one output connection at record times ``ts``
        (int64 (K,) ns), or on an output topic given by name."""
        if isinstance(out_conn, str):
            out_conn = self._outs[out_conn]
        ts = np.asarray(ts, np.int64).reshape(-1)
        if len(ts) != len(raws):
            raise ValueError(f"{len(ts)} record times for {len(raws)} messages")
        self._write(np.full(len(ts), out_conn.id, np.int64), ts, raws)

    def write_outputs(self, ts: Any, encoded: Iterable[tuple[str, Sequence[bytes]]]) -> None:
        """Write what :func:`gyro_platform.io.encode.encode_outputs` made, instant by instant
        (at each instant its topics in order), at record times ``ts`` (int64 (K,) ns)."""
        ts = np.asarray(ts, np.int64).reshape(-1)
        topics = list(encoded)
        if not topics:
            return
        k, n = len(ts), len(topics)
        cids = np.tile(np.array([self._outs[t].id for t, _ in topics], np.int64), k)
        raws: list[Any] = [None] * (k * n)
        for j, (_, rs) in enumerate(topics):
            raws[j::n] = rs
        self._write(cids, np.repeat(ts, n), raws)

    def copy_chunk(self, chunk: Any, bag: Any = None) -> int:
        """Copy every row of a :class:`~gyro_platform.io.blocks.RowChunk` whose input connection
        is copied (byte for byte, same record time, bag order); returns the rows written.
        Connections not seen yet are added from ``bag`` (an ``InputBag``)."""
        ids = np.asarray(chunk.conn_id, np.int64)
        if not len(ids):
            return 0
        if bag is not None:
            for cid in np.unique(ids).tolist():
                if cid not in self._copies:
                    conn = next((c for c in bag.connections if c.id == cid), None)
                    if conn is not None:
                        self.copy_connection(conn, bag.store_for(conn))
        lut = self._lut
        out = np.where(ids < len(lut), lut[np.minimum(ids, len(lut) - 1)], 0)
        keep = out > 0
        if keep.all():
            self._write(out, np.asarray(chunk.ts, np.int64), chunk.raws)
            return len(ids)
        idx = np.flatnonzero(keep)
        raws = chunk.raws
        self._write(out[idx], np.asarray(chunk.ts, np.int64)[idx], [raws[i] for i in idx.tolist()])
        return len(idx)

    def flush(self) -> None:
        """Commit what is pending now (sqlite3 transaction / MCAP chunk)."""
        st = self._storage()
        self._guard(st.commit if hasattr(st, "commit") else st.close_chunk)

    def _storage(self) -> Any:
        if self.closed or self.writer.storage is None:
            raise OutputWriteError(f"{self.path}: the output bag is closed" + (f" ({self.error})" if self.error else ""))
        return self.writer.storage

    def _write(self, cids: np.ndarray, ts: np.ndarray, raws: Sequence[Any]) -> None:
        self._storage()
        self._guard(lambda: self.writer.write_rows(cids, ts, raws))

    def _guard(self, fn: Any) -> Any:
        """Run a write; on a write error close the bag with what it holds, raise OutputWriteError."""
        try:
            return fn()
        except WRITE_ERRORS as e:
            self._fail(e)

    def _fail(self, e: BaseException) -> None:
        self.error = _err(e)
        atexit.unregister(self._close_at_exit)
        kept = "closed"
        try:
            self._close_after_failure()
            kept = f"closed with the {sum(self.writer.counts.values())} messages written before"
        except WRITE_ERRORS as e2:
            kept = f"left without index ({_err(e2)})"
        raise OutputWriteError(f"{self.path}: cannot write the output bag: {self.error}; {kept}") from None

    def _close_after_failure(self) -> None:
        if self.closed:
            return
        self.closed = True
        w = self.writer
        st = w.storage
        if st is None:       # the storage was closed; only metadata.yaml failed
            raise OSError(self.error)
        with signals_deferred():
            st.drop_pending()
            w.counts_from_storage()
            while True:
                try:
                    w.close()
                    return
                except OSError:
                    # no room for the summary: cut the last chunk (MCAP) and try again
                    if not (hasattr(st, "drop_last_chunk") and w.storage is not None and st.drop_last_chunk()):
                        raise
                    w.counts_from_storage()

    def close(self) -> None:
        """Commit, write index and metadata (the bag is then readable; the counts are those of
        what the file holds). SIGINT/SIGTERM wait until it is done. A write error: the bag is
        cut back to what it held and closed, then :class:`OutputWriteError`."""
        if self.closed:
            return
        with signals_deferred():
            try:
                self.writer.storage.settle()
                self.writer.counts_from_storage()
                self.writer.close()
                self.closed = True
                atexit.unregister(self._close_at_exit)
                return
            except WRITE_ERRORS as e:
                err = e
        self._fail(err)

    def _close_at_exit(self) -> None:
        """Safety net: an interpreter leaving without close() (an uncaught second Ctrl-C
        between a loop and its close) still writes index and metadata."""
        try:
            self.close()
        except Exception as e:   # noqa: BLE001 - at exit only a line can be said
            print(f"gyro-platform: {e}", file=sys.stderr)
