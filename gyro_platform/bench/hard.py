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

"""The hard-case table (``gyro-platform bench hard``).

The hard-case catalogue (:mod:`gyro_platform.engine.hardcases`): every method asked for rtol
1e-9 / atol 1e-12, error against DOP853 at rtol 1e-12, CPU s per simulated s, verdict
(ok / refused / WRONG). Writes CSV, Markdown and a PNG table.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

__all__ = ["hard", "write_hard", "plot_hard", "case_names", "unknown_cases"]


def case_names() -> list[str]:
    """Names of the hard cases (``hardcases.CASES``), in table order."""
    from ..engine.hardcases import CASES

    return [c.name for c in CASES]


def unknown_cases(cases: list[str] | None) -> list[str]:
    """The names in ``cases`` that are no hard case (empty when all are known or none given)."""
    if not cases:
        return []
    known = set(case_names())
    return [c for c in dict.fromkeys(cases) if c not in known]


def hard(out_dir: Path, quick: bool = False, cases: list[str] | None = None) -> list[dict]:
    """Case × method table (``hardcases``): error against the reference, CPU s per simulated s,
    verdict (ok / refused / WRONG). ``quick``: the tests' durations (the hour: 60 s)."""
    from ..engine.hardcases import ASK, CASES, OK_RAD, run_case, run_reference, verdict

    bad = unknown_cases(cases)
    if bad:
        raise ValueError(f"unknown case {', '.join(bad)}; known: {', '.join(case_names())}")
    rows: list[dict] = []
    for case in CASES:
        if cases and case.name not in cases:
            continue
        dur = case.duration if not quick else (60.0 if case.bench_only else case.test_duration)
        rn, rr, ra = case.reference
        run_case(case, rn, rr, ra, duration=0.005)                 # warm-up: compile, matrices
        ref = run_reference(case, dur)
        print(f"\n== {case.name} ({dur:g} s): {case.description}\n   reference {rn} rtol {rr:g}: "
              f"{ref.cpu / max(ref.sim_s, 1e-9):.3g} CPU s per sim s", flush=True)
        for m in case.methods:
            run_case(case, m, *ASK, duration=0.005)
            res = run_case(case, m, *ASK, duration=dur)
            v, err = verdict(res, ref)
            cpu = res.cpu / max(res.sim_s, 1e-3 / 2)
            row = {"case": case.name, "method": m, "integrator": res.stats.get("integrator", m), "duration": dur,
                   "error": err, "cpu_per_sim_s": cpu, "verdict": v,
                   "error_estimate": res.stats.get("max_error_estimate", math.nan),
                   "steps_per_sample": res.stats.get("n_steps", 0) / max(res.stats.get("n_samples", 1), 1),
                   "refused": (res.refused or "")[:160]}
            rows.append(row)
            print(f"   {m:18s} {v:8s} error {err:9.2e} rad  {cpu:9.3g} CPU s/sim s  "
                  f"{row['steps_per_sample']:7.1f} steps/sample  {row['refused'][:90]}", flush=True)
    write_hard(rows, out_dir, OK_RAD, ASK)
    return rows


def write_hard(rows: list[dict], out_dir: Path, ok_rad: float, ask) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    keys = ["case", "method", "integrator", "duration", "error", "cpu_per_sim_s", "verdict", "error_estimate",
            "steps_per_sample", "refused"]
    with open(out_dir / "hard.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
    cases = list(dict.fromkeys(r["case"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    cell = {(r["case"], r["method"]): r for r in rows}
    lines = [f"Asked: rtol {ask[0]:g}, atol {ask[1]:g}; verdict ok = within {ok_rad:g} rad of the reference. "
             "Cell: error (rad) / CPU s per simulated s / verdict.", "",
             "| case | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for c in cases:
        cells = []
        for m in methods:
            r = cell.get((c, m))
            if r is None:
                cells.append("")
            elif r["verdict"] == "refused":
                cells.append(f"refused / {r['cpu_per_sim_s']:.2g} s")
            else:
                cells.append(f"{r['error']:.1e} / {r['cpu_per_sim_s']:.2g} s / {r['verdict']}")
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    (out_dir / "hard.md").write_text("\n".join(lines) + "\n")
    print("\n" + "\n".join(lines))
    plot_hard(rows, cases, methods, out_dir / "hard.png", ok_rad)
    print(f"\nwrote {out_dir / 'hard.csv'}, {out_dir / 'hard.md'}, {out_dir / 'hard.png'}")


def plot_hard(rows, cases, methods, path: Path, ok_rad: float) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(1.3 * len(methods) + 3, 0.62 * len(cases) + 1.8))
    colors = {"ok": "#b7e4b0", "refused": "#f6e3a1", "WRONG": "#f4a6a6"}
    cell = {(r["case"], r["method"]): r for r in rows}
    for i, c in enumerate(cases):
        for j, m in enumerate(methods):
            r = cell.get((c, m))
            if r is None:
                continue
            ax.add_patch(plt.Rectangle((j, i), 1, 1, color=colors[r["verdict"]], ec="w"))
            txt = "refused" if r["verdict"] == "refused" else f"{r['error']:.0e} rad"
            ax.text(j + 0.5, i + 0.38, txt, ha="center", va="center", fontsize=7)
            ax.text(j + 0.5, i + 0.7, f"{r['cpu_per_sim_s']:.2g} s/s", ha="center", va="center", fontsize=6,
                    color="0.3")
    ax.set_xlim(0, len(methods))
    ax.set_ylim(len(cases), 0)
    ax.set_xticks(np.arange(len(methods)) + 0.5, methods, rotation=30, fontsize=8)
    ax.set_yticks(np.arange(len(cases)) + 0.5, cases, fontsize=8)
    ax.set_title(f"hard cases: error vs reference and CPU s per simulated s (green: ≤ {ok_rad:g} rad, "
                 "yellow: refused, red: wrong)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
