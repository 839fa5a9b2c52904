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

"""The launched node under a real ROS 2 graph's faults (issue 33, item 3), checked from outside.

Each test launches ``ros2 launch gyro_platform platform.launch.py`` from the colcon workspace
(conftest ``ros_ws``) and drives it as a user's graph does: ``ros2 bag play`` of bags written
here with rosbags (too fast for the node; looped with ``--clock``), a probe node
(``ros_probe.py``) publishing Imu, storming ``set_parameters`` and recording ``/diagnostics``,
no ``/clock`` at all with ``use_sim_time``, and SIGKILL of the node. What is checked is counts,
not timing (the machine is shared): every input sample sent is taken, dropped or reported lost
(``accepted + dropped + input_lost`` of the ``gyro_platform: node`` status = sent, within a few
%), loss is reported (WARN 'input overload'), resets and parameter changes are counted once.
"""
import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores

from imubag import T0_NS, write_imu_bag
import rosenv

LAUNCH = "ros2 launch gyro_platform platform.launch.py"
NODE = "/gyro_platform_node"
DIAG = {"/diagnostics": "diagnostic_msgs/msg/DiagnosticArray"}
#: taken + dropped + lost may differ from sent by this fraction (the loss estimate's error)
TOLERANCE = 0.03


# ---- helpers -------------------------------------------------------------------------------
def statuses(report: dict, name: str) -> list[tuple[int, str, dict]]:
    """(level, message, key → value) of every ``name`` status in the collected /diagnostics."""
    out = []
    for arr in report["topics"]["/diagnostics"]:
        for s in arr["status"]:
            if s["name"] == name:
                level = ord(s["level"]) if isinstance(s["level"], str) else int(s["level"])
                out.append((level, s["message"], {kv["key"]: kv["value"] for kv in s["values"]}))
    return out


def stamp(msg: dict) -> int:
    """header.stamp of a message dict, ns."""
    return msg["header"]["stamp"]["sec"] * 10**9 + msg["header"]["stamp"]["nanosec"]


def node_statuses(report: dict) -> list[tuple[int, str, dict]]:
    return statuses(report, "gyro_platform: node")


def counts(values: dict) -> dict[str, int]:
    """taken / dropped / lost / messages of a node status."""
    return {"taken": int(values["accepted"]), "dropped": int(values["dropped"]),
            "lost": int(values["input_lost"]), "messages": int(values["messages"])}


def assert_adds_up(c: dict, sent: int, what: str) -> None:
    total = c["taken"] + c["dropped"] + c["lost"]
    assert c["taken"] + c["dropped"] == c["messages"], f"{what}: {c}"
    assert abs(total - sent) <= TOLERANCE * sent, f"{what}: taken + dropped + lost = {total} of {sent} sent: {c}"


def launch(ws, domain: int, args: str = ""):
    proc = ws.start(f"{LAUNCH} {args}", domain=domain)
    assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), f"no 'ready:' line:\n{proc.output[-4000:]}"
    return proc


def probe_bg(ros, spec: dict, domain: int) -> rosenv.Proc:
    """ros_probe.py started in the background; :func:`probe_result` waits for its report."""
    return ros.start([ros.python, str(rosenv.PROBE), json.dumps(spec)], domain=domain)


def probe_result(proc: rosenv.Proc, timeout: float = 300.0) -> dict:
    proc.popen.wait(timeout)
    proc.stop()
    assert proc.popen.returncode == 0, proc.output[-3000:]
    return json.loads(proc.output.strip().splitlines()[-1])


def node_pid(launch_proc: rosenv.Proc) -> int:
    """Pid of the platform node that ``launch_proc`` (its own process group) started."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if os.getpgid(int(entry.name)) != launch_proc.popen.pid:
                continue
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
        except (OSError, ProcessLookupError):
            continue
        if any(c.endswith(b"platform_node") for c in cmd) and b"launch" not in cmd[1:2]:
            return int(entry.name)
    raise AssertionError("no platform_node process in the launch's group")


# ---- 1. bag play faster than the node takes it ----------------------------------------------
@pytest.fixture(scope="module")
def imu_bags_30hz(tmp_path_factory):
    """30 Hz Imu bags by size (messages)."""
    root, made = tmp_path_factory.mktemp("bags"), {}

    def bag(n):
        if n not in made:
            write_imu_bag(root / f"imu30_{n}", n, 30.0)
            made[n] = root / f"imu30_{n}"
        return made[n]
    return bag


@pytest.mark.parametrize("rate, sent", [(10, 4500), (200, 12000)])
def test_bag_play_overload_is_reported_and_the_counts_add_up(ros_ws, domain, imu_bags_30hz, rate, sent):
    """``ros2 bag play --rate R`` of 30 Hz Imu (a few thousand messages): every sample is taken,
    dropped or counted lost (the loss estimate from the stamp steps), and lost samples turn the
    node WARN 'input overload'. At --rate 200 (6 kHz) the node takes a fraction of them. What
    no node can know are the samples sent before the first one it took (its first output is
    stamped with that sample's time): those are left out of the sum, and must be few."""
    bag = imu_bags_30hz(sent)
    proc = launch(ros_ws, domain)
    try:
        report = ros_ws.ros.probe({"collect": {**DIAG, "/drift/angle": "geometry_msgs/msg/Vector3Stamped"},
                                   "pre": 2.0, "settle": 3.5,
                                   "command": ["ros2", "bag", "play", "--rate", str(rate), str(bag)]},
                                  domain=domain, timeout=300)
    finally:
        proc.stop(signal.SIGINT)
    assert report["command"]["returncode"] == 0, report["command"]["output"]
    st = node_statuses(report)
    assert st, f"no /diagnostics:\n{proc.output[-3000:]}"
    c = counts(st[-1][2])
    first = min(stamp(m) for m in report["topics"]["/drift/angle"])
    before = round((first - T0_NS) * 30.0 / 1e9)            # sent before the node's first sample
    print(f"--rate {rate}: {c} of {sent} sent, {before} before the first taken")
    assert before <= 0.1 * sent, before
    assert_adds_up(c, sent - before, f"--rate {rate}")
    if c["lost"] > 0:
        assert any(lvl == 1 and "input overload" in msg for lvl, msg, _ in st), [m for _, m, _ in st]
    if rate == 200:
        assert c["lost"] > 0.1 * sent, c            # the node cannot take 6 kHz through rclpy
    assert "Traceback" not in proc.output


# ---- 2. looped bag with /clock ------------------------------------------------------------
def test_looped_bag_with_clock_resets_once_per_loop(ros_ws, domain, tmp_path):
    """``ros2 bag play --loop --clock`` with use_sim_time: /clock (and the stamps) jump back at
    every loop; the node restarts once per loop, logs it once and counts it once."""
    write_imu_bag(tmp_path / "loop", 200, 100.0)            # 2 s per loop
    proc = launch(ros_ws, domain, "use_sim_time:=true")
    try:
        report = ros_ws.ros.probe(
            {"collect": DIAG, "best_effort": {"/clock": "rosgraph_msgs/msg/Clock"}, "pre": 2.0, "settle": 3.0,
             "command": ["timeout", "-s", "INT", "9", "ros2", "bag", "play", "--loop", "--clock", "50",
                         str(tmp_path / "loop")]}, domain=domain, timeout=300)
    finally:
        proc.stop(signal.SIGINT)
    clock = [c["clock"]["sec"] + c["clock"]["nanosec"] * 1e-9 for c in report["topics"]["/clock"]]
    loops = sum(1 for a, b in zip(clock, clock[1:]) if b < a - 0.5)
    assert loops >= 2, (f"{loops} loop restarts seen on /clock", len(clock), clock[:3], clock[-3:], report["command"])
    values = node_statuses(report)[-1][2]
    resets = int(values["resets"])
    logged = len(re.findall(r"simulation restarted", proc.output))
    by_reason = {k: v for k, v in values.items() if k.startswith("resets_by_reason.")}
    jumps = int(values.get("clock_jumps.back", 0))
    print("loops", loops, "resets", resets, "logged", logged, by_reason, "clock jumps back", jumps,
          "of them after the stamps' reset of their loop", values.get("clock_jumps.back_same_loop", 0))
    # the node's last loop may end after the probe stopped looking (or before): ±1 of /clock's count
    assert abs(jumps - loops) <= 1, (loops, jumps)
    # one reset per loop, by whichever of the loop's two signs reaches the node first: the clock's jump back,
    # or the stamps' (``bag play`` publishes /clock from its own timer, and DDS orders no two topics: the new
    # loop's first Imu may come before its first /clock, and a loop cut by the stop of ``bag play`` may have
    # no /clock at all); a clock jump after the stamps' reset of its loop does not reset again (``same_loop``)
    by_clock = int(values.get("resets_by_reason.clock_jump_back", 0))
    by_stamps = int(values.get("resets_by_reason.jump_back", 0))
    same = int(values.get("clock_jumps.back_same_loop", 0))
    # (a clock jump that overtook queued samples waits for the new loop's first one: the last may still wait)
    assert jumps - 1 <= by_clock + same <= jumps and same <= by_stamps <= same + 1 and resets == by_clock + by_stamps, \
        (loops, jumps, resets, by_reason, same)
    assert abs(resets - loops) <= 1 and logged == resets, (loops, jumps, resets, logged, by_reason)
    assert "Traceback" not in proc.output


def replay_joint_positions(bag: Path, out: Path) -> dict[int, list[float]]:
    """stamp (ns) → /gimbal/joint_states positions of ``gyro-platform replay`` of ``bag`` (every sample)."""
    subprocess.run([sys.executable, "-m", "gyro_platform", "replay", str(bag), "--out", str(out),
                    "--output-rate", "0", "--no-plot", "--quiet"], check=True, timeout=300)
    got = {}
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/gimbal/joint_states"]
        for conn, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, conn.msgtype)
            got[m.header.stamp.sec * 10**9 + m.header.stamp.nanosec] = list(m.position)
    return got


def test_looped_bag_each_loop_is_the_replay_with_a_deeper_input_queue(ros_ws, domain, tmp_path):
    """At each loop ``ros2 bag play --loop --clock`` (rosbag2 0.26) jumps /clock back, then waits
    (100 ms) for its read-ahead queue with the clock running: the loop's first 100 ms of samples
    come in one burst, 20 at 200 Hz, more than the input's keep-last 5 holds, and the loop's run
    started ~15 samples late (5e-3 rad off the replay). The input subscription takes the standard
    QoS overrides: with ``qos_overrides./imu.subscription.depth: 100`` every loop takes every
    sample, and its outputs are those of ``gyro-platform replay`` of the bag (from its first
    sample). Compared: every loop after the first (which may miss samples sent before discovery
    matched the player) and before the last (cut by the stop), whole: a clock jump that overtakes
    samples still queued from the loop before waits for the new loop's first sample."""
    rate, n = 200.0, 600                                 # 3 s per loop, compared whole
    half = n
    write_imu_bag(tmp_path / "loop", n, rate, w=(0.02, 0.0, 0.1))
    expected = replay_joint_positions(tmp_path / "loop", tmp_path / "replayed")
    window = [T0_NS + int(round(k * 1e9 / rate)) for k in range(half)]
    assert all(t in expected for t in window), sorted(expected)[:3]
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    qos_overrides:\n      /imu:\n        subscription:\n"
                      "          depth: 100\n")
    proc = launch(ros_ws, domain, f"use_sim_time:=true output_rate:=0.0 params_file:={params}")
    try:
        report = ros_ws.ros.probe(
            {"collect": {**DIAG, "/gimbal/joint_states": "sensor_msgs/msg/JointState"}, "pre": 2.0, "settle": 2.0,
             "command": ["timeout", "-s", "INT", "11", "ros2", "bag", "play", "--loop", "--clock", "100",
                         str(tmp_path / "loop")]}, domain=domain, timeout=300)
    finally:
        proc.stop(signal.SIGINT)
    loops, last = [], None                  # the node's outputs, one dict per loop (stamps jump back)
    for m in report["topics"]["/gimbal/joint_states"]:
        t = stamp(m)
        if last is None or t < last:
            loops.append({})
        loops[-1][t], last = m["position"], t
    # the first loop may miss samples published before discovery matched the player to the node
    whole = [out for out in loops[1:-1] if max(out) >= window[-1]]
    assert len(whole) >= 2, ([(len(o), min(o), max(o)) for o in loops], report["command"])
    for i, out in enumerate(whole, 2):
        missing = [round((t - T0_NS) * rate / 1e9) for t in window if t not in out]
        assert not missing, f"loop {i}: samples {missing[:20]} (of its first {half}) not taken"
        worst = max(np.max(np.abs(np.subtract(out[t], expected[t]))) for t in window)
        assert worst < 1e-9, f"loop {i}: outputs differ from the replay's by up to {worst:.3g}"
    print("loops", len(loops), "compared", len(whole), node_statuses(report)[-1][2].get("input_lost"))
    assert "Traceback" not in proc.output


# ---- 3. use_sim_time without /clock --------------------------------------------------------
def test_sim_time_without_clock_still_publishes_diagnostics_saying_so(ros_ws, domain):
    proc = launch(ros_ws, domain, "use_sim_time:=true")
    try:
        report = ros_ws.ros.probe({"wait_subscriber": "/imu", "collect": DIAG, "until": {"/diagnostics": 3},
                                   "timeout": 40.0, "publish": {"topic": "/imu", "rate": 100.0, "count": 300}},
                                  domain=domain, timeout=200)
        time.sleep(2.0)
    finally:
        proc.stop(signal.SIGINT)
    st = node_statuses(report)
    assert len(st) >= 2, f"{len(st)} diagnostics without /clock:\n{proc.output[-3000:]}"
    assert all("waiting for /clock" in msg and lvl != 0 for lvl, msg, _ in st), [m for _, m, _ in st]
    assert st[-1][0] == 1, st[-1]            # Imu flowing: WARN (not OK) while /clock is missing
    transport = statuses(report, "gyro_platform: transport")
    assert transport and "waiting for /clock" in transport[-1][2]["clock"]
    lines = [ln for ln in proc.output.splitlines() if "waiting for /clock" in ln]
    assert len(lines) == 1, lines
    assert "Traceback" not in proc.output


# ---- 4. frame_id changing mid-stream -------------------------------------------------------
def test_frame_id_changes_mid_stream(ros_ws, domain, tmp_path):
    """base_link → camera_link (no mounting: taken as base_link, counted, one log line) →
    imu_link (mounted by sensor_mountings): outputs go on through all three, the diagnostics
    count the samples of each frame."""
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    sensor_mountings:\n      - imu_link=0.0,0.0,1.5707963267948966\n"
                      "    output_rate: 20.0\n")
    proc = launch(ros_ws, domain, f"params_file:={params}")
    n = 600
    try:
        report = ros_ws.ros.probe(
            {"wait_subscriber": "/imu", "collect": {**DIAG, "/drift/angle": "geometry_msgs/msg/Vector3Stamped"},
             "settle": 3.0, "publish": {"topic": "/imu", "rate": 100.0, "count": n, "stamp": 1000.0,
                                        "w": [0.1, 0.0, 0.05],
                                        "frames": ["base_link", "camera_link", "imu_link"]}},
            domain=domain, timeout=200)
    finally:
        proc.stop(signal.SIGINT)
    out = [stamp(m) * 1e-9 for m in report["topics"]["/drift/angle"]]
    for k in range(3):                      # outputs in each third of the stream (2 s each at 20 Hz)
        inside = [t for t in out if 1000.0 + 2 * k <= t < 1000.0 + 2 * (k + 1)]
        assert len(inside) >= 20, f"phase {k}: {len(inside)} outputs"
    values = node_statuses(report)[-1][2]
    c = counts(values)
    assert_adds_up(c, n, "frames")
    frames = {k.split(".", 1)[1]: int(v) for k, v in values.items() if k.startswith("input_frames.")}
    assert set(frames) == {"base_link", "camera_link", "imu_link"}, values
    assert sum(frames.values()) == c["messages"]
    for f in frames:
        assert frames[f] >= (n / 3) * (1 - TOLERANCE) - c["lost"], frames
    assert values["frames_taken_as_base_link"] == "camera_link", values
    inp = statuses(report, "gyro_platform: input")[-1][2]
    assert int(inp["notes.identity_frame"]) == frames["camera_link"], inp
    lines = [ln for ln in proc.output.splitlines() if "has no sensor mounting" in ln]
    assert len(lines) == 1 and "camera_link" in lines[0], lines
    assert "Traceback" not in proc.output


# ---- 5. a parameter storm under 1 kHz input -------------------------------------------------
def test_parameter_storm_under_1khz_input(ros_ws, domain):
    """600 SetParameters requests at 300/s while 4000 Imu flow at 1 kHz: gate.max_rate
    alternating below and above the input's 25 rad/s (every accepted value applied to the next
    samples), with refusals (out of range, read-only) among them. The final value is the last
    accepted one, 'parameters applied' is counted once per accepted change, and every sample is
    taken, dropped or reported lost."""
    params = []
    for k in range(600):
        if k % 10 == 3:
            params.append(["input_type", "twist"])          # read-only: refused (descriptor)
        elif k % 10 == 7:
            params.append(["gate.max_rate", 1.0e9])          # out of range: refused by rclpy
        else:
            params.append(["gate.max_rate", 20.0 + (k % 2) * 10.0 + k * 1e-3])
    n = 4000
    proc = launch(ros_ws, domain)
    try:
        report = ros_ws.ros.probe(
            {"wait_subscriber": "/imu", "collect": DIAG, "settle": 3.5,
             "publish": {"topic": "/imu", "rate": 1000.0, "count": n, "w": [0.0, 0.0, 25.0]},
             "storm": {"node": NODE, "rate": 300.0, "params": params}}, domain=domain, timeout=400)
        got = ros_ws.run(f"ros2 param get --no-daemon --spin-time 3 --timeout 20 {NODE} gate.max_rate",
                         domain=domain, timeout=90)
    finally:
        proc.stop(signal.SIGINT)
    storm = report["storm"]
    unanswered = [k for k, r in enumerate(storm) if r["successful"] is None]
    assert not unanswered, f"{len(unanswered)} unanswered SetParameters requests: {unanswered[:20]}"
    accepted = [r for r in storm if r["successful"]]
    refused = [r for r in storm if not r["successful"]]
    assert len(refused) == 120 and all(r["value"] == "twist" or r["value"] == 1.0e9 for r in refused)
    assert f"Double value is: {accepted[-1]['value']}" in got.stdout, got.stdout + got.stderr
    values = node_statuses(report)[-1][2]
    assert int(values["parameter_changes"]) == len(accepted), values
    assert len(re.findall(r"parameters applied", proc.output)) == len(accepted)
    # read-only and out-of-range values are refused by rclpy (the descriptors) with a reason each
    assert all(r["reason"] for r in refused), refused[:3]
    c = counts(values)
    print(f"storm: {c} of {n} sent, {len(accepted)} changes applied")
    assert c["taken"] > 0 and c["dropped"] > 0, c                # both sides of 25 rad/s applied
    assert_adds_up(c, n, "storm")
    assert "Traceback" not in proc.output


# ---- 6. SIGKILL under ros2 launch, then launched again ---------------------------------------
def test_sigkill_then_relaunch_is_a_clean_start(ros_ws, domain):
    """The node SIGKILLed mid-stream under ``ros2 launch``; launch stopped and started again:
    ready, and the same input gives the same outputs as the first run's (a fresh simulation),
    counters from zero."""
    spec = {"wait_subscriber": "/imu", "collect": {**DIAG, "/gimbal/joint_states": "sensor_msgs/msg/JointState"},
            "settle": 2.5, "publish": {"topic": "/imu", "rate": 100.0, "count": 200, "stamp": 1000.0,
                                       "w": [0.05, -0.02, 0.1]}}
    first = launch(ros_ws, domain, "output_rate:=20.0")
    try:
        run1 = ros_ws.ros.probe(spec, domain=domain, timeout=200)
        pid = node_pid(first)
        os.kill(pid, signal.SIGKILL)
        assert first.wait_for("process has died", 30), first.output[-3000:]
    finally:
        first.stop(signal.SIGINT)
    second = launch(ros_ws, domain, "output_rate:=20.0")
    try:
        run2 = ros_ws.ros.probe(spec, domain=domain, timeout=200)
    finally:
        second.stop(signal.SIGINT)
    js1, js2 = run1["topics"]["/gimbal/joint_states"], run2["topics"]["/gimbal/joint_states"]
    assert len(js2) >= 20, f"{len(js2)} outputs after the relaunch:\n{second.output[-3000:]}"
    # the input is a constant rate: a fresh simulation gives the same outputs at the same time
    # after its first sample (which one came first depends on discovery: compare relative times)
    rel1 = {stamp(m) - stamp(js1[0]): m["position"] for m in js1}
    common = [m for m in js2 if stamp(m) - stamp(js2[0]) in rel1]
    assert len(common) >= 20, (len(common), [stamp(m) for m in js1[:3]], [stamp(m) for m in js2[:3]])
    for m in common:
        np.testing.assert_allclose(m["position"], rel1[stamp(m) - stamp(js2[0])], rtol=1e-9, atol=1e-12)
    values = node_statuses(run2)[-1][2]
    assert int(values["messages"]) <= 200 and int(values["resets"]) == 0, values
    assert "Traceback" not in second.output
