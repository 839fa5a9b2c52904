"""The simulator: input samples in, platform state integrated, outputs on demand.

``push(sample)`` integrates from the previous sample to this one with the input interpolated
linearly between them (one input sample → one ``advance`` of the integrator). ``outputs()``
evaluates gimbal angles, drift and the Newton–Euler bearing torques at the current time — do
that at the output rate, not at every sample. Internally time runs from the first sample
(``t_rel = t − t_start``) so that bag stamps of ~1.7e9 s do not cost precision.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import GimbalLockError, InputError, SimulationError
from .inputs import RateSample
from .integrators import Auto, Integrator, make_integrator
from ..physics.model import spin_momentum
from ..physics.options import NEEDS_SPECIFIC_FORCE, ModelOptions
from .output_kernel import OutputKernel
from .outputs import OutputBlock, Outputs
from .snapshots import Snapshots, first_segment
from ..physics.params import NAV1, PlatformParams
from ..physics.system import PlatformSystem
from ..physics.rotations import quat_matrix, rotvec_matrix
from ..physics.tree import TreeWork, kinematics, mass_matrix

#: ``integrator: auto`` (see ``auto_primary``): RK4 where the fastest mode λ is resolved at the
#: step (h·λ < AUTO_RK4_LIMIT; RK4's stability boundary is 2.8 on the imaginary axis) and the
#: tolerance is tight enough that its numerical damping of the nutation stays negligible
#: (rtol ≤ AUTO_RK4_MAX_RTOL); otherwise etd2, which integrates the gyroscopic linear part
#: exactly at any spin. Intervals the primary cannot bring within tolerance go to exprb.
AUTO_RK4_LIMIT = 1.5
AUTO_RK4_MAX_RTOL = 1e-6
#: below this rtol an excited nutation costs RK4 ≥ 1/(24 rtol)^¼·ωh ≈ 100 substeps per 1 ms
#: sample at ×1: etd2 (exact on the nutation) is cheaper
AUTO_RK4_MIN_RTOL = 1e-9
#: below this rtol auto's exponential method is etd4 (order 4: its error falls much faster
#: with the step than etd2's, and it keeps invariants to 1e-10 over 1000 nutation periods)
AUTO_ETD4_BELOW = 1e-9


def fastest_mode(params: PlatformParams, options: ModelOptions) -> float:
    """Largest characteristic rate (rad/s or 1/s) of the model: nutation (not in precession),
    spring restraint, the mount friction's stick zone, the servo."""
    J = params.lumped()
    L = np.abs(params.L) if options.has("rotor_gyroscopic") else np.zeros(3)
    rates = [0.0]
    if options.fidelity != "precession":
        rates.append(math.sqrt((L[0] ** 2 / J["J5"] + L[1] ** 2 / J["J7"]) / J["J4"]))
        rates.append(L[2] / math.sqrt(J["J9"] * J["J10"]))
        if options.has("gimbal_springs"):
            c = np.asarray(params.spring)
            rates.append(math.sqrt(float(np.max(c / np.array([J["J4"], J["J5"], J["J7"], J["J9"], J["J10"]])))))
    if options.mode == "stabilised":
        Imin = float(np.linalg.eigvalsh(params.platform_tensor)[0])
        if options.has("support_friction"):
            rates.append((params.support_coulomb / params.support_rate_eps + params.support_viscous) / Imin)
        if options.has("servo"):
            rates.append(params.servo_kd / Imin + math.sqrt(params.servo_kp / Imin))
    return max(rates)


def auto_primary(options: ModelOptions, params: PlatformParams = NAV1) -> str:
    """The method ``auto`` steps with: the cheaper one that reaches the tolerance without
    damping the nutation.

    RK4 (compiled, 4 right-hand sides per step) is the cheapest per step and its substeps
    follow what the motion excites; but it must resolve the fastest mode λ for stability
    (h·λ < 2.8), and it damps a nutation ω by ≈ (hω)⁶/72 per step. Held to rtol its local error
    (hω)⁴/24 ≤ rtol gives hω ≤ (24 rtol)^¼, i.e. a T2 loss ≤ 1000·2π(hω)⁵/72 ≤ 1e-4 over 1000
    nutation periods for rtol ≤ 1e-6; below rtol 1e-9 resolving an excited nutation costs RK4
    more than etd2. Beyond the stability limit (fast rotors), at looser or at tighter tolerance:
    etd2 (exact on the gyroscopic linear part, cost independent of the spin), etd4 below
    rtol 1e-9 (fourth order: fewer substeps at tight tolerance)."""
    if (fastest_mode(params, options) * options.max_step < AUTO_RK4_LIMIT
            and AUTO_RK4_MIN_RTOL <= options.rtol <= AUTO_RK4_MAX_RTOL):
        return "rk4"
    return "etd2" if options.rtol >= AUTO_ETD4_BELOW else "etd4"


def choose_integrator(options: ModelOptions, params: PlatformParams = NAV1) -> Integrator:
    """The integrator of ``options`` (``auto``: ``Auto(auto_primary(...), exprb)``)."""
    kw = dict(max_step=options.max_step, rtol=options.rtol, atol=options.atol, max_substeps=options.max_substeps)
    if options.integrator == "auto":
        return Auto(make_integrator(auto_primary(options, params), **kw), make_integrator("exprb", **kw))
    return make_integrator(options.integrator, **kw)


class Simulator:
    """Three-gyro platform simulation driven by vehicle rate samples (ROS-free)."""

    def __init__(self, params: PlatformParams = NAV1, options: ModelOptions | None = None,
                 integrator: Integrator | None = None):
        self.params = params
        self.options = options if options is not None else ModelOptions()
        self.system = PlatformSystem(params, self.options)
        self.integrator = integrator if integrator is not None else choose_integrator(self.options, params)
        self.layout = self.system.layout
        self.needs_f = bool(self.options.effects & NEEDS_SPECIFIC_FORCE)
        self._outk = OutputKernel(self.system)    # outputs (compiled)
        self._ydot = np.zeros(self.layout.n)
        self.reset()

    # ---- state -------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the initial state; the next ``push`` starts a new time base."""
        self.y = self.system.rest_state()
        self.t_start: float | None = None
        self.t_rel = 0.0
        self._last: RateSample | None = None
        self.n_samples = 0
        self.n_steps = 0
        self.max_error_estimate = 0.0
        self.max_error_norm = 0.0
        self.n_rejected = 0
        self.integrator.reset()
        st = self.layout
        if self.system.stabilised and self.options.has("earth_rate"):
            # consistent start (spec 4.7): the platform already turns with the local level
            self.y[st.Om] = self.system.w_IN

    def carry_state_from(self, old: "Simulator") -> None:
        """Continue from the integration state of ``old`` (state, time base, last sample,
        counters), when both have the same state layout (same mode and fidelity; else nothing
        is carried): used when live parameters rebuild the simulator."""
        if old.t_start is None or old.layout.n != self.layout.n:
            return
        self.y = old.y.copy()
        self.t_start = old.t_start
        self.t_rel = old.t_rel
        self.system.seg[:] = old.system.seg        # the input interval the outputs use
        self._last = old._last
        self.n_samples = old.n_samples
        self.n_steps = old.n_steps
        self.max_error_estimate = old.max_error_estimate

    @property
    def t(self) -> float | None:
        """Time (s, the samples' time base) of the last accepted sample."""
        return None if self.t_start is None else self.t_start + self.t_rel

    @property
    def stats(self) -> dict:
        """Work and achieved accuracy of the run so far.

        ``integrator``: method name (``auto:<primary>+exprb`` for auto); ``n_samples``,
        ``n_steps`` (accepted substeps), ``n_rhs``; ``max_error_estimate``: the largest local
        error estimate of any accepted step (max-norm over the state, state units: rad, rad/s;
        the quantity the tolerance limits); ``max_error_norm``: the largest weighted norm of
        those estimates (≤ 1: every step met rtol/atol); ``n_rejected``: rejected (redone)
        intervals/steps; ``rtol``, ``atol``: the tolerance asked; ``n_fallback``: intervals
        auto handed to exprb (0 otherwise)."""
        return {"integrator": self.integrator.name, "n_samples": self.n_samples, "n_steps": self.n_steps,
                "n_rhs": self.system.n_rhs, "max_error_estimate": self.max_error_estimate,
                "max_error_norm": self.max_error_norm, "n_rejected": self.n_rejected,
                "rtol": self.integrator.rtol, "atol": self.integrator.atol,
                "n_fallback": getattr(self.integrator, "n_fallback", 0)}

    def _account(self, est: float, norm: float, rejected: int) -> None:
        if est == est:
            self.max_error_estimate = max(self.max_error_estimate, float(est))
        if norm == norm:
            self.max_error_norm = max(self.max_error_norm, float(norm))
        self.n_rejected += int(rejected)

    def _first(self, s: RateSample) -> None:
        self.t_start = s.t
        self.t_rel = 0.0
        first_segment(self.system.seg, s.omega, s.specific_force)   # input held: a fresh start
        st = self.layout
        if not self.system.stabilised and st.qd is not None:
            # consistent start of free gyros on a turning vehicle (spec 4.7)
            Om = self.system.R_PB @ s.omega
            self.y[st.qd] = [-Om[1], -Om[2], Om[2], -Om[2], -Om[0]]

    def push(self, sample: RateSample) -> None:
        """Integrate to ``sample.t``. Raises ``InputError`` (state unchanged) for a non-finite
        sample, a time not after the last one, or a missing specific force that an effect
        needs; ``SimulationError`` if the integration fails (state unchanged)."""
        if not sample.is_finite():
            raise InputError(f"non-finite sample at t = {sample.t}")
        if self.needs_f and sample.specific_force is None:
            raise InputError("effects " + ", ".join(sorted(self.options.effects & NEEDS_SPECIFIC_FORCE))
                             + " need the specific force, which this sample does not carry")
        if self._last is None:
            self._first(sample)
            self._last = sample
            self.n_samples = 1
            return
        t1 = sample.t - self.t_start
        if not t1 > self.t_rel:
            raise InputError(f"sample time {sample.t!r} is not after the last one ({self.t!r})")
        integ = self.integrator
        stepper = integ.primary if isinstance(integ, Auto) else integ
        if stepper.name == "rk4" and getattr(integ, "sticky", 0) <= 0:
            # RK4 needs no per-step matrices: the compiled loop serves single samples too (the
            # same steps as push_many, and fast when the tolerance asks for many substeps)
            f = sample.specific_force
            self._push_many(np.array([sample.t]), np.asarray(sample.omega, float).reshape(1, 3),
                            np.zeros((1, 3)) if f is None else np.asarray(f, float).reshape(1, 3), f is not None,
                            0, [])
            return
        self._push_python(sample, t1)

    def _push_python(self, sample: RateSample, t1: float) -> None:
        """One sample through ``integrator.advance`` (Python)."""
        last = self._last
        self.system.set_input(self.t_rel, t1, last.omega, sample.omega, last.specific_force,
                              sample.specific_force)
        try:
            if self.integrator.uses_linear_part:   # friction regime: only the linear part depends on it
                self.system.update_regime(self.y)
            y1, stats = self.integrator.advance(self.system, self.t_rel, self.y, t1)
        except (ArithmeticError, np.linalg.LinAlgError) as e:   # ZeroDivisionError, FloatingPointError
            raise SimulationError(f"integration failed at t = {sample.t}: {type(e).__name__}: {e}; "
                                  f"state kept at t = {self.t}") from e
        if not np.all(np.isfinite(y1)):
            raise SimulationError(f"non-finite state after the step to t = {sample.t}; state kept at t = {self.t}")
        st = self.layout
        for sl in (st.quat_IB, st.quat_IP):
            if sl is not None:
                y1[sl] /= np.linalg.norm(y1[sl])
        self.y = y1
        self.t_rel = t1
        self._last = sample
        self.n_samples += 1
        self.n_steps += stats.n_steps
        self._account(stats.error_estimate, stats.error_norm, stats.n_rejected)

    def push_many(self, t, omega, specific_force=None, output_every: int = 0) -> list[Outputs]:
        """Push many samples at once (arrays: t (N,) s, omega (N, 3) rad/s, specific_force
        (N, 3) m/s² or None); returns the outputs after every ``output_every``-th sample (0:
        none). Uses the compiled batch loop (``fastpath``) for rk4/etd2/etd4 (and auto's
        primary) when the sample intervals are uniform; otherwise pushes one by one. Same
        results and the same errors as ``push``.

        Raises ``InputError`` before touching the state if any sample is bad. If the
        integration fails at some sample, the ``SimulationError`` (``GimbalLockError``,
        ``ToleranceError``, …) is raised with the state at the last good sample and the
        outputs computed before the failure in its ``outputs`` attribute."""
        t = np.asarray(t, dtype=float).reshape(-1)
        w = np.ascontiguousarray(np.asarray(omega, dtype=float).reshape(-1, 3))
        has_f = specific_force is not None
        fB = (np.ascontiguousarray(np.asarray(specific_force, dtype=float).reshape(-1, 3)) if has_f
              else np.zeros_like(w))
        if len(t) != len(w) or len(fB) != len(w):
            raise InputError("t, omega and specific_force must have the same length")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(w)) and np.all(np.isfinite(fB))):
            bad = int(np.argmin(np.isfinite(t) & np.all(np.isfinite(w), 1) & np.all(np.isfinite(fB), 1)))
            raise InputError(f"non-finite sample at index {bad}")
        if self.needs_f and not has_f:
            raise InputError("these effects need the specific force, which the samples do not carry")
        if self._last is not None and len(t):
            d = np.diff(np.concatenate([[self.t], t]))
            if np.any(d <= 0):
                bad = int(np.argmax(d <= 0))
                raise InputError(f"sample time at index {bad} ({t[bad]!r}) is not after the previous one")
        elif len(t) > 1 and np.any(np.diff(t) <= 0):
            bad = int(np.argmax(np.diff(t) <= 0)) + 1
            raise InputError(f"sample time at index {bad} ({t[bad]!r}) is not after the previous one")
        outs: list[Outputs] = []
        try:
            self._push_many(t, w, fB, has_f, output_every, outs)
        except SimulationError as e:
            e.outputs = outs
            raise
        return outs

    def _sample(self, t, w, fB, has_f, i) -> RateSample:
        return RateSample(float(t[i]), w[i].copy(), fB[i].copy() if has_f else None)

    def _push_many(self, t, w, fB, has_f, output_every, outs) -> None:
        from .batch import (COMPILED, I_EBAD, I_EST, I_H, I_NBAD, I_NORM, I_REJ, I_STEPS, I_T, N_INFO,
                               NEED_REGIME, ST_LOCK, ST_NOT_PD, ST_TOLERANCE, RegimeMatrices, run_batch)
        if len(t) == 0:
            return
        start = 0
        if self._last is None:
            self.push(self._sample(t, w, fB, has_f, 0))
            start = 1
            if output_every:
                outs.append(self.outputs())
        t_rel = np.concatenate([[self.t_rel], t[start:] - self.t_start])
        W = np.vstack([self._last.omega[None, :], w[start:]])
        prev_f = self._last.specific_force
        Fm = np.vstack([(prev_f if prev_f is not None else np.zeros(3))[None, :], fB[start:]])
        sys_ = self.system
        integ = self.integrator
        auto = isinstance(integ, Auto)
        stepper = integ.primary if auto else integ
        h_max = self.options.max_step
        dts = np.diff(t_rel)
        if len(dts) == 0:
            return
        nsub = np.maximum(1, np.ceil(dts / h_max - 1e-9))
        hs = dts / nsub
        method = COMPILED.get(stepper.name)
        uniform = method is not None and (method == 0 or np.max(np.abs(hs - hs[0])) <= 1e-9 * hs[0])

        def emit(i: int) -> bool:                 # i: index into t_rel (sample index i − 1 + start)
            return bool(output_every) and ((i - 1 + start) % output_every == 0)

        if not uniform:
            for i in range(1, len(t_rel)):
                self.push(self._sample(t, w, fB, has_f, i - 1 + start))
                if emit(i):
                    outs.append(self.outputs())
            return
        idx = np.arange(1, len(t_rel))
        sel = idx[((idx - 1 + start) % output_every) == 0].astype(np.int64) if output_every else idx[:0].astype(np.int64)
        y_out = np.zeros((len(sel), self.layout.n))
        c = np.array([0.0, 0.5, 0.5, 1.0]) if method == 0 else np.asarray(stepper.c, float)
        h_step = float(hs[0]) if method else h_max
        sets = RegimeMatrices(stepper, sys_, h_step)
        lev = np.array([stepper.level], dtype=np.int64)
        info = np.zeros(N_INFO)
        need = np.zeros(2, dtype=np.int64)
        prog = np.zeros(1, dtype=np.int64)
        first, j_done = 0, 0
        y = self.y.copy()
        while True:
            info[:] = 0.0
            try:
                last, status = run_batch(method, h_max, stepper.rtol, stepper.atol, stepper.q1, stepper.max_level,
                                         lev, info, sets.reg_of, sets.ptr, sets.idx, sets.dat, c, t_rel, W, Fm, y,
                                         sel, y_out, first, need, prog, sys_.fid, *sys_.kernel_args())
                exc = None
            except ArithmeticError as e:          # ZeroDivisionError etc. inside the compiled kernels
                last, status, exc = int(prog[0]), -1, e
            stepper.level = int(lev[0])
            # commit what was reached: outputs, state, counters
            steps = int(info[I_STEPS])
            sys_.n_rhs += steps * len(c) + (last - first if method == 0 else 0)
            self.n_steps += steps
            self.n_samples += last - first
            self._account(info[I_EST], info[I_NORM], int(info[I_REJ]))
            while j_done < len(sel) and sel[j_done] <= last:
                i = int(sel[j_done])
                self._set_at(t_rel, W, Fm, t, has_f, start, i, y_out[j_done])
                outs.append(self.outputs())
                j_done += 1
            self._set_at(t_rel, W, Fm, t, has_f, start, last, y)
            if status == 0:
                return
            if status == NEED_REGIME:
                sets.add(int(need[0]), int(need[1]))   # matrices for a new (regime, level)
                first = last
                continue
            if status > 0 and status & ST_TOLERANCE and auto:
                # the primary cannot meet the tolerance here within its budget: this interval by
                # auto's own push (primary again, then exprb), then back to the compiled loop
                i = last + 1
                while True:                        # the refused interval and auto's sticky ones
                    smp = self._sample(t, w, fB, has_f, i - 1 + start)
                    self._push_python(smp, smp.t - self.t_start)
                    if emit(i):
                        outs.append(self.outputs())
                    while j_done < len(sel) and sel[j_done] <= i:
                        j_done += 1
                    if i >= len(t_rel) - 1:
                        return
                    if integ.sticky <= 0:
                        break
                    i += 1
                first = i
                y = self.y.copy()
                lev[0] = stepper.level
                continue
            at = float(t[min(last + start, len(t) - 1)])
            if exc is not None:
                raise SimulationError(f"integration failed after t = {self.t} ({type(exc).__name__}: {exc}); "
                                      f"state kept there, stopped before the sample at t = {at}") from exc
            if status & ST_LOCK:
                raise GimbalLockError(f"gimbal lock (precession model singular) after t = {self.t}; "
                                      f"stopped before the sample at t = {at}")
            if status & ST_TOLERANCE:
                raise stepper.refuse(float(info[I_T]), float(info[I_EBAD]), float(info[I_NBAD]), float(info[I_H]))
            if status & ST_NOT_PD:
                raise SimulationError(f"mass matrix not positive definite after t = {self.t}; state kept there")
            raise SimulationError(f"non-finite state after the step to t = {at}; state kept at t = {self.t}")

    def _set_at(self, t_rel, W, Fm, t, has_f, start, i, y) -> None:
        """Make sample ``i`` of a batch (index into t_rel) the current one, with state y."""
        self.y = np.array(y, dtype=float)
        self.t_rel = float(t_rel[i])
        if i > 0:
            self.system.set_input(t_rel[i - 1], t_rel[i], W[i - 1], W[i], Fm[i - 1], Fm[i])
            self._last = RateSample(float(t[i - 1 + start]), W[i].copy(), Fm[i].copy() if has_f else None)

    def run(self, samples, output_period: float | None = None) -> list[Outputs]:
        """Push all samples; collect outputs every ``output_period`` s (None: after each)."""
        outs: list[Outputs] = []
        next_t = None
        for s in samples:
            self.push(s)
            if output_period is None or next_t is None or s.t >= next_t - 1e-12:
                outs.append(self.outputs())
                next_t = s.t + (output_period or 0.0)
        return outs

    # ---- derived quantities ------------------------------------------------------------
    def gimbal_rates(self, y: np.ndarray | None = None) -> np.ndarray:
        """Gimbal rates (5,) rad/s of state y (default: the current one; precession: from the
        model at the current input)."""
        y = self.y if y is None else y
        st = self.layout
        if st.qd is not None:
            return y[st.qd].copy()
        return self._rhs(self.t_rel, y)[st.q].copy()

    def _rhs(self, t_rel: float, y: np.ndarray) -> np.ndarray:
        self.system.rhs_into(t_rel, y, self._ydot)
        return self._ydot

    def platform_rate(self) -> np.ndarray:
        """Platform rate (3,) rad/s, platform axes: the state's (stabilised) or the vehicle
        input turned into platform axes (carried)."""
        st = self.layout
        if st.Om is not None:
            return self.y[st.Om].copy()
        return self.system.R_PB @ self.system.seg[5:8]

    def attitude_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(R_IB, R_IP) rotation matrices (vehicle → inertial, platform → inertial)."""
        st = self.layout
        R_IB = quat_matrix(self.y[st.quat_IB])
        R_IP = quat_matrix(self.y[st.quat_IP]) if st.quat_IP is not None else R_IB @ self.system.R_BP
        return R_IB, R_IP

    def reference_matrix(self) -> np.ndarray:
        """R_IC: the frame the platform should hold (inertial, or local level with Earth rate)."""
        return rotvec_matrix(self.system.w_IN * self.t_rel)

    def invariants(self) -> dict[str, float]:
        """T2 = ½ ẋᵀ A* ẋ (J) and the total angular momentum |p_Ω| (N m s, stabilised), the
        torque-free invariants of spec 4.5 (full fidelity)."""
        st = self.layout
        tree = self.system.tree
        wk = TreeWork(tree)
        v = self.y[st.v]
        w0 = np.zeros(3) if self.system.stabilised else self.platform_rate()
        kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, tree.root_dynamic,
                   self.y[st.q], v, w0, wk.R, wk.w, wk.J)
        M = np.zeros((tree.nv, tree.nv))
        mass_matrix(wk.J, tree.inertia, M)
        out = {"T2": 0.5 * float(v @ M @ v)}
        if self.system.stabilised:
            h = np.zeros(3)
            spin_momentum(self.system.L, self.y[st.q], np.zeros(5), h, np.zeros(3))
            p = (M @ v)[:3] + h
            out["p_norm"] = float(np.linalg.norm(p))
            out["p_inertial"] = self.attitude_matrices()[1] @ p
        return out

    def outputs(self) -> Outputs:
        """Outputs at the current time (see ``outputs.Outputs``), by the compiled output kernel
        (``output_kernel``; the one-instant case of ``_outputs_at``). Raises
        ``NonFiniteOutputError`` rather than return a NaN or Inf, and the model's
        ``SimulationError`` for a state it refuses (precession at gimbal lock)."""
        if self._last is None:
            raise SimulationError("no sample pushed yet")
        return self._outk.row(self.t_start + self.t_rel, self.t_rel, self.n_steps, self.y, self.system.seg)

    def _outputs_at(self, snaps: Snapshots) -> OutputBlock:
        """Outputs at the instants of ``snaps`` in one compiled call. A failure at an instant
        raises (``NonFiniteOutputError``, the model's ``SimulationError``) with ``.block``: the
        outputs of the instants before it."""
        return self._outk.block(snaps.t, snaps.t_rel, snaps.n_steps, snaps.y, snaps.seg)
