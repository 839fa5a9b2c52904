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

from .batch import COMPILED, Engine, ST_BAD_SAMPLE, ST_LOCK, ST_NOT_PD, ST_ORDER, ST_TOLERANCE
from .buffers import (H_E_BAD, H_EST, H_H_BAD, H_N_BAD, H_NORM, H_T_BAD, H_T_REL, H_T_START, J_DONE, J_HAS_F, J_JOUT,
                      J_NRHS, J_NSAMP, J_NSTEPS, J_REJ, J_STARTED)
from .checks import as_time as _time
from .checks import as_vec3 as _vec3
from .checks import check_block
from .inputs import RateSample
from .integrators import Auto, auto_method, Integrator, make_integrator
from .output_kernel import OutputKernel
from .outputs import OutputBlock, Outputs, outputs_of_row
from .snapshots import Snapshots
from ..errors import GimbalLockError, InputError, SimulationError
from ..physics.model import commit_attitudes, spin_momentum
from ..physics.options import ModelOptions, NEEDS_SPECIFIC_FORCE
from ..physics.params import NAV1, PlatformParams
from ..physics.rotations import quat_matrix
from ..physics.system import PlatformSystem, SEG_DT, SEG_F0, SEG_F1, SEG_N, SEG_T0, SEG_W0, SEG_W1
from ..physics.tree import kinematics, mass_matrix, TreeWork


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


def nutation_excited(options: ModelOptions) -> bool:
    """Whether the motion excites the nutation: a carried platform's gimbals are driven by the
    vehicle directly (not in precession, which has no nutation); a stabilised platform is held
    by its servo and the nutation stays quiet."""
    return options.mode == "carried" and options.fidelity != "precession"


def regime_switches(options: ModelOptions) -> bool:
    """Whether the model has regime changes (a stabilised platform's mount friction: stick zone
    and slip) that only the integrators which locate them (RK4) step across at tight tolerance."""
    return options.mode == "stabilised" and options.has("support_friction")


def auto_inputs(options: ModelOptions, params: PlatformParams = NAV1) -> dict:
    """What ``auto``'s rule reads of the model (``make_integrator``'s ``auto`` keywords): its
    fastest mode (``fastest_rate``, rad/s or 1/s), whether the motion excites the nutation
    (``excited``) and whether it has regime changes (``switches``)."""
    return {"fastest_rate": fastest_mode(params, options), "excited": nutation_excited(options),
            "switches": regime_switches(options)}


def auto_primary(options: ModelOptions, params: PlatformParams = NAV1) -> str:
    """The method ``auto`` steps with for this model: ``integrators.auto_method`` (the rule and
    its reasons) of :func:`auto_inputs` and the tolerance."""
    k = auto_inputs(options, params)
    return auto_method(k["fastest_rate"] * options.max_step, options.rtol, k["excited"], k["switches"])


def choose_integrator(options: ModelOptions, params: PlatformParams = NAV1) -> Integrator:
    """The integrator of ``options`` (``auto``: its primary from this model's fastest mode, see
    ``auto_primary``; the registry builds it)."""
    kw = {
        "max_step": options.max_step,
        "rtol": options.rtol,
        "atol": options.atol,
        "max_substeps": options.max_substeps,
    }
    if options.integrator == "auto":
        kw.update(auto_inputs(options, params))
    return make_integrator(options.integrator, **kw)


_F64 = np.dtype(float)
_ZERO3 = np.zeros(3)


def _with_outputs(exc: SimulationError, sim: "Simulator", snaps: Snapshots,
                  output_error: SimulationError | None = None) -> None:
    """Attach to ``exc`` (a failure of ``push_block``) the outputs of the recorded instants
    ``snaps`` up to the first that fails: ``.block``, ``.snapshots``, ``.output_failed`` (index
    of that instant or None) and ``.output_error``. ``output_error``: that failure, already
    raised by ``outputs_at(snaps)`` (then ``exc`` is it)."""
    if output_error is None:
        try:
            exc.block = sim.outputs_at(snaps)
        except SimulationError as e:
            output_error = e
    if output_error is not None:
        exc.block = output_error.block
    exc.snapshots = snaps
    exc.output_failed = None if output_error is None else len(exc.block)
    exc.output_error = output_error


class Simulator:
    """Three-gyro platform simulation driven by vehicle rate samples (ROS-free).

    The integration state lives in a compiled ``batch.Engine`` (``y`` is a view into it: an
    in-place edit changes the state). With rk4, etd2, etd4 (and auto's primary) a ``push`` is
    one compiled call and ``push_block`` one per chunk; other integrators step in Python."""

    def __init__(self, params: PlatformParams = NAV1, options: ModelOptions | None = None,
                 integrator: Integrator | None = None, *, compiled: bool = True):
        """``compiled=False``: every sample through the Python integrator (the reference the
        compiled path is tested against; slow)."""
        self.params = params
        self.options = options if options is not None else ModelOptions()
        self.system = PlatformSystem(params, self.options)
        self.integrator = integrator if integrator is not None else choose_integrator(self.options, params)
        self.layout = self.system.layout
        self.needs_f = bool(self.options.effects & NEEDS_SPECIFIC_FORCE)
        integ = self.integrator
        self._auto = integ if isinstance(integ, Auto) else None
        stepper = integ.primary if self._auto is not None else integ
        self._stepper = stepper
        self.engine = Engine(self.system, stepper if stepper.name in COMPILED else None)
        self._compiled = compiled and self.engine.method is not None
        self._outk = OutputKernel(self.system)    # outputs (compiled)
        self._ydot = np.zeros(self.layout.n)
        self.reset()

    # ---- state (kept in the engine's buffers) ------------------------------------------
    @property
    def y(self) -> np.ndarray:
        """Integration state (``layout``); a view: in-place edits change the state."""
        return self.engine.y

    @y.setter
    def y(self, value) -> None:
        self.engine.y[:] = value

    @property
    def t_start(self) -> float | None:
        """Time (s, the samples' time base) of the first sample since the start/reset."""
        return float(self.engine.fh[H_T_START]) if self.engine.ih[J_STARTED] else None

    @property
    def t_rel(self) -> float:
        """Time of the current instant relative to ``t_start`` (s)."""
        return float(self.engine.fh[H_T_REL])

    @t_rel.setter
    def t_rel(self, value: float) -> None:
        self.engine.fh[H_T_REL] = value

    @property
    def n_samples(self) -> int:
        return int(self.engine.ih[J_NSAMP])

    @property
    def n_steps(self) -> int:
        return int(self.engine.ih[J_NSTEPS])

    @n_steps.setter
    def n_steps(self, value: int) -> None:
        self.engine.ih[J_NSTEPS] = value

    @property
    def max_error_estimate(self) -> float:
        return float(self.engine.fh[H_EST])

    @property
    def max_error_norm(self) -> float:
        return float(self.engine.fh[H_NORM])

    @property
    def n_rejected(self) -> int:
        return int(self.engine.ih[J_REJ])

    @property
    def _last(self) -> RateSample | None:
        """The current sample (time, rate, specific force) as held in ``system.seg``."""
        if not self.engine.ih[J_STARTED]:
            return None
        seg = self.system.seg
        return RateSample(self.t, seg[SEG_W1:SEG_W1 + 3].copy(),
                          seg[SEG_F1:SEG_F1 + 3].copy() if self.engine.ih[J_HAS_F] else None)

    def reset(self) -> None:
        """Back to the initial state: the next ``push`` starts a new time base, and everything
        after it equals a fresh simulator fed the same samples (stage matrices are kept)."""
        self.engine.clear(self.system.rest_state())
        self.system.seg[:] = 0.0
        self.system.seg[SEG_DT] = 1.0
        self.system.regime = 0
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
        e, o = self.engine, old.engine
        e.y[:] = o.y
        e.fh[[H_T_START, H_T_REL, H_EST]] = o.fh[[H_T_START, H_T_REL, H_EST]]
        e.ih[[J_STARTED, J_NSAMP, J_NSTEPS, J_HAS_F]] = o.ih[[J_STARTED, J_NSAMP, J_NSTEPS, J_HAS_F]]
        e.tr[:], e.wr[:], e.fr[:] = o.tr, o.wr, o.fr
        self.system.seg[:] = old.system.seg

    @property
    def t(self) -> float | None:
        """Time (s, the samples' time base) of the last accepted sample."""
        return None if not self.engine.ih[J_STARTED] else self.engine.fh[H_T_START] + self.engine.fh[H_T_REL]

    @property
    def stats(self) -> dict:
        """Work and achieved accuracy of the run so far.

        ``integrator``: method name (``auto:<primary>+exprb`` for auto); ``n_samples``,
        ``n_steps`` (accepted substeps), ``n_rhs``; ``max_error_estimate``: the largest local
        error estimate of any accepted step (max-norm over the state, state units: rad, rad/s;
        the quantity the tolerance limits); ``max_error_norm``: the largest weighted norm of
        those estimates (≤ 1: every step met rtol/atol); ``n_rejected``: rejected (redone)
        intervals/steps; ``rtol``, ``atol``: the tolerance asked; ``n_fallback``: intervals
        auto handed to exprb or, where exprb refused too, to rk4 (0 otherwise); ``n_rescue``:
        those of them rk4 did."""
        return {"integrator": self.integrator.name, "n_samples": self.n_samples, "n_steps": self.n_steps,
                "n_rhs": self.system.n_rhs + int(self.engine.ih[J_NRHS]),
                "max_error_estimate": self.max_error_estimate,
                "max_error_norm": self.max_error_norm, "n_rejected": self.n_rejected,
                "rtol": self.integrator.rtol, "atol": self.integrator.atol,
                "n_fallback": getattr(self.integrator, "n_fallback", 0),
                "n_rescue": getattr(self.integrator, "n_rescue", 0)}

    def _account(self, est: float, norm: float, rejected: int) -> None:
        fh = self.engine.fh
        if est == est:
            fh[H_EST] = max(fh[H_EST], float(est))
        if norm == norm:
            fh[H_NORM] = max(fh[H_NORM], float(norm))
        self.engine.ih[J_REJ] += int(rejected)

    def _first(self, t: float, w: np.ndarray, f: np.ndarray | None) -> None:
        """The first sample after a start/reset: new time base, input held (no interval)."""
        if not (math.isfinite(t) and np.all(np.isfinite(w)) and (f is None or np.all(np.isfinite(f)))):
            raise InputError(f"non-finite sample at t = {t}")
        e = self.engine
        e.fh[H_T_START] = t
        e.fh[H_T_REL] = 0.0
        e.tr[:] = 0.0
        e.wr[0] = w
        e.fr[0] = 0.0 if f is None else f
        e.ih[J_STARTED] = 1
        e.ih[J_NSAMP] = 1
        e.ih[J_HAS_F] = f is not None
        self.system.set_input(0.0, 1.0, w, w, f, f)     # no interval yet: input held, zero slope
        st = self.layout
        if not self.system.stabilised and st.qd is not None:
            # consistent start of free gyros on a turning vehicle (spec 4.7)
            Om = self.system.R_PB @ w
            self.y[st.qd] = [-Om[1], -Om[2], Om[2], -Om[2], -Om[0]]

    def _python_now(self) -> bool:
        """This sample goes through the Python integrator (no compiled path, or auto is on its
        fallback)."""
        return not self._compiled or (self._auto is not None and self._auto.sticky > 0)

    def push(self, sample: RateSample) -> None:
        """Integrate to ``sample.t``: one compiled call (rk4, etd2, etd4, auto's primary).
        Raises ``InputError`` (state unchanged) for a sample that is not 3 finite reals (ω,
        specific force) at a real time after the last one, or misses a specific force that an
        effect needs; ``SimulationError`` if the integration fails (state, input and outputs
        unchanged)."""
        w = sample.omega
        if w.__class__ is not np.ndarray or w.dtype is not _F64 or w.shape != (3,):
            w = _vec3(w, "omega")
        f = sample.specific_force
        if f is None:
            f, has_f = self._no_force(), False
        else:
            if f.__class__ is not np.ndarray or f.dtype is not _F64 or f.shape != (3,):
                f = _vec3(f, "specific_force")
            has_f = True
        t = sample.t
        if t.__class__ is not float:
            t = _time(t)
        self._push_arrays(t, w, f, has_f)

    def push_plain(self, t: float, omega: tuple, specific_force: tuple | None) -> None:
        """:meth:`push` of a sample the input gate has checked (``TimeGate.offer_plain``): ``t``
        s (a float), ω rad/s and specific force m/s² (or None) as 3-tuples of floats, vehicle axes. No
        sample object or array is made on the compiled path (the node's per-message path);
        same results, same errors."""
        if specific_force is None:
            self._no_force()
            fx = fy = fz = 0.0
            has_f = False
        else:
            fx, fy, fz = specific_force
            has_f = True
        engine = self.engine
        if not engine.ih.item(J_STARTED) or self._python_now():
            self._push_arrays(t, np.array(omega), np.array((fx, fy, fz)), has_f)
            return
        wx, wy, wz = omega
        try:
            st = engine.push_values(t, wx, wy, wz, fx, fy, fz, has_f)
        except ArithmeticError as e:          # ZeroDivisionError etc. inside the compiled kernels
            raise self._failed(t, e) from e
        if st:
            self._refused(st, t, np.array(omega), np.array((fx, fy, fz)), has_f)

    def _no_force(self) -> np.ndarray:
        if self.needs_f:
            raise InputError("effects " + ", ".join(sorted(self.options.effects & NEEDS_SPECIFIC_FORCE))
                             + " need the specific force, which this sample does not carry")
        return _ZERO3

    def _push_arrays(self, t: float, w: np.ndarray, f: np.ndarray, has_f: bool) -> None:
        """:meth:`push` of checked arrays."""
        engine = self.engine
        if not engine.ih[J_STARTED]:
            self._first(t, w, f if has_f else None)
            return
        if self._python_now():
            self._push_python(t, w, f, has_f)
            return
        try:
            st = engine.push(t, w, f, has_f)
        except ArithmeticError as e:          # ZeroDivisionError etc. inside the compiled kernels
            raise self._failed(t, e) from e
        if st:
            self._refused(st, t, w, f, has_f)

    def _failed(self, t: float, e: ArithmeticError) -> SimulationError:
        """A compiled step raised: ``seg`` restored, the error to raise."""
        self.system.seg[:] = self.engine.segsave
        return SimulationError(f"integration failed at t = {t} ({type(e).__name__}: {e}); state kept at t = {self.t}")

    def _refused(self, st: int, t: float, w, f, has_f: bool) -> None:
        """A compiled sample came back with status ``st``: hand it to auto's fallback or raise
        (nothing was committed)."""
        if st & ST_BAD_SAMPLE:
            raise InputError(f"non-finite sample at t = {t}")
        if st & ST_ORDER:
            raise InputError(f"sample time {t!r} is not after the last one ({self.t!r})")
        if st & ST_TOLERANCE and self._auto is not None:
            # the primary cannot meet the tolerance here within its budget: auto's own push
            # (its fallback and rescue in Python; the primary is not run again), then back to
            # the compiled path
            self._auto.primary_refused = True
            try:
                self._push_python(t, w, f, has_f)
            finally:
                self._auto.primary_refused = False
            return
        if st & ST_LOCK:
            raise GimbalLockError(f"gimbal lock (precession model singular) after t = {self.t}; "
                                  f"stopped before the sample at t = {t}")
        fh = self.engine.fh
        if st & ST_TOLERANCE:
            raise self._stepper.refuse(self.t_start + float(fh[H_T_BAD]), float(fh[H_E_BAD]),
                                       float(fh[H_N_BAD]), float(fh[H_H_BAD]))
        if st & ST_NOT_PD:
            raise SimulationError(f"mass matrix not positive definite after t = {self.t}; state kept there")
        raise SimulationError(f"non-finite state after the step to t = {t}; state kept at t = {self.t}")

    def _push_python(self, t: float, w: np.ndarray, f: np.ndarray, has_f: bool) -> None:
        """One sample through ``integrator.advance`` (Python); committed only on success."""
        if not (math.isfinite(t) and np.all(np.isfinite(w)) and np.all(np.isfinite(f))):
            raise InputError(f"non-finite sample at t = {t}")
        e = self.engine
        t1 = t - e.fh[H_T_START]
        t0 = float(e.fh[H_T_REL])
        if not t1 > t0:
            raise InputError(f"sample time {t!r} is not after the last one ({self.t!r})")
        seg = self.system.seg
        saved = seg.copy()
        seg[SEG_T0], seg[SEG_DT] = t0, t1 - t0
        seg[SEG_W0:SEG_W0 + 3], seg[SEG_W1:SEG_W1 + 3] = e.wr[0], w
        seg[SEG_F0:SEG_F0 + 3], seg[SEG_F1:SEG_F1 + 3] = e.fr[0], (f if has_f else 0.0)
        try:
            if self.integrator.uses_linear_part:   # friction regime: only the linear part depends on it
                self.system.update_regime(self.y)
            y1, stats = self.integrator.advance(self.system, t0, self.y, t1)
            if not np.all(np.isfinite(y1)):
                raise SimulationError(f"non-finite state after the step to t = {t}; state kept at t = {self.t}")
        except (ArithmeticError, np.linalg.LinAlgError) as exc:   # ZeroDivisionError, FloatingPointError
            seg[:] = saved
            raise SimulationError(f"integration failed at t = {t}: {type(exc).__name__}: {exc}; "
                                  f"state kept at t = {self.t}") from exc
        except BaseException:
            seg[:] = saved
            raise
        qa, qp = (-1 if sl is None else sl.start for sl in (self.layout.quat_IB, self.layout.quat_IP))
        commit_attitudes(self.y, y1, qa, qp, seg, self.integrator.name == "etd2")      # as the compiled kernel
        self.y[:] = y1
        e.fh[H_T_REL] = t1
        e.tr[0] = t1
        e.wr[0] = w
        e.fr[0] = f if has_f else 0.0
        e.ih[J_NSAMP] += 1
        e.ih[J_HAS_F] = has_f
        e.ih[J_NSTEPS] += stats.n_steps
        self._account(stats.error_estimate, stats.error_norm, stats.n_rejected)

    # ---- blocks ------------------------------------------------------------------------
    def push_block(self, t, omega, specific_force=None, out_idx=()):
        """Push a chunk (t (N,) s, omega (N, 3) rad/s, specific_force (N, 3) m/s² or None) and
        return the ``OutputBlock`` of the outputs after each sample in ``out_idx`` (increasing
        indices into the chunk). One compiled call per chunk (rk4, etd2, etd4, auto's primary);
        the same results and errors as pushing the samples one by one.

        Raises ``InputError`` before touching the state if any sample or index is bad. If the
        integration fails at some sample, the ``SimulationError`` carries ``.block`` (the
        outputs computed before the failure) and ``.n_done`` (samples of this call taken);
        the state is that after the last good sample. If the outputs of an instant fail
        (``NonFiniteOutputError``, the model refusing the state) the integration is not
        stopped: the error raised is the output error (``.n_done`` = N) or, when the
        integration failed later, the integration error. Either carries ``.snapshots`` (the
        instants recorded), ``.output_failed`` (index into them of the first whose outputs
        failed, or None), ``.output_error`` (its error) and ``.block`` (the outputs of the
        instants before it): the caller may go on with ``outputs_at`` after it."""
        t, w, f, has_f, idx = check_block(t, omega, specific_force, out_idx, self.t_start, self.t_rel,
                                          self.options.effects & NEEDS_SPECIFIC_FORCE if self.needs_f else ())
        n, k = len(t), len(idx)
        y_out = np.zeros((k, self.layout.n))
        seg_out = np.zeros((k, SEG_N))
        ns_out = np.zeros(k, np.int64)
        done, first, j = 0, 0, 0
        try:
            if n and not self.engine.ih[J_STARTED]:
                self._first(float(t[0]), w[0], f[0] if has_f else None)
                first = done = 1
                j = self._record(idx, j, 0, y_out, seg_out, ns_out)
            while first < n:
                if self._python_now():
                    self._push_python(float(t[first]), w[first], f[first], has_f)
                    first = done = first + 1
                    j = self._record(idx, j, first - 1, y_out, seg_out, ns_out)
                    continue
                try:
                    st = self.engine.block(t, w, f, has_f, first, idx, y_out, seg_out, ns_out)
                except ArithmeticError as exc:
                    self.system.seg[:] = self.engine.segsave
                    done = int(self.engine.ih[J_DONE])
                    j = int(self.engine.ih[J_JOUT])
                    raise SimulationError(f"integration failed after t = {self.t} ({type(exc).__name__}: {exc}); "
                                          f"state kept there, stopped before the sample at t = {t[done]}") from exc
                done = int(self.engine.ih[J_DONE])
                j = int(self.engine.ih[J_JOUT])
                if st == 0:
                    break
                self._refused(st, float(t[done]), w[done], f[done], has_f)   # raises unless auto takes it
                first = done = done + 1
                j = self._record(idx, j, done - 1, y_out, seg_out, ns_out)
        except SimulationError as exc:
            exc.n_done = done
            _with_outputs(exc, self, self._snapshots(t, idx[:j], y_out[:j], seg_out[:j], ns_out[:j]))
            raise
        snaps = self._snapshots(t, idx, y_out, seg_out, ns_out)
        try:
            return self.outputs_at(snaps)
        except SimulationError as exc:      # outputs failed at an instant; every sample was taken
            exc.n_done = n
            _with_outputs(exc, self, snaps, exc)
            raise

    def _record(self, idx, j: int, i: int, y_out, seg_out, ns_out) -> int:
        """Snapshot the current instant as sample ``i`` of a block for every ``idx[j] == i``."""
        while j < len(idx) and idx[j] == i:
            y_out[j] = self.y
            seg_out[j] = self.system.seg
            ns_out[j] = self.n_steps
            j += 1
        return j

    def _snapshots(self, t, idx, y_out, seg_out, ns_out) -> Snapshots:
        t_rel = t[idx] - self.t_start if self.t_start is not None else np.zeros(len(idx))
        return Snapshots(self.t_start + t_rel if len(idx) else np.zeros(0), t_rel, y_out, seg_out, ns_out)

    def _snapshot(self) -> Snapshots:
        """The current instant as a ``Snapshots`` of one."""
        if self.t_start is None:
            raise SimulationError("no sample pushed yet")
        return Snapshots(np.array([self.t]), np.array([self.t_rel]), self.y.copy()[None, :],
                         self.system.seg.copy()[None, :], np.array([self.n_steps], np.int64))

    def push_many(self, t, omega, specific_force=None, output_every: int = 0) -> list[Outputs]:
        """Push many samples at once (arrays: t (N,) s, omega (N, 3) rad/s, specific_force
        (N, 3) m/s² or None); returns the outputs after every ``output_every``-th sample (0:
        none) as a list. ``push_block`` with ``out_idx = 0, output_every, …``: the same
        results and the same errors as ``push``.

        Raises ``InputError`` before touching the state if any sample is bad. If the
        integration fails at some sample, the ``SimulationError`` (``GimbalLockError``,
        ``ToleranceError``, …) is raised with the state at the last good sample and the
        outputs computed before the failure in its ``outputs`` attribute."""
        if isinstance(output_every, (bool, np.bool_)) or not isinstance(output_every, (int, np.integer)) \
                or output_every < 0:
            raise InputError(f"output_every must be an integer ≥ 0, got {output_every!r}")
        n = int(np.size(t))
        idx = np.arange(0, n, output_every, dtype=np.int64) if output_every else np.zeros(0, np.int64)
        try:
            block = self.push_block(t, omega, specific_force, idx)
        except SimulationError as e:
            blk = getattr(e, "block", None)
            e.outputs = [blk[i] for i in range(len(blk))] if blk is not None else []
            raise
        return [block[i] for i in range(len(block))]

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
        return self.system.R_PB @ self.system.seg[SEG_W1:SEG_W1 + 3]

    def attitude_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(R_IB, R_IP) rotation matrices (vehicle → inertial, platform → inertial)."""
        st = self.layout
        R_IB = quat_matrix(self.y[st.quat_IB])
        R_IP = quat_matrix(self.y[st.quat_IP]) if st.quat_IP is not None else R_IB @ self.system.R_BP
        return R_IB, R_IP

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
        (``output_kernel``; the one-instant case of ``outputs_at``). Raises
        ``NonFiniteOutputError`` rather than return a NaN or Inf, and the model's
        ``SimulationError`` for a state it refuses (precession at gimbal lock)."""
        return outputs_of_row(self.output_row(), self._outk.stabilised)

    def output_row(self) -> np.ndarray:
        """The numbers of :meth:`outputs` as one new row (``outputs.N_COL``,), in the layout of
        :mod:`gyro_platform.engine.outputs` (``C_*``), without building the ``Outputs`` object
        (``outputs.outputs_of_row`` makes it); the same errors."""
        e = self.engine
        if not e.ih[J_STARTED]:
            raise SimulationError("no sample pushed yet")
        fh = e.fh
        t_rel = fh.item(H_T_REL)
        return self._outk.values(fh.item(H_T_START) + t_rel, t_rel, e.ih.item(J_NSTEPS), e.y, self.system.seg)

    def outputs_at(self, snaps: Snapshots) -> OutputBlock:
        """Outputs at the instants of ``snaps`` in one compiled call. A failure at an instant
        raises (``NonFiniteOutputError``, the model's ``SimulationError``) with ``.block``: the
        outputs of the instants before it."""
        return self._outk.block(snaps.t, snaps.t_rel, snaps.n_steps, snaps.y, snaps.seg)
