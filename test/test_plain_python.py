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

"""The compiled kernels against their own source run by the interpreter (``NUMBA_DISABLE_JIT=1``,
the debugging mode docs/architecture.md names): the same command gives the same bytes. numba
compiles without fast-math, so LLVM may not reorder a float operation: a difference would be a
miscompile, a kernel relying on a compiled-only behaviour (integer overflow, an unchecked index)
or a fallback that broke (``engine.views``' intrinsics, ``physics.system.model_rhs``' overload,
``physics.jit.plain``)."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from test_cli import small_bag

from gyro_platform.messages import output_topics
from imubag import raw_by_topic

REPO = Path(__file__).resolve().parents[1]


def _run(args: list[str], cwd: Path, interpreted: bool) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), "NUMBA_DISABLE_JIT": "1" if interpreted else "0"}
    p = subprocess.run([sys.executable, "-m", "gyro_platform", *args], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=900)
    assert p.returncode in (0, 1), p.stderr[-3000:]     # 1: the scene's expectations need 30 s
    assert "Traceback" not in p.stderr, p.stderr[-3000:]
    return p


def test_the_default_scene_interpreted_writes_the_compiled_runs_csv_byte_for_byte(tmp_path):
    """The default scene (full tree, stabilised, auto: RK4 with the support friction's switch
    location) for 1 s: ``outputs.csv`` (every output, 17 significant digits) is the same file."""
    for how in ("compiled", "interpreted"):
        _run(["run", "default", "--duration", "1", "--out", how], tmp_path, how == "interpreted")
    csv = (tmp_path / "compiled" / "outputs.csv").read_bytes()
    assert len(csv.splitlines()) >= 11                   # a header and 10 outputs at least
    assert (tmp_path / "interpreted" / "outputs.csv").read_bytes() == csv


def test_a_replay_interpreted_writes_the_compiled_replays_messages_byte_for_byte(tmp_path):
    """A 2 s Imu bag at 100 Hz through the replay (gate kernels, linear model, output kernel,
    CDR encoders): every output message is the same bytes at the same record time."""
    bag = small_bag(tmp_path / "in", seconds=2.0, rate=100.0)
    got = {}
    for how in ("compiled", "interpreted"):
        _run(["replay", str(bag), "--out", how, "--no-plot", "--output-rate", "50"], tmp_path, how == "interpreted")
        got[how] = raw_by_topic(tmp_path / how)
    topics = [t for t in output_topics("") if t in got["compiled"]]
    assert len(topics) >= 10 and len(got["compiled"]["/gimbal/joint_states"]) >= 90, \
        {t: len(v) for t, v in got["compiled"].items()}
    for t in topics:
        assert got["interpreted"][t] == got["compiled"][t], t
