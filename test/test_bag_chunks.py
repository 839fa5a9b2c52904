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

"""InputBag.chunks: the rows of InputBag.messages (rosbags' Reader, or the salvage reader) in
blocks — same rows, same order, same errors — on the shared recordings, on generated sqlite3
and MCAP bags (several topics, equal and out-of-order timestamps, overlapping and compressed
MCAP chunks, a bag of several files, per-message compression (read fast, each payload
decompressed; a payload that does not decompress: the same rows, then the same error), an
unindexed MCAP file) and on damaged bags.
Issue 17: valid MCAP files with JSON/protobuf channels are read (those channels
skipped with a count), and two types on one topic are not merged into the input."""
from __future__ import annotations

import json
from pathlib import Path
import shutil

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import get_typestore, Stores
import yaml

from gyro_platform import cli
from gyro_platform.bags.reader import InputBag
from gyro_platform.errors import BagReadError
from gyro_platform.messages.blocks import RowChunk

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SHARED = sorted(p for p in BAGS.iterdir() if p.is_dir()) if BAGS.is_dir() else []
J = get_typestore(Stores.ROS2_JAZZY)
T = J.types
S = 1_000_000_000
T0 = 1_700_000_000 * S
IMU, TWS, STR = "sensor_msgs/msg/Imu", "geometry_msgs/msg/TwistStamped", "std_msgs/msg/String"


# ---- helpers -----------------------------------------------------------------------------
def stamp(ns):
    return T["builtin_interfaces/msg/Time"](sec=ns // S, nanosec=ns % S)


def imu(ns, w=(0.01, 0.02, 0.03), frame="imu_link"):
    v3 = T["geometry_msgs/msg/Vector3"]
    return T[IMU](header=T["std_msgs/msg/Header"](stamp=stamp(ns), frame_id=frame),
                  orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                  orientation_covariance=np.zeros(9), angular_velocity=v3(x=w[0], y=w[1], z=w[2]),
                  angular_velocity_covariance=np.zeros(9), linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
                  linear_acceleration_covariance=np.zeros(9))


def twist_stamped(ns, w=(0.1, 0.2, 0.3)):
    v3 = T["geometry_msgs/msg/Vector3"]
    return T[TWS](header=T["std_msgs/msg/Header"](stamp=stamp(ns), frame_id="base_link"),
                  twist=T["geometry_msgs/msg/Twist"](linear=v3(x=0.0, y=0.0, z=0.0),
                                                     angular=v3(x=w[0], y=w[1], z=w[2])))


def cdr(msg, msgtype):
    return bytes(J.serialize_cdr(msg, msgtype))


def mixed_rows(n=600, seed=1):
    """(topic, type, time ns, raw) of three topics: ties across topics, a burst written out of
    time order, and a topic written late with early times."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        t = T0 + i * 1_000_000
        rows.append(("/imu", IMU, t, cdr(imu(t, (i * 1e-3, 0.0, 0.0)), IMU)))
        if i % 5 == 0:
            rows.append(("/tw", TWS, t, cdr(twist_stamped(t), TWS)))                # tie with /imu
        if i % 50 == 0:
            rows.append(("/note", STR, int(t - rng.integers(0, 30_000_000)), cdr(T[STR](data=f"n{i}"), STR)))
    late = [("/note", STR, T0 + k * 7_000_000, cdr(T[STR](data=f"late{k}"), STR)) for k in range(40)]
    return rows + late


def write_rosbags(path, rows, storage="sqlite3", compression=None):
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    w = Writer(path, version=9, storage_plugin=plugin)
    if compression is not None:
        w.set_compression(compression, CompressionFormat.ZSTD)
    with w:
        conns = {}
        for topic, typ, t, raw in rows:
            c = conns.get((topic, typ))
            if c is None:
                c = conns[(topic, typ)] = w.add_connection(topic, typ, typestore=J)
            w.write(c, t, raw)
    return path


def write_mcap(path, rows, profile="ros2", chunk_size=4096, compression="zstd", extra_channels=(), index=True,
               chunked=True):
    """MCAP file written with the mcap package (small chunks: many, overlapping in time when
    rows are out of order). ``extra_channels``: (topic, message encoding, schema name, schema
    encoding, [(time, bytes)]) of non-CDR channels."""
    from mcap.writer import CompressionType, IndexType
    from mcap.writer import Writer as McapWriter

    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}[compression]
    with open(path, "wb") as f:
        w = McapWriter(f, chunk_size=chunk_size, compression=comp, use_chunking=chunked,
                       index_types=IndexType.ALL if index else IndexType.NONE, use_summary_offsets=index)
        w.start(profile=profile, library="test")
        chans = {}
        for topic, typ, *_ in rows:
            if (topic, typ) not in chans:
                sid = w.register_schema(name=typ, encoding="ros2msg", data=J.generate_msgdef(typ)[0].encode())
                chans[(topic, typ)] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        extra = []
        for topic, menc, sname, senc, recs in extra_channels:
            sid = w.register_schema(name=sname, encoding=senc, data=b"{}")
            cid = w.register_channel(topic=topic, message_encoding=menc, schema_id=sid)
            extra += [(t, cid, data) for t, data in recs]
        for topic, typ, t, raw in rows:
            w.add_message(chans[(topic, typ)], log_time=t, publish_time=t, data=raw)
        for t, cid, data in extra:
            w.add_message(cid, log_time=t, publish_time=t, data=data)
        w.finish()
    return path


def read_messages(path, input_only=False, topic=None):
    """(rows as (conn id, time, bytes), the BagReadError or None) through messages()."""
    rows, err = [], None
    with InputBag(path, topic) as b:
        try:
            for c, t, raw in b.messages(input_only=input_only):
                rows.append((c.id, t, bytes(raw)))
        except BagReadError as e:
            err = e
    return rows, err


def read_chunks(path, max_rows, input_only=False, topic=None):
    rows, err, sizes = [], None, []
    with InputBag(path, topic) as b:
        try:
            for ch in b.chunks(max_rows, input_only=input_only):
                assert isinstance(ch, RowChunk) and ch.conn_id.dtype == np.int64 and ch.ts.dtype == np.int64
                assert len(ch.conn_id) == len(ch.ts) == len(ch.raws)
                sizes.append(len(ch))
                rows += [(c, t, bytes(r)) for c, t, r in zip(ch.conn_id.tolist(), ch.ts.tolist(), ch.raws)]
        except BagReadError as e:
            err = e
        source = b.chunk_source
    return rows, err, sizes, source


def assert_same_rows(path, expect_source=None, max_rows=(1, 7, 4096), topic=None):
    """chunks() gives messages()' rows and error for every block size, both selections;
    returns messages()' rows and error of the whole bag."""
    for input_only in (True, False):
        ref, ref_err = read_messages(path, input_only, topic)
        for m in max_rows:
            rows, err, sizes, source = read_chunks(path, m, input_only, topic)
            assert rows == ref, (path, input_only, m)
            assert type(err) is type(ref_err), (err, ref_err)
            if err is None:      # blocks are full except the last
                assert all(s == m for s in sizes[:-1]) and (not sizes or 0 < sizes[-1] <= m)
            if expect_source is not None:
                assert source == expect_source
    return ref, ref_err


# ---- intact bags ---------------------------------------------------------------------------
@pytest.mark.parametrize("bag", SHARED, ids=[p.name for p in SHARED])
def test_shared_recordings_same_rows(bag):
    ref, err = assert_same_rows(bag, expect_source="fast")
    assert err is None and len(ref) > 1000


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_generated_bags_same_rows_and_order(tmp_path, storage):
    rows = mixed_rows()
    bag = write_rosbags(tmp_path / "b", rows, storage)
    ref, err = assert_same_rows(bag, expect_source="fast")
    assert err is None and len(ref) == len(rows)
    times = [t for _, t, _ in ref]
    assert times == sorted(times)                                      # rosbags' time order
    assert sorted(r for _, _, r in ref) == sorted(r for *_, r in rows)  # every row once


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_mcap_overlapping_small_chunks_same_order(tmp_path, compression):
    """Out-of-order rows spread over many small chunks whose time ranges overlap: the merge
    order (time, chunk offset, record order) and rosbags' chunk selection are reproduced."""
    rows = mixed_rows(400, seed=2)
    f = write_mcap(tmp_path / "x.mcap", rows, chunk_size=2048, compression=compression)
    ref, err = assert_same_rows(f, expect_source="fast")
    assert err is None and len(ref) == len(rows)


def test_multi_file_bags(tmp_path):
    """A bag folder of two storage files (connections registered in another order in the
    second file): storage ids are mapped to the bag's connection ids as rosbags maps them."""
    for storage, ext in (("sqlite3", "db3"), ("mcap", "mcap")):
        rows = mixed_rows(300)
        a = write_rosbags(tmp_path / f"a_{storage}", rows[: len(rows) // 2], storage)
        second = sorted(rows[len(rows) // 2:], key=lambda r: r[0] != "/note")   # /note registered first
        b = write_rosbags(tmp_path / f"b_{storage}", second, storage)
        bag = tmp_path / f"multi_{storage}"
        bag.mkdir()
        shutil.copy(next(a.glob(f"*.{ext}")), bag / f"part0.{ext}")
        shutil.copy(next(b.glob(f"*.{ext}")), bag / f"part1.{ext}")
        meta = yaml.safe_load((a / "metadata.yaml").read_text())
        info = meta["rosbag2_bagfile_information"]
        mb = yaml.safe_load((b / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        counts = {t["topic_metadata"]["name"]: t["message_count"] for t in mb["topics_with_message_count"]}
        for t in info["topics_with_message_count"]:
            t["message_count"] += counts[t["topic_metadata"]["name"]]
        info["message_count"] += mb["message_count"]
        info["relative_file_paths"] = [f"part0.{ext}", f"part1.{ext}"]
        info["files"] = []
        info["duration"]["nanoseconds"] = 10**12
        (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
        ref, err = assert_same_rows(bag, expect_source="fast")
        assert err is None and len(ref) == len(rows)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bags_compressed_message_by_message_same_rows(tmp_path, storage):
    rows = mixed_rows(200)
    bag = write_rosbags(tmp_path / "zmsg", rows, storage, compression=CompressionMode.MESSAGE)
    ref, err = assert_same_rows(bag, expect_source="fast")          # each payload decompressed
    assert err is None and len(ref) == len(rows)
    assert sorted(r for _, _, r in ref) == sorted(r for *_, r in rows)


def test_payloads_of_several_frames_or_without_size_same_rows(tmp_path):
    """rosbags' zstd.decompress reads several frames and frames whose header states no size."""
    import sqlite3

    import zstandard
    from rosbags.rosbag2.reader import zstd

    rows = mixed_rows(120)
    bag = write_rosbags(tmp_path / "zmsg", rows, "sqlite3", compression=CompressionMode.MESSAGE)
    db = next(bag.glob("*.db3"))
    sizeless = zstandard.ZstdCompressor(write_content_size=False)
    with sqlite3.connect(db) as con:
        for k, (mid, data) in enumerate(con.execute("SELECT id, data FROM messages ORDER BY id").fetchall()):
            raw = zstd.decompress(data)
            new = (zstd.compress(raw[:5]) + zstd.compress(raw[5:])) if k % 2 else sizeless.compress(raw)
            con.execute("UPDATE messages SET data = ? WHERE id = ?", (new, mid))
    ref, err = assert_same_rows(bag, expect_source="fast")
    try:                            # rosbags 0.11.6 (zstandard) refuses a frame without a size
        zstd.decompress(sizeless.compress(b"x"))
    except Exception:               # noqa: BLE001 - then both readers end there, with the same error
        assert isinstance(err, BagReadError)
        return
    assert err is None and sorted(r for _, _, r in ref) == sorted(r for *_, r in rows)


def test_a_payload_that_does_not_decompress_same_rows_then_same_error(tmp_path):
    import sqlite3

    rows = mixed_rows(300)
    bag = write_rosbags(tmp_path / "zmsg", rows, "sqlite3", compression=CompressionMode.MESSAGE)
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:     # the 150th message in time order: not a zstd frame
        (mid,) = con.execute("SELECT id FROM messages ORDER BY timestamp LIMIT 1 OFFSET 149").fetchone()
        con.execute("UPDATE messages SET data = ? WHERE id = ?", (b"\x00\x01\x02\x03not zstd", mid))
    ref, err = assert_same_rows(bag, expect_source="fast")
    assert isinstance(err, BagReadError) and len(ref) == 149


def test_rosbags_fallback_for_unindexed_mcap(tmp_path):
    rows = mixed_rows(200)
    bag = write_rosbags(tmp_path / "zfile", rows, "mcap", compression=CompressionMode.FILE)
    assert assert_same_rows(bag, expect_source="fast")[1] is None      # decompressed by rosbags first
    f = write_mcap(tmp_path / "noindex.mcap", sorted(rows, key=lambda r: r[2]), index=False)
    ref, err = assert_same_rows(f, expect_source="rosbags")
    assert err is None and len(ref) == len(rows)


# ---- damaged bags ----------------------------------------------------------------------------
def test_damaged_bags_same_rows_then_same_error(tmp_path):
    rows = mixed_rows(3000)
    # MCAP: garbage inside one chunk; rosbags opens the file, reading fails at that chunk
    f = write_mcap(tmp_path / "bad.mcap", rows, chunk_size=16384)
    from mcap.reader import make_reader

    with f.open("rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    data = bytearray(f.read_bytes())
    mid = chunks[len(chunks) // 2].chunk_start_offset + 80                 # inside a chunk's data
    data[mid:mid + 512] = b"\xa5" * 512
    f.write_bytes(bytes(data))
    ref, err = assert_same_rows(f, expect_source="fast", max_rows=(5, 4096))
    assert isinstance(err, BagReadError) and 0 < len(ref) < len(rows)
    # sqlite3 cut short: rosbags refuses, the salvage reader reads up to the damage
    bag = write_rosbags(tmp_path / "cut", rows, "sqlite3")
    db = next(bag.glob("*.db3"))
    db.write_bytes(db.read_bytes()[: db.stat().st_size * 2 // 3])
    ref, err = assert_same_rows(bag, expect_source="salvage", max_rows=(5, 4096))
    assert isinstance(err, BagReadError) and 0 < len(ref) < len(rows)
    # index lists more messages than the bag holds: BagReadError after every row, from both
    bag = write_rosbags(tmp_path / "count", rows, "mcap")
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["topics_with_message_count"][0]["message_count"] += 1
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    ref, err = assert_same_rows(bag, expect_source="fast", max_rows=(7,))
    assert isinstance(err, BagReadError) and "index lists" in str(err) and len(ref) == len(rows)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "", "unchunked"])
@pytest.mark.parametrize("damage", ["cut", "garbage"])
def test_salvaged_mcap_blocks_are_the_row_by_row_rows(tmp_path, compression, damage):
    """An MCAP file rosbags refuses (no footer: cut short) is salvaged a chunk at a time for the
    blocks (compiled record walk) and row by row by the mcap package for messages(): the same
    rows in the same order, then the same error — also when a chunk before the cut is garbled
    (its CRC check fails: none of its rows, the ones before it kept)."""
    rows = mixed_rows(3000)
    chunked = compression != "unchunked"
    f = write_mcap(tmp_path / "s.mcap", rows, chunk_size=16384, compression=compression if chunked else "",
                   index=False, chunked=chunked)
    data = bytearray(f.read_bytes())
    if damage == "garbage" and not chunked:      # a message record's length field: runs past the file
        data[len(data) // 3:len(data) // 3 + 64] = b"\xff" * 64
    elif damage == "garbage":
        from mcap.stream_reader import StreamReader

        with f.open("rb") as fh:                # the offset of the third chunk's data, found by reading
            pos, seen = [], 0
            for rec in StreamReader(fh, emit_chunks=True).records:
                if type(rec).__name__ == "Chunk":
                    seen += 1
                    if seen == 3:
                        pos.append(fh.tell() - len(rec.data) + 40)
                        break
        data[pos[0]:pos[0] + 64] = b"\xa5" * 64
    f.write_bytes(bytes(data[: len(data) * 3 // 4]))
    ref, err = assert_same_rows(f, expect_source="salvage", max_rows=(5, 4096))
    assert isinstance(err, BagReadError) and 0 < len(ref) < len(rows)


def _messages_in_whole_chunks(f, cut):
    """Messages of an intact MCAP file whose chunk ends at or before byte ``cut`` (what a
    salvage that drops the cut chunk reads)."""
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    n = 0
    with f.open("rb") as fh:
        for rec in StreamReader(fh).records:       # a chunk's messages come when it is read whole
            if isinstance(rec, Message) and fh.tell() <= cut:
                n += 1
    return n


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
@pytest.mark.parametrize("frac", [0.04, 0.6])
def test_a_chunk_cut_by_the_end_of_the_file_gives_its_messages_before_the_cut(tmp_path, compression, frac):
    """A recorder killed while writing a chunk (rosbag2's 768 KiB chunks; zstd and lz4 frames
    decode block by block): the messages of the cut chunk's records before the cut are read
    too, by the blocks and row by row alike, and are the bag's next rows byte for byte — also
    when the cut falls in the first chunk, which holds the channels (before: no topic found)."""
    rows = mixed_rows(12000)
    f = write_mcap(tmp_path / "whole.mcap", rows, chunk_size=786432, compression=compression, index=False)
    data = f.read_bytes()
    cut = int(len(data) * frac)
    g = tmp_path / "cut.mcap"
    g.write_bytes(data[:cut])
    ref, err = assert_same_rows(g, expect_source="salvage", max_rows=(5, 4096))
    assert isinstance(err, BagReadError) and "cut chunk" in str(err)
    assert [(t, raw) for _, t, raw in ref] == [(t, bytes(raw)) for _, _, t, raw in rows[:len(ref)]]
    whole = _messages_in_whole_chunks(f, cut)
    assert len(ref) > whole + 100, (len(ref), whole)     # more than a block's worth beyond the whole chunks
    if frac < 0.1:
        assert whole == 0


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
@pytest.mark.parametrize("tail", ["zeros", "random"])
def test_a_cut_chunk_followed_by_garbage_still_gives_the_blocks_before_it(tmp_path, compression, tail):
    """A power loss can leave the file's last bytes unwritten (zero-filled) or stale: the cut
    chunk's compressed data then runs on into garbage, at which the decompressor stops. The
    blocks before the garbage are read all the same (before: the whole cut chunk was lost —
    here the first one, with the channels: "no readable topic")."""
    rows = mixed_rows(12000)
    f = write_mcap(tmp_path / "whole.mcap", rows, chunk_size=786432, compression=compression, index=False)
    data = f.read_bytes()
    cut = int(len(data) * 0.04)                       # inside the first chunk, and so is the garbage
    assert _messages_in_whole_chunks(f, cut + 20000) == 0
    (tmp_path / "clean.mcap").write_bytes(data[:cut])
    garbage = bytes(20000) if tail == "zeros" else np.random.default_rng(4).bytes(20000)
    g = tmp_path / "garbage.mcap"
    g.write_bytes(data[:cut] + garbage)
    clean, _ = read_messages(tmp_path / "clean.mcap")
    ref, err = assert_same_rows(g, expect_source="salvage", max_rows=(5, 4096))
    assert isinstance(err, BagReadError) and "cut chunk" in str(err)
    assert len(ref) > 100 and ref == clean


WAL_WRITER = """
import os, sqlite3, sys
c = sqlite3.connect(sys.argv[1])
c.execute("PRAGMA journal_mode=WAL")
c.execute("PRAGMA wal_autocheckpoint=0")
rows = c.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id DESC LIMIT 50").fetchall()
c.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
              [(tid, t + 10**9, raw) for tid, t, raw in rows])
c.commit()
os._exit(0)                     # killed before closing: the transaction stays in the -wal file
"""


def test_a_write_ahead_log_left_beside_a_db3_is_said_not_silently_dropped(tmp_path):
    """A recorder in SQLite's WAL mode (rosbag2's 'resilient' preset) killed before closing the
    bag leaves its last transactions in ``<bag>.db3-wal``: rosbags (and so the reader) opens the
    ``.db3`` immutable and does not read them. The reader says so, naming the log and how to
    merge it; merged, the messages are read."""
    import subprocess
    import sys

    rows = mixed_rows(300)
    bag = write_rosbags(tmp_path / "wal", rows, "sqlite3")
    (bag / "metadata.yaml").unlink()               # as a killed recorder leaves it: no metadata
    db = next(bag.glob("*.db3"))
    with InputBag(bag) as b:
        assert not [w for w in b.warnings if "-wal" in w]      # none without a log
    subprocess.run([sys.executable, "-c", WAL_WRITER, str(db)], check=True)
    wal = db.with_name(db.name + "-wal")
    assert wal.stat().st_size > 32
    with InputBag(bag) as b:
        said = [w for w in b.warnings if str(wal) in w]
        assert len(said) == 1 and "not read" in said[0] and "wal_checkpoint" in said[0]
    ref, err = read_messages(bag)
    assert err is None and len(ref) == len(rows)               # the log's 50 are not in them
    # a scene driven by the bag says it too (its summary's warnings)
    scene = tmp_path / "scene.yaml"
    scene.write_text(f"name: wal\nmode: stabilised\nduration: 1\noutput_rate: 10\n"
                     f"motion: {{type: bag, path: {bag}, topic: /imu}}\n")
    cli.main(["run", str(scene), "--out", str(tmp_path / "run")])
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [w for w in summary["summary"]["warnings"] if str(wal) in w]
    import sqlite3

    sqlite3.connect(db).execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchall()    # the merge it names
    with InputBag(bag) as b:
        assert not [w for w in b.warnings if "-wal" in w]
    ref, err = read_messages(bag)
    assert err is None and len(ref) == len(rows) + 50


def test_max_rows_must_be_positive(tmp_path):
    bag = write_rosbags(tmp_path / "b", mixed_rows(10), "sqlite3")
    with InputBag(bag) as b, pytest.raises(ValueError, match="max_rows"):
        next(b.chunks(0))


# ---- issue 17: foreign MCAP channels, two types on one topic ------------------------------------
@pytest.mark.parametrize("profile", ["ros2", ""])
def test_mcap_with_json_and_protobuf_channels_is_read_not_damaged(tmp_path, profile):
    imu_rows = [("/imu", IMU, T0 + i * 10_000_000, cdr(imu(T0 + i * 10_000_000), IMU)) for i in range(300)]
    extra = [("/pose_json", "json", "Pose", "jsonschema",
              [(T0 + i * 50_000_000 + 1, json.dumps({"x": i}).encode()) for i in range(60)]),
             ("/log_pb", "protobuf", "foxglove.Log", "protobuf",
              [(T0 + i * 100_000_000 + 2, b"\x08\x01") for i in range(30)])]
    f = write_mcap(tmp_path / "foreign.mcap", imu_rows, profile=profile, extra_channels=extra)
    with InputBag(f) as b:
        assert not b.salvaged and b.damage is None and b.foreign
        assert set(b.skipped_channels) == {"/pose_json", "/log_pb"}
        assert "60 messages" in b.skipped_channels["/pose_json"] and "30 messages" in b.skipped_channels["/log_pb"]
        assert any("skipped 2 non-CDR channel(s) (90 messages)" in w for w in b.warnings)
        assert all("\n" not in w for w in b.warnings)
        assert [c.topic for c in b.connections] == ["/imu"] and b.topic == "/imu"
    ref, err = assert_same_rows(f, expect_source="mcap")
    assert err is None and [(t, r) for _, t, r in ref] == [(t, r) for *_, t, r in imu_rows]
    out = tmp_path / "out"
    code = cli.main(["replay", str(f), "--out", str(out), "--quiet", "--no-plot", "--output-rate", "10"])
    assert code == cli.EXIT_OK


def test_imu_and_twist_stamped_on_one_topic_are_not_merged(tmp_path):
    rows = []
    for i in range(200):
        t = T0 + i * 10_000_000
        rows.append(("/rate", IMU, t, cdr(imu(t), IMU)))
        if i % 4 == 0:
            rows.append(("/rate", TWS, t + 1, cdr(twist_stamped(t + 1, (5.0, 5.0, 5.0)), TWS)))
    for storage in ("sqlite3", "mcap"):
        bag = write_rosbags(tmp_path / storage, rows, storage)
        with InputBag(bag) as b:
            assert b.topic == "/rate" and b.msgtype == IMU
            assert b.skipped_input == {TWS: 50}
            assert any("mixes types" in w and "50 geometry_msgs/msg/TwistStamped" in w for w in b.warnings)
            imu_ids = {c.id for c in b.connections if c.msgtype == IMU}
        ref, _ = assert_same_rows(bag, expect_source="fast")
        only, _ = read_messages(bag, input_only=True)
        assert len(only) == 200 and {c for c, _, _ in only} == imu_ids


# ---- paced chunks (pipeline.ChunkPacer) ------------------------------------------------------
def test_paced_chunks_have_the_asked_sizes_and_the_same_rows(tmp_path):
    """``chunks(pace=…)`` cuts each block at the size asked just before it (the replay asks a
    ChunkPacer); the rows and their order are those of unpaced reading."""
    bag = write_rosbags(tmp_path / "b", mixed_rows(), "mcap")
    sizes = iter([5, 1, 64, 3, 10_000, 17] + [50] * 100)
    asked: list[int] = []

    def pace():
        asked.append(next(sizes))
        return asked[-1]

    with InputBag(bag, "/imu") as b:
        got = list(b.chunks(max_rows=200, pace=pace))
        plain = list(b.chunks(max_rows=4096))
    lens = [len(c.ts) for c in got]
    assert lens[:6] == [5, 1, 64, 3, 200, 17]                  # capped at max_rows
    assert sum(lens) == sum(len(c.ts) for c in plain)
    np.testing.assert_array_equal(np.concatenate([c.ts for c in got]), np.concatenate([c.ts for c in plain]))
    assert [r for c in got for r in c.raws] == [r for c in plain for r in c.raws]


def test_chunk_pacer_aims_at_its_wall_time_per_chunk():
    """Starts small, grows at most 4x a chunk up to max_rows while rows are cheap, and shrinks to
    ~target/seconds-per-row when they are slow (never below its start size)."""
    from gyro_platform.pipeline.pacing import ChunkPacer

    p = ChunkPacer(4096, target=0.25)
    seen = [p()]
    for _ in range(6):                       # 1 µs a row: grows 64, 256, 1024, 4096, 4096
        p.observe(p(), p() * 1e-6)
        seen.append(p())
    assert seen == [64, 256, 1024, 4096, 4096, 4096, 4096]
    p.observe(4096, 4096 * 2e-3)             # 2 ms a row: 0.25 s is 125 rows
    assert p() == 125
    p.observe(125, 125 * 1.0)                # 1 s a row: not below the start size
    assert p() == ChunkPacer.START_ROWS
    assert ChunkPacer(10)() == 10            # a small maximum is the size from the start


# ---- the replay's reader thread (pipeline.prefetched) ------------------------------------------
def test_prefetched_gives_every_item_in_order_then_the_error_and_stops_its_thread():
    """Items and their work come in order from the reader thread; an error of the source is
    raised after the items before it; closing early stops the thread (no thread left)."""
    from contextlib import closing
    import threading

    from gyro_platform.pipeline.pacing import prefetched

    def source(n, fail):
        for i in range(n):
            yield i
        if fail:
            raise BagReadError("damaged after the rows above")

    got = []
    with pytest.raises(BagReadError, match="damaged"):
        for item, res in prefetched(source(7, True), lambda i: i * i):
            got.append((item, res))
    assert got == [(i, i * i) for i in range(7)]
    assert list(prefetched(source(3, False), str)) == [(0, "0"), (1, "1"), (2, "2")]
    with closing(prefetched(source(10_000, False), lambda i: i)) as feed:
        assert next(feed) == (0, 0)
    assert not [t for t in threading.enumerate() if t.name == "gyro-bag-reader"]


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_chunks_end_at_their_payload_bound(tmp_path, storage, monkeypatch):
    """A bag with big messages on another topic (camera images beside the Imu): a chunk ends
    before it holds more than CHUNK_BYTES of payload, whatever rows were asked;
    the rows and their order are those of unbounded reading."""
    from gyro_platform.bags import reader as bag_reader

    rows = []
    for i in range(400):
        t = T0 + i * 1_000_000
        rows.append(("/imu", IMU, t, cdr(imu(t, (i * 1e-3, 0.0, 0.0)), IMU)))
        if i % 10 == 0:                        # a 20 kB "image" every 10 ms
            rows.append(("/note", STR, t, cdr(T[STR](data="x" * 20_000), STR)))
    bag = write_rosbags(tmp_path / "b", rows, storage)
    with InputBag(bag) as b:
        plain = list(b.chunks(max_rows=100_000))
    monkeypatch.setattr(bag_reader, "CHUNK_BYTES", 100_000)
    monkeypatch.setattr(bag_reader, "FETCH_ROWS", 16)
    with InputBag(bag) as b:
        got = list(b.chunks(max_rows=100_000))
    sizes = [sum(len(r) for r in c.raws) for c in got]
    assert len(got) > 5 and max(sizes) <= 100_000
    assert [r for c in got for r in c.raws] == [r for c in plain for r in c.raws]
    np.testing.assert_array_equal(np.concatenate([c.ts for c in got]), np.concatenate([c.ts for c in plain]))


def test_chunk_pacer_told_the_total_tapers_to_a_small_last_chunk():
    """With the bag's row count, no chunk is above half of what is left, so the last one (whose
    writing nothing overlaps) is small; a count short of the rows stops the tapering."""
    from gyro_platform.pipeline.pacing import ChunkPacer

    def sizes(pacer: ChunkPacer, rows: int) -> list[int]:
        out, left = [], rows
        while left:
            n = min(pacer(), left)
            pacer.took(n)
            pacer.observe(n, n * 1e-6)       # 1 µs a row: grows to max_rows
            out.append(n)
            left -= n
        return out

    got = sizes(ChunkPacer(32768, total=120_001), 120_001)
    assert sum(got) == 120_001 and max(got) == 32768
    assert got[-1] <= ChunkPacer.START_ROWS and got[-2] <= 2 * ChunkPacer.START_ROWS
    tail = got[got.index(max(got)) + 1:]
    assert all(b <= a for a, b in zip(tail, tail[1:]))           # shrinking to the end
    assert len(got) <= len(sizes(ChunkPacer(32768), 120_001)) + 12   # a few more chunks only
    short = sizes(ChunkPacer(32768, total=1000), 120_001)          # the count says 1000
    assert sum(short) == 120_001 and short[-2] == 32768           # beyond it: full-size chunks again
