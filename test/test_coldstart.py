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

"""Cold start (issue 31, item 1): on an empty kernel cache a command says on stderr that it
compiles (one line, then a line per kernel) and a signal during the compile stops it with its
documented exit code; the package's kernels are cached by content under the user cache folder
(``physics.jit``). Behaviour only: how long a cold start takes is the bench's (``bench
coldstart``), not a test's."""
from __future__ import annotations

import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from gyro_platform.errors import EXIT_INTERRUPTED, EXIT_TERMINATED
from gyro_platform.physics import jit
from gyro_platform.scenes.schema import find_scene, load_scene

ROOT = Path(__file__).resolve().parents[1]


def _cold_env(tmp_path: Path) -> dict:
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")     # empty: every kernel compiles
    env.pop("GYRO_PLATFORM_IN_TREE_CACHE", None)
    return env


HUSKY = ROOT.parent / "shared" / "data" / "bags" / "robot_localization_husky_test1"


@pytest.mark.parametrize("what, sig, code", [("run", signal.SIGINT, EXIT_INTERRUPTED),
                                             ("run", signal.SIGTERM, EXIT_TERMINATED),
                                             ("replay", signal.SIGTERM, EXIT_TERMINATED),
                                             ("compile", signal.SIGTERM, EXIT_TERMINATED)])
def test_cold_command_says_it_compiles_and_stops_on_a_signal(tmp_path, what, sig, code):
    if what == "run":
        args = ["run", "default", "--no-files", "--duration", "1"]
    elif what == "compile":
        args = ["compile"]
    else:                       # the bag is read and decoded on a reader thread: its compile is abandoned
        if not HUSKY.exists():
            pytest.skip("the shared husky recording is not here")
        args = ["replay", str(HUSKY), "--out", str(tmp_path / "out"), "--no-plot"]
    p = subprocess.Popen([sys.executable, "-m", "gyro_platform", *args],
                         cwd=ROOT, env=_cold_env(tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True, start_new_session=True)
    lines: list[str] = []
    try:
        for line in p.stderr:            # the notice, then a line per compiled kernel
            lines.append(line)
            if "  compiled " in line:
                break
        assert any("compiling the simulation kernels" in x for x in lines), "".join(lines)
        assert sum("compiling" in x for x in lines) == 1
        p.send_signal(sig)              # still compiling: the rest of the kernels
        t0 = time.monotonic()
        rest = p.communicate(timeout=60)[1]
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == code, "".join(lines) + rest
    assert ("terminated" if sig == signal.SIGTERM else "interrupted") in rest
    assert time.monotonic() - t0 < 30          # not after the compile (a generous bound, not a timing test)
    assert _helpers_of(tmp_path) == [], "a helper process of the command outlived it"
    if what == "compile":                       # its second process (--jobs 2) stopped too
        try:
            os.killpg(p.pid, 0)
        except ProcessLookupError:
            pass
        else:
            os.killpg(p.pid, signal.SIGKILL)
            pytest.fail("a process of the compile outlived it")


def _helpers_of(tmp_path: Path) -> list[int]:
    """Live ``engine.remote`` helper processes whose kernel cache is under ``tmp_path``."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            cmd = (proc / "cmdline").read_bytes()
            env = (proc / "environ").read_bytes() if b"gyro_platform.engine.remote" in cmd else b""
        except OSError:
            continue
        if f"NUMBA_CACHE_DIR={tmp_path}".encode() in env:
            found.append(int(proc.name))
    return found


def test_a_cold_command_compiles_its_output_kernel_in_a_second_process(tmp_path):
    """On an empty cache (two CPUs) ``run`` compiles the output kernel in a helper process while
    it compiles the stepping kernels, then loads it from the cache: the helper says so on each
    of its lines, the command itself does not compile it, the outputs are those of a run on a
    warm cache, and no helper outlives the command."""
    from gyro_platform.engine.remote import COMPILE_JOBS_ENV

    args = ["run", "default", "--duration", "1"]
    env = dict(_cold_env(tmp_path), **{COMPILE_JOBS_ENV: "2"})
    cold = subprocess.run([sys.executable, "-m", "gyro_platform", *args, "--out", str(tmp_path / "cold")], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=600)
    assert cold.returncode == 1 and "NOT EVALUABLE" in cold.stdout, cold.stderr  # 1 s: expectations not judged
    kernel_lines = [x for x in cold.stderr.splitlines() if "compiled output_rows " in x]
    assert len(kernel_lines) == 1 and "in the second process" in kernel_lines[0], cold.stderr
    assert "compiled block_kernel " in cold.stderr and "second process)" not in cold.stderr.split(
        "compiled block_kernel ")[1].splitlines()[0], cold.stderr
    assert _helpers_of(tmp_path) == []
    warm = subprocess.run([sys.executable, "-m", "gyro_platform", *args, "--out", str(tmp_path / "warm")], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=600)
    assert warm.returncode == 1 and "compiling" not in warm.stderr, warm.stderr
    assert (tmp_path / "cold" / "outputs.csv").read_bytes() == (tmp_path / "warm" / "outputs.csv").read_bytes()


@pytest.mark.parametrize("value, cpus, jobs", [("1", 8, 1), ("2", 1, 2), ("7", 8, 2), ("", 1, 1), ("", 2, 2),
                                               ("x", 4, 2), ("0", 1, 1)])
def test_compile_jobs_follow_the_cpus_unless_the_environment_says(monkeypatch, value, cpus, jobs):
    from gyro_platform.engine import remote

    monkeypatch.setenv(remote.COMPILE_JOBS_ENV, value)
    monkeypatch.setattr(remote.os, "sched_getaffinity", lambda pid: set(range(cpus)), raising=False)
    assert remote.compile_jobs() == jobs


def test_a_kernel_compiled_elsewhere_waits_for_that_process_once_then_compiles_here():
    """``jit.compiled_elsewhere``: the next compile of the kernel calls the wait first (once),
    then compiles here (these kernels have no cache to load from); taken back, no wait. The load
    from the cache after the wait: test_a_cold_command_compiles_its_output_kernel_in_a_second_process."""
    from numba import njit

    calls = []

    @njit
    def twice(x):
        return 2.0 * x

    @njit
    def thrice(x):
        return 3.0 * x

    jit.compiled_elsewhere(twice, lambda: calls.append("twice"))
    jit.compiled_elsewhere(thrice, lambda: calls.append("thrice"))
    jit.compiled_elsewhere(thrice, None)
    assert twice(2.0) == 4.0 and twice(3) == 6 and thrice(1.0) == 3.0
    assert calls == ["twice"]


def test_after_the_set_up_step_the_commands_compile_nothing(tmp_path):
    """``gyro-platform compile`` (the README's set-up step, colcon build's install step) on an
    empty cache compiles what the first ``run default``, ``replay`` of the husky recording and
    the node's start need: each then runs without a compile notice."""
    from gyro_platform.bench.coldstart import LOOPBACK_XML, time_to_line

    env = _cold_env(tmp_path)
    setup = subprocess.run([sys.executable, "-m", "gyro_platform", "compile"], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=1800)
    assert setup.returncode == 0, setup.stdout + setup.stderr
    assert "compiling the simulation kernels" in setup.stderr
    assert "4 of 4 steps" in setup.stdout and "bytecode of" in setup.stdout, setup.stdout
    if (os.cpu_count() or 1) >= 2:              # cold: the node's and replay's kernels in a second process
        assert "1 more process compiling: node" in setup.stdout, setup.stdout
        assert "in the second process" not in setup.stderr, setup.stderr   # and no output-kernel helpers
    again = subprocess.run([sys.executable, "-m", "gyro_platform", "compile"], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0 and "4 of 4 steps" in again.stdout, again.stdout + again.stderr
    assert "more process" not in again.stdout and "compiling" not in again.stderr   # warm: no process started
    runs = [["run", "default", "--no-files"]]
    if HUSKY.exists():
        runs.append(["replay", str(HUSKY), "--out", str(tmp_path / "husky"), "--no-plot"])
    for args in runs:
        p = subprocess.run([sys.executable, "-m", "gyro_platform", *args], cwd=ROOT, env=env, capture_output=True,
                           text=True, timeout=300)
        assert p.returncode == 0, p.stderr
        assert "compiling" not in p.stderr, (args, p.stderr)
    _, out = time_to_line([sys.executable, "-m", "gyro_platform", "node", "--transport", "dds", "--cyclonedds-config",
                           str(LOOPBACK_XML), "--domain-id", "88"], tmp_path / "numba", "ready:", timeout=300)
    assert "compiling" not in out and "not compiled yet" not in out, out    # warm: no cold start's helper


def _code_objects(pkg: Path, env: dict) -> list[str]:
    """What ``python -v`` says it loaded each module of ``pkg`` from, importing the replay."""
    p = subprocess.run([sys.executable, "-v", "-c", "import gyro_platform.replay.loop"], cwd=pkg.parent, env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    return [ln for ln in p.stderr.splitlines() if ln.startswith("# code object from") and str(pkg) in ln]


def test_the_set_up_steps_bytecode_is_what_a_process_loads_where_it_may_not_write_bytecode(tmp_path):
    """``PYTHONDONTWRITEBYTECODE=1`` (many container images and CI runners) on an editable or
    symlinked install: every process compiles each module from source until ``gyro-platform
    compile`` has written the bytecode (``write_bytecode``); then every module comes from it."""
    from gyro_platform.prefill.command import write_bytecode

    pkg = tmp_path / "gyro_platform"
    shutil.copytree(ROOT / "gyro_platform", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    path = os.pathsep.join(p for p in (str(tmp_path), os.environ.get("PYTHONPATH")) if p)   # the copy first
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPATH": path}
    before = _code_objects(pkg, env)
    assert len(before) > 20 and all(ln.endswith(".py") for ln in before), before[:3]   # from source
    assert not list(pkg.rglob("*.pyc"))                                                # and nothing written
    assert write_bytecode(pkg) == len(list(pkg.rglob("*.py")))
    after = _code_objects(pkg, env)
    assert len(after) == len(before) and all(ln.endswith(".pyc'") for ln in after), after[:3]
    (pkg / "replay" / "loop.py").write_text((pkg / "replay" / "loop.py").read_text() + "\n# changed\n")
    stale = [ln for ln in _code_objects(pkg, env) if "loop" in ln]
    assert stale == [f"# code object from {pkg / 'replay' / 'loop.py'}"]       # a changed module: its source


@pytest.mark.parametrize("args, says", [(["--scene", "no_such_scene"], "no_such_scene"),
                                        (["--jobs", "0"], "--jobs"),
                                        (["--part", "1"], "--part"),                   # without --part-dir
                                        (["--part", "7", "--part-dir", "."], "--part")])
def test_compile_refuses_bad_arguments_in_one_line(tmp_path, args, says):
    p = subprocess.run([sys.executable, "-m", "gyro_platform", "compile", *args], cwd=ROOT,
                       env=_cold_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("gyro-platform compile: error:") and says in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
    assert not (tmp_path / "numba").exists() or not any((tmp_path / "numba").rglob("*.nbc"))   # nothing compiled


def test_package_kernels_cached_by_content_under_the_cache_dir(tmp_path, monkeypatch):
    from numba.core import config

    from gyro_platform.engine import batch
    from gyro_platform.physics import system

    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path))
    d = jit.cache_dir()
    assert d == tmp_path / "gyro_platform" / jit.source_digest()
    loc = jit.PackageCacheLocator.from_function(system.platform_rhs.py_func, system.__file__)
    assert loc is not None and Path(loc.get_cache_path()) == d / "physics"
    assert loc.get_source_stamp() == jit.source_digest()       # content, not path or mtime
    assert jit.PackageCacheLocator.from_function(pytest.approx, pytest.__file__) is None   # not ours
    assert isinstance(batch.block_kernel._cache._impl.locator, jit.PackageCacheLocator)
    monkeypatch.setattr(config, "CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert jit.cache_dir() == tmp_path / "xdg" / "gyro_platform" / "numba" / jit.source_digest()


def test_cache_folder_changes_with_every_source_a_kernel_freezes_and_only_those(tmp_path, monkeypatch):
    """numba freezes a kernel's globals when it compiles, constants imported from other modules
    included (the step controller's ``SWITCH_EDGE`` from ``integrators/base.py``, which takes no
    ``njit``): on a copy of the package, changing one gives another cache folder (a stale kernel
    would otherwise plan other steps than the Python controller); changing the ROS node or the
    bench does not."""
    import shutil

    pkg = tmp_path / "gyro_platform"
    shutil.copytree(jit.PACKAGE, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(jit, "PACKAGE", pkg)

    def digest() -> str:
        monkeypatch.setattr(jit, "_DIGEST", None)
        return jit.source_digest()

    names = {str(p.relative_to(pkg.resolve())) for p in jit.digest_sources()}
    assert {"engine/batch.py", "engine/integrators/base.py", "physics/switching.py", "physics/params.py",
            "engine/integrators/__init__.py"} <= names
    assert not any(n.startswith(("ros/", "bench/", "replay/", "scenes/", "sweep/")) for n in names)
    d0 = digest()
    node = pkg / "ros" / "node.py"
    node.write_text(node.read_text() + "\n# a comment\n")
    assert digest() == d0
    base = pkg / "engine" / "integrators" / "base.py"
    text = base.read_text()
    assert "SWITCH_EDGE = 1e-3" in text
    base.write_text(text.replace("SWITCH_EDGE = 1e-3", "SWITCH_EDGE = 2e-3"))
    assert digest() != d0


def test_bench_coldstart_times_each_command_cold_then_warm(tmp_path, monkeypatch):
    """The bench row logic without running the commands: the first run of each on its fresh cache
    folder is cold (and says so), the later ones warm (the node's cache compiled in between: it
    is stopped once ready); ratio, table, JSON, Markdown, PNG."""
    import json

    from gyro_platform.bench import coldstart as cs

    seen: dict[str, int] = {}

    def fake(cache):
        n = seen.get(str(cache), 0)
        seen[str(cache)] = n + 1
        return (10.0, cs.NOTICE) if n == 0 else (2.0 + 0.1 * n, "")

    compiles: list[tuple[str, int]] = []        # (cache, runs on it before) of each `compile` command

    def fake_timed(cmd, cache, timeout=0):
        if cmd[-1] == "compile":
            compiles.append((str(cache), seen.get(str(cache), 0)))
        return (*fake(cache), 16.0)                 # 16 CPU s

    node_caches: list[str] = []

    def fake_line(cmd, cache, line, timeout=0):
        node_caches.append(str(cache))
        return fake(cache)

    monkeypatch.setattr(cs, "timed", fake_timed)
    monkeypatch.setattr(cs, "usable_cpus", lambda: 2)
    monkeypatch.setattr(cs, "time_to_line", fake_line)
    monkeypatch.setattr(cs, "_sweep_first_run", lambda d, w: lambda cache, i: (*fake(cache), {"command_s": 9.0}))
    # the new host's worker compiles nothing, cold or warm (its kernels come from the client)
    monkeypatch.setattr(cs, "_sweep_new_host", lambda d, w, c: lambda cache, i: (fake(cache)[0] / 5, "", {}))
    monkeypatch.setattr(cs, "husky_bag", lambda: (None, "not found"))
    monkeypatch.setattr(cs.shutil, "copytree", lambda src, dst: Path(dst).mkdir())   # a fresh folder: "cold"
    rows = cs.coldstart(tmp_path / "out", repeats=3)
    by = {r.name: r for r in rows}
    # --quick: the scene runs as long as its expectations need (shorter: not evaluable, exit 1)
    runs: list[list[str]] = []
    monkeypatch.setattr(cs, "timed", lambda cmd, cache, timeout=0: (runs.append(cmd), fake_timed(cmd, cache))[1])
    quick = {r.name: r for r in cs.coldstart(tmp_path / "quick", quick=True, repeats=1)}
    run = next(c for c in runs if "run" in c)
    assert float(run[run.index("--duration") + 1]) >= load_scene(find_scene("default")).test_duration
    assert quick["run_default"].status == "ok" and quick["run_default"].what == "run default --duration 30"
    assert set(by) == {"compile", "run_default", "replay_husky", "node_dds_ready", "sweep_worker_first_run",
                       "sweep_worker_new_host"}
    host = by["sweep_worker_new_host"]
    assert host.cold_s == 2.0 and host.notice is False and host.ratio == pytest.approx(2.0 / 0.44)
    assert "compiled!" not in cs._line(host) and "no compile notice" not in cs._line(by["run_default"])
    host.notice = True
    assert cs._line(host).endswith("(the cold run compiled!)")
    assert rows[0].name == "compile" and rows[0].cold_s == 10.0 and rows[0].warm_s == pytest.approx(2.1)
    assert by["replay_husky"].status == "not found"
    # the node, stopped once ready, is warm only once its cache is compiled: after its cold run
    cold_node = next(c for c in node_caches if node_caches.count(c) > 1)
    assert (cold_node, 1) in compiles
    r = by["run_default"]
    assert r.cold_s == 10.0 and r.warm_s == pytest.approx(2.2) and r.ratio == pytest.approx(10 / 2.2)
    assert r.notice and r.extra["warm_notice"] is False
    assert r.extra["after_setup_s"] == 10.0 and r.extra["after_setup_notice"] is True   # its copy compiled
    text = (tmp_path / "out" / "coldstart.md").read_text()
    # 16 CPU s on 2 CPUs: no cold run shorter than 8 s, cold ÷ warm ≥ 8 / 2.2 on this machine
    assert r.extra["cold_cpu_s"] == 16.0 and r.extra["cold_cpu_bound_s"] == 8.0 and r.extra["cpus"] == 2
    assert ("| run default | 10.00 | 2.20 | ×4.5 | ≤ ×3 ✗ | yes | 10.00 (×4.5 ✗) "
            "| 16.0 (≥ 8.0 s on 2 CPUs, ×3.6) |") in text
    doc = json.loads((tmp_path / "out" / "coldstart.json").read_text())
    assert [x["name"] for x in doc["rows"]] == [r.name for r in rows] and doc["meta"]["repeats"] == 3
    assert (tmp_path / "out" / "coldstart.png").stat().st_size > 0


def test_a_kernel_numba_cannot_cache_is_a_warning_not_a_crash():
    """numba refuses to cache a compile result with dynamic globals (as every kernel calling another
    is at ``NUMBA_OPT=0``) and warns naming the kernel's file: the package's locator must carry it
    (it did not, and ``NUMBA_OPT=0 gyro-platform run`` ended in an AttributeError traceback)."""
    from types import SimpleNamespace

    from numba.core import caching
    from numba.core.errors import NumbaWarning

    from gyro_platform.physics import tree

    cache = caching.FunctionCache(tree.kinematics.py_func)
    assert isinstance(cache._impl.locator, jit.PackageCacheLocator)
    cres = SimpleNamespace(lifted=(), library=SimpleNamespace(has_dynamic_globals=True),
                           fndesc=SimpleNamespace(qualname="kinematics"))
    with pytest.warns(NumbaWarning, match='Cannot cache compiled function "kinematics"'):
        assert cache._impl.check_cachable(cres) is False


def test_kernels_compile_with_sparse_collections_and_the_thresholds_come_back():
    """While a kernel compiles (its callees' compiles inside it too) the collector runs at
    ``COMPILE_GC_THRESHOLD``; the process's own thresholds are back after it, also after a compile
    that fails in typing."""
    import gc

    from numba import njit
    from numba.core import event
    from numba.core.errors import TypingError

    seen = []

    class Probe(event.Listener):
        def on_start(self, ev):
            seen.append(gc.get_threshold())

        def on_end(self, ev):
            pass

    @njit
    def callee(x):
        return x * 2.0

    @njit
    def caller(x):
        return callee(x) + 1.0

    @njit
    def broken(x):
        return x.no_such_attribute

    before = gc.get_threshold()
    gc.set_threshold(555, 7, 3)
    probe = Probe()
    event.register("numba:compile", probe)
    try:
        assert caller(1.0) == 3.0
        assert seen and all(t == jit.COMPILE_GC_THRESHOLD for t in seen) and len(seen) >= 2   # caller, callee
        assert gc.get_threshold() == (555, 7, 3)
        with pytest.raises(TypingError):
            broken(1.0)
        assert gc.get_threshold() == (555, 7, 3)
    finally:
        event.unregister("numba:compile", probe)
        gc.set_threshold(*before)


_LOADER = """
import json, sys
import numpy as np
from gyro_platform.physics.rotations import quat_to_matrix
R = np.empty((3, 3))
quat_to_matrix(np.array([0.1, -0.2, 0.3, 0.9]), R)
print(json.dumps({"R": [float(x) for x in np.ravel(R)], "refreshed": "numba.np.linalg" in sys.modules}))
"""


def test_a_cached_kernel_loads_without_numbas_registries_and_gives_the_compiled_result(tmp_path):
    """A process that only loads cached kernels skips numba's refresh of its implementation
    registries (``physics.jit._load_without_refresh``: ~0.25 s of every command's start) and
    its kernels give what the compiling process's gave, bit for bit."""
    env = _cold_env(tmp_path)
    runs = [json.loads(subprocess.run([sys.executable, "-c", _LOADER], cwd=ROOT, env=env, capture_output=True,
                                      text=True, check=True, timeout=300).stdout.splitlines()[-1]) for _ in range(2)]
    assert runs[0]["refreshed"] and not runs[1]["refreshed"]     # compiled (numba refreshes), then loaded
    assert runs[1]["R"] == runs[0]["R"]
    R = np.reshape(runs[1]["R"], (3, 3))
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and abs(np.linalg.det(R) - 1.0) < 1e-12


_SAVER = """
import sys, time
from numba.core import caching
import gyro_platform.physics.jit  # noqa: F401  (the locked save)
who, path, start = sys.argv[1], sys.argv[2], float(sys.argv[3])
cache = caching.IndexDataCacheFile(path, "kernel", "stamp")
while time.time() < start:          # both processes begin together
    time.sleep(0.001)
for i in range(150):
    cache.save((who, i), (who, i))
"""


def test_processes_adding_signatures_of_one_kernel_at_once_keep_every_entry_and_its_own_data(tmp_path):
    """Two processes add 150 signatures each to one kernel's cache index at the same time (the
    parallel parts of ``gyro-platform compile``, Dask workers): every entry is in the index and
    loads its own data (numba's unlocked save loses entries and pairs keys with the other
    process's data files)."""
    from numba.core import caching

    start = str(time.time() + 5.0)
    procs = [subprocess.Popen([sys.executable, "-c", _SAVER, who, str(tmp_path), start], cwd=ROOT) for who in "ab"]
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    cache = caching.IndexDataCacheFile(str(tmp_path), "kernel", "stamp")
    keys = [(who, i) for who in "ab" for i in range(150)]
    assert sorted(cache._load_index()) == sorted(keys)
    assert all(cache.load(k) == k for k in keys)


def test_a_cached_array_is_computed_once_and_a_damaged_or_unwritable_copy_is_computed_again(tmp_path, monkeypatch):
    """``jit.cached_array``: the first call computes and keeps the array in the cache folder,
    the next reads it (no compute); a damaged file, one of another shape or with a NaN is
    computed again and rewritten; where the folder cannot be made the value is still returned."""
    monkeypatch.setattr(jit, "cache_dir", lambda: tmp_path / "cache")
    calls = []

    def compute():
        calls.append(1)
        return np.arange(6.0).reshape(2, 3) / 7.0

    want = np.arange(6.0).reshape(2, 3) / 7.0
    assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want) and len(calls) == 1
    (path,) = (tmp_path / "cache" / "constants").glob("t-*.npy")
    assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want) and len(calls) == 1   # read
    assert np.array_equal(jit.cached_array("t", "other key", (2, 3), compute), want) and len(calls) == 2
    for damage in (b"not an npy file", path.read_bytes()[:-8]):
        path.write_bytes(damage)
        assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want)
        assert np.array_equal(np.load(path), want)                   # rewritten whole
    np.save(path, np.full((2, 3), np.nan))
    assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want)
    np.save(path, np.zeros((3, 2)))
    assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want)
    assert len(calls) == 6 and not list(path.parent.glob("*.tmp"))
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(jit, "cache_dir", lambda: tmp_path / "file" / "cache")   # cannot be made
    assert np.array_equal(jit.cached_array("t", "k", (2, 3), compute), want) and len(calls) == 7


_REST = """
import json
from gyro_platform.physics.model import kinematics, rest_matrices, _rest_matrices
from gyro_platform.physics.params import NAV1
M0, G0 = rest_matrices(NAV1)
loaded = bool(kinematics.signatures)
MG = _rest_matrices(NAV1)
print(json.dumps({"tree_loaded": loaded, "equal": bool((M0 == MG[0]).all() and (G0 == MG[1]).all())}))
"""


def test_a_later_process_takes_the_rest_matrices_from_the_cache_without_loading_the_tree():
    """The linear model's M0 and G0 (``model.rest_matrices``): a process after the one that
    computed them reads them from the kernel cache, bit for bit the tree's, and loads none of
    the tree kernels (~30-60 ms of a replay's or the node's start); parameters one ulp apart are
    two keys."""
    from gyro_platform.physics.model import _exact_key
    from gyro_platform.physics.params import NAV1

    runs = [json.loads(subprocess.run([sys.executable, "-c", _REST], cwd=ROOT, capture_output=True, text=True,
                                      check=True, timeout=600).stdout.splitlines()[-1]) for _ in range(2)]
    assert runs[1] == {"tree_loaded": False, "equal": True}, runs
    assert runs[0]["equal"], runs
    assert _exact_key(NAV1) != _exact_key(NAV1.with_(servo_kp=float(np.nextafter(NAV1.servo_kp, 2e3))))
