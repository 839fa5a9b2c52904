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

"""rosbags' ``Reader`` that also opens an intact sqlite3 bag with a type of no definition.

rosbag2's writer stores ``MessageDefinition::empty_message_definition_for(type)`` (an encoding
rosbags does not know, '' or ``unknown``, and an empty text) in ``message_definitions`` for a
type whose definition the recording machine did not find. rosbags' sqlite3 reader maps only
``ros2msg``/``ros2idl`` and fails with ``KeyError`` on such a bag (its MCAP reader maps '' to
no definition). :func:`reader_class` is rosbags' ``Reader`` whose sqlite3 storage reads that
row as no definition (``MessageDefinitionFormat.NONE``, as the MCAP reader does); every other
bag is opened by rosbags' own code.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any

from .paths import rosbags_api

#: encodings of ``message_definitions`` rosbags maps to a definition format
KNOWN_ENCODINGS = ("ros2msg", "ros2idl")

TOPICS_QUERY = ("SELECT topics.id, name, type, count(messages.id), serialization_format, offered_qos_profiles, "
                "type_description_hash FROM topics LEFT JOIN messages ON topics.id == messages.topic_id "
                "GROUP BY topics.id ORDER BY topics.id")


def _open_lenient(storage: Any) -> None:
    """Open rosbags ``Sqlite3Reader`` ``storage`` as its own ``open`` does (schema 4 and later:
    the only ones with ``message_definitions``), a definition of an unknown encoding read as none."""
    import apsw
    from rosbags.rosbag2.metadata import parse_qos

    rb = rosbags_api()
    fmt = rb["MsgDefFormat"]
    formats = {"ros2msg": fmt.MSG, "ros2idl": fmt.IDL}
    storage.dbconn = apsw.Connection(f"file:{storage.path}?immutable=1",
                                     flags=apsw.SQLITE_OPEN_READONLY | apsw.SQLITE_OPEN_URI)
    try:
        cur = storage.dbconn.cursor()
        (schema,) = cur.execute("SELECT schema_version FROM schema").fetchone() or (-1,)
        msgtypes = [{"name": n, "encoding": e, "msgdef": d, "digest": h} for n, e, d, h in cur.execute(
            "SELECT topic_type, encoding, encoded_message_definition, type_description_hash "
            "FROM message_definitions ORDER BY id")]

        def msgdef(name: str) -> Any:
            x = next((x for x in msgtypes if x["name"] == name), None)      # rosbags takes the first
            if x is None or x["encoding"] not in formats:
                return rb["MsgDef"](fmt.NONE, "")
            return rb["MsgDef"](formats[x["encoding"]], x["msgdef"])

        conns = [rb["Connection"](cid, topic, typ, msgdef(typ), digest, n, rb["Ext"](sfmt, parse_qos(qos)), storage)
                 for cid, topic, typ, n, sfmt, qos, digest in cur.execute(TOPICS_QUERY)]
        start, end, count = cur.execute(
            "SELECT MIN(timestamp), MAX(timestamp) + 1, COUNT(*) FROM messages").fetchone()
        storage.schema, storage.msgtypes, storage.connections = schema, msgtypes, conns
        storage.metadata = type(storage.metadata)(
            end - start if start is not None else 0, start if start is not None else 2 ** 63 - 1,
            end if end is not None else 0, count, None, None, None, None)
    except BaseException:
        storage.dbconn.close()
        storage.dbconn = None
        raise


def _unknown_encodings(path: Any) -> bool:
    """True when the database ``path`` has a ``message_definitions`` row rosbags cannot map."""
    import apsw

    try:
        db = apsw.Connection(f"file:{path}?immutable=1", flags=apsw.SQLITE_OPEN_READONLY | apsw.SQLITE_OPEN_URI)
        try:
            q = f"SELECT count(*) FROM message_definitions WHERE encoding NOT IN {KNOWN_ENCODINGS!r}"
            return bool(db.execute(q).fetchone()[0])
        finally:
            db.close()
    except apsw.Error:
        return False


@lru_cache(maxsize=None)
def reader_class() -> type:
    """rosbags' ``Reader`` (a folder through ``DirectoryReader``, a lone ``.db3``) on a sqlite3
    storage reader that opens a bag with definitions of unknown encoding (made once, on first use)."""
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.reader import DirectoryReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    class LenientSqlite3Reader(Sqlite3Reader):
        """rosbags' sqlite3 reader; a type of no definition (rosbag2's empty one) reads as none."""

        def open(self) -> None:
            try:
                super().open()
            except KeyError:            # rosbags: fmtmap[encoding] of a row it cannot map
                if not _unknown_encodings(self.path):
                    raise
                _open_lenient(self)

    class LenientDirectoryReader(DirectoryReader):
        """rosbags' ``DirectoryReader`` on :class:`LenientSqlite3Reader`."""

        STORAGE_PLUGINS = {**DirectoryReader.STORAGE_PLUGINS, "sqlite3": LenientSqlite3Reader}

    class LenientReader(Reader):
        """rosbags' ``Reader`` on :class:`LenientDirectoryReader` and :class:`LenientSqlite3Reader`."""

        STORAGE_PLUGINS = {**Reader.STORAGE_PLUGINS, "dir": LenientDirectoryReader, ".db3": LenientSqlite3Reader}

    return LenientReader
