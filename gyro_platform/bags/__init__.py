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

"""bags — rosbag2 bags in and out (sqlite3 and mcap), through rosbags.

Holds where a bag's files are (``paths``), reading an intact bag (``reader``: ``InputBag``; fast
block readers ``fast``), salvaging a damaged one (``salvage``), rosbags' reader opening a type of no definition
(``lenient``), the storage writers (``storage``,
with ``rows``: a write batch's payloads, and ``yaml_dump``: libyaml for its YAML) and writing the
output bag (``writer``: ``OutputBag``). May import ``messages`` (types, blocks, decoding),
``physics`` (jit), ``errors``, ``signals`` and ``filesystem``.

rosbags versions: ``setup.py`` pins the range tested (``rosbags>=0.11.6,<0.12``; 0.11.6 is the
first with every piece below: ``storage_mcap.decompress`` came in 0.11.6, ``DirectoryReader`` in
0.11.0, ``Stores.ROS2_JAZZY`` in 0.10.8); re-run the check with
``test/rosbags_range.sh`` (docs/replay.md). Public API used: ``rosbags.rosbag2`` (``Reader``,
``Writer``, ``ReaderError``, ``WriterError``, ``StoragePlugin``, ``CompressionMode``),
``rosbags.interfaces`` (``Connection``, message definitions, QoS) and ``rosbags.typesys``.
Internals used, and why (no public API does it at an acceptable cost):

* ``storage``: subclasses of ``storage_sqlite3.Sqlite3Writer`` (its ``SQLITE_SCHEMA`` and
  connection records on ``cursor``) and ``storage_mcap.McapWriter`` (its ``bio``, ``chunk``, a
  ``PendingChunk``, ``chunks``, ``channel_stats``, message times, ``compressor``) put in
  ``Writer.STORAGE_PLUGINS``; ``Writer.storage``, ``counts``, ``min_timestamp``,
  ``max_timestamp`` kept right by ``write_rows``. Why: ``Writer.write`` takes one message per
  call (10x slower for MCAP, 2x for sqlite3) and has no bounded commits, rollback or cut-back
  after a full disk; the files stay rosbags' (tested byte for byte).
* ``yaml_dump``: ``rosbags.rosbag2.writer.YAML`` swapped for libyaml while the writer dumps its
  QoS and ``metadata.yaml`` (ruamel: ~0.3 s for 16 topics; no hook for the dumper).
* ``fast``: ``Reader.storage`` (``reader.DirectoryReader``: ``storages``, ``metadata``;
  ``storage_sqlite3.Sqlite3Reader.dbconn``: rosbags' own query on its apsw connection;
  ``storage_mcap.McapReader.chunks``, ``ChunkInfo``: its chunk index) and
  ``storage_mcap.decompress`` (chunk size and CRC, rosbags' decompressors). Why: rows as arrays
  without a Python object per message (MCAP 0.4–0.8 µs per row against 2.4–4.9 through
  ``Reader.messages``, sqlite3 0.8–0.9 against 1.1–1.5).
* ``lenient``: a subclass of ``storage_sqlite3.Sqlite3Reader`` put in ``Reader.STORAGE_PLUGINS`` and
  ``reader.DirectoryReader.STORAGE_PLUGINS``; when rosbags' ``open`` fails on a
  ``message_definitions`` encoding it does not map (rosbag2's empty definition of a type), it sets
  the reader's ``dbconn``, ``schema``, ``msgtypes``, ``connections`` and ``metadata``
  (``ReaderMetadata``) as rosbags does. Why: rosbags' sqlite3 reader raises ``KeyError`` there
  (its MCAP reader reads it as no definition) and has no hook for it.
* ``salvage`` and ``fast``: ``metadata.parse_qos`` (QoS text → ``Qos``, as rosbags parses it)
  and ``storage_mcap.decompress`` for damaged or foreign files rosbags' ``Reader`` refuses.
* ``fast``: ``reader.zstd``, the module whose ``decompress`` rosbags' ``Reader.messages`` applies
  to each message of a bag compressed message by message (``backports.zstd`` or
  ``compression.zstd`` in 0.11.9, ``zstandard`` in 0.11.6): what a payload the kept
  decompression context does not take (several frames, no size in its header) goes to, so that
  it reads as rosbags reads it in every version. Why: rosbags sets up a context per message
  (~18 µs a 1 kHz Imu message; ~0.5 µs with one kept).
"""
from .reader import InputBag
from .writer import OutputBag

__all__ = ["InputBag", "OutputBag"]
