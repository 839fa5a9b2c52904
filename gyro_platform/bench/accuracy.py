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

"""Work-precision study: what accuracy costs in time (``gyro-platform bench accuracy``).

Every fidelity × integrator × asked tolerance (rtol 1e-4 … 1e-10, steps ≤ 1 ms) on two standard
scenes (:mod:`.bench_scenes`: a ship rolling and pitching, stabilised, 10 min; an aircraft manoeuvre
with coordinated turns and rate steps, 2 min; vehicle rates at 1 kHz), each compared with a
``full``-fidelity reference (RK4 held to rtol 1e-12, steps ≤ 0.25 ms; gimbal angles and drift
angle, end and maximum over time), timed in CPU seconds per simulated second (median of
repeats), as a real-time factor and as a speed ratio to the naive baseline a Python user would
write (``scipy.integrate.solve_ivp`` on the ``full`` model over the whole run, input
interpolated with ``np.interp``). Writes CSV, Markdown and a PNG plot, and names the cheapest
configuration that reaches 1e-3, 1e-6 and 1e-9 rad.

Timing is CPU time (``time.process_time``) of this process; the machine is shared, so medians
are quoted. Nothing here asserts speed: tests assert physics, benchmarks measure time.
"""
from __future__ import annotations

import csv
from pathlib import Path
import time

import numpy as np

from .bench_scenes import aircraft_scene, BenchScene, SAMPLE_RATE, ship_scene
from ..engine.simulator import Simulator
from ..physics.options import ModelOptions
from ..physics.params import NAV1
from ..reports.jsonio import write_json

OUT_EVERY = 100          # compare at 10 Hz
THRESHOLDS = (1e-3, 1e-6, 1e-9)


# ---------------------------------------------------------------------------------------------
# runs

def _record(outs) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([o.gimbal_angles for o in outs]), np.array([o.drift_angle for o in outs]))


def run_config(sc: BenchScene, fidelity: str, integrator: str, max_step: float, rtol: float = 1e-8,
               atol: float = 1e-12, repeats: int = 1, duration: float | None = None, max_substeps: int = 4096):
    """(gimbal (N, 5), drift (N, 3), CPU s per simulated s, simulated s) for one configuration."""
    n = len(sc.t) if duration is None else int(round(duration * SAMPLE_RATE)) + 1
    opt = ModelOptions.make("stabilised", fidelity, sc.effects, integrator=integrator, max_step=max_step,
                            rtol=rtol, atol=atol, max_substeps=max_substeps)
    times = []
    rec = None
    for _ in range(repeats):
        sim = Simulator(NAV1, opt)
        sim.push_many(sc.t[:2], sc.omega[:2], sc.force[:2])       # warm-up: compile, matrices
        sim = Simulator(NAV1, opt)
        t0 = time.process_time()
        outs = sim.push_many(sc.t[:n], sc.omega[:n], sc.force[:n], output_every=OUT_EVERY)
        times.append(time.process_time() - t0)
        rec = _record(outs)
    sim_s = sc.t[n - 1] - sc.t[0]
    return rec[0], rec[1], float(np.median(times)) / sim_s, sim_s


def naive_baseline(sc: BenchScene, rtol: float, atol: float, duration: float | None = None):
    """What a Python user would write: one ``solve_ivp`` (RK45) over the run, ``full`` model,
    the vehicle rate interpolated with ``np.interp`` in the right-hand side."""
    from scipy.integrate import solve_ivp
    n = len(sc.t) if duration is None else int(round(duration * SAMPLE_RATE)) + 1
    sim = Simulator(NAV1, ModelOptions.make("stabilised", "full", sc.effects))
    system = sim.system
    t_s, w_s, f_s = sc.t[:n], sc.omega[:n], sc.force[:n]

    def rhs(t, y):
        w = np.array([np.interp(t, t_s, w_s[:, i]) for i in range(3)])
        f = np.array([np.interp(t, t_s, f_s[:, i]) for i in range(3)])
        system.set_input(t, t + 1.0, w, w, f, f)
        return system.rhs(t, y)

    y0 = system.rest_state()
    t_eval = t_s[::OUT_EVERY]
    t0 = time.process_time()
    sol = solve_ivp(rhs, (t_s[0], t_s[-1]), y0, method="RK45", rtol=rtol, atol=atol, t_eval=t_eval)
    cpu = time.process_time() - t0
    from scipy.spatial.transform import Rotation
    q = sol.y[0:5].T
    qIP = sol.y[system.layout.quat_IP].T
    drift = Rotation.from_quat(qIP).as_rotvec()
    sim_s = t_s[-1] - t_s[0]
    return q, drift, cpu / sim_s, sim_s, sol.nfev


def errors(g, d, gref, dref) -> dict[str, float]:
    k = min(len(g), len(gref))
    eg = np.max(np.abs(g[:k] - gref[:k]), axis=1)
    ed = np.linalg.norm(d[:k] - dref[:k], axis=1)
    return {"gimbal_end": float(eg[-1]), "gimbal_max": float(eg.max()), "drift_end": float(ed[-1]),
            "drift_max": float(ed.max()), "max": float(max(eg.max(), ed.max()))}


#: (fidelity, integrator, max_step s, asked rtol): every method at its asked tolerance (atol =
#: rtol·1e-3 rad), the step only an upper bound; the error is what the reference measures
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)
CONFIGS = [
    *[(fid, integ, 1e-3, rtol) for fid in ("linear", "full") for integ in ("auto", "rk4", "etd2", "etd4")
      for rtol in RTOLS],
    *[("precession", integ, 1e-3, rtol) for integ in ("rk4", "etd2") for rtol in (1e-4, 1e-8)],
    *[("full", integ, 1e-3, rtol) for integ in ("exprb", "implicit_midpoint", "dop853") for rtol in (1e-6, 1e-9)],
]
#: integrators without a compiled batch path, and the naive baseline, run the first 60 s of a
#: scene (their cost per simulated second is what is compared; their error is measured over
#: the same window)
SLOW = {"implicit_midpoint", "dop853", "exprb"}
#: the reference: full model, RK4 held to rtol 1e-12 with steps ≤ 0.25 ms (checked against dop853)
REF = ("full", "rk4", 2.5e-4, 1e-12)


def accuracy(out_dir: Path, quick: bool = False, repeats: int = 3) -> list[dict]:
    scenes = [ship_scene(60.0 if quick else 600.0), aircraft_scene(30.0 if quick else 120.0)]
    rows: list[dict] = []
    for sc in scenes:
        print(f"\n== {sc.name}: {sc.description}", flush=True)
        big = 1 << 20                      # the reference must not refuse: an ample step budget
        g_ref, d_ref, c_ref, _ = run_config(sc, REF[0], REF[1], REF[2], rtol=REF[3], atol=REF[3] * 1e-3,
                                            max_substeps=big)
        g_chk, d_chk, _, _ = run_config(sc, "full", "dop853", REF[2], rtol=REF[3], atol=REF[3] * 1e-3,
                                        max_substeps=big, duration=min(10.0, sc.t[-1]))
        ref_err = errors(g_chk, d_chk, g_ref, d_ref)["max"]
        print(f"   reference: full, rk4 rtol 1e-12, steps ≤ 0.25 ms ({1 / c_ref:.0f}× real time); "
              f"its disagreement with dop853 at the same tolerance (first 10 s): {ref_err:.2e} rad", flush=True)
        slow_window = min(20.0 if quick else 60.0, sc.t[-1])
        base_rows = []
        for rtol, atol, label in ((1e-3, 1e-6, "default tol"), (1e-10, 1e-13, "tight tol")):
            gq, dq, cpu, sim_s, nfev = naive_baseline(sc, rtol, atol, duration=slow_window)
            e = errors(gq, dq, g_ref, d_ref)
            base_rows.append(dict(scene=sc.name, fidelity="full", integrator=f"solve_ivp RK45 ({label})",
                                  step_or_tol=f"rtol {rtol:g}", simulated_s=sim_s, cpu_per_sim_s=cpu,
                                  rtf=1 / cpu, **e, baseline=True))
            print(f"   naive solve_ivp {label:11s}: {cpu:9.3e} CPU s/sim s, max err {e['max']:.2e} "
                  f"({nfev} rhs)", flush=True)
        base_cpu = base_rows[0]["cpu_per_sim_s"]
        rows.extend(base_rows)
        for fid, integ, h, rtol in CONFIGS:
            win = slow_window if integ in SLOW else None
            try:
                g, d, cpu, sim_s = run_config(sc, fid, integ, h, rtol=rtol, atol=rtol * 1e-3,
                                              repeats=1 if integ in SLOW else repeats, duration=win)
            except Exception as ex:   # an unstable configuration is a result too
                print(f"   {fid:10s} {integ:17s} rtol {rtol:g}: FAILED ({type(ex).__name__}: {ex})")
                rows.append({"scene": sc.name, "fidelity": fid, "integrator": integ,
                             "step_or_tol": f"rtol {rtol:g}", "failed": str(ex)[:80]})
                continue
            e = errors(g, d, g_ref, d_ref)
            label = f"rtol {rtol:g}"
            row = dict(scene=sc.name, fidelity=fid, integrator=integ, step_or_tol=label, simulated_s=sim_s,
                       cpu_per_sim_s=cpu, rtf=1 / cpu, speedup_vs_naive=base_cpu / cpu, **e)
            rows.append(row)
            print(f"   {fid:10s} {integ:17s} {label:11s}: {cpu:9.3e} CPU s/sim s  RTF {1 / cpu:8.0f}  "
                  f"×{base_cpu / cpu:7.0f} vs naive  max err {e['max']:.2e} rad", flush=True)
    write_outputs(rows, out_dir)
    return rows


def cheapest(rows: list[dict], scene: str, thr: float):
    ok = [r for r in rows if r.get("scene") == scene and "failed" not in r and r["max"] <= thr]
    return min(ok, key=lambda r: r["cpu_per_sim_s"]) if ok else None


def write_outputs(rows: list[dict], out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    keys = ["scene", "fidelity", "integrator", "step_or_tol", "simulated_s", "cpu_per_sim_s", "rtf",
            "speedup_vs_naive", "gimbal_end", "gimbal_max", "drift_end", "drift_max", "max", "failed"]
    with open(out_dir / "accuracy.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
    lines = ["| scene | fidelity | integrator | step / tol | sim s | CPU s per sim s | real-time × | × naive | "
             "max err gimbal (rad) | max err drift (rad) |", "|" + "---|" * 10]
    for r in rows:
        if "failed" in r:
            lines.append(
                f"| {r['scene']} | {r['fidelity']} | {r['integrator']} | {r['step_or_tol']} | | failed | | | | |"
            )
            continue
        sp = r.get("speedup_vs_naive")
        lines.append(f"| {r['scene']} | {r['fidelity']} | {r['integrator']} | {r['step_or_tol']} | "
                     f"{r['simulated_s']:.0f} | {r['cpu_per_sim_s']:.2e} | {r['rtf']:.3g} | "
                     f"{'' if sp is None else f'{sp:.0f}'} | {r['gimbal_max']:.1e} | {r['drift_max']:.1e} |")
    lines.append("")
    for sc in sorted({r["scene"] for r in rows}):
        for thr in THRESHOLDS:
            c = cheapest(rows, sc, thr)
            lines.append(f"- {sc}: cheapest reaching {thr:g} rad: " + (
                "none" if c is None else f"{c['fidelity']} + {c['integrator']} at {c['step_or_tol']} "
                f"({c['cpu_per_sim_s']:.2e} CPU s per sim s, {c['rtf']:.0f}× real time, error {c['max']:.1e} rad)"))
    (out_dir / "accuracy.md").write_text("\n".join(lines) + "\n")
    write_json(out_dir / "accuracy.json", rows, indent=1)
    print("\n" + "\n".join(lines[-2 * len(THRESHOLDS):]))
    plot(rows, out_dir / "accuracy.png")
    print(f"\nwrote {out_dir / 'accuracy.csv'}, {out_dir / 'accuracy.md'}, {out_dir / 'accuracy.png'}")


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(6.5 * len(scenes), 4.8), squeeze=False)
    colors = {"full": "tab:blue", "linear": "tab:orange", "precession": "tab:green"}
    markers = {"auto": "*", "rk4": "o", "etd2": "s", "etd4": "D", "exprb": "P", "implicit_midpoint": "^",
               "dop853": "v"}
    for ax, sc in zip(axes[0], scenes):
        for r in rows:
            if r["scene"] != sc or "failed" in r:
                continue
            err = max(r["max"], 1e-16)
            if r.get("baseline"):
                ax.scatter(r["cpu_per_sim_s"], err, marker="X", s=90, c="k")
                ax.annotate(r["integrator"].replace("solve_ivp ", ""), (r["cpu_per_sim_s"], err), fontsize=7)
                continue
            ax.scatter(r["cpu_per_sim_s"], err, c=colors.get(r["fidelity"], "k"),
                       marker=markers.get(r["integrator"], "o"), s=40, alpha=0.85)
        for thr in THRESHOLDS:
            ax.axhline(thr, color="0.7", lw=0.8, ls="--")
        ax.axvline(1e-3, color="tab:red", lw=0.8, ls=":")
        ax.text(1.1e-3, 0.03, "1000× real time", color="tab:red", fontsize=7, rotation=90, va="bottom",
                transform=ax.get_xaxis_transform())
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU seconds per simulated second")
        ax.set_ylabel("max error vs full reference [rad]")
        ax.set_title(sc)
    handles = [plt.Line2D([], [], ls="", marker="o", c=c, label=f) for f, c in colors.items()]
    handles += [plt.Line2D([], [], ls="", marker=m, c="0.4", label=i) for i, m in markers.items()]
    handles += [plt.Line2D([], [], ls="", marker="X", c="k", label="naive solve_ivp")]
    axes[0][-1].legend(handles=handles, fontsize=7, loc="center right")
    fig.suptitle("gyro_platform: what accuracy costs in time (1 kHz vehicle input)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


__all__ = ["accuracy", "run_config", "naive_baseline", "errors", "cheapest", "write_outputs", "plot", "CONFIGS",
           "RTOLS", "REF", "SLOW", "THRESHOLDS", "OUT_EVERY"]


if __name__ == "__main__":
    accuracy(Path("results/bench"), quick=True, repeats=1)
