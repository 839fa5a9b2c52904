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

"""Peer comparison: the same carried platform in MuJoCo, at equal accuracy (``gyro-platform bench peer``).

The model (:func:`mjcf`): the platform is a body on a ball joint whose motion is prescribed
(an isotropic inertia ``BASE_INERTIA`` = 1e9 kg m², driven over each input interval by the
constant torque that takes its body rate linearly to the next sample's rate: the
piecewise-linear vehicle rate gyro_platform interpolates; the gyros' reaction, ≲ 1e-2 N m,
moves it by ≲ 1e-11 rad/s² ); under it the two gyro units of spec 1
with the NAV-1 inertias of :class:`~gyro_platform.physics.params.PlatformParams` (frame 4 on
+2, housings 5 and 7 on +3 and −3, frame 9 on +3, housing 10 on +1) and three rotor bodies on
hinges (spin +1, −1, +2) held at the NAV-1 speed by velocity actuators (``ROTOR_KV``: a
1 ms speed loop; the ideal speed control of the spec to ~1e-7 of L). No gravity, mass centres
on the joint axes (rotational dynamics only), gimbals free: gyro_platform's ``carried`` mode
with its default effects (rotor gyroscopic, Coriolis, vehicle angular acceleration),
``full`` fidelity. Initial gimbal rates: the consistent start of free gyros (spec 4.7).

The comparison (:func:`peer`): the benchmark's ship motion (:func:`~.bench_scenes.ship_scene`,
1 kHz) drives both. Each is compared with its own tight reference (gyro_platform: RK4 at rtol
1e-12, steps ≤ 0.25 ms; MuJoCo: RK4 at 1/64 ms) on the five gimbal angles at 10 Hz (max over
time and angles); the two references are compared with each other (the models agree). For
each error level (gyro_platform's error at its default tolerance, and fixed levels) the
cheapest configuration of each that reaches it is taken (gyro_platform: asked tolerance;
MuJoCo: RK4 or implicitfast with the timestep refined, 1 ms / k), and CPU seconds per
simulated second are compared: MuJoCo / kernel (``Simulator.push_many``) and MuJoCo /
consumer (the replay loop on a bag of the same motion: reading, gate, outputs, writing).
MuJoCo steps in C (``mujoco.rollout``, the base torques and rotor set points as open-loop controls).
Needs ``pip install '.[bench]'`` (mujoco); without it the benchmark says so and is skipped.
"""
from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time
from typing import Any

import numpy as np

from .bags import BAG_VERSION, cache_dir, VehicleImu, write_imu_bag
from .bench_scenes import BenchScene, SAMPLE_RATE, ship_scene
from ..physics.options import DEFAULT_EFFECTS, ModelOptions
from ..physics.params import NAV1, PlatformParams
from ..reports.jsonio import write_json
from ..scenes.motions import RateSteps

__all__ = ["mjcf", "MujocoPlatform", "gyro_run", "mujoco_run", "peer", "GIMBALS", "BASE_INERTIA", "ROTOR_KV",
           "carried_options", "available", "steps_scene", "compare_scene"]

GIMBALS = ("alpha4", "beta5", "beta7", "alpha9", "beta10")
BASE_INERTIA = 1.0e9      # kg m², the prescribed-motion base
ROTOR_KV = 0.02           # N m s/rad, rotor speed loop gain (time constant C / kv = 1 ms)
OUT_EVERY = 100           # compare at 10 Hz
#: asked tolerances of the gyro_platform sweep (atol = rtol·1e-3); 1e-6 is the default
GYRO_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
#: MuJoCo timesteps 1 ms / k (a whole number of steps per input sample)
#: (implicitfast and Euler leave out the gyroscopic velocity derivatives and blow up at these steps)
MJ_SUBSTEPS = {"RK4": (1, 2, 3, 4, 6, 8, 12, 16, 24, 32), "implicit": (1, 2, 4, 8, 16, 32)}
FIXED_LEVELS = (1e-6, 1e-8)   # rad


def available() -> str:
    """The empty string if mujoco can be imported, else why not."""
    try:
        import mujoco  # noqa: F401
    except ImportError as e:
        return f"mujoco is not installed ({e}); pip install '.[bench]'"
    return ""


def carried_options(rtol: float = 1e-6, atol: float | None = None, max_step: float = 1e-3,
                    integrator: str = "auto", max_substeps: int = 4096) -> ModelOptions:
    """gyro_platform's side of the comparison: carried, full fidelity, default carried effects."""
    return ModelOptions.make("carried", "full", DEFAULT_EFFECTS["carried"], integrator=integrator,
                             max_step=max_step, rtol=rtol, atol=rtol * 1e-3 if atol is None else atol,
                             max_substeps=max_substeps)


# ---------------------------------------------------------------------------------------------
# the MuJoCo model

def _body(name: str, joint: str, axis: str, inertia, inner: str = "") -> str:
    a, b, c = (f"{x:.17g}" for x in inertia)
    return (f'<body name="{name}"><joint name="{joint}" type="hinge" axis="{axis}"/>'
            f'<inertial pos="0 0 0" mass="0.1" diaginertia="{a} {b} {c}"/>{inner}</body>')


def mjcf(p: PlatformParams = NAV1, timestep: float = 1e-3, integrator: str = "RK4") -> str:
    """MJCF of the carried platform with the inertias and rotor speeds of ``p`` (SI units)."""
    C, A = p.rotor_C, p.rotor_A
    rotor6 = _body("rotor6", "rotor6", "1 0 0", (C[0], A[0], A[0]))
    rotor8 = _body("rotor8", "rotor8", "-1 0 0", (C[1], A[1], A[1]))
    rotor11 = _body("rotor11", "rotor11", "0 1 0", (A[2], C[2], A[2]))
    unit_a = _body("frame4", "alpha4", "0 1 0", p.frame4,
                   _body("housing5", "beta5", "0 0 1", p.housing5, rotor6)
                   + _body("housing7", "beta7", "0 0 -1", p.housing7, rotor8))
    unit_b = _body("frame9", "alpha9", "0 0 1", p.frame9, _body("housing10", "beta10", "1 0 0", p.housing10, rotor11))
    ib = f"{BASE_INERTIA:.17g}"
    motors = "".join(f'<velocity name="spin{r}" joint="rotor{r}" kv="{ROTOR_KV:.17g}"/>' for r in (6, 8, 11))
    return f"""<mujoco model="gyro_platform_carried">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="{timestep:.17g}" integrator="{integrator}" gravity="0 0 0">
    <flag contact="disable" gravity="disable"/>
  </option>
  <worldbody>
    <body name="platform"><joint name="base" type="ball"/>
      <inertial pos="0 0 0" mass="1" diaginertia="{ib} {ib} {ib}"/>
      {unit_a}
      {unit_b}
    </body>
  </worldbody>
  <actuator>{motors}</actuator>
</mujoco>
"""


@dataclass
class MujocoPlatform:
    """A compiled model and its data, with the addresses the driver needs."""

    model: Any
    data: Any
    qpos_gimbal: np.ndarray     # qpos addresses of alpha4 … beta10
    dof_gimbal: np.ndarray      # qvel addresses of alpha4 … beta10
    dof_rotor: np.ndarray       # qvel addresses of rotor 6, 8, 11
    substeps: int               # MuJoCo steps per input sample

    @staticmethod
    def build(p: PlatformParams = NAV1, sample_dt: float = 1.0 / SAMPLE_RATE, substeps: int = 1,
              integrator: str = "RK4") -> "MujocoPlatform":
        import mujoco

        m = mujoco.MjModel.from_xml_string(mjcf(p, sample_dt / substeps, integrator))
        d = mujoco.MjData(m)
        jid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in GIMBALS]
        rid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"rotor{r}") for r in (6, 8, 11)]
        mp = MujocoPlatform(m, d, m.jnt_qposadr[jid].copy(), m.jnt_dofadr[jid].copy(), m.jnt_dofadr[rid].copy(),
                            substeps)
        d.ctrl[:] = p.rotor_speed
        return mp


def mujoco_run(t: np.ndarray, omega: np.ndarray, p: PlatformParams = NAV1, substeps: int = 1,
               integrator: str = "RK4", out_every: int = OUT_EVERY) -> tuple[np.ndarray, np.ndarray, float]:
    """Drive the MuJoCo platform with body rates ``omega`` (N, 3; rad/s, platform axes) at
    uniformly spaced times ``t`` (s). Returns (output times (K,), gimbal angles (K, 5) rad,
    CPU s) with outputs at samples 0, out_every, 2·out_every, … (NaN from where MuJoCo found
    the run unstable). Stepping in C (``mujoco.rollout``, one call per output interval); the
    base torque per sample interval, ``BASE_INERTIA · Δω / Δt``, and the rotor speed set points
    are its open-loop controls (CPU time includes building them)."""
    import mujoco
    from mujoco import rollout

    dt = float(t[1] - t[0])
    mp = MujocoPlatform.build(p, dt, substeps, integrator)
    m, d = mp.model, mp.data
    d.qvel[0:3] = omega[0]
    d.qvel[mp.dof_rotor] = p.rotor_speed
    w0 = omega[0]
    d.qvel[mp.dof_gimbal] = [-w0[1], -w0[2], w0[2], -w0[2], -w0[0]]   # free gyros at rest inertially
    mujoco.mj_forward(m, d)
    sig = mujoco.mjtState.mjSTATE_FULLPHYSICS               # [time, qpos, qvel, act, …]
    spec = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED
    state = np.empty(mujoco.mj_stateSize(m, sig))
    mujoco.mj_getState(m, d, state, sig)
    n = len(t)
    keep = np.arange(0, n, out_every)
    q = np.full((keep.size, 5), np.nan)
    q[0] = d.qpos[mp.qpos_gimbal]
    qa = 1 + mp.qpos_gimbal
    bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
    c0 = time.process_time()
    ctrl = np.zeros((n - 1, m.nu + m.nv))
    ctrl[:, :m.nu] = p.rotor_speed
    ctrl[:, m.nu:m.nu + 3] = BASE_INERTIA * np.diff(omega, axis=0) / dt     # base: ω linear over each interval
    ctrl = np.repeat(ctrl, substeps, axis=0)
    for j in range(1, keep.size):
        st, _ = rollout.rollout(m, d, state, ctrl[keep[j - 1] * substeps:keep[j] * substeps], control_spec=spec)
        state = st[0, -1]
        if d.warning[bad].number or not np.all(np.isfinite(state)):
            break                                   # MuJoCo reset the state: the run is lost
        q[j] = state[qa]
    cpu = time.process_time() - c0
    return t[keep], q, cpu


def gyro_run(t: np.ndarray, omega: np.ndarray, options: ModelOptions, p: PlatformParams = NAV1,
             out_every: int = OUT_EVERY) -> tuple[np.ndarray, np.ndarray, float]:
    """gyro_platform's compiled batch (``push_many``) on the same input: (output times,
    gimbal angles (K, 5) rad, CPU s) with outputs at the same samples as :func:`mujoco_run`."""
    from ..engine.simulator import Simulator

    warm = Simulator(p, options)
    warm.push_many(t[:3], omega[:3])
    sim = Simulator(p, options)
    c0 = time.process_time()
    outs = sim.push_many(t, omega, output_every=out_every)      # a fresh simulator: samples 0, k, 2k, …
    cpu = time.process_time() - c0
    return np.array([o.t for o in outs]), np.array([o.gimbal_angles for o in outs]), cpu


def _max_err(ta, qa, tb, qb) -> float:
    """Max |Δ angle| over the instants both have (matched to 1 µs)."""
    ia = {round(x * 1e6): i for i, x in enumerate(ta)}
    pairs = [(ia[round(x * 1e6)], j) for j, x in enumerate(tb) if round(x * 1e6) in ia]
    a = np.array([qa[i] for i, _ in pairs])
    b = np.array([qb[j] for _, j in pairs])
    return float(np.max(np.abs(a - b))) if pairs else float("nan")


# ---------------------------------------------------------------------------------------------
# the comparison

def _consumer_cpu(sc: BenchScene, rtol: float) -> float:
    """CPU s per simulated s of the replay loop (bag in, gate, compiled engine, outputs at
    10 Hz, bag out) at tolerance ``rtol`` on a cached bag of the motion."""
    from ..replay.loop import replay, ReplayConfig

    bag = cache_dir() / f"peer_{sc.name}_v{BAG_VERSION}_{sc.t[-1]:g}s_mcap"
    if not (bag / "metadata.yaml").is_file():
        shutil.rmtree(bag, ignore_errors=True)
        write_imu_bag(bag, VehicleImu(sc.t, sc.omega, sc.force), "mcap")
    work = Path(tempfile.mkdtemp(prefix="gyro_bench_peer_"))
    try:
        cfg = ReplayConfig(options=carried_options(rtol), output_rate=SAMPLE_RATE / OUT_EVERY, plot=False,
                           progress=False)
        c0 = time.process_time()
        s = replay(bag, work / "out", cfg)
        return (time.process_time() - c0) / s["duration_s"]
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _cheapest(rows: list[dict], who: str, level: float) -> dict | None:
    ok = [r for r in rows if r["who"] == who and r["error"] <= level]
    return min(ok, key=lambda r: r["cpu_per_sim_s"]) if ok else None


def steps_scene(duration: float = 10.0) -> BenchScene:
    """Small body-rate steps (≤ 0.05 rad/s, ideal steps: ramps over one 1 ms sample): each
    excites the gyros' nutation (≈ 90 Hz), which the integrators must then carry."""
    f = duration / 10.0
    m = RateSteps(times=[0.5 * f, 2.5 * f, 4.5 * f, 6.5 * f, 8.5 * f],
                  rates=[[0.05, 0, 0], [0, 0, 0.05], [0, -0.05, 0.03], [0.02, 0.02, -0.02], [0, 0, 0]])
    t, w, fo = m.arrays(duration, SAMPLE_RATE)
    return BenchScene("steps", f"rate steps ≤ 0.05 rad/s (nutation excited), {duration:g} s", t, w, fo,
                      DEFAULT_EFFECTS["carried"])


def compare_scene(sc: BenchScene, repeats: int) -> dict:
    """The work-precision rows of both simulators on one scene and the equal-accuracy comparison."""
    t, w = sc.t, sc.omega
    sim_s = float(t[-1] - t[0])
    print(f"\n  scene {sc.name}: {sc.description}", flush=True)
    tg, gref, _ = gyro_run(t, w, carried_options(1e-12, 1e-15, max_step=2.5e-4, integrator="rk4",
                                                 max_substeps=1 << 20))
    tm, mref, _ = mujoco_run(t, w, substeps=64)
    agree = _max_err(tg, gref, tm, mref)
    swing = float(np.max(np.abs(gref)))
    print(f"    references: gyro_platform rk4 rtol 1e-12 vs MuJoCo RK4 1/64 ms: max |Δ| {agree:.2e} rad "
          f"(gimbal angles up to {swing:.3f} rad)", flush=True)
    rows: list[dict] = []
    for rtol in GYRO_RTOLS:
        runs = [gyro_run(t, w, carried_options(rtol)) for _ in range(repeats)]
        err = _max_err(tg, gref, runs[0][0], runs[0][1])
        rows.append({"who": "gyro_platform", "config": f"auto rtol {rtol:g}", "rtol": rtol, "error": err,
                     "cpu_per_sim_s": float(np.median([r[2] for r in runs])) / sim_s})
        print(f"    gyro_platform auto rtol {rtol:7.0e}: error {err:.2e} rad, "
              f"{rows[-1]['cpu_per_sim_s']:.3e} CPU s/sim s", flush=True)
    for integ, ks in MJ_SUBSTEPS.items():
        for k in ks:
            runs = [mujoco_run(t, w, substeps=k, integrator=integ) for _ in range(repeats)]
            err = _max_err(tm, mref, runs[0][0], runs[0][1])
            stable = np.all(np.isfinite(runs[0][1]))
            rows.append({"who": "MuJoCo", "config": f"{integ} h = 1/{k} ms", "error": err if stable else float("inf"),
                         "cpu_per_sim_s": float(np.median([r[2] for r in runs])) / sim_s})
            print(f"    MuJoCo {integ:8s} h = 1/{k:<3d} ms: " + (f"error {err:.2e} rad" if stable else "unstable")
                  + f", {rows[-1]['cpu_per_sim_s']:.3e} CPU s/sim s", flush=True)
            if stable and err < min(FIXED_LEVELS) * 1e-2:
                break                 # finer steps only cost more
    default = next(r for r in rows if r["who"] == "gyro_platform" and r["rtol"] == 1e-6)
    levels = [("gyro_platform's error at its default tolerance", max(default["error"], 1e-15))]
    levels += [(f"fixed level {lv:g} rad", lv) for lv in FIXED_LEVELS]
    comp = []
    for label, lv in levels:
        g, mj = _cheapest(rows, "gyro_platform", lv), _cheapest(rows, "MuJoCo", lv)
        c = {"level": label, "error_level": lv, "gyro": g, "mujoco": mj}
        if g is not None:
            c["consumer_cpu_per_sim_s"] = float(np.median([_consumer_cpu(sc, g["rtol"]) for _ in range(repeats)]))
        if g is not None and mj is not None:
            c["ratio_kernel"] = mj["cpu_per_sim_s"] / g["cpu_per_sim_s"]
            c["ratio_consumer"] = mj["cpu_per_sim_s"] / c["consumer_cpu_per_sim_s"]
        comp.append(c)
    return {"scene": sc.name, "description": sc.description, "simulated_s": sim_s, "references_agree_rad": agree,
            "max_gimbal_angle_rad": swing, "rows": rows, "comparison": comp}


def peer(out_dir: Path, quick: bool = False, repeats: int = 3, required: bool = False) -> int:
    """Run the comparison; print the table, write ``peer.json``, ``peer.md``, ``peer.png``.
    Exit code: 0; without mujoco 0 with a note (1 if ``required``, i.e. ``bench peer``)."""
    why = available()
    if why:
        print(f"peer comparison skipped: {why}")
        return 1 if required else 0
    duration = 2.0 if quick else 10.0
    print("\npeer comparison: the carried platform in gyro_platform and MuJoCo; gimbal angles at 10 Hz", flush=True)
    ship = ship_scene(duration)
    ship.description = ship.description.replace(", stabilised", "")    # here carried, free gimbals
    scenes = [compare_scene(sc, repeats) for sc in (ship, steps_scene(duration))]
    doc = {"scenes": scenes, "repeats": repeats, "load_avg": os.getloadavg()[0], "python": sys.version.split()[0],
           "mujoco": _mujoco_version()}
    write_outputs(doc, out_dir)
    return 0


def _mujoco_version() -> str:
    import mujoco

    return mujoco.__version__


def table(doc: dict) -> str:
    """Markdown: per scene and error level, the cheapest of each and the ratios."""
    lines = ["| scene | equal accuracy: max gimbal-angle error | gyro_platform config | kernel CPU s / sim s | "
             "consumer (replay) CPU s / sim s | MuJoCo config | MuJoCo CPU s / sim s | MuJoCo / kernel | "
             "MuJoCo / consumer |", "|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for sc in doc["scenes"]:
        for c in sc["comparison"]:
            g, m = c["gyro"], c["mujoco"]
            gtxt = "not reached" if g is None else f"{g['config']} ({g['error']:.1e} rad)"
            mtxt = "not reached" if m is None else f"{m['config']} ({m['error']:.1e} rad)"
            cons = c.get("consumer_cpu_per_sim_s")
            lines.append(
                f"| {sc['scene']} | {c['level']}: {c['error_level']:.1e} rad | {gtxt} "
                f"| {'' if g is None else format(g['cpu_per_sim_s'], '.2e')} "
                f"| {'' if cons is None else format(cons, '.2e')} "
                f"| {mtxt} | {'' if m is None else format(m['cpu_per_sim_s'], '.2e')} "
                f"| {format(c['ratio_kernel'], '.1f') if 'ratio_kernel' in c else ''} "
                f"| {format(c['ratio_consumer'], '.2f') if 'ratio_consumer' in c else ''} |")
        notes.append(f"- {sc['scene']} ({sc['description']}): the references (gyro_platform rk4 rtol 1e-12, MuJoCo "
                     f"RK4 at 1/64 ms) agree to {sc['references_agree_rad']:.1e} rad on gimbal angles up to "
                     f"{sc['max_gimbal_angle_rad']:.3f} rad")
    return "\n".join(lines + [""] + notes) + "\n"


def write_outputs(doc: dict, out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    text = table(doc)
    print("\n" + text, end="")
    write_json(out_dir / "peer.json", doc, indent=1)
    (out_dir / "peer.md").write_text(text)
    plot(doc, out_dir / "peer.png")
    print(f"wrote {out_dir / 'peer.json'}, {out_dir / 'peer.md'}, {out_dir / 'peer.png'}")


def plot(doc: dict, path: Path) -> None:
    """Work-precision diagrams (one per scene): error vs CPU s per simulated s, both simulators."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = doc["scenes"]
    fig, axes = plt.subplots(1, len(scenes), figsize=(6.5 * len(scenes), 5.0), squeeze=False)
    style = {"gyro_platform": ("tab:blue", "o"), "MuJoCo RK4": ("tab:red", "s"), "MuJoCo implicit": ("tab:orange", "^")}
    for ax, sc in zip(axes[0], scenes):
        groups: dict[str, list[dict]] = {}
        for r in sc["rows"]:
            if not np.isfinite(r["error"]):
                continue
            key = r["who"] if r["who"] == "gyro_platform" else f"MuJoCo {r['config'].split()[0]}"
            groups.setdefault(key, []).append(r)
        for key, rs in groups.items():
            c, mk = style.get(key, ("k", "o"))
            ax.plot([r["cpu_per_sim_s"] for r in rs], [max(r["error"], 1e-16) for r in rs], marker=mk, color=c,
                    label=key)
        for comp in sc["comparison"]:
            ax.axhline(comp["error_level"], color="0.7", lw=0.8, ls="--")
            if "consumer_cpu_per_sim_s" in comp:
                ax.scatter([comp["consumer_cpu_per_sim_s"]], [max(comp["gyro"]["error"], 1e-16)], marker="*", s=120,
                           color="tab:green", zorder=5)
        ax.scatter([], [], marker="*", s=120, color="tab:green", label="gyro_platform replay (consumer)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU seconds per simulated second")
        ax.set_ylabel("max gimbal-angle error vs own reference [rad]")
        ax.set_title(f"carried platform, {sc['description']}", fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
