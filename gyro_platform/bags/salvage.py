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

"""Reading what is readable of a damaged rosbag2 bag (no index, no footer, a cut-off database).

Used by :class:`.bag_reader.InputBag` when rosbags cannot open the bag. Messages are streamed
file by file, each in file order up to its damage (the files after a damaged one of a split bag
are read on), then ``BagReadError`` names each damaged file and where it broke.

* MCAP: the file is a stream of length-prefixed records, read front to back (neither the
  summary nor the footer is needed). The connections (schemas and channels, top level and in
  chunks) and the replay's blocks (:meth:`Salvage.batches`) walk the top-level records by hand
  (message indexes skipped unread), check each chunk with rosbags' ``decompress`` (size, CRC)
  and walk its records with ``bag_fast``'s compiled passes, the rows left in the chunk's
  buffer. The Chunk record the end of the file cuts (a recorder killed while writing it) is
  read as far as it decompresses (:func:`cut_chunk_records`: unchecked, its CRC covering the
  whole chunk), up to the first record the cut leaves incomplete. :meth:`Salvage.messages`
  reads row by row through the ``mcap`` package's :class:`mcap.stream_reader.StreamReader`
  (chunk CRCs checked; a short read turned into "truncated" here, since its stream returns
  short data silently; the cut chunk's records parsed by it too): the reference the blocks are
  tested against (its Python objects per record cost ~35 µs a row).
* sqlite3: read by hand with the standard ``sqlite3`` module. rosbags (and rosbag2) open a
  ``.db3`` through its ``metadata.yaml``/schema checks and give up on a database whose header
  or pages are cut off; a read-only connection with ``writable_schema`` still reads its
  ``topics`` table and the ``messages`` rows up to the damaged page, which is all we need.
"""
from __future__ import annotations

from pathlib import Path
import sqlite3
from typing import Any, BinaryIO, Iterator

import numpy as np

from .paths import read_metadata, rosbags_api, storage_files
from ..errors import BagReadError
from ..messages.blocks import RawRows


class Salvage:
    """Reads what is readable of a damaged bag: ``connections`` (rosbags ``Connection``
    tuples, ids renumbered across storage files) and ``messages(conn_ids)``."""

    def __init__(self, path: Path, files: list[Path], storage: str, why: str):
        self.path, self.files, self.storage, self.why = path, files, storage, why
        self.connections: list[Any] = []
        self._conn_key: dict[tuple[int, int], Any] = {}    # (file index, storage id) -> connection
        #: storage file -> its damage, for each file the last read stopped inside (the rest of it
        #: lost; the files after it are read on)
        self.damaged_files: dict[str, str] = {}

    @classmethod
    def open(cls, path: Path, storage: str, why: str) -> "Salvage":
        """Scan the storage files of ``path`` for connections; BagReadError if none is found."""
        files = storage_files(path)
        if not files:
            raise BagReadError(f"{path}: {why}; no storage file to salvage")
        s = cls(path, files, storage, why)
        meta = read_metadata(path) if path.is_dir() else None
        digests = {t["topic_metadata"]["name"]: t["topic_metadata"].get("type_description_hash", "")
                   for t in (meta or {}).get("topics_with_message_count", []) if "topic_metadata" in t}
        for i, f in enumerate(files):
            try:
                found = sqlite_connections(f) if storage == "sqlite3" else mcap_connections(f)
            except BagReadError as e:
                raise BagReadError(f"{f}: {why}; salvage failed too: {e}") from None
            for sid, conn in found:
                key = (conn.topic, conn.msgtype, conn.ext)
                same = next((c for c in s.connections if (c.topic, c.msgtype, c.ext) == key), None)
                if same is None:
                    same = conn._replace(id=len(s.connections) + 1,
                                         digest=conn.digest or digests.get(conn.topic, ""))
                    s.connections.append(same)
                s._conn_key[(i, sid)] = same
        if not s.connections:
            raise BagReadError(f"{path}: {why}; no readable topic found in {', '.join(map(str, files))}")
        return s

    def messages(self, conn_ids: set[int]) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, receive time ns, CDR bytes) of each storage file in turn, each up to its
        damage (a damaged file's readable rows, then the next file's), then BagReadError."""
        self.damaged_files.clear()
        for i, f in enumerate(self.files):
            src = sqlite_messages(f) if self.storage == "sqlite3" else mcap_messages(f)
            try:
                for sid, ts, raw in src:
                    conn = self._conn_key.get((i, sid))
                    if conn is not None and conn.id in conn_ids:
                        yield conn, ts, raw
            except BagReadError as e:
                self.damaged_files[str(f)] = str(e)
        raise self._end()

    def batches(self, conn_ids: set[int]) -> Iterator[tuple[np.ndarray, np.ndarray, Any]]:
        """MCAP: :meth:`messages` as blocks (bag connection ids, receive times ns, raws), a chunk
        at a time: the same rows in the same order, the same BagReadError after them."""
        if self.storage != "mcap":
            raise ValueError("batches() reads MCAP; sqlite3 rows come from messages()")
        self.damaged_files.clear()
        for i, f in enumerate(self.files):
            lut = np.full(65536, -1, np.int64)       # MCAP channel id (uint16) -> bag connection id
            for (fi, sid), c in self._conn_key.items():
                if fi == i and c.id in conn_ids:
                    lut[sid] = c.id
            try:
                yield from mcap_batches(f, lut)
            except BagReadError as e:
                self.damaged_files[str(f)] = str(e)
        raise self._end()

    def _end(self) -> BagReadError:
        """The error that ends a salvaged read: the damage of each damaged file (a split bag's
        later files are read past a damaged one: the error says so), else rosbags' reason."""
        if not self.damaged_files:
            return BagReadError(f"{self.path}: damaged bag, salvaged up to here ({self.why})")
        text = "; ".join(self.damaged_files.values())
        if len(self.files) > 1:
            last = max(i for i, f in enumerate(self.files) if str(f) in self.damaged_files)
            later = [f.name for f in self.files[last + 1:]]
            text += (f" (split bag: {len(self.damaged_files)} of {len(self.files)} files damaged, the rest of "
                     f"each lost; " + (f"read on in {', '.join(later)}" if later else "no file after it") + ")")
        return BagReadError(text)

    def close(self) -> None:
        pass


def _qos(text: Any) -> list:
    from rosbags.rosbag2.metadata import parse_qos

    try:
        return parse_qos(text or [])
    except Exception:
        return []


# ---- sqlite3 ------------------------------------------------------------------------------
def _sqlite_open(f: Path) -> sqlite3.Connection:
    """Read-only connection that tolerates a file shorter than its header says (a cut-off
    file is "malformed" to SQLite unless ``writable_schema`` is on; ``mode=ro`` still holds)."""
    db = sqlite3.connect(f"file:{f}?mode=ro&immutable=1", uri=True)
    try:
        db.execute("PRAGMA writable_schema=ON")
    except sqlite3.Error:
        pass
    return db


def sqlite_connections(f: Path) -> list[tuple[int, Any]]:
    """(topic id, Connection) of every row of the ``topics`` table (definitions from
    ``message_definitions`` when the bag has it); BagReadError if the table is unreadable."""
    rb = rosbags_api()
    try:
        db = _sqlite_open(f)
        try:
            cols = [r[1] for r in db.execute("PRAGMA table_info(topics)")]
            defs: dict[str, tuple[str, str]] = {}
            if db.execute("SELECT count(*) FROM sqlite_master WHERE name='message_definitions'").fetchone()[0]:
                for typ, enc, text in db.execute(
                        "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"):
                    defs[typ] = (enc, text)
            rows = db.execute(f"SELECT {', '.join(cols)} FROM topics ORDER BY id").fetchall()
        finally:
            db.close()
    except sqlite3.Error as e:
        raise BagReadError(f"{f}: cannot read the topics table: {e}") from None
    fmt = rb["MsgDefFormat"]
    res = []
    for row in rows:
        r = dict(zip(cols, row))
        enc, text = defs.get(r["type"], ("", ""))
        msgdef = rb["MsgDef"]({"ros2msg": fmt.MSG, "ros2idl": fmt.IDL}.get(enc, fmt.NONE), text if enc else "")
        ext = rb["Ext"](r.get("serialization_format", "cdr"), _qos(r.get("offered_qos_profiles")))
        res.append((int(r["id"]), rb["Connection"](int(r["id"]), r["name"], r["type"], msgdef,
                                                   r.get("type_description_hash") or "", 0, ext, None)))
    return res


def sqlite_messages(f: Path) -> Iterator[tuple[int, int, bytes]]:
    """(topic id, receive time ns, CDR bytes) of the rows in insertion order (rosbag2 inserts
    as it receives) until the damage, then BagReadError."""
    db = _sqlite_open(f)
    n = 0
    try:
        cur = db.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id")
        while True:
            try:
                row = cur.fetchone()
            except sqlite3.Error as e:
                raise BagReadError(f"{f}: database damaged after {n} readable messages: {e}") from None
            if row is None:
                return
            if not (isinstance(row[0], int) and isinstance(row[1], int) and isinstance(row[2], bytes)):
                raise BagReadError(f"{f}: database damaged after {n} readable messages: corrupt row {row[:2]!r}")
            n += 1
            yield row[0], row[1], row[2]
    finally:
        db.close()


# ---- MCAP ---------------------------------------------------------------------------------
class _ExactReads:
    """File wrapper for ``StreamReader``: a read that returns less than asked (but not
    nothing, which the reader itself reports as end of file) means a cut-off record."""

    def __init__(self, f: Path, fh: BinaryIO):
        self.f, self.fh = f, fh

    def read(self, n: int = -1) -> bytes:
        pos = self.fh.tell()
        data = self.fh.read(n)
        if 0 < len(data) < n:
            err = BagReadError(f"{self.f}: truncated record at offset {pos}: {len(data)} of {n} bytes")
            err.offset = pos                # (where the file ends inside a record: mcap_messages)
            raise err
        return data


def mcap_records(f: Path) -> Iterator[Any]:
    """Every record of an MCAP file in file order (``mcap.records``; chunk contents inlined,
    chunk CRCs checked); stops at DataEnd or the footer; BagReadError at a truncated or corrupt
    record (names the offset)."""
    from mcap.exceptions import EndOfFile, McapError
    from mcap.records import DataEnd, Footer
    from mcap.stream_reader import StreamReader

    with f.open("rb") as fh:
        records = StreamReader(_ExactReads(f, fh), validate_crcs=True).records
        while True:
            pos = fh.tell()
            try:
                rec = next(records)
            except StopIteration:
                return
            except EndOfFile:
                raise BagReadError(f"{f}: file ends at offset {fh.tell()} without footer (truncated)") from None
            except BagReadError:
                raise
            except McapError as e:
                raise BagReadError(f"{f}: not a readable MCAP file at offset {pos}: {e}") from None
            except Exception as e:   # CRC mismatch, decompression, a garbled record
                raise BagReadError(f"{f}: corrupt record at offset {pos}: {type(e).__name__}: {e}") from None
            if isinstance(rec, (DataEnd, Footer)):
                return
            yield rec


#: MCAP opcodes (https://mcap.dev/spec): the records the salvage reads
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_DATA_END = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F
#: not an MCAP opcode: what :func:`top_records` yields for the Chunk record the end of the file cuts
OP_CUT_CHUNK = 0x106
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: said of a cut chunk after the truncation
CUT_CHUNK_NOTE = ("; the cut chunk's records before the cut were read, unchecked (its CRC covers the whole "
                  "chunk)")


def top_records(f: Path, want: frozenset[int], cut_chunk: bool = False) -> Iterator[tuple[int, int, bytes]]:
    """(opcode, file offset, content) of the top-level records of an MCAP file whose opcode is
    in ``want``, in file order, the others skipped unread; stops at DataEnd or the footer;
    BagReadError at a bad magic or a truncated record (what :func:`mcap_records` says).
    ``cut_chunk``: a Chunk record the end of the file cuts (a recorder killed while writing it)
    is yielded first as ``OP_CUT_CHUNK`` with the content up to the cut (:func:`cut_chunk_records`),
    whether or not Chunk is in ``want``."""
    size = f.stat().st_size
    with f.open("rb") as fh:
        if fh.read(8) != MCAP_MAGIC:
            raise BagReadError(f"{f}: not a readable MCAP file at offset 0: bad magic")
        while True:
            pos = fh.tell()
            head = fh.read(9)
            if not head:
                raise BagReadError(f"{f}: file ends at offset {pos} without footer (truncated)")
            if len(head) < 9:
                raise BagReadError(f"{f}: truncated record at offset {pos}: {len(head)} of 9 bytes")
            op, n = head[0], int.from_bytes(head[1:], "little")
            if op in (OP_DATA_END, OP_FOOTER):
                return
            if pos + 9 + n > size:
                why = f"{f}: truncated record at offset {pos + 9}: {size - pos - 9} of {n} bytes"
                if cut_chunk and op == OP_CHUNK:
                    yield OP_CUT_CHUNK, pos, fh.read(size - pos - 9)
                    why += CUT_CHUNK_NOTE
                raise BagReadError(why)
            if op in want:
                yield op, pos, fh.read(n)
            else:
                fh.seek(n, 1)


def _text(b: bytes, p: int) -> tuple[str, int]:
    """An MCAP string (uint32 length, UTF-8) at ``p``; the offset after it."""
    n = int.from_bytes(b[p:p + 4], "little")
    return b[p + 4:p + 4 + n].decode(), p + 4 + n


def _chunk_fields(c: bytes) -> tuple[int, int, str, int, int]:
    """(uncompressed size, CRC, compression, offset of the records, their stored length) of a
    Chunk record's content ``c`` (https://mcap.dev/spec#chunk-op0x06)."""
    usize, crc = int.from_bytes(c[16:24], "little"), int.from_bytes(c[24:28], "little")
    comp, p = _text(c, 28)
    return usize, crc, comp, p + 8, int.from_bytes(c[p:p + 8], "little")


def _chunk_buffer(f: Path, pos: int, c: bytes) -> np.ndarray:
    """The decompressed records of the Chunk record at file offset ``pos`` (content ``c``),
    its size and CRC checked (rosbags' ``decompress``); BagReadError if they do not hold."""
    from rosbags.rosbag2.storage_mcap import decompress

    try:
        usize, crc, comp, p, n = _chunk_fields(c)
        if p + n > len(c):
            raise ValueError(f"records of {n} bytes run past the record's {len(c)}")
        return np.frombuffer(decompress(c[p:p + n], comp, usize, crc), np.uint8)
    except Exception as e:      # CRC or size mismatch, an unknown compression, garbled data
        raise BagReadError(f"{f}: corrupt record at offset {pos}: {type(e).__name__}: {e}") from None


def cut_chunk_records(c: bytes) -> np.ndarray:
    """The records of a Chunk record cut off by the end of the file (content ``c`` up to the
    cut), as far as they decompress: zstd and lz4 frames decode block by block, so what the
    blocks before the cut hold comes out (a prefix of the chunk's records); uncompressed records
    are taken as they are. Unchecked (the chunk's size and CRC cover the whole chunk): the record
    walk that follows ends at the first record the cut leaves incomplete. Empty when the cut
    falls in the chunk's header or the compression is unknown."""
    try:
        usize, _, comp, p, _ = _chunk_fields(c)
        if len(c) < p:
            return _NO_RECORDS
        data = c[p:]
        if comp == "zstd":
            try:
                from compression import zstd        # Python ≥ 3.14
            except ImportError:
                from backports import zstd          # rosbags' own dependency before 3.14
            data = _decoded_prefix(zstd.ZstdDecompressor, data)
        elif comp == "lz4":
            import lz4.frame

            data = _decoded_prefix(lz4.frame.LZ4FrameDecompressor, data)
        elif comp != "":
            return _NO_RECORDS
    except Exception:           # a header cut inside its compression name
        return _NO_RECORDS
    return np.frombuffer(bytes(data[:usize]), np.uint8)


def _decoded_prefix(decompressor: Any, data: bytes) -> bytes:
    """What the longest prefix of the compressed ``data`` that decodes without an error gives
    (a fresh ``decompressor()`` per try): all of it for a clean cut; for a cut followed by
    garbage (a power loss that left the file's tail unwritten or zero-filled) the blocks before
    the garbage, found by bisection (a prefix that fails makes every longer one fail)."""
    try:
        return decompressor().decompress(data)
    except Exception:
        pass
    good, bad, out = 0, len(data), b""          # out: what data[:good] gives
    while bad - good > 1:
        mid = (good + bad) // 2
        try:
            part = decompressor().decompress(data[:mid])
        except Exception:
            bad = mid
        else:
            good, out = mid, part
    return out


_NO_RECORDS = np.zeros(0, np.uint8)


def _spans(f: Path, pos: int, buf: np.ndarray, want: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """(opcodes, begins, ends) of a chunk's records with ``want[op]``, and the error that ended
    the walk early ("" if none) — the records before it are kept."""
    from .fast import record_spans, WALK_ERRORS

    err, at, n, ops, beg, end = record_spans(buf, want)
    why = f"{f}: corrupt record at offset {pos}: {WALK_ERRORS[err]} at offset {at} of its records" if err else ""
    return ops[:n], beg[:n], end[:n], why


def mcap_connections(f: Path) -> list[tuple[int, Any]]:
    """(channel id, Connection) of the schemas and channels in the readable part (top-level and
    in chunks, in file order; the records walked by hand and in compiled code, the messages
    skipped); damage ends the scan, keeping what was found before it."""
    rb = rosbags_api()
    fmt = rb["MsgDefFormat"]
    schemas: dict[int, tuple[str, str, str]] = {}
    res: list[tuple[int, Any]] = []
    seen: set[int] = set()
    want = np.zeros(256, np.bool_)
    want[[OP_SCHEMA, OP_CHANNEL]] = True

    def record(op: int, c: bytes) -> None:
        if op == OP_SCHEMA:
            sid = int.from_bytes(c[0:2], "little")
            name, p = _text(c, 2)
            enc, p = _text(c, p)
            n = int.from_bytes(c[p:p + 4], "little")
            schemas[sid] = (name, enc, c[p + 4:p + 4 + n].decode())
            return
        cid, sid = int.from_bytes(c[0:2], "little"), int.from_bytes(c[2:4], "little")
        if cid in seen:
            return
        topic, p = _text(c, 4)
        menc, p = _text(c, p)
        end, p, meta = p + 4 + int.from_bytes(c[p:p + 4], "little"), p + 4, {}
        while p < end:
            k, p = _text(c, p)
            meta[k], p = _text(c, p)
        seen.add(cid)
        name, senc, text = schemas.get(sid, ("", "", ""))
        mfmt = {"ros2msg": fmt.MSG, "ros2idl": fmt.IDL, "omgidl": fmt.IDL}.get(senc, fmt.NONE)
        ext = rb["Ext"](menc, _qos(meta.get("offered_qos_profiles")))
        res.append(
            (cid, rb["Connection"](cid, topic, name, rb["MsgDef"](mfmt, text if senc else ""), "", 0, ext, None))
        )

    try:
        for op, pos, c in top_records(f, frozenset((OP_SCHEMA, OP_CHANNEL, OP_CHUNK)), cut_chunk=True):
            if op not in (OP_CHUNK, OP_CUT_CHUNK):
                record(op, c)
                continue
            buf = _chunk_buffer(f, pos, c) if op == OP_CHUNK else cut_chunk_records(c)
            ops, beg, end, why = _spans(f, pos, buf, want)
            raw = buf.tobytes()
            for o, a, b in zip(ops.tolist(), beg.tolist(), end.tolist()):
                record(o, raw[a:b])
            if why:
                break
    except BagReadError:
        pass                                # damage: keep what was found before it
    except UnicodeDecodeError as e:
        raise BagReadError(f"{f}: corrupt schema record: {e}") from None
    return res


def mcap_messages(f: Path) -> Iterator[tuple[int, int, bytes]]:
    """(channel id, log time ns, CDR bytes) in file order up to the damage, then BagReadError.
    A chunk the end of the file cuts: the messages of its records before the cut, parsed by the
    ``mcap`` package from :func:`cut_chunk_records` (the reference for :func:`mcap_batches`)."""
    import io

    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    try:
        for rec in mcap_records(f):
            if isinstance(rec, Message):
                yield rec.channel_id, rec.log_time, rec.data
    except BagReadError as damage:
        cut = None
        try:
            cut = next(((p, c) for op, p, c in top_records(f, frozenset(), cut_chunk=True) if op == OP_CUT_CHUNK),
                       None)
        except BagReadError:
            pass
        at = getattr(damage, "offset", None)
        if cut is None or at is None or at < cut[0]:     # damage before the cut chunk (or none cut)
            raise
        buf = cut_chunk_records(cut[1]).tobytes()
        records = StreamReader(_ExactReads(f, io.BytesIO(buf)), skip_magic=True).records
        while True:
            try:
                rec = next(records)
            except Exception:       # the record the cut leaves incomplete, or the end of the records
                break
            if isinstance(rec, Message):
                yield rec.channel_id, rec.log_time, rec.data
        raise BagReadError(str(damage) + CUT_CHUNK_NOTE) from None


def mcap_batches(f: Path, lut: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, Any]]:
    """(``lut[channel id]``, log times ns, raws) of the messages of the channels with
    ``lut >= 0``, in file order (:func:`mcap_messages`' rows): a chunk's rows at once (its CRC
    and size checked, its records walked by ``bag_fast.walk_records``, the payloads left in
    the chunk's buffer), a message outside chunks alone; the top-level records walked by hand
    (message indexes skipped unread); BagReadError at the damage, after the rows before it."""
    from .fast import WALK_ERRORS, walk_records

    sel = lut >= 0
    every = np.uint64(2 ** 64 - 1)
    for op, pos, c in top_records(f, frozenset((OP_MESSAGE, OP_CHUNK)), cut_chunk=True):
        if op in (OP_CHUNK, OP_CUT_CHUNK):
            raw = _chunk_buffer(f, pos, c) if op == OP_CHUNK else cut_chunk_records(c)
            err, at, n, ts, cid, beg, end = walk_records(raw, np.uint64(0), every, sel)
            if n:
                yield lut[cid[:n]], ts[:n], RawRows(raw, beg[:n], end[:n])
            if err and op == OP_CHUNK:      # (a cut chunk's walk ends at the cut: top_records says so next)
                raise BagReadError(f"{f}: corrupt record at offset {pos}: {WALK_ERRORS[err]} at offset {at} "
                                   f"of its records")
        else:
            if len(c) < 22:
                raise BagReadError(f"{f}: corrupt record at offset {pos}: message record shorter than 22 bytes")
            ch = int.from_bytes(c[0:2], "little")
            if sel[ch]:
                yield (np.array([lut[ch]], np.int64), np.array([int.from_bytes(c[6:14], "little")], np.int64),
                       [c[22:]])
