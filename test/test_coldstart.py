"""Cold start (issue 31, item 1): on an empty kernel cache a command says on stderr that it
compiles (one line, then a line per kernel) and a signal during the compile stops it with its
documented exit code; the package's kernels are cached by content under the user cache folder
(``physics.jit``). Behaviour only: how long a cold start takes is the bench's (``bench
coldstart``), not a test's."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gyro_platform.errors import EXIT_INTERRUPTED, EXIT_TERMINATED
from gyro_platform.physics import jit

ROOT = Path(__file__).resolve().parents[1]


def _cold_env(tmp_path: Path) -> dict:
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")     # empty: every kernel compiles
    env.pop("GYRO_PLATFORM_IN_TREE_CACHE", None)
    return env


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, EXIT_INTERRUPTED), (signal.SIGTERM, EXIT_TERMINATED)])
def test_cold_command_says_it_compiles_and_stops_on_a_signal(tmp_path, sig, code):
    p = subprocess.Popen([sys.executable, "-m", "gyro_platform", "run", "default", "--no-files", "--duration", "1"],
                         cwd=ROOT, env=_cold_env(tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True)
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
