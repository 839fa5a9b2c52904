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

"""Loading cached kernels without parsing their bitcode, and numba's runtime kept compiled
(``physics.kernel_loading``), each in a new process (the patches are process-wide).

Behaviour: a process running the default scene from the cache parses no LLVM bitcode and
gives outputs (every gimbal and drift angle) equal bit for bit to a process with numba's own loading
(``GYRO_PLATFORM_LAZY_LOAD=0``, which parses the bitcode of every kernel it loads: the check
can fail); a kernel compiled after a lazy load, calling the loaded one, links it (its bitcode
parsed then) and computes what the Python function computes; an unknown mangled name has no
address. numba's runtime library is compiled in the first process and loaded from its file in
the next (arrays allocated by the runtime in both); a damaged file is compiled again. numba's
type of an array argument is the same as numba's own for plain arrays of every layout and dtype
kind, readonly ones and subclasses (errors too), and neither the scene nor a replay (mcap,
sqlite3) imports ``numpy.ma`` or numba's array module any more (numba's own loading does: the
check can fail); a kernel compiled and cached after those lazy environments loads again. numba's
extensions (a fake one installed for the test) are initialised where a kernel compiles, not
where one is loaded.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from gyro_platform.physics import kernel_loading
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import load_scene

ROOT = Path(__file__).resolve().parents[1]

#: counts numba's parses of LLVM bitcode in ``count[0]`` (the probes start with it)
COUNT_PARSES = """
import json
import sys
import llvmlite.binding as ll
import numpy as np
import gyro_platform.physics.jit as jit
count = [0]
parse = ll.parse_bitcode
def counted(data):
    count[0] += 1
    return parse(data)
ll.parse_bitcode = counted
"""

#: the default scene run 0.5 s from the cache (every compile refused); prints JSON: parses, the
#: number of outputs, every gimbal and drift angle (bytes, hex)
SCENE_PROBE = COUNT_PARSES + """
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import load_scene
with jit.compiles_refused():
    recorder, summary, results = run_scene(load_scene("default").with_duration(0.5))
values = np.concatenate([recorder.gimbal_angles.ravel(), recorder.drift_angle.ravel()])
print(json.dumps({"parses": count[0], "n": len(recorder), "values": values.tobytes().hex(),
                  "masked": "numpy.ma" in sys.modules, "arrayobj": "numba.np.arrayobj" in sys.modules}))
"""

#: a cached package kernel loaded lazily, then a new kernel calling it compiled (links it)
LINK_PROBE = COUNT_PARSES + """
from numba import njit
from gyro_platform.physics.rotations import quat_to_matrix
q = np.array([0.1, -0.2, 0.3, 0.9])
R = np.zeros((3, 3))
with jit.compiles_refused():
    quat_to_matrix(q, R)                       # loaded from the cache
loaded = count[0]
library = quat_to_matrix.overloads[quat_to_matrix.signatures[0]].library
@njit
def twice(q, R):
    quat_to_matrix(q, R)
    return 2.0 * R
out = twice(q, R)
ref = np.zeros((3, 3))
quat_to_matrix.py_func(q, ref)
print(json.dumps({"loaded": loaded, "after_link": count[0], "lazy": "_lazy_loaded" in library.__dict__,
                  "max_diff": float(np.max(np.abs(out - 2.0 * ref))),
                  "unknown": library.get_pointer_to_function("_ZN3not7a5kernelE")}))
"""

#: numba's runtime initialised, then an array made by a small jitted function (the runtime's
#: allocator); prints whether the runtime's library was loaded from its file, and the sum
NRT_PROBE = """
import json
import numpy as np
import gyro_platform.physics.jit as jit
from gyro_platform.physics import kernel_loading
from numba import njit
from numba.core.registry import cpu_target
@njit
def made(n):
    return np.arange(n) * 2.0
total = float(made(10).sum())
from numba.core.runtime import rtsys
print(json.dumps({"loaded": "_lazy_loaded" in rtsys.library.__dict__, "sum": total,
                  "file": str(kernel_loading.nrt_path(cpu_target.target_context.codegen()))}))
"""


@pytest.fixture(scope="module")
def default_cached():
    """This process's kernel cache holds the default scene's kernels (loaded, or compiled now)."""
    run_scene(load_scene("default").with_duration(0.5))


def _run(probe: str, **env: str) -> dict:
    full = dict(os.environ, PYTHONPATH=str(ROOT), **env)
    out = subprocess.run([sys.executable, "-c", probe], env=full, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cached_kernels_load_without_parsing_bitcode_and_give_the_same_outputs(default_cached):
    lazy = _run(SCENE_PROBE)
    numba_own = _run(SCENE_PROBE, GYRO_PLATFORM_LAZY_LOAD="0")
    assert lazy["parses"] == 0
    assert numba_own["parses"] >= 3                 # numba's loading parses each kernel's bitcode
    assert lazy["n"] == numba_own["n"] >= 10
    assert lazy["values"] == numba_own["values"]    # the same machine code: the same bits
    # numba's typeof of an array imports numpy.ma (15-19 ms) to ask whether it is masked
    assert lazy["masked"] is False and numba_own["masked"] is True
    # the environments of numba's array functions in the kernels: rebuilt without importing
    # numba's array module (~23 ms with the string code it imports). Whether numba's own loading
    # imports it depends on the environments this build's kernels carry (the scene's, compiled
    # with numba 0.63 or 0.68 here in November 2026, carry none); the rebuild itself is
    # checked with and without the patch in test_an_environment_of_numbas_module_is_rebuilt_without_it
    assert lazy["arrayobj"] is False


#: numba's environment of a function of ``numba.np.arrayobj`` rebuilt as a cached kernel's load
#: does (``physics.jit`` installs the package's loading patch unless GYRO_PLATFORM_LAZY_LOAD=0):
#: is the module imported?
REBUILD_PROBE = """
import json, sys
import gyro_platform.physics.jit
from numba.core import environment
from gyro_platform.physics import kernel_loading
env = environment._rebuild_env("numba.np.arrayobj", [1.5, "x"], "_ZN5numba2np8arrayobj4probeE")
print(json.dumps({"patched": environment._rebuild_env is kernel_loading._rebuild_env,
                  "arrayobj": "numba.np.arrayobj" in sys.modules, "name": env.globals["__name__"],
                  "consts": list(env.consts),
                  "same": environment._rebuild_env("numba.np.arrayobj", [], "_ZN5numba2np8arrayobj4probeE") is env}))
"""


def test_an_environment_of_numbas_module_is_rebuilt_without_it():
    """A cached kernel's environment of a numba module not yet imported: numba's own rebuild
    imports the module (``numba.np.arrayobj``, ~23 ms); the package's keeps its name and
    constants (what numba pickles again) and imports nothing; both return the same environment
    when asked again."""
    own = _run(REBUILD_PROBE, GYRO_PLATFORM_LAZY_LOAD="0")
    lazy = _run(REBUILD_PROBE)
    assert own["patched"] is False and own["arrayobj"] is True
    assert lazy["patched"] is True and lazy["arrayobj"] is False
    assert lazy["name"] == own["name"] == "numba.np.arrayobj"
    assert lazy["consts"] == own["consts"] == [1.5, "x"] and lazy["same"] and own["same"]


#: a replay of the bag ``argv[1]`` into ``argv[2]`` in a new process: is numpy.ma imported after it?
REPLAY_PROBE = """
import json, sys
from gyro_platform.replay.loop import replay, ReplayConfig
summary = replay(sys.argv[1], sys.argv[2], ReplayConfig(plot=False))
print(json.dumps({"masked": "numpy.ma" in sys.modules, "outputs": summary["counts"]["out"],
                  "arrayobj": "numba.np.arrayobj" in sys.modules}))
"""


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_replay_imports_no_masked_array_module(storage, tmp_path):
    from gyro_platform.bench.bags import vehicle_imu, write_imu_bag

    bag = write_imu_bag(tmp_path / "in", vehicle_imu(1.0, rate=200.0), storage=storage)
    full = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", REPLAY_PROBE, str(bag), str(tmp_path / "out")], env=full,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["outputs"] > 0 and r["masked"] is False and r["arrayobj"] is False


def _typeof_both(value):
    """(ours, numba's) type of ``value`` as an argument, or the exception each raised."""
    from numba.core.typing.typeof import _TypeofContext, Purpose

    c = _TypeofContext(Purpose.argument)
    got = []
    for f in (kernel_loading._typeof_ndarray, kernel_loading._numba_typeof_ndarray):
        try:
            got.append(f(value, c))
        except Exception as e:      # noqa: BLE001 - compared below
            got.append((type(e), str(e)))
    return got


def test_array_types_are_numbas():
    from numba.core.typing.typeof import typeof_impl

    assert typeof_impl.dispatch(np.ndarray) is kernel_loading._typeof_ndarray
    ro = np.arange(6.0)
    ro.flags.writeable = False
    values = [np.zeros(3), np.zeros((2, 3), order="F"), np.zeros((4, 4))[::2, 1:], ro, np.array(2.5),
              np.zeros(5, np.int32), np.zeros(2, np.bool_), np.zeros((1, 2, 3), np.float32),
              np.zeros(3, np.complex128), np.zeros(3, "M8[ns]"), np.zeros(3, object), np.zeros(0, np.uint8),
              np.zeros(2, [("a", "<f8"), ("b", "<i4")]), np.zeros(3).view(np.recarray)]
    for v in values:
        ours, numbas = _typeof_both(v)
        assert ours == numbas, (v.dtype, v.shape)


def test_a_kernel_compiled_after_a_lazy_load_links_the_loaded_one(default_cached):
    r = _run(LINK_PROBE)
    assert r["lazy"] is True and r["loaded"] == 0   # loaded, its bitcode not parsed
    assert r["after_link"] >= 1                     # parsed when the new kernel linked it
    assert r["max_diff"] <= 1e-15
    assert r["unknown"] == 0                        # numba's answer for a name nothing defines


#: a module of a cached kernel that calls a package kernel and numba's array functions
ROTATE_MODULE = """
import numpy as np
from numba import njit
from gyro_platform.physics.rotations import quat_to_matrix
@njit(cache=True)
def rotate_all(qs):
    out = np.empty((qs.shape[0], 3, 3))
    for i in range(qs.shape[0]):
        R = np.zeros((3, 3))
        quat_to_matrix(qs[i], R)
        out[i, :, :] = R
    return out.sum(axis=0)
"""

#: argv[1]: the folder of ``rotate.py``. The default scene's kernels loaded (their environments
#: of numba's array module rebuilt without it), then ``rotate_all`` compiled or loaded
ENV_PROBE = """
import json, sys
import numpy as np
import gyro_platform.physics.jit as jit
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import load_scene
with jit.compiles_refused():
    run_scene(load_scene("default").with_duration(0.5))
before = "numba.np.arrayobj" in sys.modules
sys.path.insert(0, sys.argv[1])
from rotate import rotate_all
qs = np.array([[0.1, -0.2, 0.3, 0.9], [0.0, 0.0, 0.0, 1.0], [0.5, 0.5, -0.5, 0.5]])
qs /= np.linalg.norm(qs, axis=1)[:, None]
got = rotate_all(qs)
ref = rotate_all.py_func(qs)
print(json.dumps({"before": before, "max_diff": float(np.max(np.abs(got - ref))),
                  "hits": int(sum(rotate_all.stats.cache_hits.values()))}))
"""


def _numba_cache_files(folder: Path, pattern: str) -> list[Path]:
    """numba's cache files of a module in ``folder``: in its ``__pycache__``, or where
    ``NUMBA_CACHE_DIR`` is set, in numba's subfolder for ``folder`` there (``<name>_<sha1 of the
    path>``, numba's ``UserProvidedCacheLocator``)."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    if not root:
        return list((folder / "__pycache__").glob(pattern))
    return list(Path(root).glob(f"{folder.name}_*/{pattern}"))


def test_a_kernel_compiled_and_cached_after_lazy_environments_loads_again(default_cached, tmp_path):
    """numba's array functions' environments rebuilt with only their module's name: a kernel
    compiled afterwards in that process, which uses them, computes what Python computes, and its
    cache file (environments pickled again) loads in the next process and computes the same."""
    (tmp_path / "rotate.py").write_text(ROTATE_MODULE)       # cached where _numba_cache_files looks
    first = _run(ENV_PROBE.replace("sys.argv[1]", repr(str(tmp_path))))
    assert first["before"] is False and first["hits"] == 0 and first["max_diff"] <= 1e-15
    assert _numba_cache_files(tmp_path, "rotate.rotate_all-*.nbc")
    second = _run(ENV_PROBE.replace("sys.argv[1]", repr(str(tmp_path))))
    assert second["before"] is False and second["hits"] == 1 and second["max_diff"] <= 1e-15


#: prints whether numba's extensions were initialised after a package kernel ran (argv[1] = 1:
#: then also after a new function of this process compiled)
EXTENSIONS_PROBE = """
import json, os, sys
import numpy as np
import gyro_platform.physics.jit as jit
from gyro_platform.physics.rotations import quat_to_matrix
R = np.zeros((3, 3))
quat_to_matrix(np.array([0.1, -0.2, 0.3, 0.9]), R)
mark = os.environ["FAKE_EXTENSION_MARK"]
seen = {"after_kernel": os.path.exists(mark), "compiled": int(sum(quat_to_matrix.stats.cache_misses.values()))}
if sys.argv[1] == "1":
    from numba import njit
    njit(lambda x: x + 1)(1)
    seen["after_own_function"] = os.path.exists(mark)
print(json.dumps(seen))
"""


def test_numba_extensions_are_initialised_where_a_kernel_compiles_not_where_one_loads(default_cached, tmp_path):
    """numba initialises its installed extensions (entry points ``numba_extensions``, read from
    every installed distribution) at a dispatcher's first call; for the package's kernels that
    happens where one compiles: loading one from the cache leaves them alone, a function of
    the process's own or a package kernel compiled on an empty cache initialise them first."""
    site = tmp_path / "site"
    (site / "fake_numba_ext-0.1.dist-info").mkdir(parents=True)
    (site / "fake_numba_ext-0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-numba-ext\n"
                                                                    "Version: 0.1\n")
    (site / "fake_numba_ext-0.1.dist-info" / "entry_points.txt").write_text(
        "[numba_extensions]\ninit = fake_numba_ext:init\n")
    (site / "fake_numba_ext.py").write_text("import os\n\ndef init():\n"
                                            "    open(os.environ['FAKE_EXTENSION_MARK'], 'w').close()\n")

    def probe(name: str, own: str, **env: str) -> dict:
        mark = tmp_path / name
        full = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(site)]), FAKE_EXTENSION_MARK=str(mark),
                    **env)
        out = subprocess.run([sys.executable, "-c", EXTENSIONS_PROBE, own], env=full, capture_output=True,
                             text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        return json.loads(out.stdout.strip().splitlines()[-1])

    loaded = probe("loaded", "1")
    assert loaded == {"after_kernel": False, "compiled": 0, "after_own_function": True}
    cold = probe("cold", "0", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    assert cold == {"after_kernel": True, "compiled": 1}


def test_the_runtime_library_is_compiled_once_then_loaded(tmp_path):
    env = {"NUMBA_CACHE_DIR": str(tmp_path)}
    first = _run(NRT_PROBE, **env)
    assert first["loaded"] is False and first["sum"] == 90.0
    assert Path(first["file"]).is_file() and Path(first["file"]).is_relative_to(tmp_path)
    second = _run(NRT_PROBE, **env)
    assert second["loaded"] is True and second["sum"] == 90.0
    Path(first["file"]).write_bytes(b"not a library")
    third = _run(NRT_PROBE, **env)                  # damaged: compiled again and rewritten
    assert third["loaded"] is False and third["sum"] == 90.0
    assert _run(NRT_PROBE, **env)["loaded"] is True
