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

"""The command line as a user meets it: exit codes, one-line errors on bad input of every kind,
scenes by name from any folder, help texts, broken pipes, results on stdout.

Bad bags are made from small synthetic bags (written with rosbags) and from the real
recordings in ../shared/data/bags (copied into tmp_path, never into the repository).
"""
from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import textwrap

import pytest
from test_replay import CABRILLO, HUSKY, imu_msg, need, S, write_bag

from gyro_platform import __version__, cli
from gyro_platform import replay as rp
from gyro_platform.bags.paths import ROS1_MAGIC
from gyro_platform.reports.recording import COLUMN_PLACEHOLDERS, CSV_COLUMNS

REPO = Path(__file__).resolve().parents[1]
PY = sys.executable
T0 = 1_700_000_000 * S


def small_bag(path: Path, seconds: float = 1.0, rate: float = 50.0, storage: str = "sqlite3",
              stamps: bool = True) -> Path:
    """An Imu bag at ``rate`` Hz turning slowly about z; header stamps 0 unless ``stamps``."""
    n = int(seconds * rate) + 1
    items = [(T0 + int(i * S / rate), imu_msg(T0 + int(i * S / rate) if stamps else 0, (0.0, 0.0, 0.01)))
             for i in range(n)]
    return write_bag(path, items, storage=storage)


def one_line_error(err: str, command: str) -> str:
    """The single error line of ``err`` (no traceback, nothing else that says error)."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"gyro-platform {command}: error: "), lines[0]
    return lines[0]


def bag_scene(tmp_path: Path, bag: Path, topic: str | None = None, duration: float = 1.0, extra: str = "") -> Path:
    p = tmp_path / "bag_scene.yaml"
    topic_line = f", topic: {topic}" if topic else ""
    p.write_text(f"name: bagscene\nduration: {duration}\noutput_rate: 10\n"
                 f"motion: {{type: bag, path: '{bag}'{topic_line}}}\n{extra}")
    return p


def run_and_replay(tmp_path: Path, bag: Path, capsys, topic: str | None = None, extra_args=()):
    """(exit, stderr) of ``run`` on a bag scene and of ``replay`` on the same bag."""
    scene = bag_scene(tmp_path, bag, topic)
    code_run = cli.main(["run", str(scene), "--out", str(tmp_path / "run_out")])
    err_run = capsys.readouterr().err
    args = ["replay", str(bag), "--out", str(tmp_path / "replay_out"), "--quiet", "--no-plot", *extra_args]
    if topic:
        args += ["--topic", topic]
    code_replay = cli.main(args)
    err_replay = capsys.readouterr().err
    return (code_run, err_run), (code_replay, err_replay)


# ---- bad input paths: exit 2, one line, for run (bag scene) and replay alike -----------------
def _ros1(tmp_path):
    p = tmp_path / "old.bag"
    p.write_bytes(ROS1_MAGIC + b"\n" + b"\0" * 64)
    return p, "ROS 1 bag"


def _ros1_renamed(tmp_path):          # a ROS 1 bag is known by its magic, whatever its name
    p = tmp_path / "old.db3"
    p.write_bytes(ROS1_MAGIC + b"\n" + b"\0" * 64)
    return p, "ROS 1 bag"


def _yaml_file(tmp_path):
    p = tmp_path / "params.yaml"
    p.write_text("a: 1\n")
    return p, "not a rosbag2 bag"


def _text_file(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("hello\n")
    return p, "not a rosbag2 bag"


def _garbage_dir(tmp_path):
    d = tmp_path / "junk"
    d.mkdir()
    (d / "readme.txt").write_text("x")
    (d / "data.bin").write_bytes(os.urandom(100))
    return d, "not a rosbag2 bag"


def _missing(tmp_path):
    return tmp_path / "nope", "no such file or directory|bag not found"


def _missing_topic(tmp_path):
    return small_bag(tmp_path / "b"), "no topic '/nope'"


def _mcap_missing_topic(tmp_path):
    return small_bag(tmp_path / "m", storage="mcap"), "no topic '/nope'"


def _split_without_metadata(tmp_path):
    d = tmp_path / "split"
    d.mkdir()
    for i in range(2):
        b = small_bag(tmp_path / f"part{i}")
        shutil.copy(next(b.glob("*.db3")), d / f"split_{i}.db3")
    return d, "ros2 bag reindex"


@pytest.mark.parametrize("make", [_ros1, _ros1_renamed, _yaml_file, _text_file, _garbage_dir, _missing,
                                  _missing_topic, _mcap_missing_topic, _split_without_metadata])
def test_bad_bag_path_is_exit_2_with_one_line(make, tmp_path, capsys):
    bag, words = make(tmp_path)
    topic = "/nope" if "topic" in make.__name__ else None
    (c1, e1), (c2, e2) = run_and_replay(tmp_path, bag, capsys, topic)
    assert c1 == c2 == cli.EXIT_USAGE == 2
    for line in (one_line_error(e1, "run"), one_line_error(e2, "replay")):
        assert any(w in line for w in words.split("|")), line
    assert not (tmp_path / "replay_out").exists() and not (tmp_path / "run_out").exists()


# ---- corrupt data: exit 3; what was readable is run and written --------------------------------
def _cut(src: Path, dst: Path, frac: float) -> Path:
    shutil.copytree(src, dst)
    for f in dst.iterdir():
        f.chmod(0o644)
        if f.suffix in (".db3", ".mcap"):
            f.write_bytes(f.read_bytes()[:int(f.stat().st_size * frac)])
    return dst


def test_truncated_bag_in_a_bag_scene_exits_3_and_keeps_the_readable_part(tmp_path, capsys):
    need(HUSKY)
    bag = _cut(HUSKY, tmp_path / "cut", 0.15)
    scene = bag_scene(tmp_path, bag, "/imu/data", duration=395.0)
    out = tmp_path / "o"
    assert cli.main(["run", str(scene), "--out", str(out)]) == cli.EXIT_DATA == 3
    cap = capsys.readouterr()
    assert "truncated" in one_line_error(cap.err, "run") or "damaged" in cap.err
    rows = list(csv.DictReader((out / "outputs.csv").open()))
    summary = json.loads((out / "summary.json").read_text())
    # the readable part: more than a few seconds of 30 Hz IMU data, all of it in the CSV
    assert len(rows) == summary["summary"]["n_outputs"] > 20
    assert summary["summary"]["error"] and any("damaged" in w for w in summary["summary"]["warnings"])
    assert all(e["passed"] is None for e in summary["expectations"])       # never judged on a fragment


def test_empty_and_garbage_storage_files_are_corrupt_data(tmp_path, capsys):
    for name, data in (("empty.db3", b""), ("noise.mcap", os.urandom(4096))):
        f = tmp_path / name
        f.write_bytes(data)
        (c1, e1), (c2, e2) = run_and_replay(tmp_path, f, capsys)
        assert c1 == c2 == cli.EXIT_DATA, (name, e1, e2)
        assert str(f) in one_line_error(e1, "run") and str(f) in one_line_error(e2, "replay")
        shutil.rmtree(tmp_path / "replay_out", ignore_errors=True)


# ---- inputs that are fine must not be refused ---------------------------------------------------
def test_db3_folder_without_metadata_is_read_like_the_bag(tmp_path, capsys):
    need(CABRILLO)
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(CABRILLO / "imu_recording.db3", bare / "imu_recording.db3")
    codes = []
    for src, out in ((CABRILLO, tmp_path / "with"), (bare, tmp_path / "without")):
        codes.append(cli.main(["replay", str(src), "--out", str(out), "--quiet", "--no-plot"]))
    assert codes == [0, 0], capsys.readouterr().err
    a, b = (json.loads(rp.sidecar_paths(tmp_path / n)[0].read_text()) for n in ("with", "without"))
    assert b["counts"] == a["counts"] and b["counts"]["in"] == 1041 and not b["input"]["salvaged"]
    assert b["error"] is None and b["output"]["messages_by_topic"] == a["output"]["messages_by_topic"]
    # its metadata.yaml given as the bag stands for the folder
    assert cli.main(["replay", str(CABRILLO / "metadata.yaml"), "--out", str(tmp_path / "m"), "--quiet",
                     "--no-plot"]) == 0


def test_header_time_on_zero_stamps_is_an_error_naming_the_fix(tmp_path, capsys):
    bag = small_bag(tmp_path / "z", stamps=False)
    out = tmp_path / "o"
    code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot", "--time-source", "header"])
    cap = capsys.readouterr()
    line = one_line_error(cap.err, "replay")
    assert code == cli.EXIT_DATA and "zero_stamp" in line and "--time-source receive" in line
    s = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert s["counts"]["accepted"] == 0 and s["counts"]["dropped_by_reason"] == {"zero_stamp": 51}
    assert s["warnings"] == [line.split("error: ", 1)[1]]
    # auto picks receive time for the same bag: every sample is used
    assert cli.main(["replay", str(bag), "--out", str(tmp_path / "o2"), "--quiet", "--no-plot"]) == 0


def test_scene_longer_than_its_bag_warns_and_leaves_expectations_not_evaluable(tmp_path, capsys):
    bag = small_bag(tmp_path / "b", seconds=2.0)
    scene = bag_scene(tmp_path, bag, duration=10.0,
                      extra="expect:\n  - {quantity: drift_rate_deg_per_h, axis: norm, max: 1.0e+9}\n")
    assert cli.main(["run", str(scene), "--no-files"]) == cli.EXIT_FAILED
    out = capsys.readouterr().out
    assert re.search(r"warning: the bag ends 2 s after its first usable sample, before the scene's duration "
                     r"\(10 s\)", out), out
    assert "N/A" in out and "not evaluable" in out and "PASS" not in out
    # as long as the bag: evaluated (and this bound passes)
    scene = bag_scene(tmp_path, bag, duration=2.0,
                      extra="expect:\n  - {quantity: drift_rate_deg_per_h, axis: norm, max: 1.0e+9}\n")
    assert cli.main(["run", str(scene), "--no-files"]) == cli.EXIT_OK
    assert "warning" not in capsys.readouterr().out


# ---- scenes ------------------------------------------------------------------------------------
BAD_SCENES = {
    "unknown key": ("duration: 1\nmotion: {type: constant, omega: [0, 0, 0]}\ncolour: red\n", "colour: unknown key"),
    "wrong type": ("duration: soon\nmotion: {type: constant, omega: [0, 0, 0]}\n", "duration: expected a number"),
    "not a mapping": ("- 1\n", "expected a mapping"),
    "bad yaml": ("duration: [1,\n", "not valid YAML"),
    "binary": (None, "not a text file"),
    "missing bag": ("duration: 1\nmotion: {type: bag, path: /no/such/bag}\n", "bag not found"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_is_exit_2_with_one_line(case, tmp_path, capsys):
    text, words = BAD_SCENES[case]
    p = tmp_path / "s.yaml"
    if text is None:
        p.write_bytes(b"\xff\xfe\x00garbage\x80")
    else:
        p.write_text(text)
    assert cli.main(["run", str(p), "--no-files"]) == cli.EXIT_USAGE
    assert words in one_line_error(capsys.readouterr().err, "run")
    assert cli.main(["replay", str(CABRILLO), "--out", str(tmp_path / "o"), "--scene", str(p), "--quiet"]) == 2
    assert words in one_line_error(capsys.readouterr().err, "replay")


@pytest.mark.parametrize("text, says", [
    ("duration: 2\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\na: [1, 2\n",
     "not valid YAML: line 4:1: expected ',' or ']', but got '<stream end>' "
     "(while parsing a flow sequence at line 3:4)"),
    ("duration: 2\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\nduration: 3\n",
     "not valid YAML: line 3:1: duplicate key 'duration' (first at line 1:1)"),
    ("duration: 2\nmotion:\n  type: constant\n  omega: [0.0, 0.0, 0.0]\n  omega: [1.0, 0.0, 0.0]\n",
     "not valid YAML: line 5:3: duplicate key 'omega' (first at line 4:3)"),
], ids=["syntax", "duplicate", "nested_duplicate"])
def test_scene_yaml_error_is_one_line_with_line_and_column(text, says, tmp_path, capsys):
    """PyYAML's message spans several lines; a scene gives one. YAML forbids a key given twice
    (PyYAML would keep the last): refused, exit 2, nothing written."""
    p = tmp_path / "s.yaml"
    p.write_text(text)
    out = tmp_path / "out"
    assert cli.main(["run", str(p), "--out", str(out)]) == cli.EXIT_USAGE
    assert capsys.readouterr().err == f"gyro-platform run: error: scene 's.yaml': {says}\n"
    assert not out.exists()


@pytest.mark.parametrize("args,words", [
    (["run", "no_such_scene"], "no such file or scene name (scenes: coning,"),
    (["run", "default", "--duration", "-1"], "--duration must be a finite number > 0"),
    (["run", "default", "--duration", "nan"], "argument --duration: expected a finite number, got nan"),
    (["run", "default", "--integrator", "euler"], "integrator: expected one of"),
    (["run", "default", "--max-step", "5"], "max_step"),
])
def test_bad_run_arguments_are_exit_2(args, words, tmp_path, capsys):
    assert cli.main([*args, "--no-files"]) == cli.EXIT_USAGE
    assert words in one_line_error(capsys.readouterr().err, "run")


def test_scenes_by_name_from_any_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", "default", "--no-files", "--duration", "0.2"]) == cli.EXIT_FAILED   # too short to judge
    assert "scene default:" in capsys.readouterr().out
    assert cli.main(["run", "coning.yaml", "--no-files", "--duration", "0.2"]) == cli.EXIT_FAILED
    bag = small_bag(tmp_path / "b")
    assert cli.main(["replay", str(bag), "--out", "o", "--scene", "earth_rest", "--quiet", "--no-plot"]) == 0
    s = json.loads(Path("o.summary.json").read_text())
    assert "earth_rate" in s["simulator"]["effects"] and s["simulator"]["fidelity"] == "full"


def test_default_fidelity_is_one_per_mode_everywhere(tmp_path, capsys):
    """Replay without a scene, a scene without ``fidelity`` and the library all take the
    mode's default from ``options.DEFAULT_FIDELITY``."""
    from gyro_platform.engine.simulator import Simulator
    from gyro_platform.physics.options import DEFAULT_FIDELITY, ModelOptions
    from gyro_platform.scenes.schema import scene_from_dict

    bag = small_bag(tmp_path / "b")
    assert cli.main(["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--no-plot"]) == 0
    s = json.loads(rp.sidecar_paths(tmp_path / "o")[0].read_text())
    assert s["simulator"]["mode"] == "stabilised"
    assert s["simulator"]["fidelity"] == DEFAULT_FIDELITY["stabilised"] == Simulator().options.fidelity
    from gyro_platform.ros.config import NodeConfig

    assert NodeConfig.from_ros_params({}).options.fidelity == DEFAULT_FIDELITY["stabilised"]
    for mode in ("stabilised", "carried"):
        sc = scene_from_dict({"mode": mode, "duration": 1, "motion": {"type": "constant", "omega": [0, 0, 0]}})
        node = NodeConfig.from_ros_params({"mode": mode, "effects": ["defaults"]})
        assert sc.fidelity == DEFAULT_FIDELITY[mode] == ModelOptions.make(mode).fidelity == node.options.fidelity
    assert set(DEFAULT_FIDELITY.values()) == {"linear", "full"}          # the README states these


# ---- outputs.csv ---------------------------------------------------------------------------------
def _column_regex(pattern: str) -> re.Pattern:
    """``<name>`` in a documented column stands for one of ``COLUMN_PLACEHOLDERS[name]``."""
    parts = re.split(r"<([a-z]+)>", pattern)
    rx = "".join(re.escape(p) if i % 2 == 0 else "(" + "|".join(map(re.escape, COLUMN_PLACEHOLDERS[p])) + ")"
                 for i, p in enumerate(parts))
    return re.compile("^" + rx + "$")


def documentation() -> str:
    """README.md and the docs/ pages, the text a user reads."""
    return "\n".join(p.read_text() for p in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))])


def test_every_csv_column_has_a_unit_and_is_documented_once(tmp_path, capsys):
    readme = documentation()
    for scene in ("default", "coning"):      # stabilised and carried: every column kind
        out = tmp_path / scene
        cli.main(["run", scene, "--out", str(out), "--duration", "0.5"])
        header = next(csv.reader((out / "outputs.csv").open()))
        pats = [_column_regex(c) for c, _, _ in CSV_COLUMNS]
        for col in header:
            hits = [c for (c, _, _), rx in zip(CSV_COLUMNS, pats) if rx.match(col)]
            assert len(hits) == 1, (col, hits)
        if scene == "default":
            for need_col in ("platform_attitude_qw", "servo_torque_z_N_m", "motor_torque_rotor11_N_m", "t_s"):
                assert need_col in header
    for c, unit, _ in CSV_COLUMNS:
        assert readme.count(f"| `{c}` |") == 1, c
        suffix = {"rad": "_rad", "rad/s": "_rad_s", "N m": "_N_m", "s": "_s"}.get(unit)
        assert suffix is None or c.endswith(suffix), (c, unit)
    capsys.readouterr()


def test_csv_round_trips_the_outputs_exactly(tmp_path):
    """Values in outputs.csv equal the simulator's outputs bit for bit (repr of floats)."""
    from gyro_platform.reports.recording import csv_row
    from gyro_platform.scenes.runner import run_scene
    from gyro_platform.scenes.schema import load_scene

    rec, _, _ = run_scene(load_scene("default").with_duration(0.3), out_dir=tmp_path)
    rows = list(csv.DictReader((tmp_path / "outputs.csv").open()))
    for o, r in zip(rec._outs, rows):
        for k, v in csv_row(o).items():
            assert float(r[k]) == v or (math.isnan(v) and math.isnan(float(r[k]))), k
    q = [[float(r[f"platform_attitude_{c}"]) for c in ("qx", "qy", "qz", "qw")] for r in rows]
    assert all(abs(sum(x * x for x in qq) - 1) < 1e-12 for qq in q)


# ---- help, version, pipes -------------------------------------------------------------------
def test_help_texts_list_exit_codes_and_no_rst_markup(capsys):
    for args in ([], ["run"], ["replay"], ["bench"], ["node"]):
        with pytest.raises(SystemExit) as e:
            cli.main([*args, "--help"])
        assert e.value.code == 0
        text = capsys.readouterr().out
        assert "``" not in text and "exit status:" in text, args
        for code in cli.EXIT_CODES:
            assert re.search(rf"^  {code}\s", text, re.M), (args, code)
        if not args:
            assert re.search(r"^    node\s", text, re.M) and re.search(r"^    replay\s", text, re.M)


def test_the_docs_document_the_exit_codes():
    readme = documentation()
    for code in cli.EXIT_CODES:
        assert re.search(rf"^\| `{code}` \|", readme, re.M), code


def test_version_and_usage_errors(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"gyro-platform {__version__}"
    for bad in (["frobnicate"], ["run", "default", "--bogus"], ["replay", "x"], []):
        with pytest.raises(SystemExit) as e:
            cli.main(bad)
        assert e.value.code == cli.EXIT_USAGE
        assert "Traceback" not in capsys.readouterr().err


def _cli(args: list[str], cwd: Path, env: dict | None = None, shell_tail: str = "") -> subprocess.CompletedProcess:
    cmd = " ".join([PY, "-m", "gyro_platform.cli", *args])
    return subprocess.run(["bash", "-c", f"set -o pipefail; {cmd} {shell_tail}"], cwd=cwd, capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(REPO), **(env or {})}, timeout=600)


def test_broken_pipe_is_quiet(tmp_path):
    p = _cli(["run", "default", "--no-files", "--duration", "0.5"], tmp_path, shell_tail="| head -1")
    assert p.stdout.startswith("scene default:") and p.stdout.count("\n") == 1
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr, p.stderr
    assert p.returncode == 0


def test_replay_results_on_stdout_progress_on_stderr(tmp_path):
    need(CABRILLO)
    p = _cli(["replay", str(CABRILLO), "--out", "o", "--no-plot"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("/logic_tube/imu: 1041 in, 1041 accepted")
    assert "drift rate (least-squares slope" in p.stdout and "wrote o" in p.stdout
    assert "msg/s" not in p.stderr and "it/s" not in p.stderr        # no progress bar into a pipe
    info = [ln for ln in p.stderr.splitlines() if "logic_tube_bno085" in ln]
    assert len(info) == 1 and "info:" in info[0] and "warning" not in p.stderr


def _replay_on_a_terminal(bag: Path, cwd: Path, *extra: str) -> tuple[int, str, str]:
    """Replay ``bag`` with stderr on a 100-column pseudo-terminal (stdout a pipe): (exit status,
    stdout, what the terminal showed)."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = subprocess.Popen([PY, "-m", "gyro_platform.cli", "replay", str(bag), "--out", "o", "--no-plot",
                             *extra], cwd=cwd, stdout=subprocess.PIPE, stderr=slave, text=True,
                            env={**os.environ, "PYTHONPATH": str(REPO)})
    os.close(slave)
    shown = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:          # the child closed the terminal (EIO)
            break
        if not chunk:
            break
        shown += chunk
    out = proc.stdout.read()
    code = proc.wait(timeout=600)
    os.close(master)
    return code, out, shown.decode(errors="replace")


def test_replay_progress_bar_on_a_terminal_only_and_not_with_quiet(tmp_path):
    bag = small_bag(tmp_path / "in", seconds=2.0)           # 101 messages
    code, out, shown = _replay_on_a_terminal(bag, tmp_path)
    assert code == 0 and out.startswith("/imu: 101 in"), shown
    assert "101/101" in shown and "100%" in shown and "msg/s" in shown, shown   # the bar reached the total
    shutil.rmtree(tmp_path / "o")
    (tmp_path / "o.summary.json").unlink()
    code, out, shown = _replay_on_a_terminal(bag, tmp_path, "--quiet")
    assert code == 0 and "msg/s" not in shown and "%" not in shown, shown


def test_a_replay_that_shows_no_bar_does_not_load_tqdm(tmp_path):
    """Into a pipe (or with ``--quiet``) no bar is drawn, and tqdm (~40 ms with its lock) is not
    imported inside the replay's clock."""
    bag = small_bag(tmp_path / "in", seconds=1.0)
    probe = ("import sys; from gyro_platform.replay import replay, ReplayConfig; "
             "s = replay(sys.argv[1], sys.argv[2], ReplayConfig(plot=False)); "
             "print(s['counts']['accepted'], s['error'], 'tqdm' in sys.modules)")
    p = subprocess.run([PY, "-c", probe, str(bag), str(tmp_path / "o")], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.split() == ["51", "None", "False"], p.stdout       # 51 samples replayed, tqdm not loaded


def test_a_command_line_freezes_its_start_up_objects_and_a_library_call_does_not(tmp_path):
    """The process's own command line moves the objects of its start-up (numpy, numba, the
    command's modules: ~10⁵) to the collector's permanent generation before the command runs, so
    that no full collection scans them again (4-7 % of a warm ``run`` or ``replay``, benchmarks
    in docs/benchmarks.md), and keeps the collector off while they are made (no collection
    until the command runs, ~25 ms of a replay's start; on again for the command); ``main(argv)``
    called by a program leaves its collector alone (it collects while the modules load)."""
    probe = textwrap.dedent("""
        import gc, importlib, sys
        n, seen = [0], []
        gc.callbacks.append(lambda phase, info: n.__setitem__(0, n[0] + (phase == "start")))
        load = importlib.import_module

        def import_module(name, *rest):
            m = load(name, *rest)
            if name == "gyro_platform.scenes.command" and not getattr(m, "probed", False):
                m.probed, run = True, m.run
                m.run = lambda a: seen.append((gc.get_freeze_count(), gc.isenabled(), n[0] - n0)) or run(a)
            return m

        importlib.import_module = import_module
        from gyro_platform.cli import main
        lib = sys.argv[1] == "library"
        sys.argv[1:] = ["run", "default", "--duration", "0.2", "--no-files"]
        n0 = n[0]
        code = main(sys.argv[1:] if lib else None)
        print(code, *seen[0], gc.isenabled())
    """)
    got = {}
    for how in ("command", "library"):
        p = subprocess.run([PY, "-c", probe, how], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                           env={**os.environ, "PYTHONPATH": str(REPO)})
        assert p.returncode == 0, p.stderr[-2000:]
        code, frozen, enabled, collections, after = p.stdout.split()[-5:]
        assert code in ("0", "1"), p.stdout      # 1: 0.2 s is too short for the scene's expectations
        assert enabled == after == "True", p.stdout     # on while the command runs, and after it
        got[how] = (int(frozen), int(collections))
    assert got["command"][0] > 50_000 and got["command"][1] == 0, got
    assert got["library"][0] == 0 and got["library"][1] > 10, got


# ---- a regular (non-editable) install finds its scenes --------------------------------------
def test_non_editable_install_finds_scenes_from_any_folder(tmp_path):
    """A real install into a fresh prefix, the way colcon installs an ament_python package
    (``setup.py install --single-version-externally-managed``; pip's wheel install lays out the
    same: the package under <prefix>/lib/pythonX.Y/site-packages, data files under
    <prefix>/share). The installed console script then runs scenes by name from an unrelated
    folder, with no source tree in reach. (pip itself needs the ``wheel`` package to build,
    which this environment lacks.)"""
    prefix = tmp_path / "prefix"
    src = tmp_path / "src"            # a clean copy: the build leaves build/ and egg-info behind
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".git", "results", "__pycache__", "*.egg-info",
                                                             "build", ".venv", "test"))
    record = tmp_path / "installed.txt"
    inst = subprocess.run([PY, "setup.py", "-q", "install", "--single-version-externally-managed",
                           "--record", str(record), "--prefix", str(prefix)],
                          cwd=src, capture_output=True, text=True, timeout=600)
    assert inst.returncode == 0, inst.stderr[-2000:]
    shutil.rmtree(src)                # nothing of the source tree is left to find
    files = [Path(f) for f in record.read_text().split()]
    site = next(prefix.glob("lib/python*/site-packages"))
    assert prefix / "share/gyro_platform/config/scenes/default.yaml" in files
    exe = next(f for f in files if f.name == "gyro-platform")
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    p = subprocess.run([PY, str(exe), "run", "default", "--duration", "0.3", "--no-files"], cwd=work,
                       capture_output=True, text=True, env=env, timeout=600)
    assert p.stdout.startswith("scene default:"), p.stderr
    assert p.returncode == cli.EXIT_FAILED, p.stderr      # ran; too short to judge the expectations
    p = subprocess.run([PY, str(exe), "run", "earth_rest.yaml", "--duration", "2", "--out", "r"], cwd=work,
                       capture_output=True, text=True, env=env, timeout=600)
    assert (work / "r" / "outputs.csv").is_file(), p.stderr
    probe = ("import gyro_platform, gyro_platform.ros.config as c; "
             "print(gyro_platform.__file__); print(c.resolve_scene('default'))")
    p = subprocess.run([PY, "-c", probe], cwd=work, capture_output=True, text=True, env=env, timeout=600)
    mod, scene = p.stdout.split()
    assert Path(mod).is_relative_to(site), mod
    assert Path(scene) == prefix / "share/gyro_platform/config/scenes/default.yaml"


# ---- plots ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("scene", ["default", "rate_step_shock"])
def test_every_plot_panel_has_title_units_and_legend_and_the_title_fits(scene):
    import matplotlib.pyplot as plt

    from gyro_platform.scenes.runner import run_scene
    from gyro_platform.scenes.schema import load_scene

    sc = load_scene(scene)
    rec, summary, _ = run_scene(sc.with_duration(0.5))
    long_title = f"{sc.name}: {sc.description} " * 3                 # far wider than the figure
    fig = rec.figure(long_title, summary)
    try:
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        assert len(fig.axes) >= 3
        for ax in fig.axes:
            assert ax.get_title(), ax
            assert re.search(r"\[[^\]]+\]$", ax.get_ylabel()), ax.get_ylabel()
            assert ax.get_legend() is not None and ax.get_legend().get_texts(), ax.get_title()
        assert re.search(r"\[s\]$", fig.axes[-1].get_xlabel())
        for text in (fig._suptitle, *(ax.title for ax in fig.axes)):
            box = text.get_window_extent(r)
            assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1, text.get_text()[:40]
        # every text is plain (no mathtext: its parser is built on first use, ~0.15 s)
        labels = [t.get_text() for ax in fig.axes for t in (*ax.get_xticklabels(), *ax.get_yticklabels())]
        assert labels and not [s for s in labels if "$" in s], labels
    finally:
        plt.close(fig)


@pytest.mark.parametrize("args,words", [
    (["--output-rate", "-1"], "--output-rate -1.0: must be 0 (every sample) or a finite rate"),
    (["--output-rate", "inf"], "argument --output-rate: expected a finite number, got inf"),
    (["--diagnostics-rate", "inf"], "argument --diagnostics-rate: expected a finite number, got inf"),
    (["--diagnostics-rate", "0"], "--diagnostics-rate 0.0"),
    (["--namespace", "bad ns"], "not a ROS namespace"),
    (["--namespace", "1robot"], "not a ROS namespace"),
    (["--max-gap", "0"], "max_gap"),
    (["--max-rate", "nan"], "argument --max-rate: expected a finite number, got nan"),
    (["--mount", "imu=1,2"], "mounting"),
])
def test_bad_replay_arguments_are_exit_2_and_write_nothing(args, words, tmp_path, capsys):
    bag = small_bag(tmp_path / "b")
    out = tmp_path / "o"
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", *args]) == cli.EXIT_USAGE
    assert words in one_line_error(capsys.readouterr().err, "replay")
    assert not out.exists() and not rp.sidecar_paths(out)[0].exists()


@pytest.mark.parametrize("flag", ["--namespace", "--topic", "--out"])
def test_a_text_option_given_as_double_dash_is_one_usage_error(flag, tmp_path, capsys):
    """argparse makes ``--flag=--`` an empty list without a word: refused as a usage error
    (exit 2, one line naming the flag), not a traceback."""
    bag = small_bag(tmp_path / "b")
    args = ["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", f"{flag}=--"]
    with pytest.raises(SystemExit) as e:
        cli.main(args)
    assert e.value.code == cli.EXIT_USAGE
    assert f"argument {flag}: expected one value" in one_line_error(capsys.readouterr().err, "replay")
    assert not (tmp_path / "o").exists()


def test_namespaces_that_are_valid_pass():
    for ns in ("", "/", "robot1", "/robot1/", "a/b_c", "_x"):
        assert rp.NAMESPACE_RE.fullmatch(ns), ns
    for ns in ("a b", "a//b", "9a", "a__b", "a-b"):
        assert not rp.NAMESPACE_RE.fullmatch(ns), ns


# ---- issue 17: values refused up front, no usable input, exit codes -----------------------------
@pytest.mark.parametrize("args,words", [
    (["--output-rate", "-5"], "--output-rate -5.0: must be 0 (every sample) or a finite rate"),
    (["--output-rate", "nan"], "argument --output-rate: expected a finite number, got nan"),
    (["--diagnostics-rate", "nan"], "argument --diagnostics-rate: expected a finite number, got nan"),
    (["--max-gap", "inf"], "argument --max-gap: expected a finite number, got inf"),
    (["--reset-on-jump-back", "nan"], "argument --reset-on-jump-back: expected a finite number, got nan"),
    (["--namespace", "bad name!"], "--namespace 'bad name!': not a ROS namespace"),
    (["--namespace", "a//b"], "not a ROS namespace"),
    (["--namespace", "a" * 230], "--namespace: too long"),
    (["--output-rate=--"], "argument --output-rate: expected one float value"),
    (["--mount", "imu=a,b,c"], "--mount: mounting"),
    (["--mount", "base_link=0,0,1"], "base_link is the vehicle frame itself"),
    (["--mount", "imu=0,0,1", "--mount", "imu=0,0,2"], "frame 'imu' is mounted twice"),
    (["--max-specific-force", "0"], "--max-specific-force: max_specific_force = 0.0"),
])
def test_more_bad_replay_values_are_exit_2_naming_the_flag(args, words, tmp_path, capsys):
    bag = small_bag(tmp_path / "b")
    out = tmp_path / "o"
    try:
        code = cli.main(["replay", str(bag), "--out", str(out), "--quiet", *args])
    except SystemExit as e:           # argparse's own refusal
        code = e.code
    assert code == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "Traceback" not in err and words in err, err
    assert not out.exists() and not rp.sidecar_paths(out)[0].exists()


@pytest.mark.parametrize("args,words", [
    (["--duration", "1e12"], "--duration: 1e+12 makes the run too big to start"),
    (["--duration", "inf"], "argument --duration: expected a finite number, got inf"),
    (["--max-step", "1e-12"], "max_step' = 1e-12 s; allowed [1e-06, 1] s"),
    (["--duration", "1e6", "--max-step", "1e-6"], "makes the run too big to start"),
    (["--max-step", "nan"], "argument --max-step: expected a finite number, got nan"),
])
def test_runs_too_big_to_run_are_refused_with_an_estimate(args, words, capsys):
    assert cli.main(["run", "default", "--no-files", *args]) == cli.EXIT_USAGE
    line = one_line_error(capsys.readouterr().err, "run")
    assert words in line, line
    if "too big" in line:
        assert re.search(r"GiB of memory \(bound 8 GiB\), ≥ .+ of CPU \(bound 1e\+09 steps\)", line), line


@pytest.mark.parametrize("extra,words", [
    ("params: {servo_kp: true}\n", "params.servo_kp: expected a number, got a boolean True"),
    ("params: {bias_torque: [[0, 0], [0, 0, 1.0e-7]]}\n", "params.bias_torque[0]: expected a number, got a list"),
    ("sample_rate: 1.0e+9\n", "sample_rate: 1e+09 makes the run too big to start"),
    ("max_step: 1.0e-12\n", "max_step: option 'max_step' = 1e-12 s; allowed [1e-06, 1] s"),
    ("rtol: 1.0e-300\n", "rtol: must be ≥ 1e-13"),
    ("rtol: 1.0e-14\n", "rtol: must be ≥ 1e-13"),        # one floor, one message (options.RTOL_MIN)
])
def test_scene_values_that_cannot_be_meant_are_refused(extra, words, tmp_path, capsys):
    p = tmp_path / "s.yaml"
    p.write_text("duration: 60\nmotion: {type: constant, omega: [0, 0, 0.01]}\n" + extra)
    assert cli.main(["run", str(p), "--no-files"]) == cli.EXIT_USAGE
    assert words in one_line_error(capsys.readouterr().err, "run")
    big = tmp_path / "d.yaml"
    big.write_text("duration: 1.0e+12\nmotion: {type: constant, omega: [0, 0, 0.01]}\n")
    assert cli.main(["run", str(big), "--no-files"]) == cli.EXIT_USAGE
    line = one_line_error(capsys.readouterr().err, "run")
    assert "duration: 1e+12 makes the run too big to start: ~1e+14 samples, 1e+13 outputs" in line


def test_ctrl_c_while_a_command_is_set_up_is_one_line_and_130(monkeypatch, capsys):
    """A Ctrl-C in the first ~0.5 s (imports, parser) printed a KeyboardInterrupt traceback."""
    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["run", "default"]) == cli.EXIT_INTERRUPTED == 130
    assert capsys.readouterr().err == "gyro-platform: interrupted\n"


def test_node_help_says_a_signal_stops_it_with_exit_0(capsys):
    with pytest.raises(SystemExit):
        cli.main(["node", "--help"])
    out = capsys.readouterr().out
    assert "node: Ctrl-C or SIGTERM is how a node is stopped (ros2 launch, systemd): exit 0" in " ".join(out.split())


@pytest.mark.parametrize("motion,words", [
    ("{type: constant, omega: [1.0e200, 0, 0]}", "motion 'constant': cannot be generated"),
    ("{type: random, seed: 1, angle_rms_deg: 1.0e300, band_hz: [0.1, 1.0e300]}",   # (its rates: not finite)
     "sample_rate: 100 Hz cannot carry the motion's 1e+300 Hz"),
    ("{type: random, seed: 1, angle_rms_deg: 1, components: 100000000000}",
     "motion.components: must be ≤ 256, got 100000000000"),
])
def test_motions_beyond_floating_point_are_refused_before_anything_is_written(motion, words, tmp_path, capsys):
    """A rate of 1e200 rad/s or an RMS of 1e300° cannot be simulated (a traceback, or a 4 TiB
    allocation, before): exit 2 in one line, no file; in a sweep such a draw is 'refused'."""
    p = tmp_path / "s.yaml"
    p.write_text(f"duration: 2\nmotion: {motion}\n")
    out = tmp_path / "out"
    assert cli.main(["run", str(p), "--out", str(out)]) == cli.EXIT_USAGE
    assert words in one_line_error(capsys.readouterr().err, "run")
    assert not out.exists()


def test_a_topic_without_messages_is_exit_3_not_0(tmp_path, capsys):
    from test_replay import T

    bag = write_bag(tmp_path / "e", [], extra=[("/other", "std_msgs/msg/String",
                                                [(T0, T["std_msgs/msg/String"](data="x"))])])
    out = tmp_path / "o"
    assert cli.main(["replay", str(bag), "--out", str(out), "--quiet", "--no-plot"]) == cli.EXIT_DATA
    line = one_line_error(capsys.readouterr().err, "replay")
    assert "topic /imu has no messages: no outputs" in line
    s = json.loads(rp.sidecar_paths(out)[0].read_text())
    assert s["counts"]["out"] == 0 and s["output"]["messages_by_topic"]["/other"] == 1   # the copy is written


def test_every_sample_dropped_is_exit_3_for_replay_and_run(tmp_path, capsys):
    """Every rate over --max-rate: no output; replay and run both exit 3 with the hint."""
    n = 50
    bag = write_bag(tmp_path / "over", [(T0 + i * S // 50, imu_msg(T0 + i * S // 50, (40.0, 0.0, 0.0)))
                                        for i in range(n)])
    (c1, e1), (c2, e2) = run_and_replay(tmp_path, bag, capsys)
    assert c1 == c2 == cli.EXIT_DATA
    for line in (one_line_error(e1, "run"), one_line_error(e2, "replay")):
        assert "none of the 50 input messages was accepted (50 dropped as over_rate)" in line, line


def test_exit_codes_are_distinct_and_documented_in_help(capsys):
    from gyro_platform import errors

    codes = [errors.EXIT_OK, errors.EXIT_FAILED, errors.EXIT_USAGE, errors.EXIT_DATA, errors.EXIT_WRITE,
             errors.EXIT_INTERRUPTED, errors.EXIT_TERMINATED]
    assert len(set(codes)) == len(codes) == len(errors.EXIT_CODES) and set(codes) == set(errors.EXIT_CODES)
    assert errors.EXIT_INTERRUPTED == 128 + 2 and errors.EXIT_TERMINATED == 128 + 15


def test_signals_inside_a_deferred_block_arrive_after_it():
    """In process: a SIGTERM during ``deferred_signals`` is held until the block ends, then
    raised as ``Terminated`` (a KeyboardInterrupt); a second signal after the stop raises nothing."""
    import signal as sg
    import threading

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers live in the main thread only")
    done = []
    # Ctrl-C raising, as in a terminal (a test run started as a background job inherits SIGINT ignored)
    before = sg.signal(sg.SIGINT, sg.default_int_handler)
    try:
        stopped_then_restored(done)
    finally:
        sg.signal(sg.SIGINT, before)


def stopped_then_restored(done: list) -> None:
    """The body of the test above: SIGTERM held by ``deferred_signals``, then raised; the handlers
    in place before ``StopSignals`` restored after it."""
    import signal as sg

    from gyro_platform.signals import deferred_signals, StopSignals, Terminated

    with StopSignals("test") as stop:
        assert sg.getsignal(sg.SIGTERM) == stop._handler      # never SIGTERM the test runner itself
        with pytest.raises(Terminated):
            with deferred_signals():
                os.kill(os.getpid(), sg.SIGTERM)
                for _ in range(1000):       # the handler runs between bytecodes: give it some
                    done.append(1)
                done.append("closed")
        assert done[-1] == "closed" and stop.received == sg.SIGTERM
        os.kill(os.getpid(), sg.SIGINT)     # already stopping: noted, not raised
        sum(range(1000))
    assert sg.getsignal(sg.SIGINT) is sg.default_int_handler


def test_the_ros2_run_entry_sets_one_blas_thread_before_numpy_loads(tmp_path):
    """``platform_node`` (setup.py's console script, what ``ros2 run`` and the launch file start)
    is ``cli.platform_node``: the one-BLAS-thread limit (engine.blas) is set before the node's
    imports load NumPy, so its OpenBLAS starts no worker per core. Here the node module is a probe
    that loads NumPy and reports its BLAS threads (the real node runs through the same console
    script in the ROS tests); called without the entry, the probe sees a thread per core."""
    probe = textwrap.dedent("""
        import sys, types
        def main():
            import numpy
            from threadpoolctl import threadpool_info
            print(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
            return 0
        node = types.ModuleType("gyro_platform.ros.node")
        node.main = main
        sys.modules["gyro_platform.ros.node"] = node
        from gyro_platform import cli
        sys.exit(cli.platform_node() if sys.argv[1] == "entry" else main())
    """)
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    threads = {}
    for how in ("entry", "direct"):
        p = subprocess.run([PY, "-c", probe, how], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                           env={**env, "PYTHONPATH": str(REPO)})
        assert p.returncode == 0, p.stderr[-2000:]
        threads[how] = int(p.stdout.split()[-1])
    assert threads["entry"] == 1, threads
    if (os.cpu_count() or 1) > 1:            # the probe can tell: without the entry a worker per core
        assert threads["direct"] > 1, threads


EXIT_PROBE = """
import atexit, sys, threading, time
from gyro_platform.signals import exit_now
atexit.register(lambda: print("atexit ran", flush=False))
print("buffered", end=" ")
sys.stderr.write("err buffered ")
if sys.argv[1] == "thread":
    def late():
        time.sleep(0.3)
        print("thread finished", end=" ")
    threading.Thread(target=late).start()
exit_now(int(sys.argv[2]))
print("not reached")
"""


@pytest.mark.parametrize("mode, code", [("plain", 0), ("plain", 3), ("thread", 143)])
def test_a_command_ends_without_teardown_but_with_its_atexit_handlers_output_and_status(mode, code):
    """``exit_now`` (the console script's end): the atexit handlers run, buffered stdout and
    stderr reach the pipe, the status is the command's; a thread still running is waited for
    (the usual exit) instead of being cut off."""
    r = subprocess.run([sys.executable, "-c", EXIT_PROBE, mode, str(code)], capture_output=True, text=True,
                       timeout=60, env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert r.returncode == code
    assert r.stderr == "err buffered "
    expect = "buffered thread finished atexit ran\n" if mode == "thread" else "buffered atexit ran\n"
    assert r.stdout == expect
