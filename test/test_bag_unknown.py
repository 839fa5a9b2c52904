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

"""Bags real recorders make that are neither clean nor damaged, and split bags damaged in part.

A sqlite3 bag with a type of no definition (rosbag2's ``empty_message_definition_for``:
encoding '' or ``unknown``, empty text) opens as an intact bag in ``replay``, a scene and a
fleet sweep, its undefined topic copied raw; a topic the output bag cannot hold (an MCAP channel
without a schema) is one warning line on stderr and in the summary's ``warnings``; a split bag
whose first file is cut is read on in its later files (exit 3, the damaged file named).
"""
from __future__ import annotations

import json
from pathlib import Path
import shutil
import sqlite3

import pytest
import yaml

from gyro_platform import cli
from gyro_platform.bags import InputBag
from gyro_platform.errors import EXIT_DATA, EXIT_OK
from gyro_platform.replay import sidecar_paths
from imubag import raw_by_topic

S = 1_000_000_000
T0 = 1_700_000_000 * S
#: the payload of the undefined topic's messages (CDR header + 8 bytes)
FOO = b"\x00\x01\x00\x00" + b"\x07" * 8


def _imu(stamp: int) -> bytes:
    from test_chunked import imu

    return imu(stamp, (0.02, 0.01, 0.03))


def _imu_bag(path: Path, n: int, t0: int = T0, storage: str = "sqlite3") -> Path:
    """``n`` 1 kHz Imu messages on /imu/data (rosbags' Writer, version 9)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as w:
        c = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        for i in range(n):
            t = t0 + i * S // 1000
            w.write(c, t, _imu(t))
    return path


def undefined_type_bag(path: Path, encoding: str = "", n: int = 500) -> Path:
    """An Imu bag plus /custom of type my_pkg/msg/Foo whose ``message_definitions`` row is
    rosbag2's empty definition (``encoding``, empty text, no hash), as the recorder writes it for a
    type it has no definition of; 10 messages."""
    _imu_bag(path, n)
    db = next(path.glob("*.db3"))
    c = sqlite3.connect(db)
    c.execute("INSERT INTO topics(id, name, type, serialization_format, offered_qos_profiles, type_description_hash) "
              "VALUES (2, '/custom', 'my_pkg/msg/Foo', 'cdr', '', '')")
    c.execute("INSERT INTO message_definitions(id, topic_type, encoding, encoded_message_definition, "
              "type_description_hash) VALUES (2, 'my_pkg/msg/Foo', ?, '', '')", (encoding,))
    for i in range(10):
        c.execute("INSERT INTO messages(topic_id, timestamp, data) VALUES (2, ?, ?)", (T0 + i * S // 20 + 1, FOO))
    c.commit()
    c.close()
    meta = yaml.safe_load((path / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["message_count"] += 10
    info["files"][0]["message_count"] += 10
    info["topics_with_message_count"].append({"message_count": 10, "topic_metadata": {
        "name": "/custom", "offered_qos_profiles": [], "serialization_format": "cdr", "type": "my_pkg/msg/Foo",
        "type_description_hash": ""}})
    (path / "metadata.yaml").write_text(yaml.safe_dump(meta))
    return path


def _replay(bag: Path, out: Path, capsys) -> tuple[int, dict, str]:
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot"])
    err = capsys.readouterr().err
    return code, json.loads(sidecar_paths(out)[0].read_text()), err


# ---- a type of no definition (sqlite3) --------------------------------------------------------
@pytest.mark.parametrize("encoding", ["", "unknown"])
def test_a_type_without_definition_opens_as_an_intact_bag(tmp_path, encoding):
    bag = undefined_type_bag(tmp_path / "bag", encoding)
    with InputBag(bag) as b:
        assert not b.salvaged and b.damage is None and b.chunk_source == ""
        assert b.topic == "/imu/data" and b.message_count == 510
        conn = next(c for c in b.connections if c.topic == "/custom")
        assert conn.msgtype == "my_pkg/msg/Foo" and conn.msgcount == 10 and not conn.msgdef.data
        assert sum(len(ch.ts) for ch in b.chunks(4096)) == 510 and b.chunk_source == "fast"


def test_replay_of_a_type_without_definition_is_exit_0_and_copies_it_raw(tmp_path, capsys):
    bag = undefined_type_bag(tmp_path / "bag")
    code, summary, err = _replay(bag, tmp_path / "out", capsys)
    assert code == EXIT_OK, err
    assert "damaged" not in err and summary["error"] is None and not summary["input"]["salvaged"]
    assert summary["counts"]["in"] == summary["counts"]["accepted"] == 500
    assert "skipped_topics" not in summary["output"] and summary["warnings"] == []
    rows = raw_by_topic(tmp_path / "out")
    assert rows["/custom"] == _rows_of(bag, "/custom") and len(rows["/custom"]) == 10
    assert rows["/imu/data"] == _rows_of(bag, "/imu/data")
    meta = yaml.safe_load((tmp_path / "out" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    custom = next(t["topic_metadata"] for t in meta["topics_with_message_count"]
                  if t["topic_metadata"]["name"] == "/custom")
    assert custom["type"] == "my_pkg/msg/Foo" and custom["type_description_hash"] == ""
    db = sqlite3.connect(next((tmp_path / "out").glob("*.db3")))
    assert db.execute("SELECT type_description_hash FROM topics WHERE name = '/custom'").fetchall() == [("",)]


def _rows_of(bag: Path, topic: str) -> list[tuple[int, bytes]]:
    """Rows of ``topic`` read straight from the bag's database (rosbags cannot open it)."""
    db = sqlite3.connect(next(bag.glob("*.db3")))
    return [(t, bytes(d)) for t, d in db.execute(
        "SELECT timestamp, data FROM messages JOIN topics ON topics.id = topic_id WHERE name = ? "
        "ORDER BY timestamp", (topic,))]


def test_a_scene_driven_by_a_bag_with_a_type_without_definition_runs(tmp_path):
    from gyro_platform.scenes.runner import run_scene
    from gyro_platform.scenes.schema import scene_from_dict

    bag = undefined_type_bag(tmp_path / "bag")
    d = {"name": "t", "mode": "stabilised", "effects": ["defaults"], "duration": 10.0, "output_rate": 10.0,
         "motion": {"type": "bag", "path": str(bag), "topic": "/imu/data"}}
    _, summary, _ = run_scene(scene_from_dict(d, source="x.yaml"))
    assert summary["n_samples"] == 500
    assert not any("damaged" in w for w in summary["warnings"]), summary["warnings"]


def test_a_fleet_sweep_over_a_bag_with_a_type_without_definition_runs_it(tmp_path):
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    from gyro_platform.sweep.command import run_sweep
    from gyro_platform.sweep.spec import load_sweep

    bag = undefined_type_bag(tmp_path / "bag")
    scene = tmp_path / "scene.yaml"
    scene.write_text("name: t\nmode: stabilised\neffects: [defaults]\nduration: 10.0\noutput_rate: 10.0\n"
                     f"motion: {{type: bag, path: {bag}, topic: /imu/data}}\n")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"scene: {scene}\nbags: [{bag}]\n")
    res = run_sweep(load_sweep(sweep), tmp_path / "out", workers=1)
    (rec,) = res.records
    assert rec["status"] == "ok", rec
    assert rec["n_samples"] == 500


# ---- an MCAP channel without a schema ---------------------------------------------------------
@pytest.mark.parametrize("mode", ["noschema", "emptyschema"])
def test_a_channel_without_schema_is_copied_or_said(tmp_path, capsys, mode):
    from mcap.writer import Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    msgdef, _ = store.generate_msgdef("sensor_msgs/msg/Imu", ros_version=2)
    bag = tmp_path / "in.mcap"
    with bag.open("wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        sid = w.register_schema("sensor_msgs/msg/Imu", "ros2msg", msgdef.encode())
        cid = w.register_channel("/imu/data", "cdr", sid, {"offered_qos_profiles": ""})
        sid2 = 0 if mode == "noschema" else w.register_schema("my_pkg/msg/Foo", "", b"")
        cid2 = w.register_channel("/custom", "cdr", sid2, {"offered_qos_profiles": ""})
        for i in range(500):
            t = T0 + i * S // 1000
            w.add_message(cid, log_time=t, data=_imu(t), publish_time=t)
            if i % 50 == 0:
                w.add_message(cid2, log_time=t, data=FOO, publish_time=t)
        w.finish()
    code, summary, err = _replay(bag, tmp_path / "out", capsys)
    assert code == EXIT_OK, err
    assert summary["counts"]["accepted"] == 500
    copied = summary["output"]["messages_by_topic"].get("/custom", 0)
    if mode == "emptyschema":       # a type name, no definition: copied raw
        assert copied == 10 and summary["warnings"] == [] and "skipped_topics" not in summary["output"]
        assert raw_by_topic(tmp_path / "out")["/custom"][0][1] == FOO
    else:                           # nothing to name the type with: not copied, and said
        assert copied == 0 and "/custom" in summary["output"]["skipped_topics"]
        lines = [w for w in summary["warnings"] if "/custom" in w]
        assert len(lines) == 1 and "not in the output bag" in lines[0]
        said = [ln for ln in err.splitlines() if "/custom" in ln]
        assert len(said) == 1 and "warning" in said[0], err


# ---- a split bag whose first file is damaged --------------------------------------------------
def split_bag(path: Path, storage: str) -> Path:
    """Two storage files of 1000 1 kHz Imu messages each (the second 1 s after the first) with a
    merged ``metadata.yaml``, as ``ros2 bag record --max-bag-duration`` leaves them."""
    ext = "mcap" if storage == "mcap" else "db3"
    path.mkdir()
    metas = []
    for k in range(2):
        part = _imu_bag(path.parent / f"part{k}", 1000, T0 + k * S, storage)
        shutil.move(str(part / f"part{k}.{ext}"), str(path / f"{path.name}_{k}.{ext}"))
        metas.append(yaml.safe_load((part / "metadata.yaml").read_text())["rosbag2_bagfile_information"])
    m = metas[0]
    m["files"][0]["path"] = f"{path.name}_0.{ext}"
    metas[1]["files"][0]["path"] = f"{path.name}_1.{ext}"
    m["files"].append(metas[1]["files"][0])
    m["relative_file_paths"] = [f["path"] for f in m["files"]]
    m["message_count"] = 2000
    m["topics_with_message_count"][0]["message_count"] = 2000
    (path / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": m}))
    return path


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_split_bag_with_a_damaged_first_file_is_read_on_in_the_next(tmp_path, capsys, storage):
    bag = split_bag(tmp_path / "split", storage)
    first = sorted(bag.glob("split_0.*"))[0]
    with first.open("r+b") as f:
        f.truncate(first.stat().st_size // 2)
    code, summary, err = _replay(bag, tmp_path / "out", capsys)
    assert code == EXIT_DATA, err
    n = summary["counts"]["in"]
    assert 1000 < n < 2000 and summary["counts"]["accepted"] == n       # the intact second file is read
    assert list(summary["input"]["damaged_files"]) == [str(first)]
    error = [ln for ln in err.splitlines() if "error" in ln]
    assert len(error) == 1 and first.name in error[0] and "read on in split_1." in error[0], err
    assert "read on in split_1." in summary["error"]
    rows = raw_by_topic(tmp_path / "out")["/imu/data"]
    assert len(rows) == n and rows[-1][0] == T0 + S + 999 * S // 1000
