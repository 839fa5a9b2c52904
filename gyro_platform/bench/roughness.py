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

"""Cost that does not follow input roughness (``gyro-platform bench roughness``).

The replay's model (stabilised, linear, default effects, ``auto``) driven by a 1 kHz vehicle IMU
(:func:`.bags.vehicle_imu`: a ground vehicle on a rough road, MEMS noise) and by the same IMU
with a 37 Hz engine vibration on top (:func:`gyro_platform.engine.hardcases.engine_vibration`,
0.3 rad/s: the mount friction kinks ~220 times a second), over a sweep of tolerances (``SWEEP``,
rtol 1e-4 … 1e-10 in half decades, atol = rtol·1e-3): right-hand sides and steps per sample,
rejected steps and the delivered error (largest gimbal-angle or drift-angle difference, rad)
against a tight reference (RK4 at rtol 1e-12, steps ≤ 0.1 ms). The table's rows are rtol 1e-4,
1e-6 and 1e-8 (``RTOLS``); each compares the two inputs **at the same delivered accuracy** (issue
31 item 3): the vibrating input's right-hand sides per sample where its sweep reaches the smooth
input's delivered error (``cost_at_error``, log-log between the two sweep points around it) ÷ the
smooth input's (the bar holds this ratio), beside the plain ratio at the same rtol. Then how far
that holds: the same-rtol ratio at rtol 1e-6 for vibrations of 0.03–3 rad/s (x axis; y ⅔, z ⅓ of
it at twice the frequency) at 12–300 Hz (``GRID``). Last, the same IMU on a parked vehicle
(:func:`parked`: noise and bias only, the relative rates hovering about the friction's zone, so
kinks every sample), compared with the smooth input the same way (``parked_rows``; no bar). Counts,
not times: they do not depend on the machine. Writes ``roughness.json`` (the sweep, the grid and the
parked rows under ``meta``), ``roughness.md`` and ``roughness.png`` (work against delivered error,
the whole sweep).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path

import numpy as np

from .bags import vehicle_imu, VehicleImu
from .bars import BARS
from .report import write_report
from ..engine.hardcases import engine_vibration
from ..engine.simulator import Simulator
from ..physics.options import DEFAULT_EFFECTS, ModelOptions
from ..physics.params import NAV1, PlatformParams

__all__ = ["roughness", "RoughRow", "surfaces", "parked", "run_surface", "cost_at_error", "RTOLS", "SWEEP", "GRID",
           "grid", "compared", "parked_rows"]

RTOLS = (1e-4, 1e-6, 1e-8)
#: the tolerances swept for the work-precision curves: 1e-4 … 1e-10 in half decades (holds ``RTOLS``)
SWEEP = tuple(float(f"{10.0 ** (-k / 2):.0e}") for k in range(8, 21))
#: the reference: RK4 held to rtol 1e-12 (atol 1e-15) with steps ≤ 0.1 ms and an ample budget
REFERENCE = ("rk4", 1e-12, 1e-15, 1e-4, 1 << 16)
OUT_EVERY = 10                       # compare at 100 Hz
#: vibration amplitudes (rad/s, x axis) and frequencies (Hz) of the grid, at rtol 1e-6
GRID = ((0.03, 0.3, 1.0, 3.0), (12.0, 37.0, 120.0, 300.0))


@dataclass
class RoughRow:
    """One tolerance: the smooth and the vibrating input's work and delivered error."""

    rtol: float
    integrator: str
    smooth_rhs: float                # right-hand sides per sample
    vibrating_rhs: float
    smooth_steps: float              # accepted steps per sample
    vibrating_steps: float
    smooth_rejected: int
    vibrating_rejected: int
    smooth_error: float              # rad, against the reference
    vibrating_error: float
    #: the vibrating input's right-hand sides per sample at the smooth input's delivered error
    #: (``cost_at_error`` on the sweep; nan where the sweep does not reach it)
    vibrating_rhs_equal: float = float("nan")

    @property
    def ratio(self) -> float:
        """Right-hand sides per sample at the same delivered accuracy, vibrating ÷ smooth (its bar:
        ``bars.BARS["roughness"]``; nan where the vibrating sweep does not reach the error)."""
        return self.vibrating_rhs_equal / self.smooth_rhs

    @property
    def same_rtol_ratio(self) -> float:
        """Right-hand sides per sample at the same rtol, vibrating ÷ smooth."""
        return self.vibrating_rhs / self.smooth_rhs


def cost_at_error(points: list[tuple[float, float]], target: float) -> float:
    """Work to deliver ``target``: ``points`` are (right-hand sides per sample, delivered error, rad)
    from the loosest tolerance to the tightest. The first point at or below ``target`` and the one
    before it bracket it; the work is interpolated between them in log-log (the loosest point's work
    if it is already there; nan if no point reaches ``target``)."""
    for i, (rhs, err) in enumerate(points):
        if err <= target:
            if i == 0:
                return rhs
            (r0, e0), (r1, e1) = points[i - 1], (rhs, max(err, 1e-300))
            f = math.log(e0 / target) / math.log(e0 / e1)
            return math.exp(math.log(r0) + f * math.log(r1 / r0))
    return math.nan


def surfaces(duration: float) -> dict[str, VehicleImu]:
    """The two inputs: the vehicle IMU of :func:`.bags.vehicle_imu` and the same plus the engine vibration."""
    imu = vehicle_imu(duration, 1000.0)
    return {"smooth": imu,
            "vibrating": VehicleImu(imu.t, imu.omega + engine_vibration(imu.t, noise=False), imu.force)}


def parked(duration: float) -> VehicleImu:
    """The same IMU on the vehicle at rest (:func:`.bags.vehicle_imu` ``parked``: its noise and bias
    only): the mount axes' relative rates hover about zero, inside ±2.8e-3 rad/s a sample, and
    cross the friction's ±ε zone several times a sample."""
    return vehicle_imu(duration, 1000.0, parked=True)


def run_surface(imu: VehicleImu, integrator: str, rtol: float, atol: float, max_step: float = 1e-3,
                max_substeps: int = 4096, params: PlatformParams = NAV1) -> tuple[np.ndarray, dict]:
    """(angles (N, 8): gimbal angles and drift angle at 100 Hz, rad; the simulator's stats)."""
    opt = ModelOptions.make("stabilised", "linear", DEFAULT_EFFECTS["stabilised"], integrator=integrator,
                            rtol=rtol, atol=atol, max_step=max_step, max_substeps=max_substeps)
    sim = Simulator(params, opt)
    outs = sim.push_many(imu.t, imu.omega, imu.force, output_every=OUT_EVERY)
    return np.array([[*o.gimbal_angles, *o.drift_angle] for o in outs]), sim.stats


def roughness(out_dir: Path, quick: bool = False) -> list[RoughRow]:
    """Run, print the table, write the report (see module doc)."""
    duration = 2.0 if quick else 10.0
    inputs = {**surfaces(duration), "parked": parked(duration)}
    ref = {k: run_surface(imu, REFERENCE[0], REFERENCE[1], REFERENCE[2], REFERENCE[3], REFERENCE[4])[0]
           for k, imu in inputs.items()}
    sweep: dict[str, list[dict]] = {k: [] for k in inputs}
    for rtol in SWEEP:
        for k, imu in inputs.items():
            ang, st = run_surface(imu, "auto", rtol, rtol * 1e-3)
            n = st["n_samples"]
            sweep[k].append({"rtol": rtol, "rhs": st["n_rhs"] / n, "steps": st["n_steps"] / n,
                             "rejected": st["n_rejected"], "error": float(np.abs(ang - ref[k]).max()),
                             "integrator": st["integrator"]})
    rows = [RoughRow(rtol, s["integrator"], s["rhs"], v["rhs"], s["steps"], v["steps"], s["rejected"],
                     v["rejected"], s["error"], v["error"], equal)
            for rtol, s, v, equal in compared(sweep, "vibrating")]
    cells = grid(inputs["smooth"], rows[1].smooth_rhs)
    still = parked_rows(sweep)
    write_report("roughness", rows, table(rows, duration) + "\n" + grid_table(cells) + "\n" + parked_table(still),
                 out_dir, lambda rows, path: plot(rows, sweep, path), duration_s=duration,
                 reference=list(REFERENCE[:4]), sweep=sweep, grid=cells, parked=still)
    return rows


def compared(sweep: dict[str, list[dict]], other: str) -> list[tuple[float, dict, dict, float]]:
    """(rtol, the smooth input's sweep point, ``other``'s, ``other``'s work at the smooth input's
    error: ``cost_at_error`` on its sweep, nan where it never gets there) at each of ``RTOLS``."""
    curve = [(p["rhs"], p["error"]) for p in sweep[other]]
    out = []
    for rtol in RTOLS:
        s, o = (next(q for q in sweep[k] if q["rtol"] == rtol) for k in ("smooth", other))
        out.append((rtol, s, o, cost_at_error(curve, s["error"])))
    return out


def parked_rows(sweep: dict[str, list[dict]]) -> list[dict]:
    """The parked input against the smooth one at ``RTOLS`` (:func:`compared`): its work, error, and
    its work at the smooth input's error."""
    return [{"rtol": rtol, "smooth_rhs": s["rhs"], "parked_rhs": p["rhs"], "parked_rhs_equal": equal,
             "ratio": equal / s["rhs"], "same_rtol_ratio": p["rhs"] / s["rhs"], "smooth_error": s["error"],
             "parked_error": p["error"], "parked_rejected": p["rejected"]}
            for rtol, s, p, equal in compared(sweep, "parked")]


def _equal_cells(work: float, ratio: float, missing: str) -> tuple[str, str]:
    """The table's "same error" work and its ratio, or "not reached" and ``missing`` where the
    sweep never delivered the smooth input's error (``work`` nan)."""
    return (f"{work:.2f}", f"×{ratio:.2f}") if not math.isnan(work) else ("not reached", missing)


def parked_table(rows: list[dict]) -> str:
    """The parked vehicle's rows as Markdown (not held to a bar: issue 31's is the vibrating input's)."""
    lines = ["A parked vehicle (the same IMU at rest: its noise and bias only, the relative rates hovering "
             "about the friction's ±ε zone): right-hand sides per sample ÷ the smooth input's", "",
             "| rtol | rhs/sample smooth | rhs/sample parked, same rtol / same error | at equal accuracy "
             "| at the same rtol | rejected parked | error smooth / parked, rad |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        equal, ratio = _equal_cells(r["parked_rhs_equal"], r["ratio"], "—")
        lines.append(f"| {r['rtol']:g} | {r['smooth_rhs']:.2f} | {r['parked_rhs']:.2f} / {equal} | {ratio} | "
                     f"×{r['same_rtol_ratio']:.2f} | {r['parked_rejected']} | {r['smooth_error']:.1e} / "
                     f"{r['parked_error']:.1e} |")
    return "\n".join(lines) + "\n"


def grid(imu: VehicleImu, smooth_rhs: float, rtol: float = 1e-6) -> list[dict]:
    """Right-hand sides per sample of ``imu`` plus each vibration of ``GRID`` (auto at ``rtol``),
    and their ratio to ``smooth_rhs`` (the smooth input's at the same rtol)."""
    from ..engine.hardcases import VIBRATION_AMP

    cells = []
    for amp in GRID[0]:
        for hz in GRID[1]:
            w = imu.omega + engine_vibration(imu.t, noise=False, scale=amp / VIBRATION_AMP[0], hz=hz)
            _, st = run_surface(VehicleImu(imu.t, w, imu.force), "auto", rtol, rtol * 1e-3)
            rhs = st["n_rhs"] / st["n_samples"]
            cells.append({"amplitude": amp, "hz": hz, "rhs": rhs, "ratio": rhs / smooth_rhs})
    return cells


def grid_table(cells: list[dict]) -> str:
    """The grid as a Markdown table of ratios (rows: amplitude, columns: frequency)."""
    lines = ["How far it holds: right-hand sides per sample ÷ the smooth input's at rtol 1e-6, by vibration "
             "amplitude (rad/s, x axis) and frequency", "",
             "| amplitude \\ frequency | " + " | ".join(f"{hz:g} Hz" for hz in GRID[1]) + " |",
             "|---|" + "---|" * len(GRID[1])]
    for amp in GRID[0]:
        row = [c for c in cells if c["amplitude"] == amp]
        lines.append(f"| {amp:g} rad/s | " + " | ".join(f"×{c['ratio']:.2f}" for c in row) + " |")
    return "\n".join(lines) + "\n"


def table(rows: list[RoughRow], duration: float) -> str:
    """The Markdown table."""
    lines = [f"Input roughness ({duration:g} s of a 1 kHz vehicle IMU, smooth ÷ with a 37 Hz engine vibration; "
             "stabilised linear model, auto; error: largest gimbal or drift angle difference from RK4 at rtol "
             "1e-12; at equal accuracy: the vibrating input's work where its sweep of tolerances reaches the "
             "smooth input's error)", "",
             "| rtol | method | rhs/sample smooth | rhs/sample vibrating, same rtol / same error "
             f"| vibrating ÷ smooth at equal accuracy (bar {BARS['roughness']}) | at the same rtol "
             "| steps/sample smooth / vibrating | rejected smooth / vibrating | error smooth / vibrating, rad |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        equal, ratio = _equal_cells(r.vibrating_rhs_equal, r.ratio, "✗")
        lines.append(f"| {r.rtol:g} | {r.integrator} | {r.smooth_rhs:.2f} | {r.vibrating_rhs:.2f} / "
                     f"{equal} | {ratio} | ×{r.same_rtol_ratio:.2f} | "
                     f"{r.smooth_steps:.2f} / {r.vibrating_steps:.2f} | {r.smooth_rejected} / {r.vibrating_rejected} | "
                     f"{r.smooth_error:.1e} / {r.vibrating_error:.1e} |")
    return "\n".join(lines) + "\n"


def plot(rows: list[RoughRow], sweep: dict[str, list[dict]], path: Path) -> None:
    """Work (rhs per sample) against delivered error over the sweep, both inputs; the table's
    tolerances labelled."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    marked = {r.rtol for r in rows}
    for key, style in (("smooth", "o-"), ("vibrating", "s--"), ("parked", "^:")):
        pts = sweep[key]
        ax.loglog([max(p["error"], 1e-16) for p in pts], [p["rhs"] for p in pts], style, ms=4, label=key)
        for p in pts:
            if p["rtol"] in marked:
                ax.annotate(f"rtol {p['rtol']:g}", (max(p["error"], 1e-16), p["rhs"]), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
    ax.set_xlabel("delivered error vs reference, rad")
    ax.set_ylabel("right-hand sides per 1 kHz sample")
    ax.set_title("cost against input roughness (auto, stabilised linear; rtol 1e-4 … 1e-10)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
