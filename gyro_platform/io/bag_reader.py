"""Replay a rosbag2 recording through the simulator into an output bag (ROS-free, rosbags).

``gyro-platform replay IN_BAG --out OUT_BAG [--topic T] [--scene S] [--storage sqlite3|mcap]
[--output-rate HZ] [--mount FRAME=qx,qy,qz,qw | FRAME=roll,pitch,yaw] …``

* Input: a rosbag2 directory (any version rosbags reads, sqlite3 or mcap; bags without type
  definitions are read with the Jazzy typestore) or a single ``.db3``/``.mcap`` file. The input
  topic (``--topic``; default: the first ``Imu``/``Twist``/``TwistStamped`` topic) goes through
  :mod:`gyro_platform.io.messages` (mounting rotation → base_link) and the
  :class:`~gyro_platform.io.gate.TimeGate`, whose decisions drive the simulator.
* Output: a rosbag2 version-9 bag (storage of the input unless ``--storage``) with every input
  connection copied byte for byte (same record times) plus the output topics of
  :mod:`gyro_platform.io.messages` in the root namespace (or ``--namespace``): header stamps in the
  input's time base (header stamp, or receive time when the stamps are 0), record time = the
  receive time of the input message that produced them, i.e. when a live node would publish.
  Outputs every accepted sample on the grid ``floor((t − t_origin)·rate)`` (default 10 Hz,
  ``--output-rate 0``: every accepted sample); ``/diagnostics`` at 1 Hz of receive time.
* Streams: one message in memory at a time (rosbags readers are generators; the writer writes
  as it goes), so memory does not grow with the bag length. Also written, next to the bag:
  ``OUT_BAG.summary.json`` (counts, drops by reason, resets, duration, wall time, real-time
  factor, output ranges, drift rate) and ``OUT_BAG.png`` (via ``gyro_platform.io.recording``).
* Damage: a bag that rosbags cannot open (truncated mcap without footer, sqlite3 file cut
  short) is salvaged — its readable messages are streamed up to the damage — and a read
  error mid-stream ends the replay. Either way the output bag is closed properly (readable),
  the summary names the error, and the command exits with status 3. A path that is no rosbag2
  bag (missing, ROS 1, YAML or other file, empty folder), a missing topic or a bad option: one
  line, exit 2, nothing written. Results go to stdout, progress and errors to stderr.

Library use: :func:`read_samples` (also used by scene files of type ``bag``) streams gate
decisions; :func:`apply_decision` applies one to a ``Simulator``; :func:`replay` does it all.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sqlite3
import struct
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .io import messages as msgs
from .errors import InputError, SimulationError
from .engine.inputs import RateSample
from .io.messages import INPUT_TYPES, MessageTypes, Mounting, Rejected
from .io.gate import Action, Decision, GateConfig, TimeGate

NS = 1_000_000_000
DEFAULT_OUTPUT_RATE = 10.0      # Hz
DEFAULT_DIAGNOSTICS_RATE = 1.0  # Hz
PLOT_POINTS = 4000              # at most this many outputs are kept for the plot

# exit status: the CLI's (gyro_platform.cli.EXIT_CODES); EXIT_ERROR is the bad-input one
EXIT_OK, EXIT_ERROR, EXIT_DAMAGED, EXIT_INTERRUPTED = 0, 2, 3, 130
ROS1_MAGIC = b"#ROSBAG V2.0"
#: a ROS 2 namespace (empty or "/" = root): tokens [A-Za-z_][A-Za-z0-9_]*, no "__", joined by "/"
NAMESPACE_RE = re.compile(r"/?(?:(?!.*__)[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*/?)?")


class BagReadError(Exception):
    """The input bag cannot be read (further); the message names the file and what failed."""


class BagPathError(BagReadError):
    """The input path is not a rosbag2 bag at all (missing, a ROS 1 bag, a YAML or other file,
    a folder without storage file): a bad input path, not damaged data."""


class ReplayError(Exception):
    """The replay cannot start as asked (no input topic, output exists, topic clash …)."""


# =========================================================================================
# input bag
# =========================================================================================
def _rosbags():
    """Lazy import of the rosbags pieces used here."""
    from rosbags.interfaces import (Connection, ConnectionExtRosbag2, MessageDefinition,
                                    MessageDefinitionFormat)
    from rosbags.rosbag2 import Reader, ReaderError
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    return dict(Connection=Connection, Ext=ConnectionExtRosbag2, MsgDef=MessageDefinition,
                MsgDefFormat=MessageDefinitionFormat, Reader=Reader, ReaderError=ReaderError,
                Stores=Stores, from_idl=get_types_from_idl, from_msg=get_types_from_msg,
                get_typestore=get_typestore)


def _storage_files(path: Path) -> list[Path]:
    """Storage files of a bag directory (metadata order if readable) or the file itself."""
    if path.is_file():
        return [path]
    meta = _read_metadata(path)
    if meta and meta.get("relative_file_paths"):
        files = [path / Path(p).name for p in meta["relative_file_paths"]]
        return [f for f in files if f.exists()]
    return sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))


def _bag_path(path: Path) -> Path:
    """The bag to open for a user's path: a bag's ``metadata.yaml`` stands for its folder.
    BagPathError for a missing path, a ROS 1 bag and folders or files that hold no bag."""
    if not path.exists():
        raise BagPathError(f"{path}: no such file or directory")
    if path.is_file() and path.name == "metadata.yaml":
        path = path.parent
    ros1 = [path] if path.is_file() else sorted(path.glob("*.bag"))
    for f in ros1:
        try:
            with f.open("rb") as fh:
                is_ros1 = fh.read(len(ROS1_MAGIC)) == ROS1_MAGIC
        except OSError as e:
            raise BagPathError(f"{f}: cannot read: {e.strerror or e}") from None
        if is_ros1 or (f.suffix == ".bag" and path.is_file()):
            raise BagPathError(f"{f}: a ROS 1 bag; convert it to rosbag2 first "
                               f"(rosbags-convert --src {f} --dst OUT_DIR)")
    if path.is_file() and path.suffix not in (".db3", ".mcap"):
        raise BagPathError(f"{path}: not a rosbag2 bag (give a bag folder with metadata.yaml, "
                           f"or a .db3 / .mcap file)")
    return path


def _reader_path(path: Path) -> Path:
    """What rosbags' Reader opens: the folder when it has ``metadata.yaml``, else its single
    storage file (rosbags reads a lone .db3/.mcap file without metadata). A folder of several
    storage files without metadata cannot be ordered: BagPathError naming the fix."""
    if path.is_file() or (path / "metadata.yaml").is_file():
        return path
    files = _storage_files(path)
    if len(files) == 1:
        return files[0]
    if not files:
        raise BagPathError(f"{path}: not a rosbag2 bag (no metadata.yaml, no .db3 / .mcap file)")
    raise BagPathError(f"{path}: {len(files)} storage files but no metadata.yaml; "
                       f"recreate it with 'ros2 bag reindex {path}'")


def _read_metadata(path: Path) -> dict | None:
    """``rosbag2_bagfile_information`` of ``path/metadata.yaml``, None if absent or unreadable."""
    try:
        import yaml

        doc = yaml.safe_load((path / "metadata.yaml").read_text())
        return doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    except Exception:
        return None


def storage_of(path: Path) -> str:
    """``sqlite3`` or ``mcap`` for a bag directory or storage file."""
    files = _storage_files(path) if path.is_dir() else [path]
    meta = _read_metadata(path) if path.is_dir() else None
    if meta and meta.get("storage_identifier") in ("sqlite3", "mcap"):
        return meta["storage_identifier"]
    for f in files:
        if f.suffix == ".mcap":
            return "mcap"
        if f.suffix == ".db3":
            return "sqlite3"
    raise BagPathError(f"{path}: not a rosbag2 bag (give a bag folder with metadata.yaml, "
                       f"or a .db3 / .mcap file)")


class InputBag:
    """Streaming reader of one rosbag2 bag: connections up front, messages as a generator.

    ``connections``: rosbags ``Connection`` tuples of every topic; ``topic``: the input topic;
    ``salvaged``: True when rosbags could not open the bag and its readable part is scanned
    instead (``damage`` says why). Use as a context manager.
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
        self._reader: Any = None
        self._salvage: _Salvage | None = None
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
        rb = _rosbags()
        path = self.path = _bag_path(self.path)
        self.storage = storage_of(path)
        try:
            reader = rb["Reader"](_reader_path(path))
            reader.open()
        except (rb["ReaderError"], OSError, KeyError, ValueError) as e:
            self.damage = f"rosbags cannot open it: {e}"
            self._salvage = _Salvage.open(path, self.storage, self.damage)
            self.salvaged = True
            self.connections = list(self._salvage.connections)
        else:
            self._reader = reader
            self.connections = list(reader.connections)
            self.message_count = reader.message_count
        self._choose_topic()

    def close(self) -> None:
        if self._reader is not None:
            try:
                self._reader.close()
            finally:
                self._reader = None
        if self._salvage is not None:
            self._salvage.close()
            self._salvage = None

    def _choose_topic(self) -> None:
        if self.requested_topic is not None:
            conns = [c for c in self.connections if c.topic == self.requested_topic]
            if not conns:
                raise ReplayError(f"{self.path}: no topic {self.requested_topic!r}; topics: "
                                  + ", ".join(f"{c.topic} ({c.msgtype})" for c in self.connections))
            if conns[0].msgtype not in INPUT_TYPES:
                raise ReplayError(f"{self.path}: topic {self.requested_topic!r} has type {conns[0].msgtype}; "
                                  f"the input must be one of {', '.join(INPUT_TYPES)}")
            self.topic = self.requested_topic
        else:
            first = next((c for c in self.connections if c.msgtype in INPUT_TYPES), None)
            if first is None:
                raise ReplayError(f"{self.path}: no Imu, Twist or TwistStamped topic; topics: "
                                  + (", ".join(f"{c.topic} ({c.msgtype})" for c in self.connections) or "none"))
            self.topic = first.topic
        self.msgtype = next(c.msgtype for c in self.connections if c.topic == self.topic)

    # ---- messages ------------------------------------------------------------------------
    def is_input(self, conn: Any) -> bool:
        return conn.topic == self.topic and conn.msgtype in INPUT_TYPES

    def messages(self, input_only: bool = False) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, receive time ns, CDR bytes) in bag order; BagReadError on damage,
        including fewer (or more) messages than the bag's index lists."""
        conns = [c for c in self.connections if self.is_input(c)] if input_only else self.connections
        if self._salvage is not None:
            src = self._salvage.messages({c.id for c in conns})
        else:
            src = self._reader.messages(connections=conns)
        expected = sum(c.msgcount for c in conns) if self._reader is not None else None
        n = 0
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
            n += 1
            self.messages_read = n
            yield item

    def store_for(self, conn: Any) -> Any:
        """Typestore to decode ``conn``: the bag's own definition if it has one, else Jazzy."""
        store = self._stores.get(conn.id)
        if store is None:
            store = self._stores[conn.id] = _store_for(conn)
        return store

    def deserialize(self, conn: Any, raw: bytes) -> Any:
        """CDR bytes → rosbags message object (raises on a corrupt payload)."""
        return self.store_for(conn).deserialize_cdr(raw, conn.msgtype)


def _store_for(conn: Any) -> Any:
    rb = _rosbags()
    fmt = rb["MsgDefFormat"]
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


# ---- salvage readers ---------------------------------------------------------------------
class _Salvage:
    """Reads what is readable of a damaged bag (no index, no footer, cut-off database)."""

    def __init__(self, path: Path, files: list[Path], storage: str, why: str):
        self.path, self.files, self.storage, self.why = path, files, storage, why
        self.connections: list[Any] = []
        self._conn_key: dict[tuple[int, int], Any] = {}    # (file index, storage id) -> connection
        self._handles: list[Any] = []

    @classmethod
    def open(cls, path: Path, storage: str, why: str) -> "_Salvage":
        files = _storage_files(path)
        if not files:
            raise BagReadError(f"{path}: {why}; no storage file to salvage")
        s = cls(path, files, storage, why)
        meta = _read_metadata(path) if path.is_dir() else None
        digests = {t["topic_metadata"]["name"]: t["topic_metadata"].get("type_description_hash", "")
                   for t in (meta or {}).get("topics_with_message_count", []) if "topic_metadata" in t}
        for i, f in enumerate(files):
            try:
                found = _sqlite_connections(f) if storage == "sqlite3" else _mcap_connections(f)
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
        for i, f in enumerate(self.files):
            src = _sqlite_messages(f) if self.storage == "sqlite3" else _mcap_messages(f)
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


def _sqlite_open(f: Path) -> sqlite3.Connection:
    """Read-only connection that tolerates a file shorter than its header says (a cut-off
    file is "malformed" to SQLite unless ``writable_schema`` is on; ``mode=ro`` still holds)."""
    db = sqlite3.connect(f"file:{f}?mode=ro&immutable=1", uri=True)
    try:
        db.execute("PRAGMA writable_schema=ON")
    except sqlite3.Error:
        pass
    return db


def _sqlite_connections(f: Path) -> list[tuple[int, Any]]:
    rb = _rosbags()
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


def _sqlite_messages(f: Path) -> Iterator[tuple[int, int, bytes]]:
    """Rows in insertion order (rosbag2 inserts as it receives) until the damage."""
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


_MCAP_MAGIC = b"\x89MCAP0\r\n"


def _mcap_records(f: Path) -> Iterator[tuple[int, bytes]]:
    """Every record of an MCAP file in file order, chunk contents inlined; stops at DataEnd or
    the footer; BagReadError at a truncated or corrupt record (names the offset)."""
    from rosbags.rosbag2.storage_mcap import decompress

    with f.open("rb") as bio:
        if bio.read(8) != _MCAP_MAGIC:
            raise BagReadError(f"{f}: not an MCAP file (bad magic)")
        while True:
            pos = bio.tell()
            head = bio.read(9)
            if not head:
                raise BagReadError(f"{f}: file ends at offset {pos} without footer (truncated)")
            if len(head) < 9:
                raise BagReadError(f"{f}: truncated record header at offset {pos}")
            op, size = head[0], struct.unpack("<Q", head[1:])[0]
            body = bio.read(size)
            if len(body) != size:
                raise BagReadError(f"{f}: truncated record at offset {pos}: {len(body)} of {size} bytes")
            if op in (0x02, 0x0F):          # footer, data end
                return
            if op != 0x06:
                yield op, body
                continue
            try:                            # chunk: inline its records
                _, _, usize, crc = struct.unpack_from("<QQQI", body, 0)
                (clen,) = struct.unpack_from("<I", body, 28)
                comp = body[32:32 + clen].decode()
                (rlen,) = struct.unpack_from("<Q", body, 32 + clen)
                data = decompress(body[40 + clen:40 + clen + rlen], comp, usize, crc)
            except Exception as e:
                raise BagReadError(f"{f}: corrupt chunk at offset {pos}: {e}") from None
            sub = memoryview(data)
            i = 0
            while i < len(sub):
                if i + 9 > len(sub):
                    raise BagReadError(f"{f}: corrupt chunk at offset {pos}")
                sop, ssize = sub[i], struct.unpack_from("<Q", sub, i + 1)[0]
                yield sop, bytes(sub[i + 9:i + 9 + ssize])
                i += 9 + ssize


def _mcap_str(b: bytes, i: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", b, i)
    return b[i + 4:i + 4 + n].decode(), i + 4 + n


def _mcap_connections(f: Path) -> list[tuple[int, Any]]:
    """Schemas and channels of the readable part (scans it once, one chunk in memory)."""
    rb = _rosbags()
    from rosbags.rosbag2.storage_mcap import get_qos

    fmt = rb["MsgDefFormat"]
    schemas: dict[int, tuple[str, str, str]] = {}
    res: list[tuple[int, Any]] = []
    seen: set[int] = set()
    try:
        for op, body in _mcap_records(f):
            if op == 0x03:
                (sid,) = struct.unpack_from("<H", body, 0)
                name, i = _mcap_str(body, 2)
                enc, i = _mcap_str(body, i)
                (n,) = struct.unpack_from("<I", body, i)
                schemas[sid] = (name, enc, body[i + 4:i + 4 + n].decode())
            elif op == 0x04:
                cid, sid = struct.unpack_from("<HH", body, 0)
                topic, i = _mcap_str(body, 4)
                enc, i = _mcap_str(body, i)
                (n,) = struct.unpack_from("<I", body, i)
                if cid in seen:
                    continue
                seen.add(cid)
                name, senc, text = schemas.get(sid, ("", "", ""))
                mfmt = {"ros2msg": fmt.MSG, "ros2idl": fmt.IDL, "omgidl": fmt.IDL}.get(senc, fmt.NONE)
                ext = rb["Ext"](enc, get_qos(body[i + 4:i + 4 + n]))
                res.append((cid, rb["Connection"](cid, topic, name, rb["MsgDef"](mfmt, text if senc else ""),
                                                  "", 0, ext, None)))
    except BagReadError:
        pass                                # damage: keep what was found before it
    except (struct.error, UnicodeDecodeError) as e:
        raise BagReadError(f"{f}: corrupt schema or channel record: {e}") from None
    return res


def _mcap_messages(f: Path) -> Iterator[tuple[int, int, bytes]]:
    for op, body in _mcap_records(f):
        if op == 0x05 and len(body) >= 22:
            cid, _, log_time, _ = struct.unpack_from("<HIQQ", body, 0)
            yield cid, log_time, body[22:]


# =========================================================================================
# samples
# =========================================================================================
@dataclass(frozen=True, slots=True)
class BagSample:
    """One input-topic message with the gate's decision. ``receive_ns``: bag record time (ns);
    ``msg``: the decoded message (None if it could not be decoded)."""

    decision: Decision
    receive_ns: int
    msg: Any
    connection: Any
    rawdata: bytes

    @property
    def sample(self) -> RateSample | None:
        return self.decision.sample

    @property
    def receive_time(self) -> float:
        """Receive time, s since the epoch (for display; use ``receive_ns`` for arithmetic)."""
        return self.receive_ns / NS


def judge(bag: InputBag, conn: Any, raw: bytes, receive_ns: int, mounting: Mounting,
          gate: TimeGate) -> tuple[Decision, Any]:
    """Decode one input message, map it to base_link and let the gate decide (never raises)."""
    try:
        msg = bag.deserialize(conn, raw)
    except Exception as e:
        return gate.offer(Rejected("bad_message", f"cannot decode {conn.msgtype}: {e}"), receive_ns), None
    return gate.offer(msgs.reading_from_msg(msg, mounting), receive_ns), msg


def read_samples(bag_path: str | Path, topic: str | None = None, *, mounting: Mounting | None = None,
                 gate: TimeGate | None = None) -> Iterator[BagSample]:
    """Stream the input topic of a bag as gate decisions (a generator: one message at a time).

    ``topic``: default the first Imu/Twist/TwistStamped topic; ``mounting``: sensor frames
    (default: base_link only, unknown frames taken as identity); ``gate``: default
    ``TimeGate()``. Raises BagReadError (naming the file) when the bag cannot be read,
    ReplayError when it has no usable topic.
    """
    mounting = mounting or Mounting()
    gate = gate or TimeGate()
    with InputBag(bag_path, topic) as bag:
        for conn, ts, raw in bag.messages(input_only=True):
            decision, msg = judge(bag, conn, raw, ts, mounting, gate)
            yield BagSample(decision, ts, msg, conn, raw)


def apply_decision(sim: Any, decision: Decision) -> str:
    """Apply a gate decision to a ``Simulator``. Returns ``"pushed"``, ``"reset"`` (reset, then
    pushed), ``"dropped"``, ``"rejected"`` (the simulator refused the sample: InputError, state
    unchanged) or ``"restarted"`` (the integration failed: SimulationError; the simulator is
    reset and restarted at this sample). Outputs already taken are never touched."""
    if decision.action is Action.DROP or decision.sample is None:
        return "dropped"
    if decision.action is Action.RESET:
        sim.reset()
    try:
        sim.push(decision.sample)
    except InputError:
        return "rejected"
    except SimulationError:
        sim.reset()
        try:
            sim.push(decision.sample)
        except SimulationError:
            return "rejected"
        return "restarted"
    return "reset" if decision.action is Action.RESET else "pushed"


# =========================================================================================
# output bag
# =========================================================================================
def default_qos() -> list:
    """QoS offered by the output publishers: reliable, volatile, keep last 10 (rclpy default)."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                    QosTime)

    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]


class OutputBag:
    """rosbag2 version-9 writer that copies input connections and adds the output topics."""

    def __init__(self, path: Path, storage: str):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = path
        self.storage = storage
        plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
        self.writer = Writer(path, version=9, storage_plugin=plugin)
        self.writer.open()
        self._copies: dict[int, Any] = {}     # input connection id -> output connection
        self._by_key: dict[tuple, Any] = {}
        self._outs: dict[str, Any] = {}
        self.skipped: dict[str, str] = {}     # input topics that could not be copied -> why
        self.counts: dict[str, int] = {}
        self.closed = False

    def copy_connection(self, conn: Any, store: Any) -> Any | None:
        """Output connection for an input connection (same topic, type, definition, QoS)."""
        if conn.id in self._copies:
            return self._copies[conn.id]
        key = (conn.topic, conn.msgtype, conn.ext.serialization_format, tuple(conn.ext.offered_qos_profiles))
        out = self._by_key.get(key)
        if out is None:
            out = self._add_copy(conn, store)
            if out is not None:
                self._by_key[key] = out
        self._copies[conn.id] = out
        return out

    def _add_copy(self, conn: Any, store: Any) -> Any | None:
        rb = _rosbags()
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
        self._outs[topic] = shared or self.writer.add_connection(
            topic, msgtype, typestore=msgs.jazzy_typestore(), offered_qos_profiles=default_qos())

    def write_raw(self, out_conn: Any, ts: int, raw: bytes) -> None:
        self.writer.write(out_conn, ts, raw)
        self.counts[out_conn.topic] = self.counts.get(out_conn.topic, 0) + 1

    def write_msg(self, topic: str, ts: int, msg: Any) -> None:
        raw = msgs.jazzy_typestore().serialize_cdr(msg, msg.__msgtype__)
        self.write_raw(self._outs[topic], ts, raw)

    def close(self) -> None:
        """Write index and metadata (the bag is then readable); falls back to abort on failure."""
        if self.closed:
            return
        self.closed = True
        try:
            self.writer.close()
        except Exception:
            self.writer.abort()
            raise


# =========================================================================================
# statistics, plot series, progress
# =========================================================================================
class _Stats:
    """Streaming min/max of every output column (``recording.csv_row`` names, units in the
    names) and a streaming least-squares fit of the drift angle over the last segment (the
    outputs since the last reset), so the drift rate is a slope over the whole segment and not
    the instantaneous rate, which follows the vehicle's oscillations."""

    def __init__(self) -> None:
        self.lo: dict[str, float] = {}
        self.hi: dict[str, float] = {}
        self.non_finite: dict[str, int] = {}
        self.n = 0
        self.last = None
        self._fit = _LineFit()

    def add(self, out: Any, new_segment: bool) -> None:
        from .io.recording import csv_row

        self.n += 1
        for k, v in csv_row(out).items():
            if not math.isfinite(v):
                self.non_finite[k] = self.non_finite.get(k, 0) + 1
                continue
            if k not in self.lo or v < self.lo[k]:
                self.lo[k] = v
            if k not in self.hi or v > self.hi[k]:
                self.hi[k] = v
        if new_segment or self.last is None:
            self._fit = _LineFit()
        if np.all(np.isfinite(out.drift_angle)):
            self._fit.add(out.t, np.asarray(out.drift_angle, float))
        self.last = out

    def ranges(self) -> dict[str, list[float]]:
        return {k: [self.lo[k], self.hi[k]] for k in self.lo}

    def drift(self) -> dict[str, Any]:
        """Final drift angle (rad) and the least-squares drift rate of the last segment (rad/s
        and deg/h, per platform axis and norm; absent with fewer than 2 outputs)."""
        if self.last is None:
            return {}
        ax = lambda v: {"x": float(v[0]), "y": float(v[1]), "z": float(v[2]),  # noqa: E731
                        "norm": float(np.linalg.norm(v))}
        res: dict[str, Any] = {"final_drift_angle_rad": ax(np.asarray(self.last.drift_angle, float))}
        slope = self._fit.slope()
        if slope is not None:
            res["drift_rate_rad_s"] = ax(slope)
            res["drift_rate_deg_h"] = ax(slope * 180 / math.pi * 3600)
            res["fit_s"] = self._fit.span
            res["fit_outputs"] = self._fit.n
        return res


class _LineFit:
    """Streaming least-squares slope of y (k,) against t (s); times taken relative to the first
    for conditioning. ``slope()`` is None with fewer than 2 distinct times."""

    def __init__(self) -> None:
        self.n, self.t0, self.span = 0, 0.0, 0.0
        self.st = self.stt = 0.0
        self.sy = self.sty = None

    def add(self, t: float, y: np.ndarray) -> None:
        if self.n == 0:
            self.t0, self.sy, self.sty = t, np.zeros_like(y), np.zeros_like(y)
        x = t - self.t0
        self.n += 1
        self.st += x
        self.stt += x * x
        self.sy += y
        self.sty += x * y
        self.span = x

    def slope(self) -> np.ndarray | None:
        den = self.n * self.stt - self.st ** 2
        if self.n < 2 or den <= 1e-300:
            return None
        return (self.n * self.sty - self.st * self.sy) / den


class _PlotSeries:
    """At most ``cap`` outputs, evenly thinned (stride doubles when full): bounded memory."""

    def __init__(self, cap: int = PLOT_POINTS):
        self.cap, self.stride, self.i, self.items = cap, 1, 0, []

    def add(self, out: Any) -> None:
        if self.i % self.stride == 0:
            self.items.append(out)
            if len(self.items) >= self.cap:
                self.items = self.items[::2]
                self.stride *= 2
        self.i += 1


class Progress:
    """Plain-text progress bar on stderr (no dependencies): redrawn in place on a terminal,
    a line every 10 % otherwise."""

    def __init__(self, total: int | None, enabled: bool = True, stream: Any = None):
        self.total, self.enabled = total, enabled
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = time.perf_counter()
        self.last_draw = 0.0
        self.last_decile = -1
        self.last_n = -1

    def update(self, n: int, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.tty:
            if not force and now - self.last_draw < 0.2:
                return
            self.last_draw = now
            self.stream.write("\r" + self._line(n, now))
            self.stream.flush()
        else:
            decile = int(10 * n / self.total) if self.total else n // 10000
            if (force and n != self.last_n) or decile > self.last_decile:
                self.last_decile, self.last_n = decile, n
                self.stream.write(self._line(n, now) + "\n")
                self.stream.flush()

    def _line(self, n: int, now: float) -> str:
        rate = n / max(now - self.t0, 1e-9)
        if self.total:
            frac = min(n / self.total, 1.0)
            bar = "#" * int(30 * frac)
            return f"replay [{bar:<30}] {100 * frac:5.1f}% {n}/{self.total} msgs {rate:,.0f} msg/s"
        return f"replay {n} msgs {rate:,.0f} msg/s"

    def done(self, n: int) -> None:
        if self.enabled:
            self.update(n, force=True)
            if self.tty:
                self.stream.write("\n")


# =========================================================================================
# replay
# =========================================================================================
@dataclass
class ReplayConfig:
    """How to replay. Rates in Hz (``output_rate`` 0 or None: every accepted sample)."""

    topic: str | None = None
    storage: str | None = None
    output_rate: float | None = DEFAULT_OUTPUT_RATE
    diagnostics_rate: float = DEFAULT_DIAGNOSTICS_RATE
    mounting: Mounting = field(default_factory=Mounting)
    gate: GateConfig = field(default_factory=GateConfig)
    namespace: str = ""
    params: Any = None
    options: Any = None
    plot: bool = True
    progress: bool = True


def sidecar_paths(out_bag: Path) -> tuple[Path, Path]:
    """(summary JSON, plot PNG) next to the output bag: ``OUT.summary.json``, ``OUT.png``."""
    out_bag = Path(out_bag)
    return out_bag.with_name(out_bag.name + ".summary.json"), out_bag.with_name(out_bag.name + ".png")


def _grid_index(t_ns: int, origin_ns: int, rate: float) -> int:
    """Index of the output slot of ``t_ns``: floor((t − origin)·rate) (rate in Hz)."""
    return math.floor((t_ns - origin_ns) * 1e-9 * rate + 1e-9)


def replay(in_bag: str | Path, out_bag: str | Path, config: ReplayConfig | None = None) -> dict[str, Any]:
    """Replay ``in_bag`` into ``out_bag``; returns the summary (also written as JSON).

    Raises BagReadError / ReplayError if nothing could be started (no output is created then).
    A read error after the start ends the replay; the output bag is closed (readable) and the
    summary's ``error`` names it.
    """
    from .engine.simulator import Simulator

    cfg = config or ReplayConfig()
    in_bag, out_bag = Path(in_bag), Path(out_bag)
    if out_bag.exists():
        raise ReplayError(f"{out_bag}: exists already; choose another --out (nothing is overwritten)")
    summary_path, plot_path = sidecar_paths(out_bag)
    wall0 = time.perf_counter()
    bag = InputBag(in_bag, cfg.topic)
    bag.open()
    try:
        if bag.salvaged:
            print(f"gyro-platform replay: warning: {in_bag}: {bag.damage}; salvaging the readable messages",
                  file=sys.stderr)
        out_topics = msgs.output_topics(cfg.namespace)
        # /diagnostics is shared by every node (status names tell them apart): no clash there
        clash = sorted({c.topic for c in bag.connections
                        if c.topic in out_topics and not (c.topic == "/diagnostics" and c.msgtype == out_topics[c.topic])})
        if clash:
            raise ReplayError(f"{in_bag}: has output topic(s) {clash} already; use --namespace to separate them")
        kwargs = {}
        if cfg.params is not None:
            kwargs["params"] = cfg.params
        if cfg.options is not None:
            kwargs["options"] = cfg.options
        sim = Simulator(**kwargs)
        out = OutputBag(out_bag, cfg.storage or bag.storage)
        try:
            for conn in bag.connections:
                out.copy_connection(conn, bag.store_for(conn))
            for topic, typ in out_topics.items():
                out.add_output(topic, typ)
            run = _Run(bag, out, sim, cfg)
            run.loop()
        finally:
            out.close()       # index + metadata written: the bag is readable whatever happened
    finally:
        bag.close()
    summary = run.summary(in_bag, out_bag, time.perf_counter() - wall0)
    if out.skipped:
        summary["output"]["skipped_topics"] = out.skipped
    summary["files"] = {"bag": str(out_bag), "summary": str(summary_path), "plot": None}
    if cfg.plot:
        summary["files"]["plot"], summary["recorder"] = run.plot(plot_path)
    summary_path.write_text(json.dumps(summary, indent=2, default=_json_default) + "\n")
    return summary


#: why a drop reason took every sample, and the fix
DROP_HINTS = {
    "zero_stamp": "every header stamp is 0; time by receive time instead (--time-source receive or auto)",
    "unknown_frame": "the input frame has no mounting; give --mount FRAME=... or --unknown-frame identity",
    "over_rate": "every rate exceeds --max-rate; raise it if the rates are real",
    "no_rate": "the messages carry no angular rate",
    "non_finite": "every rate is NaN or infinite",
    "bad_message": "no message could be decoded",
}


def no_sample_hint(dropped_by_reason: dict[str, int], n_in: int) -> str:
    """One line: no sample of ``n_in`` was accepted, the main drop reason and its fix."""
    if not dropped_by_reason:
        return f"none of the {n_in} input messages was accepted: no outputs"
    reason, count = max(dropped_by_reason.items(), key=lambda kv: kv[1])
    hint = DROP_HINTS.get(reason, "see dropped_by_reason in the summary")
    return f"none of the {n_in} input messages was accepted ({count} dropped as {reason}): {hint}"


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


class _Run:
    """State of one replay loop (kept out of ``replay`` to keep that readable)."""

    def __init__(self, bag: InputBag, out: OutputBag, sim: Any, cfg: ReplayConfig):
        self.bag, self.out, self.sim, self.cfg = bag, out, sim, cfg
        self.types = MessageTypes.rosbags()
        self.gate = TimeGate(cfg.gate)
        self.stats = _Stats()
        self.series = _PlotSeries()
        self.outcomes: dict[str, int] = {}
        self.n_msgs = 0
        self.n_in = 0
        self.n_out = 0
        self.slot: int | None = None        # output grid slot of the last output
        self.diag_slot: int | None = None
        self.first_rx: int | None = None
        self.first_ts: int | None = None
        self.last_ts: int | None = None
        self.last_out = None
        self.new_segment = True
        self.error: str | None = None
        self.interrupted = False
        self.sim_errors: list[str] = []
        self.identity_frames: list[str] = []
        self.diag_topic = msgs.resolve("/diagnostics")

    def loop(self) -> None:
        progress = Progress(self.bag.message_count, self.cfg.progress)
        try:
            for conn, ts, raw in self.bag.messages():
                self.n_msgs += 1
                if self.first_ts is None:
                    self.first_ts = ts
                self.last_ts = ts
                copy = self.out.copy_connection(conn, self.bag.store_for(conn))
                if copy is not None:
                    self.out.write_raw(copy, ts, raw)
                if self.bag.is_input(conn):
                    self._input(conn, ts, raw)
                progress.update(self.n_msgs)
        except BagReadError as e:
            self.error = str(e)
        except KeyboardInterrupt:
            self.interrupted = True
            self.error = "interrupted"
        finally:
            progress.done(self.n_msgs)

    def _input(self, conn: Any, ts: int, raw: bytes) -> None:
        self.n_in += 1
        n_identity = self.gate.notes["identity_frame"]
        decision, msg = judge(self.bag, conn, raw, ts, self.cfg.mounting, self.gate)
        if self.gate.notes["identity_frame"] > n_identity:
            frame = str(msg.header.frame_id)
            if frame not in self.identity_frames:
                self.identity_frames.append(frame)
                print(f"gyro-platform replay: info: frame_id {frame!r} has no --mount; taken as "
                      f"base_link, counted in the summary (--unknown-frame reject drops such samples)",
                      file=sys.stderr)
        outcome = apply_decision(self.sim, decision)
        self.outcomes[outcome] = self.outcomes.get(outcome, 0) + 1
        if outcome in ("reset", "restarted"):
            self.slot = None
            self.new_segment = True
        if outcome == "restarted" and len(self.sim_errors) < 100:
            self.sim_errors.append(f"t={decision.stamp_ns}: integration failed, simulator restarted")
        if outcome in ("pushed", "reset", "restarted"):
            rate = self.cfg.output_rate
            slot = _grid_index(decision.stamp_ns, self.gate.origin_ns, rate) if rate else None
            if self.slot is None or rate is None or rate <= 0 or slot > self.slot:
                self.slot = slot
                self._emit(decision.stamp_ns, ts)
        # diagnostics on the receive clock, like a node's timer
        if self.first_rx is None:
            self.first_rx = ts
        dslot = _grid_index(ts, self.first_rx, self.cfg.diagnostics_rate)
        if self.diag_slot is None or dslot > self.diag_slot:
            self.diag_slot = dslot
            self.out.write_msg(self.diag_topic, ts, msgs.diagnostic_array(
                self.gate.snapshot(), self.last_out, self.types, ts, self._sim_figures()))

    def _emit(self, stamp: int, ts: int) -> None:
        try:
            o = self.sim.outputs()
        except SimulationError as e:
            self.outcomes["output_failed"] = self.outcomes.get("output_failed", 0) + 1
            if len(self.sim_errors) < 100:
                self.sim_errors.append(f"t={stamp}: outputs failed: {e}")
            return
        for topic, m in msgs.output_messages(o, self.types, stamp, self.cfg.namespace):
            self.out.write_msg(topic, ts, m)
        self.n_out += 1
        self.stats.add(o, self.new_segment)
        self.new_segment = False
        self.series.add(o)
        self.last_out = o

    def _sim_figures(self) -> dict[str, Any]:
        return {"outputs": self.n_out, **{f"sim_{k}": v for k, v in self.outcomes.items()}}

    # ---- results --------------------------------------------------------------------------
    def summary(self, in_bag: Path, out_bag: Path, wall: float) -> dict[str, Any]:
        snap = self.gate.snapshot()
        duration = 0.0 if self.first_ts is None else (self.last_ts - self.first_ts) / NS
        opts = self.sim.options
        return {
            "input": {"bag": str(in_bag), "storage": self.bag.storage, "topic": self.bag.topic,
                      "type": self.bag.msgtype, "messages": self.n_msgs, "topic_messages": self.n_in,
                      "salvaged": self.bag.salvaged, "damage": self.bag.damage,
                      "time_source": snap["time_source"]},
            "output": {"bag": str(out_bag), "storage": self.out.storage, "version": 9,
                       "messages": sum(self.out.counts.values()), "messages_by_topic": dict(self.out.counts),
                       "outputs": self.n_out, "output_rate_hz": self.cfg.output_rate or None,
                       "diagnostics_rate_hz": self.cfg.diagnostics_rate, "namespace": self.cfg.namespace},
            "counts": {"in": self.n_in, "accepted": snap["accepted"], "dropped": snap["dropped"],
                       "dropped_by_reason": snap["dropped_by_reason"], "resets": snap["resets"],
                       "resets_by_reason": snap["resets_by_reason"], "notes": snap["notes"],
                       "simulator": dict(self.outcomes), "out": self.n_out},
            "gate": snap,
            "duration_s": duration,
            "wall_time_s": wall,
            "real_time_factor": duration / wall if wall > 0 else None,
            "messages_per_s": self.n_msgs / wall if wall > 0 else None,
            "ranges": self.stats.ranges(),
            "non_finite_outputs": self.stats.non_finite,
            "drift": self.stats.drift(),
            "simulator": {"mode": opts.mode, "fidelity": opts.fidelity, "effects": sorted(opts.effects),
                          "stats": self.sim.stats, "errors": self.sim_errors[:20]},
            "config": {"gate": vars(self.cfg.gate), "mounting": self.cfg.mounting.frames(),
                       "unknown_frame": self.cfg.mounting.unknown_frame,
                       "frames_taken_as_base_link": self.identity_frames},
            "warnings": self.warnings(snap),
            "error": self.error,
        }

    def warnings(self, snap: dict[str, Any]) -> list[str]:
        """What a user must know about this replay's results (also printed)."""
        res = []
        if self.n_in and not snap["accepted"]:
            res.append(no_sample_hint(snap["dropped_by_reason"], self.n_in))
        elif self.n_in == 0 and self.error is None:
            res.append(f"topic {self.bag.topic} has no messages: no outputs")
        return res

    def plot(self, path: Path) -> tuple[str | None, Any]:
        """PNG and Recorder summary of the (thinned) output series, via ``recording.Recorder``."""
        if not self.series.items:
            return None, None
        try:
            from .io.recording import Recorder
        except ImportError as e:
            print(f"gyro-platform replay: warning: no plot ({e})", file=sys.stderr)
            return None, {"unavailable": str(e)}
        rec = Recorder()
        for o in self.series.items:
            rec.append(o)
        try:
            rec.plot(path, title=f"replay of {self.bag.path.name}, topic {self.bag.topic} "
                                 f"({self.sim.options.mode}, {self.sim.options.fidelity})")
            return str(path), rec.summary()
        except Exception as e:  # a plot must not lose the replay
            print(f"gyro-platform replay: warning: plot failed: {e}", file=sys.stderr)
            return None, {"error": str(e)}


# =========================================================================================
# command line
# =========================================================================================
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``gyro-platform replay``."""
    p = parser
    p.add_argument("in_bag", metavar="IN_BAG", help="rosbag2 directory (sqlite3 or mcap) or .db3/.mcap file")
    p.add_argument("--out", required=True, metavar="OUT_BAG", help="output bag directory (must not exist)")
    p.add_argument("--topic", help="input topic (default: the first Imu/Twist/TwistStamped topic)")
    p.add_argument("--scene", metavar="S", help="scene YAML: params, options, output rate")
    p.add_argument("--storage", choices=("sqlite3", "mcap"), help="output storage (default: as the input)")
    p.add_argument("--output-rate", type=float, metavar="HZ",
                   help=f"output rate, Hz (default: the scene's, else {DEFAULT_OUTPUT_RATE:g}; 0 = every sample)")
    p.add_argument("--diagnostics-rate", type=float, default=DEFAULT_DIAGNOSTICS_RATE, metavar="HZ",
                   help="/diagnostics rate on the receive clock, Hz (default 1)")
    p.add_argument("--mount", action="append", default=[], metavar="FRAME=Q",
                   help="sensor mounting in base_link: FRAME=qx,qy,qz,qw or FRAME=roll,pitch,yaw (rad); repeatable")
    p.add_argument("--unknown-frame", choices=Mounting.UNKNOWN_POLICIES, default="identity",
                   help="frame_id without --mount: take as base_link (default) or drop the samples")
    p.add_argument("--time-source", choices=("auto", "header", "receive"), default="auto",
                   help="sample time: header stamp, bag receive time, or auto (header unless the first is 0)")
    p.add_argument("--max-gap", type=float, default=GateConfig.max_gap, metavar="S",
                   help=f"longest input gap, s (default {GateConfig.max_gap:g})")
    p.add_argument("--on-gap", choices=("reset", "integrate"), default=GateConfig.on_gap,
                   help="after a longer gap: restart the simulation (default) or integrate across")
    p.add_argument("--reset-on-jump-back", type=float, default=GateConfig.reset_on_jump_back, metavar="S",
                   help=f"time jumping back more than this restarts (looped bag), s (default "
                        f"{GateConfig.reset_on_jump_back:g}); smaller steps back are dropped")
    p.add_argument("--max-rate", type=float, default=GateConfig.max_rate, metavar="RAD_S",
                   help=f"drop samples with |omega| above this, rad/s (default {GateConfig.max_rate:g})")
    p.add_argument("--namespace", default="", help="namespace of the output topics (default: root)")
    p.add_argument("--no-plot", action="store_true", help="do not write OUT_BAG.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def print_results(summary: dict[str, Any], out_bag: Any, file: Any = None) -> None:
    """The replay's results on stdout: counts, output files, warnings."""
    out = file if file is not None else sys.stdout
    c = summary["counts"]
    drops = f" {c['dropped_by_reason']}" if c["dropped_by_reason"] else ""
    print(f"{summary['input']['topic']}: {c['in']} in, {c['accepted']} accepted, {c['dropped']} dropped{drops}, "
          f"{c['resets']} resets; {c['out']} outputs; "
          f"{summary['duration_s']:.1f} s of data in {summary['wall_time_s']:.2f} s "
          f"(x{summary['real_time_factor'] or 0:.0f} real time) -> {out_bag}", file=out)
    d = summary.get("drift") or {}
    if "drift_rate_deg_h" in d:
        print(f"drift rate (least-squares slope of the drift angle over the last {d['fit_s']:.1f} s): "
              f"{d['drift_rate_deg_h']['norm']:.4g} deg/h", file=out)
    for w in summary.get("warnings", []):
        print(f"warning: {w}", file=out)
    files = summary["files"]
    print("wrote " + ", ".join(str(files[k]) for k in ("bag", "summary", "plot") if files.get(k)), file=out)


def config_from_args(args: argparse.Namespace) -> ReplayConfig:
    """ReplayConfig from parsed arguments (loads the scene if given)."""
    frames = dict(Mounting.parse_spec(s) for s in args.mount)
    cfg = ReplayConfig(
        topic=args.topic, storage=args.storage, diagnostics_rate=args.diagnostics_rate,
        mounting=Mounting(frames, unknown_frame=args.unknown_frame),
        gate=GateConfig(max_gap=args.max_gap, on_gap=args.on_gap, reset_on_jump_back=args.reset_on_jump_back,
                        max_rate=args.max_rate, time_source=args.time_source),
        namespace=args.namespace, plot=not args.no_plot, progress=not args.quiet)
    if args.scene:
        try:
            from .scenes.runner import load_scene
        except ImportError as e:
            raise ReplayError(f"--scene needs gyro_platform.scenes.runner.load_scene: {e}") from None
        scene = load_scene(args.scene)
        cfg.params, cfg.options = scene.params, scene.options
        if getattr(scene, "output_rate", None):
            cfg.output_rate = float(scene.output_rate)
    if args.output_rate is not None:
        if not (math.isfinite(args.output_rate) and args.output_rate >= 0):
            raise ReplayError(f"--output-rate {args.output_rate}: must be a finite rate >= 0 Hz (0 = every sample)")
        cfg.output_rate = args.output_rate if args.output_rate > 0 else None
    if not (math.isfinite(cfg.diagnostics_rate) and cfg.diagnostics_rate > 0):
        raise ReplayError(f"--diagnostics-rate {cfg.diagnostics_rate}: must be a finite rate > 0 Hz")
    if not NAMESPACE_RE.fullmatch(cfg.namespace):
        raise ReplayError(f"--namespace {cfg.namespace!r}: not a ROS namespace (tokens of letters, digits and "
                          f"'_' separated by '/', not starting with a digit)")
    return cfg


def run(args: argparse.Namespace) -> int:
    """``gyro-platform replay``: exit 0 ok, 2 cannot start (bad argument, not a bag, no input
    topic), 3 input damaged (partial output written), 130 interrupted. Results go to stdout,
    progress, warnings and errors to stderr."""
    try:
        cfg = config_from_args(args)
        summary = replay(args.in_bag, args.out, cfg)
    except BagPathError as e:
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_ERROR
    except BagReadError as e:    # rosbags and the salvage reader both failed: corrupt data
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_DAMAGED
    except (ReplayError, ValueError) as e:
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_ERROR
    print_results(summary, args.out)
    if summary["counts"]["in"] and not summary["counts"]["accepted"] and not summary["error"]:
        print(f"gyro-platform replay: error: {summary['warnings'][0]}", file=sys.stderr)
        return EXIT_ERROR
    if summary["error"]:
        if summary["error"] == "interrupted":
            print("gyro-platform replay: interrupted; the output bag is closed and readable", file=sys.stderr)
            return EXIT_INTERRUPTED
        print(f"gyro-platform replay: error: {summary['error']}; output bag closed and readable "
              f"({summary['output']['messages']} messages)", file=sys.stderr)
        return EXIT_DAMAGED
    return EXIT_OK
