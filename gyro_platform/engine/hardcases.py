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

"""Hard cases as a catalogue: where integrators are tempted to be silently wrong.

Each ``HardCase`` is a short run (1 kHz vehicle input) that ``run_case`` integrates with one
method at one tolerance, returning the final gimbal angles (rad; stabilised: plus the platform
attitude) or the refusal. ``gyro-platform bench hard`` runs every case × method at rtol 1e-9 /
atol 1e-12 against DOP853 at rtol 1e-12 / atol 1e-15 and gives a verdict per cell:

- ``ok``: ends within ``OK_RAD`` (1e-5 rad) of the reference;
- ``refused``: raised ``SimulationError`` (the tolerance cannot be met within the budget, or
  the state went non-finite) with the simulator's state finite and at the last good sample;
- ``WRONG``: neither — the silent failure this catalogue exists to catch.

Tests (``test/test_accuracy_on_request.py``) assert that no cell is ``WRONG`` at the
``test_duration`` of each case; timings are only measured by the benchmark.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import time
from typing import Callable

import numpy as np

from .integrators import fd_jacobian, make_integrator
from .simulator import Simulator
from ..errors import SimulationError
from ..physics.gyro import GimballedGyro, GyroModel
from ..physics.options import DEFAULT_EFFECTS, ModelOptions
from ..physics.params import NAV1, PlatformParams
from ..physics.rotations import matrix_rotvec, quat_matrix

RATE = 1000.0                 # Hz, vehicle input
OK_RAD = 1e-5                 # verdict threshold against the reference (rad)
ASK = (1e-9, 1e-12)           # the tolerance asked of every method (rtol, atol)
REFERENCE = ("dop853", 1e-12, 1e-15)
#: the reference's step budget (it must not refuse: steps down to max_step / 2^22 ≈ 0.2 ns)
REF_SUBSTEPS = 1 << 22
METHODS = ("auto", "rk4", "etd2", "etd4", "exprb", "implicit_midpoint", "rk45", "dop853", "radau")
SPIN = NAV1.rotor_speed[0]
FREE = ("rotor_gyroscopic", "coriolis")          # stabilised with servo and mount friction off


def _spin(factor: float) -> PlatformParams:
    return NAV1.with_(rotor_speed=(SPIN * factor,) * 3)


def _sines(t: np.ndarray) -> np.ndarray:
    """A vehicle turning in all three axes (rad/s)."""
    return np.column_stack([0.3 * np.sin(2.0 * t), 0.2 * np.cos(3.0 * t), 0.1 + 0.05 * np.sin(5.0 * t)])


def _steps_and_shock(t: np.ndarray) -> np.ndarray:
    """Rate steps (2 rad/s roll at 50 ms, −1 rad/s yaw at 120 ms) and a 1 ms 20 rad/s pitch shock."""
    w = np.zeros((len(t), 3))
    w[t >= 0.05, 0] = 2.0
    w[t >= 0.12, 2] = -1.0
    w[(t >= 0.15) & (t < 0.151), 1] = 20.0
    return w


def _ship(t: np.ndarray) -> np.ndarray:
    return np.column_stack([math.radians(10) * 2 * math.pi * 0.1 * np.cos(2 * math.pi * 0.1 * t),
                            math.radians(5) * 2 * math.pi * 0.1 * np.cos(2 * math.pi * 0.1 * t + math.pi / 2),
                            0 * t])


#: engine vibration of a ground vehicle: frequency (Hz) and rate amplitudes (rad/s, x y z; z at twice it)
VIBRATION_HZ = 37.0
VIBRATION_AMP = (0.3, 0.2, 0.1)


def engine_vibration(t: np.ndarray, noise: bool = True, seed: int = 37, scale: float = 1.0,
                     hz: float = VIBRATION_HZ) -> np.ndarray:
    """A 37 Hz engine vibration (rad/s, vehicle axes; ``VIBRATION_AMP``, yaw at 74 Hz), with
    ``noise`` plus the white noise of a MEMS gyro sampled at 1 kHz (0.005 °/s/√Hz: 2.8e-3 rad/s
    RMS per sample): the vehicle rate sweeps through zero ~220 times a second, each time a kink
    of the support friction (:mod:`gyro_platform.physics.switching`). ``scale`` multiplies the
    amplitudes, ``hz`` replaces the frequency (Hz)."""
    w = 2.0 * math.pi * hz
    a0, a1, a2 = (scale * a for a in VIBRATION_AMP)
    v = np.column_stack([a0 * np.sin(w * t), a1 * np.sin(w * t + 1.0), a2 * np.sin(2.0 * w * t + 0.3)])
    if noise:
        v += math.radians(0.005) * math.sqrt(1000.0) * np.random.default_rng(seed).standard_normal((len(t), 3))
    return v


def _vibrating(t: np.ndarray) -> np.ndarray:
    return _sines(t) + engine_vibration(t)


Q_LARGE = (0.2, -0.15, 0.25, 0.1, -0.3)               # rad
QD_LARGE = (0.5, -1.0, 1.5, 2.0, -0.8)                # rad/s
OM_FREE = (0.5, -0.3, 0.2)                            # rad/s, free platform


@dataclass(frozen=True)
class HardCase:
    """One hard case. ``kind``: 'platform' (``Simulator``) or 'gyro' (``gyro.GyroModel``,
    the single gyro with massive gimbals). ``init(y, layout)`` sets the initial state after the
    first sample; ``motion(t)`` gives the vehicle rate (rad/s, vehicle axes)."""

    name: str
    description: str
    #: what happens and what the user is told
    outcome: str
    duration: float                       # s, benchmark
    test_duration: float                  # s, tests
    mode: str = "carried"
    fidelity: str = "full"
    effects: tuple[str, ...] | None = None
    params: PlatformParams = NAV1
    init: Callable | None = None
    motion: Callable = _sines
    kind: str = "platform"
    bench_only: bool = False
    reference: tuple = REFERENCE
    methods: tuple[str, ...] = METHODS
    gyro_state: tuple = ()


def _set_large(y, lay, om=None, qd=QD_LARGE):
    y[lay.q] = Q_LARGE
    if om is not None:
        y[lay.Om] = om
    y[lay.qd] = qd


CASES: list[HardCase] = [
    HardCase("carried_large_angles", "carried, full model, gimbals at 0.1–0.3 rad with rates 0.5–2 rad/s, "
             "vehicle turning", "all methods within tolerance or refuse; exponential methods substep (their "
             "linear part is the rest state)", 0.5, 0.1, init=lambda y, lay: _set_large(y, lay)),
    HardCase("free_platform", "stabilised, servo and mount friction off (free platform), full model, same "
             "large state, platform turning 0.6 rad/s", "within tolerance or refused", 0.3, 0.1, mode="stabilised",
             effects=FREE, init=lambda y, lay: _set_large(y, lay, OM_FREE)),
    HardCase("free_platform_spin10", "free platform as above, rotor spin ×10 (nutation 8e3 rad/s)",
             "RK4 substeps ~10× (or refuses); exponential methods keep one step per sample", 0.3, 0.05,
             mode="stabilised", effects=FREE, params=_spin(10), init=lambda y, lay: _set_large(y, lay, OM_FREE)),
    HardCase("free_platform_spin100", "free platform as above, rotor spin ×100 (nutation 8e4 rad/s)",
             "explicit RK methods pay ×100 in steps or refuse; exprb and etd keep their cost", 0.1, 0.02,
             mode="stabilised", effects=FREE, params=_spin(100), init=lambda y, lay: _set_large(y, lay, OM_FREE)),
    *[HardCase(f"carried_turning_spin{f}", f"carried, full model, from the consistent start, vehicle turning in "
               f"three axes, rotor spin ×{f}", "the cost of a fast rotor: exprb and etd keep their steps (the "
               "gyroscopic part is in their linear part), RK4 must resolve the nutation (h·ω < 2.8)", 0.3, 0.05,
               params=_spin(f), effects=("rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration"))
      for f in (1, 10, 100)],
    HardCase("large_nutation", "carried, torque-free, both units nutating with ~0.04 rad amplitude",
             "within tolerance; T2 conserved (see test)", 0.3, 0.05, effects=FREE, motion=lambda t: 0 * _sines(t),
             init=lambda y, lay: _set_large(y, lay, qd=(30.0, -25.0, 25.0, 30.0, -30.0))),
    HardCase("near_gimbal_lock", "single gyro with massive gimbals (gyro.py), inner ring at 89.9°, ring "
             "rates 2 / −1.5 rad/s", "the massive rings keep the mass matrix regular: every method passes or "
             "refuses; the massless model raises GimbalLockError", 0.2, 0.05, kind="gyro",
             gyro_state=(0.1, math.radians(89.9), 2.0, -1.5, 2513.274)),
    HardCase("rate_steps_shocks", "stabilised default (linear, servo, mount friction): roll step 2 rad/s, "
             "yaw step −1 rad/s, 1 ms pitch shock of 20 rad/s", "friction kinks: methods substep there; "
             "within tolerance or refused", 0.3, 0.2, mode="stabilised", fidelity="linear",
             motion=_steps_and_shock),
    HardCase("vibrating_vehicle", "stabilised default (linear, servo, mount friction), vehicle turning with a "
             "37 Hz engine vibration of 0.3 rad/s and MEMS gyro noise", "the mount friction kinks ~220 times a "
             "second: rk4 (auto) ends its steps at them; within tolerance or refused", 1.0, 0.2,
             mode="stabilised", fidelity="linear", motion=_vibrating),
    HardCase("twin_gyro_symmetric_spin100", "carried, unit A nutating symmetrically (β̇5 = β̇7 + 1e-6) at "
             "spin ×100", "physically unstable: the antisymmetric mode β5 − β7 has no gyroscopic restraint "
             "(spec 7.2) and grows exponentially from the 1e-6 seed while T2 is conserved; methods follow it "
             "within tolerance — the growth is physics, reported by the gimbal angles, not refused", 0.3, 0.05,
             effects=FREE, params=_spin(100), motion=lambda t: 0 * _sines(t),
             init=lambda y, lay: y.__setitem__(lay.qd, (0.0, 30.0 + 1e-6, 30.0, 0.0, 0.0))),
    HardCase("one_hour", "stabilised default, ship rolling 10°/pitching 5° at 0.1 Hz, 1 h at 1 kHz "
             "(3.6e6 samples)", "compiled methods only; reference rk4 at rtol 1e-12", 3600.0, 0.0,
             mode="stabilised", fidelity="linear", motion=_ship, bench_only=True,
             reference=("rk4", 1e-12, 1e-15), methods=("auto", "rk4", "etd2", "etd4")),
]


@dataclass
class CaseResult:
    """Final angles (rad: gimbal angles, stabilised + platform attitude rotation vector), CPU s,
    simulated s; ``refused``: the SimulationError message (None if the run completed);
    ``finite``: the state after the run (or after the refusal) is finite; ``stats``."""

    angles: np.ndarray
    cpu: float
    sim_s: float
    refused: str | None = None
    finite: bool = True
    stats: dict = field(default_factory=dict)
    attitude: np.ndarray | None = None
    vehicle: np.ndarray | None = None


def _platform_run(case: HardCase, method: str, rtol: float, atol: float, duration: float,
                  max_substeps: int) -> CaseResult:
    eff = case.effects if case.effects is not None else DEFAULT_EFFECTS[case.mode]
    opt = ModelOptions(mode=case.mode, fidelity=case.fidelity, effects=frozenset(eff), integrator=method,
                       rtol=rtol, atol=atol, max_substeps=max_substeps)
    t = np.arange(0.0, duration + 0.5 / RATE, 1.0 / RATE)
    w = case.motion(t)
    sim = Simulator(case.params, opt)
    sim.push_many(t[:1], w[:1])
    if case.init is not None:
        case.init(sim.y, sim.layout)
    refused = None
    c0 = time.process_time()
    try:
        sim.push_many(t[1:], w[1:])
    except SimulationError as e:
        refused = str(e)
    cpu = time.process_time() - c0
    lay = sim.layout
    att = sim.y[lay.quat_IP].copy() if lay.quat_IP is not None else None
    return CaseResult(sim.y[lay.q].copy(), cpu, float(sim.t - t[0]), refused, bool(np.all(np.isfinite(sim.y))),
                      sim.stats, att, sim.y[lay.quat_IB].copy())


class _GyroSystem:
    """The gimballed gyro as an ODE system with a linear part (its Jacobian at the initial
    state: what the exponential methods linearise about)."""

    def __init__(self, model: GyroModel, y0: np.ndarray):
        self.model = model
        self.rhs = model.rhs
        self._A = fd_jacobian(model.rhs, 0.0, y0)

    def linear_part(self):
        return self._A, ("gyro", id(self))


def _gyro_run(case: HardCase, method: str, rtol: float, atol: float, duration: float,
              max_substeps: int) -> CaseResult:
    y = np.asarray(case.gyro_state, float)
    system = _GyroSystem(GyroModel(GimballedGyro()), y)
    name = "etd2" if method == "auto" else method      # auto's choice for a fast rotor (no Simulator here)
    integ = make_integrator(name, max_step=1e-3, rtol=rtol, atol=atol, max_substeps=max_substeps)
    n = int(round(duration * RATE))
    refused = None
    t = 0.0
    c0 = time.process_time()
    try:
        for k in range(n):
            y, _ = integ.advance(system, t, y, (k + 1) / RATE)
            t = (k + 1) / RATE
    except SimulationError as e:
        refused = str(e)
    cpu = time.process_time() - c0
    return CaseResult(y[:2].copy(), cpu, t, refused, bool(np.all(np.isfinite(y))), {"integrator": integ.name})


def run_case(case: HardCase, method: str, rtol: float, atol: float, duration: float | None = None,
             max_substeps: int = 4096) -> CaseResult:
    """Run one case with one method at one tolerance (duration: s, default the bench's)."""
    d = case.duration if duration is None else duration
    return (_gyro_run if case.kind == "gyro" else _platform_run)(case, method, rtol, atol, d, max_substeps)


def run_reference(case: HardCase, duration: float | None = None) -> CaseResult:
    """The case's reference run (tight tolerance, ample budget)."""
    name, rtol, atol = case.reference
    return run_case(case, name, rtol, atol, duration, max_substeps=REF_SUBSTEPS)


def angle_error(res: CaseResult, ref: CaseResult) -> float:
    """Largest angle difference (rad): gimbal angles, the platform attitude (stabilised) and the
    vehicle attitude (the mount angles are the two attitudes' difference)."""
    e = float(np.max(np.abs(res.angles - ref.angles)))
    for a, b in ((res.attitude, ref.attitude), (res.vehicle, ref.vehicle)):
        if a is not None and b is not None:
            e = max(e, float(np.linalg.norm(matrix_rotvec(quat_matrix(b).T @ quat_matrix(a)))))
    return e


def verdict(res: CaseResult, ref: CaseResult) -> tuple[str, float]:
    """('ok' | 'refused' | 'WRONG', error in rad (nan if refused))."""
    if res.refused is not None:
        return ("refused" if res.finite else "WRONG"), math.nan
    err = angle_error(res, ref)
    return ("ok" if err <= OK_RAD else "WRONG"), err
