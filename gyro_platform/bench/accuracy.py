"""Benchmarks: what accuracy costs in time.

``gyro-platform bench accuracy`` — work-precision study: every fidelity × integrator × asked
tolerance (rtol 1e-4 … 1e-10, steps ≤ 1 ms) on
two standard scenes (a ship rolling and pitching, stabilised, 10 min; an aircraft manoeuvre with
coordinated turns and rate steps, 2 min; vehicle rates at 1 kHz), each compared with a
``full``-fidelity reference (RK4 held to rtol 1e-12, steps ≤ 0.25 ms; gimbal angles and drift angle, end and maximum over
time), timed in CPU seconds per simulated second (median of repeats), as a real-time factor and
as a speed ratio to the naive baseline a Python user would write (``scipy.integrate.solve_ivp``
on the ``full`` model over the whole run, input interpolated with ``np.interp``). Writes CSV,
Markdown and a PNG plot, and names the cheapest configuration that reaches 1e-3, 1e-6 and
1e-9 rad.

``gyro-platform bench hard`` — the hard-case catalogue (``hardcases``): every method asked for
rtol 1e-9 / atol 1e-12, error against DOP853 at rtol 1e-12, CPU s per simulated s, verdict
(ok / refused / WRONG); exit code 1 if any cell is WRONG.

``gyro-platform bench effects`` — the cost of each effect (CPU µs per sample with the effect
on versus off): what is off costs nothing.

Timing is CPU time (``time.process_time``) of this process; the machine is shared, so medians
are quoted. Nothing here asserts speed: tests assert physics, benchmarks measure time.
"""
from __future__ import annotations

import csv
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scenes.motions import CoordinatedTurn, RateSteps, Sine, Sinusoidal
from ..physics.options import DEFAULT_EFFECTS, ModelOptions
from ..physics.params import NAV1
from ..engine.simulator import Simulator

SAMPLE_RATE = 1000.0     # Hz, vehicle input
OUT_EVERY = 100          # compare at 10 Hz
THRESHOLDS = (1e-3, 1e-6, 1e-9)


# ---------------------------------------------------------------------------------------------
# scenes

@dataclass
class BenchScene:
    name: str
    description: str
    t: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    effects: frozenset


def ship_scene(duration: float = 600.0) -> BenchScene:
    """Ship rolling and pitching, 10° at 0.1 Hz (pitch 5° at 0.1 Hz, quarter period later)."""
    m = Sinusoidal(roll=Sine(math.radians(10.0), 0.1, 0.0), pitch=Sine(math.radians(5.0), 0.1, math.pi / 2))
    t, w, f = m.arrays(duration, SAMPLE_RATE)
    eff = DEFAULT_EFFECTS["stabilised"] | {"mass_unbalance"}
    return BenchScene("ship", f"ship rolling 10° / pitching 5° at 0.1 Hz, stabilised, {duration:g} s", t, w, f, eff)


def aircraft_scene(duration: float = 120.0) -> BenchScene:
    """Aircraft: right coordinated turn (60 m/s, 30° bank), then yaw/roll rate steps."""
    half = duration / 2
    turn = CoordinatedTurn(speed=60.0, bank=math.radians(30.0), roll_time=3.0, start=2.0, hold=half - 10.0)
    t1, w1, f1 = turn.arrays(half, SAMPLE_RATE)
    steps = RateSteps(times=[0.0, 5.0, 10.0, 15.0, 25.0, 35.0, 45.0],
                      rates=[[0, 0, 0], [0.5, 0, 0], [0, 0, 0], [0, 0, 0.3], [0, 0, 0], [0, 0.2, 0], [0, 0, 0]])
    t2, w2, f2 = steps.arrays(half, SAMPLE_RATE)
    t = np.concatenate([t1, t2[1:] + t1[-1]])
    w = np.vstack([w1, w2[1:]])
    f = np.vstack([f1, f2[1:]])
    eff = DEFAULT_EFFECTS["stabilised"] | {"mass_unbalance"}
    return BenchScene("aircraft", f"aircraft: coordinated turn then rate steps, stabilised, {duration:g} s",
                      t, w, f, eff)


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
                rows.append(dict(scene=sc.name, fidelity=fid, integrator=integ,
                                 step_or_tol=f"rtol {rtol:g}", failed=str(ex)[:80]))
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
            lines.append(f"| {r['scene']} | {r['fidelity']} | {r['integrator']} | {r['step_or_tol']} | | failed | | | | |")
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
    (out_dir / "accuracy.json").write_text(json.dumps(rows, indent=1, default=float))
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


# ---------------------------------------------------------------------------------------------
# effects cost

def effects_cost(out_dir: Path, repeats: int = 5) -> list[dict]:
    """CPU µs per sample (compiled batch, 1 kHz, 20 s ship motion) with each effect on alone
    on top of the minimum (rotor gyroscopic + servo), per fidelity."""
    sc = ship_scene(20.0)
    from ..physics.options import EFFECTS
    rows = []
    base = {"rotor_gyroscopic", "servo"}
    for fid in ("full", "linear"):
        for extra in [None] + sorted(set(EFFECTS) - base - {"vehicle_angular_acceleration"}):
            eff = frozenset(base | ({extra} if extra else set()))
            opt = ModelOptions.make("stabilised", fid, eff, integrator="rk4", max_step=1e-3)
            ts = []
            for _ in range(repeats):
                sim = Simulator(NAV1, opt)
                sim.push_many(sc.t[:2], sc.omega[:2], sc.force[:2])
                t0 = time.process_time()
                sim.push_many(sc.t[2:], sc.omega[2:], sc.force[2:])
                ts.append((time.process_time() - t0) / (len(sc.t) - 2) * 1e6)
            rows.append({"fidelity": fid, "effect": extra or "(minimum)", "us_per_sample": float(np.median(ts))})
            print(f"{fid:7s} {extra or '(minimum)':30s} {np.median(ts):6.2f} µs/sample", flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "effects.json").write_text(json.dumps(rows, indent=1))
    return rows


def hotpath(repeats: int = 5) -> dict:
    """µs per sample: Python ``push`` (what the ROS node does per message) and compiled
    ``push_many``, stabilised default effects, 1 kHz."""
    sc = ship_scene(10.0)
    res = {}
    for fid, integ in (("full", "etd2"), ("linear", "etd2"), ("linear", "rk4"), ("full", "rk4")):
        opt = ModelOptions.make("stabilised", fid, DEFAULT_EFFECTS["stabilised"], integrator=integ, max_step=1e-3)
        from ..engine.inputs import RateSample
        tp, tb = [], []
        for _ in range(repeats):
            sim = Simulator(NAV1, opt)
            sim.push_many(sc.t[:3], sc.omega[:3])
            t0 = time.process_time()
            for i in range(3, 2003):
                sim.push(RateSample(float(sc.t[i]), sc.omega[i]))
            tp.append((time.process_time() - t0) / 2000 * 1e6)
            sim = Simulator(NAV1, opt)
            sim.push_many(sc.t[:3], sc.omega[:3])
            t0 = time.process_time()
            sim.push_many(sc.t[3:], sc.omega[3:])
            tb.append((time.process_time() - t0) / (len(sc.t) - 3) * 1e6)
        res[f"{fid}+{integ}"] = {"push_us": float(np.median(tp)), "batch_us": float(np.median(tb))}
        print(f"{fid:7s} {integ:5s}  push {np.median(tp):7.2f} µs/sample   batch {np.median(tb):6.2f} µs/sample "
              f"(real time ×{1e3 / np.median(tb):.0f} at 1 kHz)", flush=True)
    return res


# ---------------------------------------------------------------------------------------------
# CLI

def add_arguments(p) -> None:
    p.add_argument("what", choices=["accuracy", "effects", "hotpath", "hard"], help="which benchmark")
    p.add_argument("--out", default="results/bench", help="output folder (default results/bench)")
    p.add_argument("--quick", action="store_true",
                   help="short scenes (accuracy: 60 s ship, 30 s aircraft; hard: the tests' durations)")
    p.add_argument("--case", action="append", default=None, help="hard: only this case (repeatable)")
    p.add_argument("--repeats", type=int, default=3, help="timing repeats (median quoted)")


def run(args) -> int:
    out = Path(args.out)
    if args.what == "accuracy":
        accuracy(out, quick=args.quick, repeats=args.repeats)
    elif args.what == "hard":
        rows = hard(out, quick=args.quick, cases=args.case)
        return 1 if any(r["verdict"] == "WRONG" for r in rows) else 0
    elif args.what == "effects":
        effects_cost(out, repeats=args.repeats)
    else:
        res = hotpath(repeats=args.repeats)
        out.mkdir(parents=True, exist_ok=True)
        (out / "hotpath.json").write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(run(__import__("argparse").Namespace(what="accuracy", out="results/bench", quick=True, repeats=1)))


# ---------------------------------------------------------------------------------------------
# hard cases: every method asked for the same tolerance, verdict against a tight reference

def hard(out_dir: Path, quick: bool = False, cases: list[str] | None = None) -> list[dict]:
    """Case × method table (``hardcases``): error against the reference, CPU s per simulated s,
    verdict (ok / refused / WRONG). ``quick``: the tests' durations (the hour: 60 s)."""
    from ..engine.hardcases import ASK, CASES, OK_RAD, run_case, run_reference, verdict
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
            row = dict(case=case.name, method=m, integrator=res.stats.get("integrator", m), duration=dur,
                       error=err, cpu_per_sim_s=cpu, verdict=v,
                       error_estimate=res.stats.get("max_error_estimate", math.nan),
                       steps_per_sample=res.stats.get("n_steps", 0) / max(res.stats.get("n_samples", 1), 1),
                       refused=(res.refused or "")[:160])
            rows.append(row)
            print(f"   {m:18s} {v:8s} error {err:9.2e} rad  {cpu:9.3g} CPU s/sim s  "
                  f"{row['steps_per_sample']:7.1f} steps/sample  {row['refused'][:90]}", flush=True)
    _write_hard(rows, out_dir, OK_RAD, ASK)
    return rows


def _write_hard(rows: list[dict], out_dir: Path, ok_rad: float, ask) -> None:
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
    _plot_hard(rows, cases, methods, out_dir / "hard.png", ok_rad)
    print(f"\nwrote {out_dir / 'hard.csv'}, {out_dir / 'hard.md'}, {out_dir / 'hard.png'}")


def _plot_hard(rows, cases, methods, path: Path, ok_rad: float) -> None:
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
