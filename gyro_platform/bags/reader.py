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

"""Reading an intact rosbag2 bag (sqlite3 or mcap; a folder, a lone storage file, a folder
without ``metadata.yaml``) with rosbags: connections, the input topic, messages as a stream,
CDR decoding through the bag's own definitions or the Jazzy typestore.

A bag that rosbags cannot open is handed to :mod:`.bag_salvage`. Errors: ``BagPathError``
(not a bag), ``BagReadError`` (damaged), ``ReplayError`` (no usable input topic).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from .fast import Batch, McapBag, row_batches
from .lenient import reader_class
from .paths import reader_path, resolve_bag_path, rosbags_api, storage_files, storage_of
from .salvage import Salvage
from .. import messages as msgs
from ..errors import BagReadError, ReplayError
from ..messages import INPUT_TYPES
from ..messages.blocks import concat_rows, row_lens, RowChunk
from ..messages.typedefs import core_msgdef, core_typestore, has_type

#: a chunk of :meth:`InputBag.chunks` ends once its rows hold this much payload (bytes), however
#: many rows were asked: a 1 kHz Imu chunk of 32 768 rows is ~11 MB, but a bag that also carries
#: camera images would otherwise put gigabytes in one chunk
CHUNK_BYTES = 64 * 2 ** 20
#: rows fetched at a time from SQLite or rosbags before they are cut into chunks
FETCH_ROWS = 4096


def _check_counts(conns: Any) -> None:
    """ValueError unless every connection's message count (``metadata.yaml``) is a count."""
    for c in conns:
        if type(c.msgcount) is not int or c.msgcount < 0:
            raise ValueError(f"metadata.yaml: topic {c.topic}: message_count {c.msgcount!r} is not a count")


class InputBag:
    """Streaming reader of one rosbag2 bag: connections up front, messages as a generator
    (:meth:`messages`) or in blocks (:meth:`chunks`).

    ``connections``: rosbags ``Connection`` tuples of every topic that is read; ``topic`` and
    ``msgtype``: the input topic and its type (the type of the topic's first connection);
    ``salvaged``: True when rosbags could not open the bag and its readable part is scanned
    instead (``damage`` says why); ``foreign``: why an intact MCAP bag that rosbags refuses
    (non-ROS 2 profile, jsonschema/protobuf schemas) is read with the ``mcap`` package instead.
    Never read: channels whose messages are not CDR (``skipped_channels``: topic → reason)
    and connections of another type on the input topic (``skipped_input``: type → message
    count; they are not merged into the input), and the write-ahead log of a ``.db3`` left
    beside it (:func:`wal_warning`). ``warnings``: one line per such fact, for the user. Use
    as a context manager.
    """

    def __init__(self, path: str | Path, topic: str | None = None):
        self.path = Path(path)
        self.requested_topic = topic
        self.topic: str | None = None
        self.msgtype: str | None = None
        self.connections: list[Any] = []
        self.message_count: int | None = None
        self.storage: str = ""
        self.salvaged = False
        self.damage: str | None = None
        self.foreign: str | None = None
        self.skipped_channels: dict[str, str] = {}
        self.skipped_input: dict[str, int] = {}
        #: salvaged bag: storage file -> its damage, for each file whose rest is lost (a split
        #: bag's later files are read on past a damaged one)
        self.damaged_files: dict[str, str] = {}
        self.warnings: list[str] = []
        #: reader of the last :meth:`chunks` call: "fast" (bag_fast on rosbags' index),
        #: "mcap" (the mcap package, foreign MCAP), "rosbags" or "salvage" (row by row)
        self.chunk_source = ""
        self._reader: Any = None
        self._salvage: Salvage | None = None
        self._mcap: McapBag | None = None
        self._stores: dict[int, Any] = {}
        self.messages_read = 0

    # ---- open / close --------------------------------------------------------------------
    def __enter__(self) -> "InputBag":
        self.open()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def open(self) -> None:
        """Open the bag and pick the input topic; raises BagReadError or ReplayError."""
        rb = rosbags_api()
        path = self.path = resolve_bag_path(self.path)
        self.storage = storage_of(path)
        if self.storage == "sqlite3":
            self.warnings += [w for w in map(wal_warning, storage_files(path)) if w]
        try:
            reader = reader_class()(reader_path(path))   # rosbags' Reader; also a type of empty definition
            reader.open()
            _check_counts(reader.connections)
        except (ReplayError, BagReadError):    # the path itself (BagPathError: several files, no metadata …)
            raise
        except Exception as e:      # ReaderError, OSError, a decompressor's or YAML's error …: a damaged bag
            named = not isinstance(e, (rb["ReaderError"], OSError, ValueError)) or isinstance(e, UnicodeError)
            text = " ".join(str(e).split())        # one line (YAML errors span several)
            why = f"rosbags cannot open it: {type(e).__name__ + ': ' if named else ''}{text}"
            self._mcap = self._foreign_mcap(path, why) if self.storage == "mcap" else None
            if self._mcap is not None:
                conns = list(self._mcap.connections)
                self.message_count = sum(c.msgcount for c in conns)
            else:
                self.damage = why
                self._salvage = Salvage.open(path, self.storage, self.damage)
                self.salvaged = True
                self.damaged_files = self._salvage.damaged_files     # filled as it is read
                conns = list(self._salvage.connections)
        else:
            self._reader = reader
            conns = list(reader.connections)
            self.message_count = reader.message_count
        self.connections = self._readable(conns)
        self._choose_topic()

    def _foreign_mcap(self, path: Path, why: str) -> McapBag | None:
        """The bag read with the ``mcap`` package when every file is an intact, indexed MCAP file
        that rosbags refuses for what it holds (not for damage); else None."""
        try:
            bag = McapBag(storage_files(path))
        except ValueError:
            return None
        if not bag.foreign_reasons():
            return None
        self.foreign = f"{why}; read with the mcap package ({'; '.join(bag.foreign_reasons())})"
        self.warnings.append(f"{path}: {self.foreign}")
        return bag

    def _readable(self, conns: list[Any]) -> list[Any]:
        """``conns`` without the channels that are not CDR (recorded in ``skipped_channels``)."""
        keep = []
        for c in conns:
            fmt = c.ext.serialization_format
            if fmt == "cdr":
                keep.append(c)
            else:
                self.skipped_channels[c.topic] = (f"message encoding {fmt!r}, type {c.msgtype or '?'!r}: "
                                                  f"{c.msgcount} messages not read (only CDR is)")
        if self.skipped_channels:
            n = sum(c.msgcount for c in conns if c.ext.serialization_format != "cdr")
            self.warnings.append(f"{self.path}: skipped {len(self.skipped_channels)} non-CDR channel(s) "
                                 f"({n} messages): " + ", ".join(
                                     f"{c.topic} ({c.ext.serialization_format})" for c in conns
                                     if c.ext.serialization_format != "cdr"))
        return keep

    def close(self) -> None:
        if self._reader is not None:
            try:
                self._reader.close()
            finally:
                self._reader = None
        if self._salvage is not None:
            self._salvage.close()
            self._salvage = None
        self._mcap = None

    def _choose_topic(self) -> None:
        if self.requested_topic is not None:
            conns = [c for c in self.connections if c.topic == self.requested_topic]
            if not conns:
                raise ReplayError(f"{self.path}: no topic {self.requested_topic!r}; topics: "
                                  + ", ".join(f"{c.topic} ({c.msgtype})" for c in self.connections))
            if conns[0].msgtype not in INPUT_TYPES:
                raise ReplayError(f"{self.path}: topic {self.requested_topic!r} has type {conns[0].msgtype}; "
                                  f"the input must be one of {', '.join(INPUT_TYPES)}")
            self.topic, self.msgtype = self.requested_topic, conns[0].msgtype
        else:
            first = next((c for c in self.connections if c.msgtype in INPUT_TYPES), None)
            if first is None:
                raise ReplayError(f"{self.path}: no Imu, Twist or TwistStamped topic; topics: "
                                  + (", ".join(f"{c.topic} ({c.msgtype})" for c in self.connections) or "none"))
            self.topic, self.msgtype = first.topic, first.msgtype
        for c in self.connections:
            if c.topic == self.topic and c.msgtype != self.msgtype:
                self.skipped_input[c.msgtype] = self.skipped_input.get(c.msgtype, 0) + c.msgcount
        if self.skipped_input:
            self.warnings.append(f"{self.path}: topic {self.topic} mixes types; the input is its first "
                                 f"connection's type {self.msgtype}, not used as input: " + ", ".join(
                                     f"{n} {t} messages" for t, n in self.skipped_input.items()))

    # ---- messages ------------------------------------------------------------------------
    def is_input(self, conn: Any) -> bool:
        """True for the connections of the input topic with the input type."""
        return conn.topic == self.topic and conn.msgtype == self.msgtype

    def _selected(self, input_only: bool) -> list[Any]:
        return [c for c in self.connections if self.is_input(c)] if input_only else list(self.connections)

    def _source(self, conns: list[Any]) -> Iterator[tuple[Any, int, bytes]]:
        if self._salvage is not None:
            return self._salvage.messages({c.id for c in conns})
        if self._mcap is not None:
            return _rows(self._mcap.batches(conns), {c.id: c for c in conns})
        return self._reader.messages(connections=conns)

    def _guarded(self, src: Iterator[Any], conns: list[Any], size: Any) -> Iterator[Any]:
        """Items of ``src`` with rosbags/sqlite/decompression errors turned into BagReadError
        and the row count checked against the bag's index at the end (``size(item)`` rows each)."""
        expected = sum(c.msgcount for c in conns) if self._salvage is None else None
        n = 0
        self.messages_read = 0
        while True:
            try:
                item = next(src)
            except StopIteration:
                if expected is not None and n != expected:   # e.g. garbage inside an unchecked chunk
                    raise BagReadError(f"{self.path}: damaged: {n} messages readable, its index lists "
                                       f"{expected}") from None
                return
            except BagReadError:
                raise
            except Exception as e:  # rosbags ReaderError, apsw/sqlite errors, zstd/lz4 errors …
                raise BagReadError(f"{self.path}: damaged: reading failed after {n} messages: "
                                   f"{type(e).__name__}: {e}") from e
            n += size(item)
            self.messages_read = n
            yield item

    def messages(self, input_only: bool = False) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, receive time ns, CDR bytes) in bag order; BagReadError on damage,
        including fewer (or more) messages than the bag's index lists."""
        conns = self._selected(input_only)
        return self._guarded(self._source(conns), conns, lambda _: 1)

    def chunks(self, max_rows: int = 4096, input_only: bool = False,
               pace: Callable[[], int] | None = None) -> Iterator[RowChunk]:
        """The rows of :meth:`messages` in blocks of at most ``max_rows`` (:class:`RowChunk`:
        connection ids, receive times ns, CDR bytes): same rows, same order, same errors (every
        row before a damage is yielded, then BagReadError); a block holds at most ``CHUNK_BYTES``
        of payload (camera images on other topics stay bounded). ``pace``: asked before each block
        for its size (≤ ``max_rows``; e.g. ``pipeline.ChunkPacer``). Intact sqlite3 and indexed
        MCAP bags are read by :mod:`.bag_fast` (no Python object per row); the rest through
        rosbags or the salvage reader."""
        if max_rows < 1:
            raise ValueError(f"max_rows = {max_rows}; must be >= 1")
        conns = self._selected(input_only)
        batches, self.chunk_source = None, "rosbags"
        if self._mcap is not None:
            batches, self.chunk_source = self._mcap.batches(conns), "mcap"
        elif self._reader is not None and conns:
            batches = row_batches(self._reader, conns, min(max_rows, FETCH_ROWS))
            self.chunk_source = "rosbags" if batches is None else "fast"
        if batches is None and self._salvage is not None and self._salvage.storage == "mcap":
            batches, self.chunk_source = self._salvage.batches({c.id for c in conns}), "salvage"
        if batches is None:
            self.chunk_source = "salvage" if self._salvage is not None else "rosbags"
            batches = _batches(self._source(conns), min(max_rows, FETCH_ROWS))
        return _rechunk(self._guarded(batches, conns, lambda b: len(b[1])),
                        (lambda: max_rows) if pace is None else (lambda: max(1, min(max_rows, pace()))))

    def store_for(self, conn: Any) -> Any:
        """Typestore to decode ``conn``: the bag's own definition if it has one, else Jazzy."""
        store = self._stores.get(conn.id)
        if store is None:
            store = self._stores[conn.id] = typestore_for(conn)
        return store

    def deserialize(self, conn: Any, raw: bytes) -> Any:
        """CDR bytes → rosbags message object (raises on a corrupt payload)."""
        return self.store_for(conn).deserialize_cdr(raw, conn.msgtype)


#: bytes of an SQLite write-ahead log's header: a longer log holds pages (frames)
WAL_HEADER = 32


def wal_warning(db: Path) -> str | None:
    """The line to say when the SQLite database ``db`` has a non-empty write-ahead log beside
    it (``<db>-wal``: a recorder in WAL mode, such as rosbag2's 'resilient' preset, stopped
    without closing the bag): rosbags, and so this reader, opens the ``.db3`` immutable and
    does not read the log, whose transactions (the last messages recorded) are then missing.
    None when there is none."""
    wal = db.with_name(db.name + "-wal")
    try:
        size = wal.stat().st_size
    except OSError:
        return None
    if size <= WAL_HEADER:
        return None
    return (f"{wal}: a write-ahead log of {size} bytes beside the database (a recorder stopped without closing "
            f"it): the messages in it are not read; merge it first by opening the bag once with SQLite, e.g. "
            f"sqlite3 {db} 'PRAGMA wal_checkpoint(TRUNCATE)'")


def typestore_for(conn: Any) -> Any:
    """Typestore that decodes ``conn``: one built from the bag's own message definition (MSG
    or IDL) when it has a usable one, else the Jazzy typestore — for the types of
    :mod:`.typedefs` its small copy (``core_typestore``: the same definitions and bytes)."""
    rb = rosbags_api()
    fmt = rb["MsgDefFormat"]
    if has_type(conn.msgtype) and (
            (conn.msgdef.format == fmt.MSG and conn.msgdef.data == core_msgdef(conn.msgtype))  # rosbags' text
            or conn.msgdef.format == fmt.NONE or not conn.msgdef.data):     # no definition: Jazzy's
        return core_typestore()         # the Jazzy definitions of these types (not the 0.13 s full store)
    if conn.msgdef.format != fmt.NONE and conn.msgdef.data:
        try:
            store = rb["get_typestore"](rb["Stores"].EMPTY)
            if conn.msgdef.format == fmt.MSG:
                store.register(rb["from_msg"](conn.msgdef.data, conn.msgtype))
            else:
                sep = "=" * 80 + "\n"
                data = conn.msgdef.data
                parts = [p.split("\n", 1)[1] for p in data.split(sep)[1:]] if data.startswith(sep + "IDL: ") else [data]
                for idl in parts:
                    store.register(rb["from_idl"](idl))
            store.get_msgdef(conn.msgtype)
            return store
        except Exception:
            pass
    return msgs.jazzy_typestore()


def _rows(batches: Iterator[Batch], by_id: dict[int, Any]) -> Iterator[tuple[Any, int, bytes]]:
    """(connection, time, raw) rows of batches."""
    for cid, ts, raws in batches:
        for c, t, r in zip(cid.tolist(), ts.tolist(), raws):
            yield by_id[c], t, r


def _batches(src: Iterator[tuple[Any, int, bytes]], max_rows: int) -> Iterator[Batch]:
    """Rows of a (connection, time, raw) stream grouped ``max_rows`` at a time; a failure is
    raised after the batch of rows read before it."""
    cid: list[int] = []
    ts: list[int] = []
    raws: list[bytes] = []

    def batch() -> Batch:
        return np.array(cid, np.int64), np.array(ts, np.int64), raws

    try:
        for conn, t, raw in src:
            cid.append(conn.id)
            ts.append(t)
            raws.append(raw)
            if len(raws) >= max_rows:
                yield batch()
                cid, ts, raws = [], [], []
    except Exception:
        if raws:
            yield batch()
        raise
    if raws:
        yield batch()


def _rechunk(batches: Iterator[Batch], rows: Callable[[], int]) -> Iterator[RowChunk]:
    """RowChunks of exactly ``rows()`` rows (asked before each; the last one shorter), or fewer:
    at most ``CHUNK_BYTES`` of payload (at least one row), from batches of any size; rows
    collected before an error are yielded before it propagates."""
    parts: list[Batch] = []
    have = nbytes = 0
    try:
        for b in batches:
            parts.append(b)
            have += len(b[1])
            nbytes += _payload(b[2])
            while have and (have >= (m := rows()) or nbytes >= CHUNK_BYTES):
                m = min(m, have) if nbytes < CHUNK_BYTES else min(m, have, _rows_within(parts, CHUNK_BYTES))
                chunk, parts = _take(parts, m)
                have -= m
                nbytes = sum(_payload(p[2]) for p in parts)
                yield chunk
    except Exception:
        if have:
            yield _take(parts, have)[0]
        raise
    if have:
        yield _take(parts, have)[0]


def _rows_within(parts: list[Batch], limit: int) -> int:
    """How many of the first rows of ``parts`` hold at most ``limit`` bytes of payload (at least 1)."""
    got = done = 0
    for _, _, raws in parts:
        lens = row_lens(raws)
        ends = got + np.cumsum(lens)
        k = int(np.searchsorted(ends, limit, side="right"))
        if k < len(lens):
            return max(1, done + k)
        got, done = int(ends[-1]) if len(lens) else got, done + len(lens)
    return max(1, done)


def _payload(raws: Any) -> int:
    """Payload bytes of a batch's rows (a list of bytes or a RawRows)."""
    return int(row_lens(raws).sum())


def _take(parts: list[Batch], n: int) -> tuple[RowChunk, list[Batch]]:
    """First ``n`` rows of ``parts`` as one RowChunk, and the rest."""
    cids, tss, raws = [], [], []
    got = 0
    rest: list[Batch] = []
    for i, (c, t, r) in enumerate(parts):
        k = min(len(t), n - got)
        cids.append(c[:k])
        tss.append(t[:k])
        raws.append(r[:k] if k < len(r) else r)
        got += k
        if k < len(t):
            rest = [(c[k:], t[k:], r[k:])] + parts[i + 1:]
            break
        if got == n:
            rest = parts[i + 1:]
            break
    if len(cids) == 1:
        return RowChunk(cids[0], tss[0], raws[0]), rest
    return RowChunk(np.concatenate(cids), np.concatenate(tss), concat_rows(raws)), rest
