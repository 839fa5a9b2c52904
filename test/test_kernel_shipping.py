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

"""This machine's compiled kernels installed in another kernel cache (a new Dask worker host).

Behaviour: ``physics.jit.add_cache_files`` adds only what a cache lacks (a kernel whose index is
there keeps its files byte for byte; a path leaving the folder is refused before anything is
written), and the kernels it installed load in a process with that cache without compiling
(``compiles_refused``; the same process on the empty cache is refused: the check can fail).
Through real Dask: a worker whose cache is empty, sent the kernels by ``sweep --scheduler``'s
``ship_kernels``, runs the default scene's sweep compiling nothing (numba's compile events,
counted in the worker) and gives the drift rate of oracle O9(b).
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

from gyro_platform.engine.batch import block_kernel
from gyro_platform.physics.jit import add_cache_files, cache_dir, cache_files
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import load_scene

ROOT = Path(__file__).resolve().parents[1]
#: numba's name of the stepping kernel's cache files (index ``.nbi``, data ``.<n>.nbc``)
KERNEL = (f"engine/batch.block_kernel-{block_kernel.py_func.__code__.co_firstlineno}"
          f".py{sys.version_info[0]}{sys.version_info[1]}")

#: runs the default scene for 0.5 s with every compile refused; prints "loaded" or "refused: …"
PROBE = """
from gyro_platform.physics.jit import compile_notices, compiles_refused, CompileRefused
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import load_scene
compile_notices("probe")
try:
    with compiles_refused():
        run_scene(load_scene("default").with_duration(0.5))
    print("loaded")
except CompileRefused as e:
    print("refused:", e)
"""


@pytest.fixture(scope="module")
def default_kernels():
    """This process's cache holds the default scene's kernels (loaded, or compiled now)."""
    run_scene(load_scene("default").with_duration(0.5))
    return cache_files(cache_dir())


def _probe(cache: Path) -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=600)
    return out.stdout.strip() or out.stderr.strip().splitlines()[-1]


def test_installed_kernels_load_without_compiling(default_kernels, tmp_path):
    cache = tmp_path / "cache"
    assert _probe(cache).startswith("refused:")          # an empty cache would compile
    folder = cache / "gyro_platform" / cache_dir().name
    added = add_cache_files(default_kernels, folder)
    assert added >= 10
    assert (folder / f"{KERNEL}.nbi").is_file()
    assert _probe(cache) == "loaded"
    assert add_cache_files(default_kernels, folder) == 0  # everything there: nothing added again


def test_only_what_is_missing_is_added(tmp_path):
    theirs = {"engine/m.f-10.py311.nbi": b"index f", "engine/m.f-10.py311.1.nbc": b"code f",
              "engine/m.g-20.py311.nbi": b"index g", "engine/m.g-20.py311.1.nbc": b"code g 1",
              "engine/m.g-20.py311.2.nbc": b"code g 2", "constants/a.npy": b"a", "constants/b.npy": b"b"}
    ours = tmp_path / "cache"
    (ours / "engine").mkdir(parents=True)
    (ours / "constants").mkdir()
    (ours / "engine/m.f-10.py311.nbi").write_bytes(b"our index f")        # a kernel this cache has
    (ours / "engine/m.f-10.py311.1.nbc").write_bytes(b"our code f")
    (ours / "constants/a.npy").write_bytes(b"our a")
    assert add_cache_files(theirs, ours) == 2                             # kernel g and constant b
    assert (ours / "engine/m.f-10.py311.nbi").read_bytes() == b"our index f"
    assert (ours / "engine/m.f-10.py311.1.nbc").read_bytes() == b"our code f"
    assert (ours / "constants/a.npy").read_bytes() == b"our a"
    assert (ours / "engine/m.g-20.py311.2.nbc").read_bytes() == b"code g 2"
    assert (ours / "constants/b.npy").read_bytes() == b"b"
    assert cache_files(ours) == {**theirs, "engine/m.f-10.py311.nbi": b"our index f",
                                 "engine/m.f-10.py311.1.nbc": b"our code f", "constants/a.npy": b"our a"}


@pytest.mark.parametrize("bad", ["../escape.nbi", "/etc/x.npy", "engine/../../x.nbc", "a//b.npy"])
def test_a_path_leaving_the_cache_is_refused_before_anything_is_written(tmp_path, bad):
    with pytest.raises(ValueError, match="not a path inside the cache folder"):
        add_cache_files({"constants/ok.npy": b"ok", bad: b"x"}, tmp_path / "cache")
    assert not (tmp_path / "cache").exists()


def test_a_new_worker_host_runs_a_sweep_on_the_clients_kernels(default_kernels, tmp_path):
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    pytest.importorskip("pyarrow.parquet", reason="the results table is Parquet: pip install '.[sweep]'")
    from distributed import Client, LocalCluster

    from gyro_platform.sweep.command import run_sweep
    from gyro_platform.sweep.spec import load_sweep

    spec = tmp_path / "sweep.yaml"
    spec.write_text("scene: default\nduration: 12\nseed: 3\nruns: 1\n"
                    "vary:\n  bias_torque[4]: {dist: list, values: [2.0e-7]}\n")
    worker_cache = tmp_path / "worker_cache"          # the other host's cache: empty
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=40, env={"NUMBA_CACHE_DIR": str(worker_cache)}) as cluster, \
            Client(cluster) as client:
        def count_compiles():
            from numba.core import event

            class Count(event.Listener):
                n = 0

                def on_start(self, ev):
                    Count.n += 1

                def on_end(self, ev):
                    pass
            event.register("numba:compile", Count())
            import builtins
            builtins._gyro_compiles = Count
            return str(__import__("gyro_platform.physics.jit", fromlist=["cache_dir"]).cache_dir())

        folders = set(client.run(count_compiles).values())
        assert folders == {str(worker_cache / "gyro_platform" / cache_dir().name)}
        said: list[str] = []
        res = run_sweep(load_sweep(spec), tmp_path / "out", client=client, progress=said.append)
        compiles = client.run(lambda: __import__("builtins")._gyro_compiles.n)
    assert any("sent this machine's compiled kernels to the workers" in s for s in said), said
    assert list(compiles.values()) == [0]
    (rec,) = res.records
    assert rec["status"] == "ok", rec
    assert rec["drift_rate_z_deg_per_h"] == pytest.approx(-0.41035 * 2, rel=0.05)     # O9(b), Q10 = 2e-7 N m
    assert (worker_cache / "gyro_platform" / cache_dir().name / f"{KERNEL}.nbi").is_file()


def test_the_sweep_command_through_a_scheduler_sends_its_kernels_to_a_new_hosts_worker(default_kernels, tmp_path):
    """``gyro-platform sweep --scheduler`` to a ``dask scheduler`` and ``dask worker`` of their
    own (the bench's new-host row): the worker, on an empty cache, compiles nothing."""
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    pytest.importorskip("pyarrow.parquet", reason="the results table is Parquet: pip install '.[sweep]'")
    from gyro_platform.bench.coldstart import _sweep_new_host, NOTICE

    client = tmp_path / "client"
    add_cache_files(default_kernels, client / "gyro_platform" / cache_dir().name)
    worker = tmp_path / "worker"
    wall, worker_err, extra = _sweep_new_host(2.0, tmp_path, client)(worker, 0)
    assert 0 < wall < extra["command_s"]
    assert NOTICE not in worker_err and "from the client installed" in worker_err
    assert (worker / "gyro_platform" / cache_dir().name / f"{KERNEL}.nbi").is_file()
