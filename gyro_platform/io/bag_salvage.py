"""Reading what is readable of a damaged rosbag2 bag (no index, no footer, a cut-off database).

Used by :class:`.bag_reader.InputBag` when rosbags cannot open the bag. Messages are streamed
in file order up to the damage, then ``BagReadError`` names the file and where it broke.

* MCAP: the ``mcap`` package's :class:`mcap.stream_reader.StreamReader` reads the records
  front to back (it needs neither the summary nor the footer) with chunk CRCs checked; a short
  read is turned into "truncated" here, since its stream returns short data silently.
* sqlite3: read by hand with the standard ``sqlite3`` module. rosbags (and rosbag2) open a
  ``.db3`` through its ``metadata.yaml``/schema checks and give up on a database whose header
  or pages are cut off; a read-only connection with ``writable_schema`` still reads its
  ``topics`` table and the ``messages`` rows up to the damaged page, which is all we need.
"""
from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any, BinaryIO, Iterator

from ..errors import BagReadError
from .bag_paths import read_metadata, rosbags_api, storage_files


class Salvage:
    """Reads what is readable of a damaged bag: ``connections`` (rosbags ``Connection``
    tuples, ids renumbered across storage files) and ``messages(conn_ids)``."""

    def __init__(self, path: Path, files: list[Path], storage: str, why: str):
        self.path, self.files, self.storage, self.why = path, files, storage, why
        self.connections: list[Any] = []
        self._conn_key: dict[tuple[int, int], Any] = {}    # (file index, storage id) -> connection

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
        """(connection, receive time ns, CDR bytes) up to the damage, then BagReadError."""
        for i, f in enumerate(self.files):
            src = sqlite_messages(f) if self.storage == "sqlite3" else mcap_messages(f)
            for sid, ts, raw in src:
                conn = self._conn_key.get((i, sid))
                if conn is not None and conn.id in conn_ids:
                    yield conn, ts, raw
        raise BagReadError(f"{self.path}: damaged bag, salvaged up to here ({self.why})")

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
            raise BagReadError(f"{self.f}: truncated record at offset {pos}: {len(data)} of {n} bytes")
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


def mcap_connections(f: Path) -> list[tuple[int, Any]]:
    """(channel id, Connection) of the schemas and channels in the readable part (scans it
    once, one chunk in memory); damage ends the scan, keeping what was found before it."""
    from mcap.records import Channel, Schema

    rb = rosbags_api()
    fmt = rb["MsgDefFormat"]
    schemas: dict[int, tuple[str, str, str]] = {}
    res: list[tuple[int, Any]] = []
    seen: set[int] = set()
    try:
        for rec in mcap_records(f):
            if isinstance(rec, Schema):
                schemas[rec.id] = (rec.name, rec.encoding, rec.data.decode())
            elif isinstance(rec, Channel) and rec.id not in seen:
                seen.add(rec.id)
                name, senc, text = schemas.get(rec.schema_id, ("", "", ""))
                mfmt = {"ros2msg": fmt.MSG, "ros2idl": fmt.IDL, "omgidl": fmt.IDL}.get(senc, fmt.NONE)
                ext = rb["Ext"](rec.message_encoding, _qos(rec.metadata.get("offered_qos_profiles")))
                res.append((rec.id, rb["Connection"](rec.id, rec.topic, name,
                                                     rb["MsgDef"](mfmt, text if senc else ""), "", 0, ext, None)))
    except BagReadError:
        pass                                # damage: keep what was found before it
    except UnicodeDecodeError as e:
        raise BagReadError(f"{f}: corrupt schema record: {e}") from None
    return res


def mcap_messages(f: Path) -> Iterator[tuple[int, int, bytes]]:
    """(channel id, log time ns, CDR bytes) in file order up to the damage, then BagReadError."""
    from mcap.records import Message

    for rec in mcap_records(f):
        if isinstance(rec, Message):
            yield rec.channel_id, rec.log_time, rec.data
