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

"""The plot helper process (reports.plot_process): the PNG it draws is byte for byte the one this
process would draw, matplotlib is then never imported here, and whatever happens to the helper
(killed, hung, interrupted, unused) the plot is still drawn or the helper goes away on its own."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent("""
    import sys, signal, time
    sys.path.insert(0, {root!r})
    from gyro_platform.reports import plot_process
    plot_process.start()                       # first, as the command line does
    from gyro_platform.scenes.runner import run_scene
    from gyro_platform.scenes.schema import load_scene
    rec, summary, _ = run_scene(load_scene("rate_step_shock").with_duration(0.5))
    helper = plot_process._helper
    what = {what!r}
    if what == "kill":
        helper.kill(); helper.wait()
    elif what == "hang":
        helper.send_signal(signal.SIGSTOP)       # a helper that never answers
        plot_process.TIMEOUT_S = 2.0
    elif what == "sigint":
        time.sleep(3.0)                         # matplotlib imported by now: the handler is set
        helper.send_signal(signal.SIGINT); time.sleep(0.5)
    plot_process.draw(rec, {out!r}, "a title", summary)
    print("helper", helper.returncode, "matplotlib here", "matplotlib" in sys.modules)
    rec.plot({ref!r}, "a title", summary)      # the same figure drawn in this process
""")


def run(tmp_path: Path, what: str) -> tuple[str, bytes, bytes]:
    out, ref = tmp_path / "helper.png", tmp_path / "here.png"
    code = SCRIPT.format(root=str(ROOT), what=what, out=str(out), ref=str(ref))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    return p.stdout.strip(), out.read_bytes(), ref.read_bytes()


@pytest.mark.parametrize("what", ["draw", "sigint"])
def test_the_helper_draws_the_same_png_and_this_process_never_imports_matplotlib(tmp_path, what):
    said, png, ref = run(tmp_path, what)
    assert said == "helper 0 matplotlib here False"
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png == ref


@pytest.mark.parametrize("what", ["kill", "hang"])
def test_a_killed_or_hung_helper_leaves_the_plot_to_this_process(tmp_path, what):
    said, png, ref = run(tmp_path, what)
    assert said == f"helper {-signal.SIGKILL} matplotlib here True"
    assert png == ref


def test_an_unused_helper_exits_at_the_end_of_its_input():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "gyro_platform.reports.plot_process"], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, env=env)
    p.stdin.close()                             # the command ended without a plot
    assert p.wait(timeout=600) == 0 and p.stdout.read() == b""
