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

"""Cold start beside warm (``gyro-platform bench coldstart``; issue 31 item 1): whole commands in
subprocesses, each first on an empty kernel cache, then again on the cache it filled.

Rows (``--quick``: 5 s of the scene, the husky recording's first 30 s):

* ``gyro-platform compile``, the set-up step (README set-up command, ``colcon build``): cold on
  an empty cache, then warm; the cache it filled is copied for the last column of the others;
* ``run default`` (the README's first command: CSV, JSON and plot written);
* ``replay`` of the shared husky recording, default options (bag, summary and plot written;
  "not found" when the recording is absent);
* the DDS node (``node --transport dds``, loopback config): wall time to its ``ready:`` line,
  then stopped by SIGTERM (the rclpy node warms up the same kernels; it needs a ROS install);
  stopped, the cold node has not finished compiling in the background, so ``gyro-platform
  compile`` fills its cache (untimed) before the warm runs;
* a Dask worker's first run: ``sweep`` of one default-scene run on a fresh one-worker local
  cluster; the figure is the run's own ``wall_s`` in the fresh worker (its kernels compiled or
  loaded), the whole command beside it;
* a Dask worker on a new host: the same sweep through ``--scheduler`` to a ``dask scheduler``
  and a ``dask worker`` of their own, the worker on the cache under test (cold: empty), the
  sweep command on a copy of the set-up step's cache, whose kernels it sends the worker
  (``sweep.kernels``); the figure is again the run's own ``wall_s``, and the worker's stderr the
  notice column's (it should compile nothing).

"Cold" is a fresh ``NUMBA_CACHE_DIR`` (nothing compiled: what a fresh install, CI runner,
container or new worker host pays); "warm" the same folder afterwards (median of ``repeats``).
Each command's stderr on the cold run has to say that kernels compile (``compile notice`` column;
the new host's worker, sent its kernels, must not). Beside the cold wall time of the set-up step,
``run default`` and the husky replay, the CPU the cold command used (``cold_cpu_s``: user + system
time of it and of the processes it waited for, its compile helpers): with ``N`` usable CPUs no run
of that much work ends sooner than CPU ÷ ``N``, which bounds cold ÷ warm from below on this machine
(last column; not for the node, stopped once ready, nor the Dask worker, whose figure is its run
inside the worker). "First run after the set-up step": the command once on a copy of the cache
``gyro-platform compile`` filled (a fresh install that ran the README's set-up command or a ``colcon
build``), against warm. Wall clock, interpreter start-up included; the machine may be shared (load
average in the JSON). Writes ``coldstart.json``, ``coldstart.md`` and ``coldstart.png`` under
``--out``.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import json
from pathlib import Path
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

from .bags import husky_bag, short_copy
from .bars import BARS
from .report import write_report
from ..engine.remote import compile_cpus as usable_cpus
from ..filesystem import child_env
from ..scenes.schema import find_scene, load_scene

__all__ = ["ColdRow", "coldstart", "table"]

#: the issue's bar: cold within this factor of warm
TARGET = BARS["cold_over_warm"]
ROOT = Path(__file__).resolve().parents[2]
LOOPBACK_XML = ROOT / "config" / "cyclonedds_loopback.xml"
NOTICE = "compiling the simulation kernels"
READY_TIMEOUT_S = 900.0
SWEEP_SPEC = """scene: default
duration: {duration}
seed: 2026
runs: 1
vary:
  bias_torque[4]: {{dist: normal, mean: 1.0e-7, std: 2.0e-8}}
"""


@dataclass
class ColdRow:
    """One command: ``cold_s`` (empty kernel cache) and ``warm_s`` (median, cache filled)."""

    name: str
    what: str
    status: str = "ok"                  # ok | not found | failed: …
    cold_s: float | None = None
    warm_s: float | None = None
    notice: bool | None = None          # the cold run said on stderr that kernels compile
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def ratio(self) -> float | None:
        if self.cold_s is None or not self.warm_s:
            return None
        return self.cold_s / self.warm_s


def _cpu_bound(row: ColdRow) -> None:
    """From the cold run's CPU (``extra['cold_cpu_s']``): ``cpus`` (this machine's usable CPUs)
    and ``cold_cpu_bound_s``, the shortest cold wall time that much CPU allows on them (s)."""
    n = usable_cpus()
    row.extra.update(cpus=n, cold_cpu_bound_s=row.extra["cold_cpu_s"] / n)


def _children_cpu() -> float:
    """User + system seconds of the waited-for child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _env(cache: Path) -> dict[str, str]:
    env = child_env(NUMBA_CACHE_DIR=str(cache), PYTHONUNBUFFERED="1")
    env.pop("GYRO_PLATFORM_IN_TREE_CACHE", None)
    return env


def _cli() -> list[str]:
    return [sys.executable, "-m", "gyro_platform"]


def timed(cmd: list[str], cache: Path, timeout: float = 1800.0) -> tuple[float, str, float]:
    """(wall s, stderr, CPU s: user + system of the command and the processes it waited for) of
    a command run to its end; RuntimeError on a non-zero exit."""
    c0 = _children_cpu()
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=str(ROOT), env=_env(cache), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    cpu = _children_cpu() - c0
    if r.returncode != 0:
        raise RuntimeError(f"exit {r.returncode}: {r.stderr.strip().splitlines()[-1:] or ''}")
    return wall, r.stderr, cpu


def time_to_line(cmd: list[str], cache: Path, line: str, timeout: float = READY_TIMEOUT_S) -> tuple[float, str]:
    """(wall s until a stderr/stdout line containing ``line``, the output so far); the process is
    then stopped by SIGTERM (killed if it does not end within 20 s)."""
    env = _env(cache)
    env.setdefault("CYCLONEDDS_URI", LOOPBACK_XML.as_uri())
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=str(ROOT), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         stdin=subprocess.DEVNULL)
    seen: list[str] = []
    wall = None
    try:
        assert p.stdout is not None
        for text in p.stdout:
            seen.append(text)
            if line in text:
                wall = time.perf_counter() - t0
                break
            if time.perf_counter() - t0 > timeout:
                break
    finally:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    if wall is None:
        raise RuntimeError(f"no {line!r} line (exit {p.returncode}): {''.join(seen[-3:]).strip()}")
    return wall, "".join(seen)


def _measure(row: ColdRow, run, repeats: int, work: Path, prefilled: Path | None = None,
             fill=None) -> ColdRow:
    """``run(cache, i)`` -> (wall s, stderr, extra): once on an empty cache, then ``repeats``
    times on the filled one; then once on a copy of ``prefilled`` (the cache the set-up step
    ``gyro-platform compile`` filled, if it ran): ``extra['after_setup_s']``. ``fill(cache)``,
    untimed between the cold run and the warm ones, fills the cache where the cold run does not
    (the node, stopped once ready, before its background compile ends)."""
    cache = Path(tempfile.mkdtemp(prefix="numba_cold_", dir=work))
    try:
        if prefilled is not None:
            after = work / f"numba_setup_{row.name}"
            shutil.copytree(prefilled, after)
            try:
                a, err_a, _ = run(after, repeats + 1)
            finally:
                shutil.rmtree(after, ignore_errors=True)
            row.extra["after_setup_s"] = a
            row.extra["after_setup_notice"] = NOTICE in err_a      # it compiled something the set-up did not
        cold, err, extra = run(cache, 0)
        row.cold_s, row.notice = cold, NOTICE in err
        row.extra.update({f"cold_{k}": v for k, v in extra.items()})
        if "cold_cpu_s" in row.extra:
            _cpu_bound(row)
        if fill is not None:
            fill(cache)
        warm, warm_extra = [], []
        for i in range(repeats):
            w, err_w, ex = run(cache, i + 1)
            warm.append(w)
            warm_extra.append(ex)
            row.extra["warm_notice"] = NOTICE in err_w      # a warm run compiles nothing
        row.warm_s = float(np.median(warm))
        for k in (warm_extra[0] if warm_extra else {}):
            row.extra[f"warm_{k}"] = float(np.median([e[k] for e in warm_extra]))
    except KeyboardInterrupt:
        raise
    except Exception as e:                  # noqa: BLE001 - one row fails, the others go on
        row.status = f"failed: {type(e).__name__}: {str(e)[:160]}"
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return row


def _sweep_spec(work: Path, duration: float) -> Path:
    """The one-run sweep file of the Dask rows (``SWEEP_SPEC``)."""
    spec = work / "coldstart_sweep.yaml"
    spec.write_text(SWEEP_SPEC.format(duration=duration))
    return spec


def _run_wall(out: Path) -> float:
    """The run's own ``wall_s`` (s) from the sweep's ``results.csv`` in ``out``; ``out`` removed."""
    with open(out / "results.csv", newline="") as f:
        rec = next(csv.DictReader(f))
    shutil.rmtree(out, ignore_errors=True)
    return float(rec["wall_s"])


def _sweep_first_run(duration: float, work: Path):
    spec = _sweep_spec(work, duration)

    def run(cache: Path, i: int):
        out = work / f"sweep_{cache.name}_{i}"
        wall, err, _ = timed([*_cli(), "sweep", str(spec), "--workers", "1", "--out", str(out), "--no-plots"], cache)
        return _run_wall(out), err, {"command_s": wall}
    return run


def _sweep_new_host(duration: float, work: Path, client_cache: Path):
    """A worker on another host: ``dask scheduler`` and ``dask worker`` processes of their own,
    the worker on the kernel cache under test (``cache``: empty when cold), the sweep command
    (``--scheduler``) on ``client_cache`` (what the set-up step filled), which sends the worker
    its kernels (``sweep.kernels``). stderr is the worker's: its compile notices, if any."""
    spec = _sweep_spec(work, duration)
    dask = [sys.executable, "-m", "dask"]

    def run(cache: Path, i: int):
        out, sched_file = work / f"sweep_host_{cache.name}_{i}", work / f"scheduler_{cache.name}_{i}.json"
        log = work / f"worker_{cache.name}_{i}.log"
        with open(log, "w") as wlog:
            procs = [subprocess.Popen([*dask, "scheduler", "--scheduler-file", str(sched_file), "--port", "0",
                                       "--no-dashboard"], env=_env(client_cache), stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL)]
            try:
                procs.append(subprocess.Popen([*dask, "worker", "--scheduler-file", str(sched_file), "--nthreads", "1",
                                               "--nworkers", "1", "--no-dashboard"], env=_env(cache),
                                              stdout=subprocess.DEVNULL, stderr=wlog))
                address, t0 = None, time.monotonic()
                while address is None:          # the scheduler's file, once written whole
                    try:
                        address = json.loads(sched_file.read_text())["address"]
                    except (OSError, ValueError, KeyError):
                        if time.monotonic() - t0 > 60.0:
                            raise RuntimeError("dask scheduler did not start within 60 s") from None
                        time.sleep(0.05)
                wall, _, _ = timed([*_cli(), "sweep", str(spec), "--scheduler", address, "--out", str(out),
                                    "--no-plots"], client_cache)
            finally:
                for p in reversed(procs):
                    p.terminate()
                    try:
                        p.wait(timeout=20)
                    except subprocess.TimeoutExpired:
                        p.kill()
                        p.wait()
        return _run_wall(out), log.read_text(errors="replace"), {"command_s": wall}
    return run


def coldstart(out_dir: Path, quick: bool = False, repeats: int = 3) -> list[ColdRow]:
    """Every row cold then warm; print the table, write JSON, Markdown and PNG."""
    duration = 5.0 if quick else None
    rows: list[ColdRow] = []
    work = Path(tempfile.mkdtemp(prefix="gyro_bench_coldstart_"))
    print(f"cold start: each command on an empty kernel cache, then warm (median of {repeats}); "
          "several minutes", flush=True)
    prefilled = None
    try:
        # the set-up step: the kernel cache filled by ``gyro-platform compile`` (README set-up, colcon build)
        setup = ColdRow("compile", "gyro-platform compile (the set-up step; then each command below runs warm)")
        cache = Path(tempfile.mkdtemp(prefix="numba_prefill_", dir=work))
        try:
            setup.cold_s, err, setup.extra["cold_cpu_s"] = timed([*_cli(), "compile"], cache)
            _cpu_bound(setup)
            setup.notice = NOTICE in err
            setup.warm_s = timed([*_cli(), "compile"], cache)[0]
            prefilled = cache
        except Exception as e:              # noqa: BLE001 - the rows below are measured all the same
            setup.status = f"failed: {type(e).__name__}: {str(e)[:160]}"
        rows.append(setup)
        print(_line(setup), flush=True)

        # a run shorter than the scene's test_duration leaves its expectations not evaluable (exit 1)
        run_s = max(duration, load_scene(find_scene("default")).test_duration) if duration else None
        run_d = ["--duration", f"{run_s:g}"] if run_s else []

        def run_default(cache: Path, i: int):
            out = work / f"run_{cache.name}_{i}"
            wall, err, cpu = timed([*_cli(), "run", "default", "--out", str(out), *run_d], cache)
            shutil.rmtree(out, ignore_errors=True)
            return wall, err, {"cpu_s": cpu}
        rows.append(_measure(ColdRow("run_default", " ".join(["run default", *run_d])),
                             run_default, repeats, work, prefilled))
        print(_line(rows[-1]), flush=True)

        path, why = husky_bag()
        what = "replay husky (30 Hz Imu, mcap), default options" + (", first 30 s" if quick else "")
        if path is None:
            rows.append(ColdRow("replay_husky", what, status=why))
        else:
            bag = short_copy(path, 30.0) if quick else path

            def replay(cache: Path, i: int):
                out = work / f"husky_{cache.name}_{i}"
                wall, err, cpu = timed([*_cli(), "replay", str(bag), "--out", str(out)], cache)
                shutil.rmtree(out, ignore_errors=True)
                for f in out.parent.glob(out.name + ".*"):      # OUT.summary.json, OUT.png
                    f.unlink()
                return wall, err, {"cpu_s": cpu}
            rows.append(_measure(ColdRow("replay_husky", what), replay, repeats, work, prefilled))
        print(_line(rows[-1]), flush=True)

        def node(cache: Path, i: int):
            wall, err = time_to_line([*_cli(), "node", "--transport", "dds", "--cyclonedds-config", str(LOOPBACK_XML),
                                      "--domain-id", str(90 + i % 10)], cache, "ready:")
            return wall, err, {}

        def compiled(cache: Path) -> None:        # what the cold node was compiling when it was stopped
            timed([*_cli(), "compile"], cache)

        rows.append(_measure(ColdRow("node_dds_ready", "node --transport dds: time to its ready: line"),
                             node, repeats, work, prefilled, fill=compiled))
        print(_line(rows[-1]), flush=True)

        rows.append(_measure(ColdRow("sweep_worker_first_run",
                                     f"Dask worker's first run (default scene{', 5 s' if quick else ''}, 1 worker)"),
                             _sweep_first_run(duration or 60.0, work), repeats, work, prefilled))
        print(_line(rows[-1]), flush=True)

        host = ColdRow("sweep_worker_new_host", f"Dask worker on a new host, kernels from the client (default scene"
                       f"{', 5 s' if quick else ''}, sweep --scheduler; client after the set-up step)",
                       extra={"expects_compile": False})
        if prefilled is None:
            host.status = "not measured: the set-up step failed (the client's kernels are its cache)"
        else:
            client_cache = work / "numba_client"
            shutil.copytree(prefilled, client_cache)
            host = _measure(host, _sweep_new_host(duration or 60.0, work, client_cache), repeats, work, prefilled)
        rows.append(host)
        print(_line(rows[-1]), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    write_outputs(rows, out_dir, quick=quick, repeats=repeats)
    return rows


# ---------------------------------------------------------------------------------------------
# output

def _after(r: ColdRow) -> str:
    """'first run after the set-up step' cell: seconds, ratio to warm, ✓/✗ against the target."""
    a = r.extra.get("after_setup_s")
    if a is None or not r.warm_s:
        return ""
    ok = "✓" if TARGET.met(a / r.warm_s) and not r.extra.get("after_setup_notice") else "✗"
    return f"{a:.2f} (×{a / r.warm_s:.1f} {ok})"


def _bound(r: ColdRow) -> str:
    """'cold CPU' cell: CPU s of the cold run, and the wall time and cold ÷ warm it allows at best."""
    b = r.extra.get("cold_cpu_bound_s")
    if b is None:
        return ""
    best = f", ×{b / r.warm_s:.1f}" if r.warm_s and r.name != "compile" else ""
    return f"{r.extra['cold_cpu_s']:.1f} (≥ {b:.1f} s on {r.extra['cpus']} CPUs{best})"


def _line(r: ColdRow) -> str:
    if r.status != "ok":
        return f"  {r.what}: {r.status}"
    after = f"; first run after the set-up step {_after(r)}" if _after(r) else ""
    cpu = f" (CPU {_bound(r)})" if _bound(r) else ""
    if r.name == "compile":
        return f"  {r.what}: cold {r.cold_s:.2f} s{cpu}, warm {r.warm_s:.2f} s"
    expect = r.extra.get("expects_compile", True)
    odd = "" if r.notice == expect else (" (no compile notice on the cold run!)" if expect else
                                         " (the cold run compiled!)")
    return f"  {r.what}: cold {r.cold_s:.2f} s{cpu}, warm {r.warm_s:.2f} s, ×{r.ratio:.1f}{after}{odd}"


def table(rows: list[ColdRow]) -> str:
    """The Markdown table: one line per command."""
    lines = ["| command | cold s (empty kernel cache) | warm s | cold ÷ warm | target | compile notice "
             "| first run after the set-up step, s (÷ warm) | cold CPU s (its wall at best, ÷ warm) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.status != "ok":
            lines.append(f"| {r.what} | {r.status} | | | {TARGET} | | | |")
            continue
        if r.name == "compile":
            lines.append(f"| {r.what} | {r.cold_s:.2f} | {r.warm_s:.2f} | | | {'yes' if r.notice else 'no'} | "
                         f"| {_bound(r)} |")
            continue
        ok = "✓" if TARGET.met(r.ratio) else "✗"
        cmd = ""
        if "cold_command_s" in r.extra:
            cmd = f" (whole command {r.extra['cold_command_s']:.1f} / {r.extra['warm_command_s']:.1f} s)"
        lines.append(f"| {r.what}{cmd} | {r.cold_s:.2f} | {r.warm_s:.2f} | ×{r.ratio:.1f} | {TARGET} {ok} "
                     f"| {'yes' if r.notice else 'no'} | {_after(r)} | {_bound(r)} |")
    return "\n".join(lines) + "\n"


def write_outputs(rows: list[ColdRow], out_dir: Path, **meta: Any) -> None:
    write_report("coldstart", rows, table(rows), out_dir, plot, **meta)


def plot(rows: list[ColdRow], path: Path) -> None:
    """Horizontal bars, seconds: cold beside warm per command, the ratio written beside."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.status == "ok"]
    fig, ax = plt.subplots(figsize=(10, 0.7 * max(len(ok), 1) + 1.6))
    y = np.arange(len(ok))
    ax.barh(y - 0.27, [r.cold_s for r in ok], 0.27, label="cold (empty kernel cache)", color="tab:orange")
    ax.barh(y, [r.extra.get("after_setup_s", 0.0) for r in ok], 0.27,
            label="first run after the set-up step (gyro-platform compile)", color="tab:green")
    ax.barh(y + 0.27, [r.warm_s for r in ok], 0.27, label="warm", color="tab:blue")
    for yi, r in zip(y, ok):
        if r.name != "compile":
            ax.text(r.cold_s * 1.02, yi - 0.27, f"×{r.ratio:.1f}", va="center", fontsize=8)
    ax.set_yticks(y, [r.what for r in ok], fontsize=7)
    ax.set_xlabel("wall seconds, whole command (lower is better)")
    ax.invert_yaxis()
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"cold start beside warm (target: cold within ×{TARGET.bound:g} of warm)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
