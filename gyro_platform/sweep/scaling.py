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

"""Benchmark of sweeps: runs per minute of the 60 s default scene on 1 and 2 local workers.

``gyro-platform bench sweep`` runs the same Monte Carlo sweep (bias torque on β10 drawn from a
normal distribution) once per worker count into fresh folders, times it as a user sees it
(cluster start included) and the runs alone (measured from the started cluster's first task
to the last record), and checks that the result tables are identical.
Writes ``results/bench/sweep.{csv,md,png}``.
"""
from __future__ import annotations

import json
from pathlib import Path
import tempfile
import time

SPEC = """scene: default
duration: {duration}
seed: 2026
runs: {runs}
vary:
  bias_torque[4]: {{dist: normal, mean: 1.0e-7, std: 2.0e-8}}
  support_coulomb: {{dist: uniform, low: 2.0e-3, high: 8.0e-3}}
"""
TIMING = ("cpu_s", "wall_s")


def _strip(records: list[dict]) -> str:
    return json.dumps([{k: v for k, v in r.items() if k not in TIMING} for r in records], sort_keys=True)


def scaling(out_dir: Path, runs: int = 8, duration: float = 60.0, workers=(1, 2)) -> list[dict]:
    from .command import close_client, make_client, run_sweep
    from .spec import load_sweep

    rows = []
    reference = None
    with tempfile.TemporaryDirectory() as tmp:
        spec_path = Path(tmp) / "bench_sweep.yaml"
        spec_path.write_text(SPEC.format(duration=duration, runs=runs))
        spec = load_sweep(spec_path)
        for n in workers:
            t0 = time.perf_counter()
            client = make_client(n)                 # the local cluster, as run_sweep makes it
            started = time.perf_counter()
            try:
                res = run_sweep(spec, Path(tmp) / f"w{n}", client=client)
                runs_wall = time.perf_counter() - started
            finally:
                close_client(client)
            wall = time.perf_counter() - t0
            ok = [r for r in res.records if r["status"] == "ok"]
            same = reference is None or _strip(res.records) == reference
            reference = reference or _strip(res.records)
            rows.append({"workers": n, "runs": runs, "ok": len(ok), "sim_s_per_run": duration,
                         "wall_s": wall, "runs_per_min": 60.0 * runs / wall,
                         "cpu_s_per_run": sum(r["cpu_s"] for r in ok) / max(1, len(ok)),
                         "cluster_start_s": started - t0,
                         "runs_per_min_excl_startup": 60.0 * runs / runs_wall,
                         "identical_to_1_worker": same})
    base = rows[0]["runs_per_min"]
    for r in rows:
        r["scaling"] = r["runs_per_min"] / base
    write(rows, Path(out_dir))
    return rows


def table(rows: list[dict]) -> str:
    head = ("| workers | runs | wall s | runs/min | × 1 worker | CPU s per run | cluster start s "
            "| runs/min without cluster start | table identical |\n|---|---|---|---|---|---|---|---|---|\n")
    return head + "".join(
        f"| {r['workers']} | {r['runs']} | {r['wall_s']:.1f} | {r['runs_per_min']:.1f} | {r['scaling']:.2f} "
        f"| {r['cpu_s_per_run']:.2f} | {r['cluster_start_s']:.1f} | {r['runs_per_min_excl_startup']:.1f} "
        f"| {'yes' if r['identical_to_1_worker'] else 'NO'} |\n"
        for r in rows)


def write(rows: list[dict], out_dir: Path) -> None:
    import csv

    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "sweep.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out_dir / "sweep.md").write_text(table(rows))
    fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
    x = [r["workers"] for r in rows]
    ax.bar([v - 0.18 for v in x], [r["runs_per_min"] for r in rows], width=0.36, label="with cluster start")
    ax.bar([v + 0.18 for v in x], [r["runs_per_min_excl_startup"] for r in rows], width=0.36,
           label="runs only")
    ax.set_xticks(x, [str(v) for v in x])
    ax.set_xlabel("local Dask worker processes")
    ax.set_ylabel(f"runs per minute ({rows[0]['sim_s_per_run']:g} s default scene)")
    ax.set_title("sweep throughput")
    ax.legend()
    fig.savefig(out_dir / "sweep.png", dpi=100)
    plt.close(fig)
