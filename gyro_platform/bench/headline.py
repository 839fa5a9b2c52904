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

"""The headline table of ``gyro-platform bench`` (no WHAT): one line per figure a user meets,
as a ratio beside its target, gathered from the section reports of the same run (``coldstart``,
``consumer``, ``roughness``, ``peer`` JSON in the output folder; a section not run is left
out). Printed last and written to ``headline.md`` and ``headline.json``; the README's table is
this table. Each row is held to its bar of ``bars.BARS``. Imports ``bars`` and ``reports.jsonio``
only."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .bars import BARS
from .report import cpu_ceiling_text
from ..reports.jsonio import write_json

__all__ = ["headline", "headline_rows", "table"]


def _load(out_dir: Path, stem: str, since: float) -> dict | None:
    """The report ``stem``, if written at or after ``since`` (s since the epoch): this run's."""
    path = out_dir / f"{stem}.json"
    try:
        if path.stat().st_mtime < since:
            return None
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _mark(met) -> str:
    if met is None:
        return ""
    if isinstance(met, (list, tuple)):
        return "; ".join(_mark(m) for m in met)
    return "✓" if met else "✗"


def headline_rows(out_dir: Path, since: float = 0.0) -> list[dict[str, Any]]:
    """The rows of the reports in ``out_dir`` written since ``since`` (s since the epoch; an
    older report, of a section this run left out, is not this run's): ``figure``, ``measured``
    (text), ``value`` (the number held to the first bar), ``target`` (the bars' text) and ``met``
    (True, False, None where there is no bar, or a list of them for a row of two figures)."""
    rows: list[dict[str, Any]] = []

    def add(figure: str, measured: str, value: float | None, target: str = "", met: Any = None) -> None:
        rows.append({"figure": figure, "measured": measured, "value": value, "target": target, "met": met})

    keys = ("cold_over_warm", "replay_over_floor", "roughness", "peer")
    cold_bar, floor_bar, rough_bar, peer_bar = (BARS[k] for k in keys)
    cold = _load(out_dir, "coldstart", since)
    for r in (cold or {}).get("rows", []):
        if r.get("status") != "ok" or r.get("cold_s") is None or not r.get("warm_s"):
            continue
        if r["name"] == "compile":
            add("set-up step `gyro-platform compile`, empty kernel cache", f"{r['cold_s']:.1f} s", r["cold_s"])
            continue
        ratio = r["cold_s"] / r["warm_s"]
        extra = r.get("extra") or {}
        after = extra.get("after_setup_s")
        bound = ""
        if extra.get("cold_cpu_bound_s") is not None:     # the cold run's CPU on this machine's CPUs
            best = extra["cold_cpu_bound_s"] / r["warm_s"]
            bound = f", its CPU {extra['cold_cpu_s']:.0f} s allows ≥ ×{best:.1f} on {extra['cpus']} CPUs"
        text = f"×{ratio:.1f} ({r['cold_s']:.1f} s / {r['warm_s']:.2f} s{bound})"
        if after is None:
            add(f"{r['what']}: cold ÷ warm", text, ratio, str(cold_bar), cold_bar.met(ratio))
        else:
            a = after / r["warm_s"]
            add(f"{r['what']}: cold ÷ warm; after the set-up step ÷ warm", f"{text}; ×{a:.1f}", ratio,
                str(cold_bar), [cold_bar.met(ratio), cold_bar.met(a)])
    cons = _load(out_dir, "consumer", since)
    for r in (cons or {}).get("rows", []):
        if r.get("status") != "ok":
            continue
        extra = r.get("extra") or {}
        bar = BARS.get(r.get("target") or "")
        target = "" if bar is None else str(bar)
        met = (lambda v: None) if bar is None else bar.met
        if r.get("rtf") is not None and r["name"] != "sqlite3_floor":
            over = extra.get("replay_over_floor")
            whole = extra.get("whole_command_rtf")      # the command in a new process, start-up included
            printed = extra.get("new_process_rtf")      # what that command reports (kernels loaded in it)
            rtf = f"×{r['rtf']:.3g}"
            if whole is not None:
                prints = "" if printed is None else f"new process: prints ×{printed:.3g}, "
                rtf += f" ({prints}whole command ×{whole:.3g})"
            ceiling = cpu_ceiling_text(extra)                  # what its CPU allows on this machine's CPUs
            if ceiling:
                rtf += f" ({ceiling})"
            if over is None:
                add(f"{r['what']}: real-time ×", rtf, r["rtf"], target, met(r["rtf"]))
            else:
                add(f"{r['what']}: real-time ×; replay ÷ its I/O floor",
                    f"{rtf}; {over:.2f} (floor ×{extra.get('floor_rtf', 0):.3g})", r["rtf"],
                    f"{target}; {floor_bar}", [met(r["rtf"]), floor_bar.met(over)])
        elif r["name"].startswith("node") and r.get("us_per_sample") is not None:
            us = r["us_per_sample"]
            add(r["what"], f"{us:.1f} µs", us, target, met(us))
    rough = _load(out_dir, "roughness", since)
    for r in (rough or {}).get("rows", []):
        same = f"at the same rtol ×{r['vibrating_rhs'] / r['smooth_rhs']:.2f}, errors {r['smooth_error']:.1e} / " \
               f"{r['vibrating_error']:.1e} rad"
        eq = r.get("ratio")             # null: the vibrating sweep does not reach the smooth input's error
        add(f"vibrating ÷ smooth 1 kHz IMU, right-hand sides per sample at equal delivered accuracy, smooth at rtol "
            f"{r['rtol']:g} ({r['integrator']})",
            (f"×{eq:.2f}" if eq is not None else "not reached in the sweep") + f" ({same})", eq,
            str(rough_bar), False if eq is None else rough_bar.met(eq))
    peer = _load(out_dir, "peer", since)
    for sc in (peer or {}).get("scenes", []):
        c = next((c for c in sc.get("comparison", []) if "ratio_kernel" in c), None)
        if c is None:
            continue
        add(f"MuJoCo ÷ kernel CPU at equal accuracy, {sc['scene']} ({c['error_level']:.1e} rad)",
            f"×{c['ratio_kernel']:.1f} (÷ consumer ×{c['ratio_consumer']:.2f})", c["ratio_kernel"],
            str(peer_bar), peer_bar.met(c["ratio_kernel"]))
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: figure, measured, target, ✓/✗."""
    lines = ["| figure | measured | target | |", "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['figure']} | {r['measured']} | {r['target']} | {_mark(r['met'])} |")
    return "\n".join(lines) + "\n"


def headline(out_dir: Path, since: float = 0.0) -> list[dict[str, Any]]:
    """Print the headline table of the reports in ``out_dir`` written since ``since``; write
    ``headline.md`` and ``headline.json`` there (nothing when there is no such report)."""
    rows = headline_rows(out_dir, since)
    if not rows:
        return rows
    text = table(rows)
    print("\nheadline (this run's figures; the README's table)\n" + text, end="")
    (out_dir / "headline.md").write_text(text)
    write_json(out_dir / "headline.json", {"rows": rows}, indent=1)
    return rows
