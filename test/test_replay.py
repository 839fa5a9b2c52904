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

"""Replay: real recordings through the simulator into output bags, read back with rosbags.

The two real bags are replayed once each (module fixtures) with the real simulator; the
expectations (counts, stamps, copies) are computed from the input bag independently of the
replay code.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
import shutil

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader, Writer
from rosbags.typesys import get_typestore, Stores

from gyro_platform import cli
from gyro_platform import messages as m
from gyro_platform import replay as rp
from gyro_platform.bags.paths import read_metadata
from gyro_platform.engine.outputs import BEARING_FRAMES, BEARING_NAMES, GIMBAL_NAMES, MOUNT_NAMES
from gyro_platform.pipeline.gate import TimeGate
from gyro_platform.pipeline.gate_rules import Action, GateConfig
from imubag import raw_by_topic, write_imu_bag

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
CABRILLO = BAGS / "cabrillo_rov_bno085_imu"
HUSKY = BAGS / "robot_localization_husky_test1"
JAZZY = get_typestore(Stores.ROS2_JAZZY)
T = JAZZY.types
S = 1_000_000_000
# robot_localization README: static_transform_publisher 0 -0.3 0.52 -1.570796327 0 1.570796327 base_link imu_link
HUSKY_RPY = (math.pi / 2, 0.0, -math.pi / 2)


def need(bag: Path) -> None:
    if not bag.exists():
        pytest.skip(f"real recording absent: {bag} (see shared/data/bags)")


# ---- independent expectations from the input bag -----------------------------------------
def input_facts(bag: Path, topic: str) -> dict:
    """Counts, raw messages per topic and the sample times the gate should pick."""
    counts, stamps, recv = {}, [], []
    with AnyReader([bag], default_typestore=JAZZY) as r:
        for c, ts, raw in r.messages():
            counts[c.topic] = counts.get(c.topic, 0) + 1
            if c.topic == topic:
                msg = r.deserialize(raw, c.msgtype)
                stamps.append(msg.header.stamp.sec * S + msg.header.stamp.nanosec)
                recv.append(ts)
    use_header = stamps[0] != 0
    times = np.array(stamps if use_header else recv, dtype=np.int64)
    assert np.all(np.diff(times) > 0) and np.diff(times).max() < S, "precondition: a clean recording"
    return {"counts": counts, "times": times, "recv": np.array(recv, dtype=np.int64), "use_header": use_header}


def grid_count(times_ns: np.ndarray, rate: float | None) -> int:
    """Outputs on the grid floor((t − t0)·rate): one at the first sample and one per new slot."""
    if not rate:
        return len(times_ns)
    slots = [math.floor((int(t) - int(times_ns[0])) * 1e-9 * rate + 1e-9) for t in times_ns]
    return 1 + sum(1 for a, b in zip(slots, slots[1:]) if b > a)


def read_output(bag: Path, undecodable_ok: tuple[str, ...] = ()) -> dict[str, list]:
    """topic -> [(record ts, message)] via AnyReader (the output carries its type definitions);
    records of the topics in ``undecodable_ok`` that do not decode are left out."""
    res: dict[str, list] = {}
    with AnyReader([bag]) as r:
        for c, ts, raw in r.messages():
            try:
                msg = r.deserialize(raw, c.msgtype)
            except Exception:
                if c.topic in undecodable_ok:
                    continue
                raise
            res.setdefault(c.topic, []).append((ts, msg))
    return res


# ---- the two real replays (once each) -----------------------------------------------------
@pytest.fixture(scope="module")
def cabrillo(tmp_path_factory):
    need(CABRILLO)
    out = tmp_path_factory.mktemp("cab") / "out"
    cfg = rp.ReplayConfig(output_rate=None, progress=False)          # every sample
    summary = rp.replay(CABRILLO, out, cfg)
    return {
        "bag": CABRILLO,
        "out": out,
        "summary": summary,
        "topic": "/logic_tube/imu",
        "rate": None,
        "storage": "sqlite3",
        "facts": input_facts(CABRILLO, "/logic_tube/imu"),
    }


@pytest.fixture(scope="module")
def husky(tmp_path_factory):
    need(HUSKY)
    out = tmp_path_factory.mktemp("husky") / "out"
    cfg = rp.ReplayConfig(output_rate=2.0, progress=False,
                          mounting=m.Mounting({"imu_link": HUSKY_RPY}, unknown_frame="reject"))
    summary = rp.replay(HUSKY, out, cfg)
    return {"bag": HUSKY, "out": out, "summary": summary, "topic": "/imu/data", "rate": 2.0, "storage": "mcap",
            "facts": input_facts(HUSKY, "/imu/data")}


@pytest.fixture(params=["cabrillo", "husky"])
def run(request):
    return request.getfixturevalue(request.param)


def test_output_bag_counts_per_topic(run):
    facts, out = run["facts"], read_output(run["out"])
    n_out = grid_count(facts["times"], run["rate"])
    n_diag = grid_count(facts["recv"], 1.0)
    expected = dict(facts["counts"])
    expected.update({t: n_out for t in m.output_topics() if t != "/diagnostics"})
    expected["/diagnostics"] = n_diag
    assert {t: len(v) for t, v in out.items()} == expected
    with Reader(run["out"]) as r:                                   # metadata agrees with the data
        assert {c.topic: c.msgcount for c in r.connections} == expected
        assert r.message_count == sum(expected.values())
    meta = read_metadata(run["out"])
    assert meta["version"] == 9 and meta["storage_identifier"] == run["storage"]


def test_output_types_qos_and_hashes(run):
    with Reader(run["out"]) as r:
        conns = {c.topic: c for c in r.connections}
    for topic, typ in m.output_topics().items():
        c = conns[topic]
        assert c.msgtype == typ and c.digest == JAZZY.hash_rihs01(typ)
        (qos,) = c.ext.offered_qos_profiles
        assert (qos.reliability.name, qos.durability.name, qos.history.name, qos.depth) == \
            ("RELIABLE", "VOLATILE", "KEEP_LAST", 10)
    meta_topics = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in
                   read_metadata(run["out"])["topics_with_message_count"]}
    assert meta_topics["/gimbal/joint_states"]["offered_qos_profiles"][0]["reliability"] == "reliable"


def test_input_topics_copied_byte_identically(run):
    src, dst = raw_by_topic(run["bag"]), raw_by_topic(run["out"])
    for topic, msgs in src.items():
        assert dst[topic] == msgs, topic
    with Reader(run["bag"]) as a, Reader(run["out"]) as b:
        qa = {c.topic: c.ext.offered_qos_profiles for c in a.connections}
        qb = {c.topic: c.ext.offered_qos_profiles for c in b.connections}
        assert all(qb[t] == q for t, q in qa.items())                 # QoS kept as recorded


def test_output_stamps_follow_the_input_time_base(run):
    facts, out = run["facts"], read_output(run["out"])
    accepted_times = set(facts["times"].tolist())
    recv_of = dict(zip(facts["times"].tolist(), facts["recv"].tolist()))
    for topic in m.output_topics():
        recs = out[topic]
        ts = np.array([x[0] for x in recs])
        stamps = np.array([x[1].header.stamp.sec * S + x[1].header.stamp.nanosec for x in recs])
        assert np.all(np.diff(ts) >= 0) and np.all(np.diff(stamps) > 0), topic
        if topic == "/diagnostics":
            assert np.array_equal(ts, stamps)                          # node clock = receive time
            continue
        assert set(stamps.tolist()) <= accepted_times                 # stamped at an input sample's time
        assert all(recv_of[s] == t for s, t in zip(stamps.tolist(), ts.tolist()))  # recorded when received
    js = out["/gimbal/joint_states"]
    if facts["use_header"]:
        lag = [(t - (x.header.stamp.sec * S + x.header.stamp.nanosec)) / 1e6 for t, x in js]
        assert 15 < min(lag) and max(lag) < 40                        # husky: receive − stamp 20–36 ms
    assert run["summary"]["input"]["time_source"] == ("header" if facts["use_header"] else "receive")


def test_output_values_finite_and_bounded(run):
    out = read_output(run["out"])
    for _, js in out["/gimbal/joint_states"]:
        assert js.name[:8] == [*GIMBAL_NAMES, *MOUNT_NAMES]            # stabilised: mount joints too (then rotors)
        assert np.all(np.isfinite(js.position))
        assert np.max(np.abs(js.position[:5])) < 1e-3                 # servo holds the pick-offs (rad)
        assert np.max(np.abs(js.position[5:])) < math.pi + 1e-9
        assert np.all(np.isfinite(js.velocity[:5])) and np.all(np.isfinite(js.effort[:5]))
        assert np.all(np.isfinite(js.velocity)) and np.all(np.isfinite(js.effort))   # no NaN (issue 14)
    for name in BEARING_NAMES:
        for _, w in out[f"/bearing/{name}/torque"]:
            assert w.header.frame_id == BEARING_FRAMES[name]
            f, tq = w.wrench.force, w.wrench.torque
            assert (f.x, f.y, f.z) == (0.0, 0.0, 0.0)
            v = np.array([tq.x, tq.y, tq.z])
            assert np.all(np.isfinite(v)) and np.linalg.norm(v) < 1.0    # N m; the servo limit is 2
    for topic, bound in (("/drift/angle", 1e-3), ("/drift/rate", 1e-2)):
        for _, v in out[topic]:
            vec = np.array([v.vector.x, v.vector.y, v.vector.z])
            assert v.header.frame_id == "platform" and np.all(np.isfinite(vec)) and np.max(np.abs(vec)) < bound
    for _, d in out["/diagnostics"]:
        assert [s.name for s in d.status] == ["gyro_platform: input", "gyro_platform: platform"]


def test_summary_consistent_with_the_bags(run):
    s, facts = run["summary"], run["facts"]
    out = read_output(run["out"])
    assert json.loads(rp.sidecar_paths(run["out"])[0].read_text()) == json.loads(json.dumps(s, default=str))
    n_in = facts["counts"][run["topic"]]
    c = s["counts"]
    assert c["in"] == n_in == s["input"]["topic_messages"]
    assert c["accepted"] + c["dropped"] == n_in and c["dropped"] == 0 and c["resets"] == 0
    assert c["simulator"] == {"pushed": n_in}
    taken = s["config"]["frames_taken_as_base_link"]
    assert taken == (["logic_tube_bno085"] if run["topic"] == "/logic_tube/imu" else [])
    assert c["out"] == len(out["/gimbal/joint_states"]) == s["output"]["outputs"]
    assert s["output"]["messages_by_topic"] == {t: len(v) for t, v in out.items()}
    assert s["input"]["messages"] == sum(facts["counts"].values())
    with Reader(run["bag"]) as r:
        assert s["duration_s"] == pytest.approx((r.end_time - 1 - r.start_time) / S, abs=1e-9)
    assert s["real_time_factor"] == pytest.approx(s["duration_s"] / s["wall_time_s"])
    assert s["error"] is None                      # speed is a benchmark, not a test
    pos = np.array([x.position for _, x in out["/gimbal/joint_states"]])
    for i, name in enumerate((*GIMBAL_NAMES, *MOUNT_NAMES)):
        assert s["ranges"][name + "_rad"] == [pos[:, i].min(), pos[:, i].max()], name
    # the drift rate is the least-squares slope of the drift angle over the whole run (no
    # resets here), not the last instantaneous rate: numpy's fit of the output bag's angles
    ang = out["/drift/angle"]
    t = np.array([(mm.header.stamp.sec * S + mm.header.stamp.nanosec) / S for _, mm in ang])
    y = np.array([[mm.vector.x, mm.vector.y, mm.vector.z] for _, mm in ang])
    slope = np.polyfit(t - t[0], y, 1)[0]
    d = s["drift"]
    got = [d["drift_rate_rad_s"][k] for k in "xyz"]
    np.testing.assert_allclose(got, slope, rtol=1e-6, atol=1e-9 * np.abs(slope).max())
    assert d["drift_rate_deg_h"]["norm"] == pytest.approx(np.linalg.norm(slope) * 180 / math.pi * 3600, rel=1e-6)
    assert d["fit_outputs"] == len(ang) and d["fit_s"] == pytest.approx(t[-1] - t[0], abs=1e-6)
    assert [d["final_drift_angle_rad"][k] for k in "xyz"] == list(y[-1])
    png = Path(s["files"]["plot"])
    assert png.name == run["out"].name + ".png" and png.stat().st_size > 10_000
    assert s["recorder"]["n_outputs"] == c["out"]


def test_husky_samples_are_rotated_into_base_link():
    need(HUSKY)
    mount = m.Mounting({"imu_link": HUSKY_RPY}, unknown_frame="reject")
    rot = mount.matrix("imu_link")
    forces = []
    for i, bs in enumerate(rp.read_samples(HUSKY, mounting=mount)):
        w = bs.msg.angular_velocity
        np.testing.assert_allclose(bs.sample.omega, rot @ [w.x, w.y, w.z], atol=1e-15)
        forces.append(bs.sample.specific_force)
        if i == 199:
            break
    assert np.mean(forces, axis=0)[2] > 9.6                           # gravity up in base_link


def test_read_samples_streams_lazily(monkeypatch):
    """The reader is a generator: it yields the first sample after pulling one message."""
    need(HUSKY)
    pulled = []
    orig = Reader.messages

    def counting(self, *a, **k):
        for item in orig(self, *a, **k):
            pulled.append(item[1])
            yield item

    monkeypatch.setattr(Reader, "messages", counting)
    gen = rp.read_samples(HUSKY)
    first = next(gen)
    assert len(pulled) == 1 and first.decision.action is Action.ACCEPT
    assert first.receive_ns == pulled[0]
    next(gen)
    assert len(pulled) == 2
    gen.close()                                                       # closes the bag


def test_read_samples_cabrillo_uses_receive_time():
    need(CABRILLO)
    gate = TimeGate()
    n, prev = 0, -1.0
    for bs in rp.read_samples(CABRILLO, gate=gate):
        assert bs.decision.action is Action.ACCEPT and bs.decision.source == "receive"
        assert bs.decision.stamp_ns == bs.receive_ns and bs.sample.t > prev
        prev = bs.sample.t
        n += 1
    assert n == 1041 and gate.snapshot()["notes"]["identity_frame"] == 1041
    assert 9.5 < gate.snapshot()["input_rate_hz"] < 10.5


# ---- damaged bags ------------------------------------------------------------------------
def _cut_copy(src: Path, dst: Path, frac: float) -> Path:
    shutil.copytree(src, dst)
    for f in dst.iterdir():
        f.chmod(0o644)
        if f.suffix in (".db3", ".mcap"):
            data = f.read_bytes()
            f.write_bytes(data[:int(len(data) * frac)])
    return dst


@pytest.mark.parametrize("name,frac", [("cabrillo", 0.2), ("husky", 0.15)])
def test_truncated_bag_gives_clear_error_and_readable_partial_output(name, frac, tmp_path, capsys):
    src = CABRILLO if name == "cabrillo" else HUSKY
    need(src)
    bag = _cut_copy(src, tmp_path / "cut", frac)
    out = tmp_path / "out"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--output-rate", "1", "--no-plot"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_DATA
    storage_file = next(f for f in bag.iterdir() if f.suffix in (".db3", ".mcap"))
    assert f"error: {storage_file}" in err and ("truncated" in err or "damaged" in err)
    assert "output bag closed and readable" in err
    summary = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert str(storage_file) in summary["error"] and summary["input"]["salvaged"]
    got = read_output(out)                                            # readable, every message decodes
    full = input_facts(src, summary["input"]["topic"])["counts"][summary["input"]["topic"]]
    n_in = len(got[summary["input"]["topic"]])
    assert 0 < n_in < full and n_in == summary["counts"]["in"]
    assert len(got["/gimbal/joint_states"]) == summary["counts"]["out"] > 0
    # the salvaged part is the bag's beginning, byte for byte
    head = raw_by_topic(src)[summary["input"]["topic"]][:n_in]
    assert raw_by_topic(out)[summary["input"]["topic"]] == head


def test_corrupt_chunk_mid_stream_ends_replay_with_readable_output(tmp_path, capsys):
    """An intact index but garbage inside a chunk: rosbags opens the bag, reading fails later."""
    need(HUSKY)
    bag = _cut_copy(HUSKY, tmp_path / "bad", 1.0)
    f = next(bag.glob("*.mcap"))
    data = bytearray(f.read_bytes())
    data[len(data) // 7:len(data) // 7 + 4096] = b"\xff" * 4096
    f.write_bytes(bytes(data))
    out = tmp_path / "out"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--output-rate", "1", "--no-plot"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_DATA and f"error: {bag}: damaged" in err
    got = read_output(out)
    assert 0 < len(got["/imu/data"]) < 11865 and len(got["/gimbal/joint_states"]) > 0


def _small_mcap(path: Path) -> Path:
    """A 200-message 1 kHz Imu bag in MCAP (rosbags, Jazzy)."""
    return write_bag(path, [(T0 + i * 10**6, imu_msg(T0 + i * 10**6, (0.01, 0.0, 0.02))) for i in range(200)],
                     "mcap", topic="/imu/data")


@pytest.mark.parametrize("head", [0, 1, 5, 8, 9, 10, 20, 26, 40])
def test_mcap_file_of_a_few_bytes_is_a_damaged_bag_not_a_traceback(head, tmp_path, capsys):
    bag = _small_mcap(tmp_path / "src")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(next(bag.glob("*.mcap")).read_bytes()[:head])
    code = cli.main(["replay", str(cut), "--out", str(tmp_path / "out"), "--quiet", "--no-plot"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_DATA and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith(f"gyro-platform replay: error: {cut}"), err


@pytest.mark.parametrize("field,value", [
    ("  starting_time:\n    nanoseconds_since_epoch: ", "abc"),   # text where a number belongs
    ("  - message_count: ", "lots"),                                # the input topic's count
    ("  - message_count: ", "-5"),
    ("  compression_mode: ", "file"),                               # compressed, but the file is not
])
def test_damaged_metadata_is_salvaged_with_one_line_not_a_traceback(field, value, tmp_path, capsys):
    """A metadata.yaml field rosbags chokes on (TypeError, a decompressor's error …) or that
    says nothing sensible: the bag is damaged (exit 3), its messages salvaged, one line each."""
    bag = _small_mcap(tmp_path / "src")
    meta = bag / "metadata.yaml"
    text = meta.read_text()
    lines = text.split("\n")
    key = field.rsplit("\n", 1)[-1]
    i = max(j for j, ln in enumerate(lines) if ln.startswith(key)) if "\n" not in field else \
        [j for j, ln in enumerate(lines) if ln == field.split("\n")[0]][-1] + 1
    lines[i] = key + value
    if value == "file":
        lines = [ln.replace("compression_format: ''", "compression_format: zstd") for ln in lines]
    meta.write_text("\n".join(lines))
    out = tmp_path / "out"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_DATA and "Traceback" not in err, err
    assert all(ln.startswith("gyro-platform replay: ") for ln in err.splitlines()), err
    summary = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert summary["input"]["salvaged"] and summary["counts"]["in"] == 200


def test_salvaged_bag_out_of_time_order_reports_its_whole_duration(tmp_path):
    """A salvaged bag is read in file order, which need not be time order (a killed recorder's
    last rows can be older than the ones before): ``duration_s`` is the span of the record
    times, not last-in-file minus first (it said 0.0 s here before)."""
    items = [(T0 + i * 10**6, imu_msg(T0 + i * 10**6, (0.01, 0.0, 0.02))) for i in range(200)]
    late = T["std_msgs/msg/String"](data="written last, stamped first")
    bag = write_bag(tmp_path / "src", items, "mcap", topic="/imu/data",
                    extra=[("/note", "std_msgs/msg/String", [(T0, late)])])
    f = next(bag.glob("*.mcap"))
    f.write_bytes(f.read_bytes()[:-8])                 # no end magic: rosbags refuses, salvage reads it
    summary = rp.replay(bag, tmp_path / "out", rp.ReplayConfig(plot=False, progress=False))
    assert summary["input"]["salvaged"] and summary["counts"]["in"] == 200
    assert summary["duration_s"] == pytest.approx(0.199, abs=1e-9)


def test_no_output_at_all_is_said_in_the_summary_too(tmp_path, capsys, monkeypatch):
    """Samples simulated but every output failing (1e300 m/s² let through the gate into the
    anisoelastic and unbalance effects: not finite): exit 3 and the summary's warnings say why
    (they were empty). By default the gate drops such samples (``over_specific_force``); no flag
    lets them through (flags are finite, and ‖f‖ of 1e300 components is inf), so the gate's bound
    is lifted after the flags were checked."""
    items = []
    for i in range(50):
        msg = imu_msg(T0 + i * 10**6, (0.01, 0.0, 0.02))
        msg.linear_acceleration.x = msg.linear_acceleration.y = msg.linear_acceleration.z = 1e300
        items.append((T0 + i * 10**6, msg))
    bag = write_bag(tmp_path / "in", items, "mcap", topic="/imu/data")
    scene = tmp_path / "s.yaml"
    scene.write_text("mode: stabilised\neffects: [defaults, anisoelastic, mass_unbalance]\nduration: 2\n"
                     "motion: {type: constant, omega: [0, 0, 0]}\n")
    dropped = tmp_path / "dropped"
    code = cli.main(["replay", str(bag), "--out", str(dropped), "--quiet", "--no-plot", "--scene", str(scene)])
    assert code == cli.EXIT_DATA and "every specific force exceeds --max-specific-force" in capsys.readouterr().err
    summary = json.loads(rp.sidecar_paths(dropped)[0].read_text())
    assert summary["gate"]["dropped_by_reason"] == {"over_specific_force": 50} and summary["simulated"] == 0
    import importlib

    command = importlib.import_module("gyro_platform.replay.command")
    checked = command.config_from_args

    def no_force_bound(args):
        cfg = checked(args)
        object.__setattr__(cfg.gate, "max_specific_force", math.inf)
        return cfg

    monkeypatch.setattr(command, "config_from_args", no_force_bound)
    out = tmp_path / "out"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot", "--scene", str(scene)])
    capsys.readouterr()
    summary = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert code == cli.EXIT_DATA and summary["counts"]["out"] == 0 and summary["simulated"] == 50
    assert any("no output could be computed" in w for w in summary["warnings"]), summary["warnings"]


@pytest.mark.parametrize("flag,value", [("--output-rate", "1e20"), ("--output-rate", "1e300"),
                                        ("--diagnostics-rate", "1e300"), ("--output-rate", "1.0000001e6")])
def test_rates_beyond_the_grid_are_refused_before_the_start(flag, value, tmp_path, capsys):
    """An output or diagnostics rate whose slot numbers would leave int64 (found by an audit:
    1e20 Hz gave 93 outputs of 2000 and a drift rate 100x off, with numpy warnings) is refused
    with one line and exit 2, nothing written; 1e6 Hz and 0 give an output after every sample."""
    bag = _small_mcap(tmp_path / "src")
    out = tmp_path / "out"
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot", flag, value]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"error: {flag} " in err and "1e+06] Hz" in err and not out.exists()
    for ok in ("1e6", "0"):
        code = cli.main(["replay", str(bag), "--out", str(tmp_path / ok), "--quiet", "--no-plot", "--output-rate", ok])
        assert code == 0 and json.loads(rp.sidecar_paths(tmp_path / ok)[0].read_text())["counts"]["out"] == 200


@pytest.mark.parametrize("flag", ["--max-gap", "--reset-on-jump-back"])
def test_gate_times_beyond_int64_ns_are_taken_as_no_limit(flag, tmp_path, capsys):
    """1e300 s as a gap or jump limit (found by an audit: OverflowError traceback, an output bag
    without summary): no limit, as 1e20 s was already."""
    bag = _small_mcap(tmp_path / "src")
    out = tmp_path / "out"
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot", flag, "1e300"]) == 0
    assert "Traceback" not in capsys.readouterr().err
    assert json.loads(rp.sidecar_paths(out)[0].read_text())["counts"]["accepted"] == 200


def test_a_fifo_as_input_is_refused_as_a_path(tmp_path, capsys):
    """A FIFO named like a bag is an input problem (exit 2, one line), not a write failure
    (it said exit 4, "cannot write the output: …: Not a directory")."""
    fifo = tmp_path / "x.mcap"
    os.mkfifo(fifo)
    out = tmp_path / "out"
    assert cli.main(["replay", str(fifo), "--out", str(out), "--quiet", "--no-plot"]) == cli.EXIT_USAGE
    why = "not a rosbag2 bag (neither a folder nor a regular file)"
    assert capsys.readouterr().err == f"gyro-platform replay: error: {fifo}: {why}\n"
    assert not out.exists()


# ---- bad input end to end (synthetic bag) ------------------------------------------------
def imu_msg(stamp_ns, w, frame="base_link", cov_w=0.0):
    cov = np.zeros(9)
    cov[0] = cov_w
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp_ns // S,
                                                                               nanosec=stamp_ns % S),
                                        frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=T["geometry_msgs/msg/Vector3"](x=w[0], y=w[1], z=w[2]),
        angular_velocity_covariance=cov,
        linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9))


def write_bag(path: Path, items, storage="sqlite3", topic="/imu", msgtype="sensor_msgs/msg/Imu", extra=()):
    from rosbags.rosbag2 import StoragePlugin

    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection(topic, msgtype, typestore=JAZZY)
        others = {t: w.add_connection(t, ty, typestore=JAZZY) for t, ty, _ in extra}
        for ts, msg in items:
            raw = msg if isinstance(msg, bytes) else JAZZY.serialize_cdr(msg, msgtype)
            w.write(conn, ts, raw)
        for t, _, recs in extra:
            for ts, msg in recs:
                w.write(others[t], ts, JAZZY.serialize_cdr(msg, msg.__msgtype__))
    return path


T0 = 1_700_000_000 * S
DT = S // 50


def bad_stream():
    """(receive ns, message, expected decision reason)."""
    w = (0.01, -0.02, 0.03)
    seq, t = [], T0
    for i in range(10):
        seq.append((t, imu_msg(t, w), "start" if i == 0 else "ok"))
        t += DT
    seq.append((t, imu_msg(0, w), "zero_stamp"))
    seq.append((t + 1, imu_msg(t - DT, w), "repeated_stamp"))
    seq.append((t + 2, imu_msg(t - 3 * DT, w), "backward_stamp"))
    seq.append((t + 3, imu_msg(t, (math.nan, 0.0, 0.0)), "non_finite"))
    seq.append((t + 4, imu_msg(t, (40.0, 0.0, 0.0)), "over_rate"))
    seq.append((t + 5, imu_msg(t, w, cov_w=-1.0), "no_rate"))
    seq.append((t + 6, imu_msg(t, w, frame="elsewhere"), "unknown_frame"))
    seq.append((t + 7, b"\x00\x01\x00\x00garbage", "bad_message"))
    for i in range(5):
        seq.append((t + 8 + i, imu_msg(t, w), "ok"))
        t += DT
    t += 3 * S                                                        # gap > max_gap 1 s
    for i in range(5):
        seq.append((t, imu_msg(t, w), "gap" if i == 0 else "ok"))
        t += DT
    t -= 20 * S                                                       # the recording loops
    seq.append((t + 25 * S, imu_msg(t, w), "jump_back"))
    for i in range(4):
        t += DT
        seq.append((t + 25 * S, imu_msg(t, w), "ok"))
    return seq


def test_every_bad_input_gets_its_decision_and_counter(tmp_path):
    seq = bad_stream()
    bag = write_bag(tmp_path / "bad", [(ts, msg) for ts, msg, _ in seq])
    mount = m.Mounting(unknown_frame="reject")
    reasons = [bs.decision.reason for bs in rp.read_samples(bag, mounting=mount)]
    assert reasons == [r for _, _, r in seq]

    out = tmp_path / "out"
    cfg = rp.ReplayConfig(output_rate=None, progress=False, plot=False, storage="mcap", mounting=mount)
    s = rp.replay(bag, out, cfg)
    expect_drop = dict.fromkeys(("zero_stamp", "repeated_stamp", "backward_stamp", "non_finite", "over_rate", "no_rate",
                                 "unknown_frame", "bad_message"), 1)
    assert s["counts"]["dropped_by_reason"] == expect_drop
    assert s["counts"]["resets_by_reason"] == {"gap": 1, "jump_back": 1}
    n_acc = sum(1 for _, _, r in seq if r in ("start", "ok", "gap", "jump_back"))
    assert s["counts"]["accepted"] == n_acc and s["counts"]["in"] == len(seq)
    assert s["counts"]["simulator"] == {"pushed": n_acc - 2, "reset": 2, "dropped": 8}
    got = read_output(out, undecodable_ok=("/imu",))                  # mcap output from a sqlite3 input
    assert read_metadata(out)["storage_identifier"] == "mcap"
    js = got["/gimbal/joint_states"]
    assert len(js) == n_acc                                           # a reset loses no emitted output
    stamps = [x.header.stamp.sec * S + x.header.stamp.nanosec for _, x in js]
    backwards = [i for i in range(1, len(stamps)) if stamps[i] <= stamps[i - 1]]
    assert len(backwards) == 1                                        # only at the loop
    assert got["/imu"] and len(got["/imu"]) == len(seq) - 1           # the garbage record is copied, not decoded
    assert raw_by_topic(out)["/imu"] == raw_by_topic(bag)["/imu"]


def test_gap_integrate_and_twist_topic_selection(tmp_path):
    v3 = T["geometry_msgs/msg/Vector3"]
    items, t = [], T0
    for i in range(30):
        tw = T["geometry_msgs/msg/TwistStamped"](
            header=m.header(m.MessageTypes.rosbags(), t, "base_link"),
            twist=T["geometry_msgs/msg/Twist"](linear=v3(x=0.0, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=0.2)))
        items.append((t, tw))
        t += DT if i != 15 else 2 * S
    odom = [(T0 + i * DT, T["geometry_msgs/msg/Twist"](linear=v3(x=1.0, y=0.0, z=0.0),
                                                       angular=v3(x=0.0, y=0.0, z=0.0))) for i in range(5)]
    # two input-type topics: /a_cmd (Twist) comes first in the bag, --topic picks /vel
    bag = write_bag(tmp_path / "tw", items, topic="/vel", msgtype="geometry_msgs/msg/TwistStamped",
                    extra=[("/z_cmd", "geometry_msgs/msg/Twist", odom)])
    out = tmp_path / "out"
    cfg = rp.ReplayConfig(topic="/vel", output_rate=5.0, progress=False, plot=False,
                          gate=GateConfig(on_gap="integrate"))
    s = rp.replay(bag, out, cfg)
    assert s["input"]["topic"] == "/vel" and s["counts"]["resets"] == 0
    assert s["counts"]["notes"]["gap_integrated"] == 1
    assert len(read_output(out)["/z_cmd"]) == 5
    with rp.InputBag(bag) as b:                                        # default: first input-type topic
        assert b.topic == "/vel"


def test_scene_sets_model_and_output_rate(tmp_path):
    seq = [(ts, msg) for ts, msg, r in bad_stream()[:10]]
    bag = write_bag(tmp_path / "b", seq)
    scene = tmp_path / "s.yaml"
    scene.write_text(f"name: s\nmode: carried\nduration: 1\noutput_rate: 25\n"
                     f"motion: {{type: bag, path: {bag}}}\n")
    out = tmp_path / "out"
    assert cli.main(["replay", str(bag), "--out", str(out), "--scene", str(scene), "--quiet", "--no-plot"]) == 0
    s = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert s["simulator"]["mode"] == "carried" and s["output"]["output_rate_hz"] == 25.0
    # carried: gimbals and rotors, no mount joints
    assert len(read_output(out)["/gimbal/joint_states"][0][1].name) == 8


def test_cli_errors_are_clear(tmp_path, capsys):
    bag = write_bag(tmp_path / "b", [(ts, msg) for ts, msg, _ in bad_stream()[:5]])
    out = tmp_path / "out"
    assert cli.main(["replay", str(tmp_path / "nope"), "--out", str(out), "--quiet"]) == cli.EXIT_USAGE
    assert f"{tmp_path / 'nope'}: no such file" in capsys.readouterr().err
    assert cli.main(["replay", str(bag), "--out", str(out), "--topic", "/x", "--quiet"]) == cli.EXIT_USAGE
    assert "no topic '/x'; topics: /imu (sensor_msgs/msg/Imu)" in capsys.readouterr().err
    assert not out.exists()
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot"]) == 0
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet"]) == cli.EXIT_USAGE
    assert "exists already" in capsys.readouterr().err
    # an output bag as input: its output topics clash unless a namespace separates them
    out2 = tmp_path / "out2"
    assert cli.main(["replay", str(out), "--out", str(out2), "--quiet"]) == cli.EXIT_USAGE
    assert "--namespace" in capsys.readouterr().err
    assert cli.main(["replay", str(out), "--out", str(out2), "--quiet", "--no-plot", "--namespace", "again"]) == 0
    again = read_output(out2)
    first = read_output(out)
    assert len(again["/again/gimbal/joint_states"]) == len(first["/gimbal/joint_states"]) > 0
    assert raw_by_topic(out2)["/gimbal/joint_states"] == raw_by_topic(out)["/gimbal/joint_states"]  # copied
    assert len(again["/diagnostics"]) == 2 * len(first["/diagnostics"])       # shared, as on a robot
    code = cli.main(["replay", str(bag), "--out", str(tmp_path / "o3"), "--mount", "imu=1,2", "--quiet"])
    assert code == cli.EXIT_USAGE == 2
    assert "mounting" in capsys.readouterr().err


def test_many_unmounted_frames_are_named_up_to_sixteen_and_cut(tmp_path, capsys):
    """40 frame_ids without ``--mount``, one of 100 000 characters: 16 info lines and one for the
    rest (a bag of many frames printed a line each), the summary's list cut the same way
    (``messages.frame_label``); every sample is still taken as base_link and integrated."""
    frames = ["x" * 100_000] + [f"f{i}" for i in range(39)]
    items = [(T0 + k * S // 100, imu_msg(T0 + k * S // 100, (0.0, 0.0, 0.01), frame=frames[k % 40]))
             for k in range(200)]
    bag = write_bag(tmp_path / "frames", items)
    summary = rp.replay(bag, tmp_path / "out", rp.ReplayConfig(progress=False, plot=False))
    info = [ln for ln in capsys.readouterr().err.splitlines() if "has no --mount" in ln or "more than 16" in ln]
    assert len(info) == 17 and "more than 16" in info[-1] and max(map(len, info)) < 250
    taken = summary["config"]["frames_taken_as_base_link"]
    assert len(taken) == 17 and taken[-1] == "…" and len(taken[0]) == 64
    assert summary["counts"]["accepted"] == 200


def test_an_input_slower_than_max_gap_is_no_usable_input(tmp_path, capsys):
    """A 0.5 Hz Imu against max_gap 1 s: every sample restarted the simulation, nothing was
    integrated, and the replay said '30 accepted, 29 resets, 30 outputs' and exited 0 (every
    output the initial state). Now exit 3 with one line naming max_gap; --max-gap 3 integrates."""
    bag = tmp_path / "slow"
    write_imu_bag(bag, 30, 0.5)
    code = cli.main(["replay", str(bag), "--out", str(tmp_path / "out"), "--quiet", "--no-plot"])
    err = capsys.readouterr().err
    assert code == 3 and "none of the 30 accepted samples was integrated" in err and "--max-gap" in err, err
    summary = json.loads((tmp_path / "out.summary.json").read_text())
    assert summary["no_usable_input"] and summary["counts"]["resets_by_reason"] == {"gap": 29}
    assert any("max_gap" in w for w in summary["warnings"])
    code = cli.main(["replay", str(bag), "--out", str(tmp_path / "ok"), "--quiet", "--no-plot", "--max-gap", "3"])
    assert code == 0 and not json.loads((tmp_path / "ok.summary.json").read_text())["no_usable_input"]


def test_samples_the_simulator_refuses_are_said_with_its_reason(tmp_path, capsys):
    """A Twist bag (no specific force) under a scene with mass_unbalance (which needs it): every
    sample is refused; the line said only 'see dropped_by_reason' (the summary: 'the simulator
    refused the sample'). Now it carries the simulator's reason, and the summary its errors."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    Twist, Vec3 = ts.types["geometry_msgs/msg/Twist"], ts.types["geometry_msgs/msg/Vector3"]
    bag = tmp_path / "twist"
    with Writer(bag, version=8) as writer:
        conn = writer.add_connection("/cmd", Twist.__msgtype__, typestore=ts)
        for k in range(50):
            m = Twist(linear=Vec3(x=0.0, y=0.0, z=0.0), angular=Vec3(x=0.0, y=0.0, z=0.1))
            writer.write(conn, 10**9 + k * 10**7, ts.serialize_cdr(m, Twist.__msgtype__))
    scene = tmp_path / "unb.yaml"
    scene.write_text("name: unb\neffects: [defaults, mass_unbalance]\nduration: 2\n"
                     "motion: {type: constant, omega: [0, 0, 0]}\n")
    code = cli.main(["replay", str(bag), "--out", str(tmp_path / "out"), "--scene", str(scene), "--quiet",
                     "--no-plot"])
    err = capsys.readouterr().err
    assert code == 3 and "refused" in err and "mass_unbalance" in err and "specific force" in err, err
    summary = json.loads((tmp_path / "out.summary.json").read_text())
    assert "mass_unbalance" in summary["simulator"]["errors"][0]
