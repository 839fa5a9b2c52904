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

"""One BLAS thread per process (engine.blas): every BLAS library, NumPy's and SciPy's (loaded
later, when a method needs it), ends at one thread, and the command line sets it before a
command runs."""
import json
import subprocess
import sys

PROBE = """
import json
from threadpoolctl import threadpool_info
{setup}
print(json.dumps([(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]))
"""


def _blas_threads(setup: str) -> list:
    """(library path, threads) of every BLAS library in a fresh interpreter after ``setup``
    (started with two threads, as on a 2-core machine)."""
    out = subprocess.run([sys.executable, "-c", PROBE.format(setup=setup)], capture_output=True, text=True,
                         env={"OPENBLAS_NUM_THREADS": "2", "PATH": ""}, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_every_blas_library_ends_at_one_thread():
    before = _blas_threads("import numpy, scipy.linalg")
    assert len(before) >= 1       # the probe sees them (at 2 threads, or 1 on a 1-core machine)
    after = _blas_threads("import numpy\nfrom gyro_platform.engine.blas import limit_blas_threads\n"
                          "limit_blas_threads()\nimport scipy.linalg")
    assert {p for p, _ in after} >= {p for p, _ in before}           # SciPy's, loaded after the call, too
    assert all(n == 1 for _, n in after)


def test_the_call_does_not_import_scipy():
    # SciPy's BLAS is loaded by the methods that need scipy.linalg, not at start-up (0.36 s)
    out = subprocess.run([sys.executable, "-c", "import sys\nfrom gyro_platform.engine.blas import limit_blas_threads\n"
                          "limit_blas_threads()\nprint('scipy.linalg' in sys.modules)"],
                         capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"]


def test_the_command_line_limits_before_the_command_runs():
    # a command that is refused (exit 2: no such scene) has still passed the set-up
    after = _blas_threads("import contextlib, io\nimport gyro_platform.cli as c\n"
                          "with contextlib.redirect_stderr(io.StringIO()):\n"
                          "    assert c.main(['run', '/nonexistent/scene.yaml']) == 2")
    assert after and all(n == 1 for _, n in after)


def test_without_threadpoolctl_nothing_changes_and_nothing_breaks():
    # (the probe holds threadpool_info already; the package's own import of threadpoolctl fails)
    after = _blas_threads("import sys, numpy, scipy.linalg\nsys.modules['threadpoolctl'] = None\n"
                          "from gyro_platform.engine.blas import limit_blas_threads\n"
                          "assert limit_blas_threads() is False")
    assert sorted(after) == sorted(_blas_threads("import numpy, scipy.linalg"))      # as they were
