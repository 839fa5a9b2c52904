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

"""numba's library pieces made cheaper to compile (``physics.lean_overloads``), each in a new
process with an empty kernel cache (the replacement is process-wide, installed at the first
compile).

Behaviour: a kernel with a slice assignment from an array, compiled where numba is as shipped,
compiles numba's shape-formatting error and its string machinery (the check can fail); compiled
after the package's ``jit`` is imported, it compiles neither, still raises ``ValueError`` on a
shape mismatch (the constant message) and assigns what numpy assigns. (The message decoder,
the package's kernel with such an assignment, is checked against rosbags by its own tests, which
run with the replacement installed.)
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]

PROBE = r"""
import json, sys
import numpy as np
from numba import njit
from numba.core import event
if sys.argv[1] == "package":
    import gyro_platform.physics.jit  # noqa: F401  (installs the lean overloads at the first compile)

@njit
def put(a, b, k):
    a[:k] = b
    return a

with event.install_recorder("numba:compile") as rec:
    put(np.zeros(4), np.ones(2), 2)
names = sorted({ev.data["dispatcher"].py_func.__qualname__ for _, ev in rec.buffer
                if ev.is_start and isinstance(ev.data, dict) and "dispatcher" in ev.data})
a = put(np.zeros(4), np.arange(1.0, 4.0), 3)
try:
    put(np.zeros(4), np.ones(3), 2)
    err = None
except ValueError as e:
    err = str(e)
print(json.dumps({"compiled": names, "result": a.tolist(), "error": err}))
"""


def _probe(mode: str, tmp_path: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True,
                         timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _string_machinery(names: list[str]) -> list[str]:
    return [n for n in names if "shape_context" in n or "join" in n or "str_generic" in n]


def test_numba_as_shipped_formats_the_shapes(tmp_path):
    got = _probe("numba", tmp_path)
    assert _string_machinery(got["compiled"]), got["compiled"]
    assert got["error"] == "cannot assign slice of shape (2,) from input of shape (3,)"


def test_package_compiles_no_string_machinery_and_still_raises(tmp_path):
    from gyro_platform.physics.lean_overloads import MESSAGE

    got = _probe("package", tmp_path)
    assert not _string_machinery(got["compiled"]), got["compiled"]
    assert "shape_mismatch" in " ".join(got["compiled"])        # the replacement took its place
    assert got["result"] == [1.0, 2.0, 3.0, 0.0]
    assert got["error"] == MESSAGE
