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

"""The output rosbag2 bag (version 9, sqlite3 or mcap): input connections copied byte for
byte plus the simulator's output topics, offered with the rclpy default QoS.

rosbags' ``Writer`` makes the connections, the sqlite3 schema (rosbag2 Jazzy, schema version 4:
``schema``, ``metadata``, ``topics``, ``message_definitions``, ``messages``), the MCAP schemas
and channels (profile ``ros2``, encodings ``ros2msg``/``ros2idl``, channel metadata
``offered_qos_profiles``) and ``metadata.yaml``; only the per-message write is replaced by a
batched one (:meth:`OutputBag.write_many`, :meth:`OutputBag.copy_chunk`; storage side in
:mod:`.bag_storage`) whose files are those rosbags writes (tested field by field; MCAP byte
for byte up to its metadata record).

What survives a fault (issue 17):

* the output is committed in bounded chunks: sqlite3 transactions (rollback journal) and MCAP
  chunks are written to the file at least every ``bag_storage.COMMIT_ROWS`` messages or
  ``COMMIT_SECONDS`` of wall time (MCAP also every 1 MiB chunk), so a SIGKILL loses at most
  the last chunk (sqlite3 ``synchronous=OFF``: an OS crash or power cut may lose more); the
  readable part has no ``metadata.yaml`` and is read by
  ``InputBag`` (the lone ``.db3``; an MCAP without footer through its salvage);
* ``close()`` defers SIGINT/SIGTERM until the index and ``metadata.yaml`` are written (a second
  Ctrl-C is taken after it);
* a full disk (``ENOSPC``, ``EFBIG``, sqlite3 "database or disk is full") while writing or
  closing: the bag is cut back to the last complete chunk, closed with index and metadata
  counting what it holds, and :class:`~gyro_platform.errors.OutputError` names the file
  and the error. Output paths are checked before a run by :func:`gyro_platform.errors.check_output_path`.
"""
from __future__ import annotations

import atexit
from contextlib import contextmanager
from functools import lru_cache
import os
from pathlib import Path
import re
import sys
from typing import Any, Iterable, Iterator, Sequence

import numpy as np

from .paths import rosbags_api
from .rows import Rows, segments
from .storage import SQLITE_ERRORS, writer_class
from .. import messages as msgs
from ..errors import OutputError
from ..messages.typedefs import core_typestore, has_type
from ..signals import deferred_signals


#: type hash handed to rosbags' ``Writer`` for a type without one (it asks for one), written over
#: with '' (rosbag2's hash of a type it has no definition of)
NO_HASH = "RIHS01_" + "0" * 64


def default_qos() -> list:
    """QoS offered by the output publishers: reliable, volatile, keep last 10 (rclpy default)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]


def _err(e: BaseException) -> str:
    """One-line text of an OSError / sqlite3 error (``[Errno 28] No space left on device``)."""
    if isinstance(e, OSError) and e.errno is not None:
        return f"[Errno {e.errno}] {e.strerror or os.strerror(e.errno)}"
    return f"{type(e).__name__}: {e}"


def _store_of(msgtype: str) -> Any:
    """The typestore that defines ``msgtype`` at least cost: the small one of the types this
    package writes, else rosbags' Jazzy store."""
    return core_typestore() if has_type(msgtype) else msgs.jazzy_typestore()


@lru_cache(maxsize=None)
def _definition(msgtype: str) -> tuple[str, str]:
    """(message definition, RIHS01 hash) of ``msgtype`` as rosbags' writer derives them from
    its typestore, once per process (~0.2 ms each: a run adds ~15 output connections)."""
    store = _store_of(msgtype)
    return store.generate_msgdef(msgtype, ros_version=2)[0], store.hash_rihs01(msgtype)


#: what a full disk or an unwritable file looks like from the storage writers
WRITE_ERRORS = (OSError, *SQLITE_ERRORS)


# ---- the output bag --------------------------------------------------------------------------
class OutputBag:
    """rosbag2 version-9 writer that copies input connections and adds the output topics.

    Writes raise :class:`OutputError` (the bag is then already closed, readable, with
    what it held before the failure)."""

    def __init__(self, path: Path, storage: str):
        from rosbags.rosbag2 import StoragePlugin

        self.path = Path(path)
        self.storage = storage
        plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
        self.writer = writer_class()(self.path, version=9, storage_plugin=plugin)
        try:
            self.writer.open()
        except WRITE_ERRORS as e:
            raise OutputError(f"{self.path}: cannot create the output bag: {_err(e)}") from None
        self._copies: dict[int, Any] = {}     # input connection id -> output connection
        self._by_key: dict[tuple, Any] = {}
        self._outs: dict[str, Any] = {}
        self._lut = np.zeros(1, np.int64)     # input connection id -> output id (0: not copied)
        self.skipped: dict[str, str] = {}     # input topics that could not be copied -> why
        self._batch: list[tuple[np.ndarray, np.ndarray, Any]] | None = None   # see batched()
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
            if conn.msgtype not in jazzy.fielddefs:     # copied raw, with what the bag says of it
                return self._add_undefined(conn, msgdef or "", digest or "")
            msgdef, _ = jazzy.generate_msgdef(conn.msgtype, ros_version=2)
            digest = jazzy.hash_rihs01(conn.msgtype)
        return self.writer.add_connection(conn.topic, conn.msgtype, msgdef=msgdef, rihs01=digest,
                                          serialization_format=conn.ext.serialization_format,
                                          offered_qos_profiles=conn.ext.offered_qos_profiles)

    def _add_undefined(self, conn: Any, msgdef: str, digest: str) -> Any | None:
        """Output connection of a type neither the bag nor Jazzy defines (rosbag2 records one,
        with an empty definition, when the recording machine lacks the type): its rows are
        copied byte for byte. Definition ``msgdef`` (empty: an empty ``ros2msg`` one, which rosbags
        and rosbag2 read) and type hash ``digest`` (empty, as rosbag2 writes it, when the bag has
        none: rosbags' ``Writer`` asks for one, so a placeholder is written over). None (the
        topic in ``skipped``) for a channel without a type name or when the writer refuses it."""
        if not re.fullmatch(r"[A-Za-z]\w*(/\w+)+", conn.msgtype or ""):    # rosbags' '__schemaless__' …
            self.skipped[conn.topic] = (f"no type name ({conn.msgtype!r}: e.g. an MCAP channel without a schema) "
                                        f"and no definition: its {conn.msgcount} messages are not copied")
            return None
        try:
            out = self.writer.add_connection(conn.topic, conn.msgtype, msgdef=msgdef, rihs01=digest or NO_HASH,
                                             serialization_format=conn.ext.serialization_format,
                                             offered_qos_profiles=conn.ext.offered_qos_profiles)
        except WRITE_ERRORS:
            raise
        except Exception as e:      # rosbags' WriterError, its checks of a definition …
            self.skipped[conn.topic] = (f"type {conn.msgtype} has no definition in the bag nor in Jazzy and "
                                        f"the writer refused it ({_err(e)})")
            return None
        if not digest:
            out = out._replace(digest="")
            self.writer.connections[-1] = out       # (just added; metadata.yaml is written from these)
            cursor = getattr(self.writer.storage, "cursor", None)     # sqlite3: the rows written with it
            if cursor is not None:
                cursor.execute("UPDATE topics SET type_description_hash = '' WHERE id = ?", (out.id,))
                cursor.execute("UPDATE message_definitions SET type_description_hash = '' "
                               "WHERE topic_type = ? AND type_description_hash = ?", (conn.msgtype, NO_HASH))
        return out

    def add_output(self, topic: str, msgtype: str) -> None:
        """Add an output topic; an input topic of the same name and type is shared (/diagnostics)."""
        shared = next((c for c in self._copies.values() if c is not None and c.topic == topic
                       and c.msgtype == msgtype), None)
        msgdef, digest = _definition(msgtype)
        self._outs[topic] = shared or self._guard(lambda: self.writer.add_connection(
            topic, msgtype, msgdef=msgdef, rihs01=digest, offered_qos_profiles=default_qos()))

    def output_connection(self, topic: str) -> Any:
        """The output connection of an output topic added with :meth:`add_output`."""
        return self._outs[topic]

    # ---- messages --------------------------------------------------------------------------
    def write_raw(self, out_conn: Any, ts: int, raw: bytes) -> None:
        """Write CDR bytes on an output connection at record time ``ts`` (ns)."""
        self.write_many(out_conn, np.array([ts], np.int64), [raw])

    def write_msg(self, topic: str, ts: int, msg: Any) -> None:
        """Serialise a Jazzy message and write it on output topic ``topic`` at ``ts`` (ns)."""
        raw = _store_of(msg.__msgtype__).serialize_cdr(msg, msg.__msgtype__)
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
        """Write what :func:`gyro_platform.messages.encode.encode_outputs` made, instant by instant
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

    def write_topics(self, ts: Any, encoded: Iterable[tuple[str, Any]]) -> None:
        """Write what :func:`gyro_platform.messages.encode.encode_outputs` made (its K messages per
        topic: bytes, or one uint8 array (K, size) with ``arrays=True``) topic by topic, each
        at record times ``ts`` (int64 (K,) ns): the rows and order of one :meth:`write_many`
        per topic, in one write."""
        ts = np.asarray(ts, np.int64).reshape(-1)
        topics = list(encoded)
        if not topics or not len(ts):
            return
        for t, rs in topics:
            if len(rs) != len(ts):
                raise ValueError(f"{len(ts)} record times for {len(rs)} messages on {t}")
        cids = np.repeat(np.array([self._outs[t].id for t, _ in topics], np.int64), len(ts))
        self._write(cids, np.tile(ts, len(topics)), Rows([rs for _, rs in topics]))

    def copy_chunk(self, chunk: Any, bag: Any = None) -> int:
        """Copy every row of a :class:`~gyro_platform.messages.blocks.RowChunk` whose input connection
        is copied (byte for byte, same record time, bag order); returns the rows written.
        Connections not seen yet are added from ``bag`` (an ``InputBag``)."""
        ids = np.asarray(chunk.conn_id, np.int64)
        if not len(ids):
            return 0
        lut = self._lut
        if bag is not None:
            fresh = (ids >= len(lut)) | (lut[np.minimum(ids, len(lut) - 1)] == 0)
            for cid in sorted(set(ids[fresh].tolist())):
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
            raise OutputError(f"{self.path}: the output bag is closed" + (f" ({self.error})" if self.error else ""))
        return self.writer.storage

    @contextmanager
    def batched(self) -> Iterator[None]:
        """Writes inside the block are kept and written at its end as one write, in their
        order (the same rows as written one by one; fewer, larger appends). The replay calls it
        on its writer thread (the bag has no thread of its own: one was measured slower)."""
        if self._batch is not None:         # nested: the outer block writes
            yield
            return
        self._batch = []
        try:
            yield
        finally:
            batch, self._batch = self._batch, None
            if batch and not self.closed:
                if len(batch) == 1:
                    cids, ts, raws = batch[0]
                else:
                    cids, ts = np.concatenate([b[0] for b in batch]), np.concatenate([b[1] for b in batch])
                    raws = Rows([seg for b in batch for seg in segments(b[2])])
                self._guard(lambda: self.writer.write_rows(cids, ts, raws))

    def _write(self, cids: np.ndarray, ts: np.ndarray, raws: Any) -> None:
        self._storage()
        if self._batch is not None:
            self._batch.append((cids, ts, raws))
            return
        self._guard(lambda: self.writer.write_rows(cids, ts, raws))

    def _guard(self, fn: Any) -> Any:
        """Run a write; on a write error close the bag with what it holds, raise OutputError."""
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
        raise OutputError(f"{self.path}: cannot write the output bag: {self.error}; {kept}") from None

    def _close_after_failure(self) -> None:
        if self.closed:
            return
        self.closed = True
        w = self.writer
        st = w.storage
        if st is None:       # the storage was closed; only metadata.yaml failed
            raise OSError(self.error)
        with deferred_signals():
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
        cut back to what it held and closed, then :class:`OutputError`."""
        if self.closed:
            return
        with deferred_signals():
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
