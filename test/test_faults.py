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

"""Faults from outside, on a real ``gyro-platform`` process: Ctrl-C, SIGTERM, a storm of signals
while the outputs close, SIGKILL, a full disk (``RLIMIT_FSIZE``), and output paths that cannot
be written (checked before anything runs).

The replays run a generated 20 s, 1 kHz Imu bag with a scene whose ``max_step`` (2 µs) makes
every sample cost ≥ 500 integrator steps, so that the process is still busy when the signal
arrives, on the per-sample path as on a compiled one. What must survive each fault is what the
README's "Exit codes and what survives a fault" section says.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import resource
import signal
import subprocess
import sys
import time

import pytest
from test_replay import imu_msg, S, write_bag

from gyro_platform import cli
from gyro_platform.errors import EXIT_CODES
from gyro_platform.replay import sidecar_paths

REPO = Path(__file__).resolve().parents[1]
PY = sys.executable
T0 = 1_700_000_000 * S
ENV = {**os.environ, "PYTHONPATH": str(REPO)}
#: a replay slow enough to be interrupted seconds into it, whatever the kernel's speed: the full
#: tree's right-hand side at 500 steps per 1 kHz sample (≈ 40 s for the 20 s bag)
SLOW_SCENE = ("name: slow\nduration: 1000\nfidelity: full\nmax_step: 2.0e-6\noutput_rate: 100\n"
              "motion: {type: bag, path: '%s'}\n")


def make_bag(path: Path, seconds: float, rate: float = 1000.0, storage: str = "sqlite3") -> Path:
    """An Imu bag at ``rate`` Hz (header stamps = record times), a slow coning-like motion."""
    import math

    n = int(seconds * rate)
    items = []
    for i in range(n):
        t = T0 + int(i * S / rate)
        s = i / rate
        items.append((t, imu_msg(t, (0.1 * math.sin(0.7 * s), 0.05 * math.sin(1.3 * s), 0.02))))
    return write_bag(path, items, storage=storage)


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    """{storage: 20 s 1 kHz bag}, the slow scene, and a warm numba cache (one tiny replay)."""
    d = tmp_path_factory.mktemp("faults")
    bags = {st: make_bag(d / f"big_{st}", 20.0, storage=st) for st in ("sqlite3", "mcap")}
    scene = d / "slow.yaml"
    scene.write_text(SLOW_SCENE % bags["sqlite3"])
    tiny = make_bag(d / "tiny", 0.05)
    p = subprocess.run([PY, "-m", "gyro_platform.cli", "replay", str(tiny), "--out", str(d / "warm"), "--quiet",
                        "--no-plot", "--scene", str(scene)], env=ENV, capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr
    return {"bags": bags, "scene": scene, "dir": d}


def start_replay(bag: Path, out: Path, scene: Path, *extra: str, preexec=None) -> subprocess.Popen:
    return subprocess.Popen([PY, "-m", "gyro_platform.cli", "replay", str(bag), "--out", str(out), "--quiet",
                             "--no-plot", "--scene", str(scene), *extra],
                            env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=preexec)


def wait_running(proc: subprocess.Popen, out: Path, settle: float = 4.0, timeout: float = 300.0) -> None:
    """Until the output bag exists (the replay loop is about to start), then ``settle`` s more."""
    t_end = time.monotonic() + timeout
    while not out.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < t_end, "the replay did not start"
        time.sleep(0.05)
    time.sleep(settle)
    assert proc.poll() is None, ("the replay ended before the signal", proc.communicate())


def read_bag(out: Path) -> dict[str, int]:
    """Messages per topic, read with rosbags' Reader and with our InputBag (they must agree)."""
    from rosbags.rosbag2 import Reader

    from gyro_platform.bags.reader import InputBag

    with Reader(out) as r:
        by_rosbags: dict[str, int] = {}
        for c, _, _ in r.messages():
            by_rosbags[c.topic] = by_rosbags.get(c.topic, 0) + 1
    with InputBag(out, "/imu") as b:
        ours: dict[str, int] = {}
        for c, _, _ in b.messages():
            ours[c.topic] = ours.get(c.topic, 0) + 1
        assert not b.salvaged, b.damage
    assert ours == by_rosbags
    return ours


def error_lines(err: str) -> list[str]:
    assert "Traceback" not in err, err
    return [ln for ln in err.splitlines() if ln.startswith("gyro-platform replay:")]


# ---- signals -------------------------------------------------------------------------------
@pytest.mark.parametrize("sig,code,word,storage", [
    (signal.SIGINT, 130, "interrupted", "sqlite3"),
    (signal.SIGTERM, 143, "terminated", "sqlite3"),
    (signal.SIGTERM, 143, "terminated", "mcap"),
])
def test_a_signal_stops_the_replay_in_order(big, tmp_path, sig, code, word, storage):
    """One SIGINT or SIGTERM: exit 130 / 143, one line, the bag closed and readable by rosbags
    and by InputBag with every message the summary counts, the summary's error names the stop."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"][storage], out, big["scene"])
    wait_running(proc, out)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == code == {v: k for k, v in {130: "interrupted", 143: "terminated"}.items()}[word]
    assert code in EXIT_CODES
    assert error_lines(err) == [f"gyro-platform replay: {word}; the output bag is closed and readable"], err
    summary = json.loads(sidecar_paths(out)[0].read_text())
    assert summary["error"] == word
    counts = read_bag(out)
    assert sum(counts.values()) == summary["output"]["messages"] > 0
    assert counts == summary["output"]["messages_by_topic"]
    assert 0 < summary["counts"]["in"] < 20_000              # stopped part-way
    assert counts["/imu"] == summary["input"]["messages"]      # every message read was copied


def test_a_storm_of_signals_while_closing_leaves_a_readable_bag(big, tmp_path):
    """Ctrl-C, then Ctrl-C and SIGTERM every 20 ms until the process ends (a second Ctrl-C while
    the bag closes): no traceback, exit 130 (the first signal decides), the bag readable."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"]["sqlite3"], out, big["scene"])
    wait_running(proc, out)
    proc.send_signal(signal.SIGINT)
    n = 0
    while proc.poll() is None and n < 1000:
        time.sleep(0.02)
        try:
            proc.send_signal((signal.SIGINT, signal.SIGTERM)[n % 2])
        except ProcessLookupError:
            break
        n += 1
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and n > 0
    summary = json.loads(sidecar_paths(out)[0].read_text())
    assert summary["error"] == "interrupted"
    assert sum(read_bag(out).values()) == summary["output"]["messages"] > 0


@pytest.mark.parametrize("where,sig", [
    ("making the output bag", signal.SIGTERM),         # OutputBag.__init__: held, raised after it
    ("setting up the output", signal.SIGINT),          # OutputBag.add_output: before the loop
    ("writing the last chunk", signal.SIGTERM),        # _Run._written: held, raised after it
    ("closing the bag", signal.SIGINT),                # OutputBag.close: held, raised after it
    ("drawing the plot", signal.SIGTERM),              # _Run.plot: held until the summary is written
])
def test_a_signal_in_any_window_keeps_the_summary_and_plot(where, sig, tmp_path, monkeypatch, capsys):
    """A signal arriving outside the chunk loop (found by an audit: the summary and the plot were
    lost, with exit 130/143) still leaves a closed bag, a summary saying why and a plot. The
    signal is real (os.kill of this process inside the window), the stop the command's own."""
    from gyro_platform.bags.writer import OutputBag
    from gyro_platform.replay import loop

    target = {
        "making the output bag": (OutputBag, "__init__"),
        "setting up the output": (OutputBag, "add_output"),
        "writing the last chunk": (loop._Run, "_written"),
        "closing the bag": (OutputBag, "close"),
        "drawing the plot": (loop._Run, "plot"),
    }[where]
    original = getattr(*target)
    sent = []

    def with_signal(*a, **k):
        last = where != "writing the last chunk" or sys._getframe(1).f_code.co_name == "loop"   # not a chunk's hand-off
        if not sent and last:
            sent.append(sig)
            os.kill(os.getpid(), sig)
        return original(*a, **k)

    monkeypatch.setattr(*target, with_signal)
    bag = make_bag(tmp_path / "in", 0.5, storage="mcap")
    out = tmp_path / "out"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--output-rate", "100"])
    err = capsys.readouterr().err
    word = "terminated" if sig == signal.SIGTERM else "interrupted"
    assert sent and code == (143 if sig == signal.SIGTERM else 130), err
    assert err.strip().splitlines()[-1] == f"gyro-platform replay: {word}; the output bag is closed and readable"
    summary_path, plot_path = sidecar_paths(out)
    summary = json.loads(summary_path.read_text())
    assert summary["error"] == word and summary["interrupted_by"] == signal.Signals(sig).name
    if where == "making the output bag":          # closed before any connection: empty, readable
        from rosbags.rosbag2 import Reader

        with Reader(out) as r:
            assert r.message_count == 0 == summary["output"]["messages"]
        return
    got = read_bag(out)
    assert got.get("/imu", 0) == summary["counts"]["in"]
    assert got.get("/gimbal/joint_states", 0) == summary["counts"]["out"]
    if summary["counts"]["out"]:
        assert summary["files"]["plot"] == str(plot_path) and plot_path.stat().st_size > 10_000
    assert (summary["counts"]["in"] == 0) == (where in ("making the output bag", "setting up the output"))


def test_sigkill_leaves_no_crash_for_the_next_reader(big, tmp_path):
    """SIGKILL cannot be caught: no summary. Whatever is left must not crash a reader: replaying
    it ends with a documented exit code and no traceback."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"]["sqlite3"], out, big["scene"])
    wait_running(proc, out)
    proc.kill()
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert not sidecar_paths(out)[0].exists()
    p = subprocess.run([PY, "-m", "gyro_platform.cli", "replay", str(out), "--out", str(tmp_path / "again"),
                        "--quiet", "--no-plot", "--topic", "/imu"], env=ENV, capture_output=True, text=True,
                       timeout=600)
    assert "Traceback" not in p.stderr and p.returncode in EXIT_CODES, p.stderr


def test_sigkill_loses_at_most_the_last_commit_chunk(big, tmp_path):
    """After SIGKILL, seconds into the run, the output bag holds the input copied so far up to
    the writer's commit bound (at least one committed chunk of /imu)."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"]["sqlite3"], out, big["scene"])
    wait_running(proc, out, settle=8.0)
    proc.kill()
    proc.communicate(timeout=60)
    from gyro_platform.bags.reader import InputBag

    with InputBag(out, "/imu") as b:
        n = sum(1 for c, _, _ in b.messages() if c.topic == "/imu")
    assert n > 0


# ---- full disk -------------------------------------------------------------------------------
def _fsize_limit(nbytes: int):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))
    return set_limit


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_full_disk_during_replay_is_exit_4_with_one_line(big, tmp_path, storage):
    """A file size limit (what a full disk looks like to the writer: EFBIG/ENOSPC) during the
    replay: exit 4 and one line naming the cause, no traceback."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"][storage], out, big["scene"], "--output-rate", "0",
                        preexec=_fsize_limit(1 << 20))
    _, err = proc.communicate(timeout=900)
    assert proc.returncode == cli.EXIT_WRITE == 4, err
    lines = error_lines(err)
    assert len(lines) == 1 and lines[0].startswith("gyro-platform replay: error: cannot write the output: "), err
    assert any(w in lines[0] for w in ("too large", "full", "I/O")), lines[0]


def test_full_disk_during_replay_leaves_the_written_part_readable_and_the_summary(big, tmp_path):
    """The bag closed with what it held, and the summary of what was simulated written beside it
    (the limit is the bag's size; the summary is small): it was lost with the exit 4."""
    out = tmp_path / "o"
    proc = start_replay(big["bags"]["sqlite3"], out, big["scene"], "--output-rate", "0",
                        preexec=_fsize_limit(1 << 20))
    proc.communicate(timeout=900)
    assert proc.returncode == cli.EXIT_WRITE
    assert (out / "metadata.yaml").is_file()
    assert sum(read_bag(out).values()) > 0
    summary = json.loads((tmp_path / "o.summary.json").read_text())
    assert summary["write_error"] and summary["error"].startswith("cannot write the output")
    assert summary["counts"]["accepted"] > 0 and summary["files"]["summary"]


def test_full_disk_during_run_is_exit_4(tmp_path):
    """``run`` writing its CSV into a file size limit: exit 4, one line, no traceback."""
    cmd = [PY, "-m", "gyro_platform.cli", "run", "default", "--duration", "20", "--out", str(tmp_path / "r")]
    p = subprocess.run(cmd, env=ENV, capture_output=True, text=True, timeout=900, preexec_fn=_fsize_limit(100_000))
    assert p.returncode == cli.EXIT_WRITE, p.stderr
    assert "Traceback" not in p.stderr
    lines = [ln for ln in p.stderr.splitlines() if "error" in ln]
    assert len(lines) == 1 and lines[0].startswith("gyro-platform run: error: cannot write the results to "), p.stderr


def test_full_disk_during_run_leaves_whole_csv_rows(tmp_path):
    subprocess.run([PY, "-m", "gyro_platform.cli", "run", "default", "--duration", "20", "--out", str(tmp_path / "r")],
                   env=ENV, capture_output=True, text=True, timeout=900, preexec_fn=_fsize_limit(100_000))
    text = (tmp_path / "r" / "outputs.csv").read_text()
    lines = text.splitlines()
    assert text.endswith("\n") and len({ln.count(",") for ln in lines}) == 1


# ---- output paths refused before the start ------------------------------------------------------
@pytest.fixture
def read_only_dir(tmp_path):
    """A read-only tmpfs (root in a container may mount), else a chmod 0555 folder when not root."""
    d = tmp_path / "ro"
    d.mkdir()
    if os.geteuid() != 0:
        d.chmod(0o555)
        yield d
        d.chmod(0o755)
        return
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(d)], capture_output=True)
    if p.returncode != 0:
        pytest.skip(f"root cannot be kept out of a folder without a read-only mount: {p.stderr!r}")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=False)


def _replay_refused(bag: Path, out: Path, capsys, *extra: str) -> str:
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE, err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1 and lines[0].startswith("gyro-platform replay: error: --out "), err
    return lines[0]


def test_unwritable_replay_outputs_are_refused_before_the_start(tmp_path, read_only_dir, capsys):
    bag = make_bag(tmp_path / "b", 0.2)
    afile = tmp_path / "afile"
    afile.write_text("x")
    assert "cannot write in" in _replay_refused(bag, read_only_dir / "o", capsys)
    assert "is a file, not a folder" in _replay_refused(bag, afile / "o", capsys)
    assert "is a file, not a folder" in _replay_refused(bag, afile / "deeper" / "o", capsys)
    out = tmp_path / "o"
    sidecar_paths(out)[0].mkdir()
    assert "o.summary.json is a folder" in _replay_refused(bag, out, capsys)
    assert not out.exists()
    sidecar_paths(out)[0].rmdir()
    sidecar_paths(out)[1].mkdir()                    # the plot: refused unless --no-plot
    assert "o.png is a folder" in _replay_refused(bag, out, capsys)
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot"]) == cli.EXIT_OK
    assert "exists already" in _replay_refused(bag, out, capsys)


@pytest.mark.parametrize("command", [["run", "default", "--duration", "0.2"], ["bench", "hotpath"],
                                     ["sweep", str(REPO / "config" / "sweeps" / "drift_budget.yaml")]])
def test_unwritable_out_folders_are_refused_before_the_start(command, tmp_path, read_only_dir, capsys):
    if command[0] == "sweep" and not Path(command[1]).is_file():
        pytest.skip("no quick sweep file")
    afile = tmp_path / "afile"
    afile.write_text("x")
    for out, words in ((read_only_dir / "r", "cannot write in"), (afile / "r", "is a file, not a folder"),
                       (afile, "is a file, not a folder")):
        code = cli.main([*command, "--out", str(out)])
        cap = capsys.readouterr()
        assert code == cli.EXIT_USAGE, cap.err
        lines = [ln for ln in cap.err.splitlines() if "error" in ln]
        assert len(lines) == 1 and words in lines[0] and "Traceback" not in cap.err, cap.err
        assert f"gyro-platform {command[0]}: error: --out" in lines[0]
        assert not cap.out.startswith("scene")            # refused before the scene ran
    if command[0] == "run":
        (tmp_path / "r" / "outputs.csv").mkdir(parents=True)
        assert cli.main([*command, "--out", str(tmp_path / "r")]) == cli.EXIT_USAGE
        assert "outputs.csv is a folder" in capsys.readouterr().err


@pytest.mark.parametrize("sig,code,word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_a_signal_stops_run_with_one_line(tmp_path, sig, code, word):
    """``run`` of a synthetic scene (30 s at ≥ 500 steps per sample): SIGTERM / Ctrl-C end it
    with 143 / 130 and one line, no traceback."""
    scene = tmp_path / "slow.yaml"
    scene.write_text("name: slowrun\nduration: 30\nsample_rate: 100\nmax_step: 2.0e-6\n"
                     "motion: {type: constant, omega: [0, 0, 0.01]}\n")
    proc = subprocess.Popen([PY, "-m", "gyro_platform.cli", "run", str(scene), "--out", str(tmp_path / "r")],
                            env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().startswith("scene slowrun")       # printed just before the run starts
    time.sleep(3.0)
    assert proc.poll() is None
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.strip().splitlines() == [f"gyro-platform run: {word}"], err
