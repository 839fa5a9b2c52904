"""Time integrators for the simulator: one ``advance(system, t0, y0, t1)`` per input sample.

All methods integrate ``dy/dt = system.rhs(t, y)`` from ``t0`` to exactly ``t1`` (s) and return
the new state and a ``StepStats``. The simulator calls ``advance`` once per input-sample interval
(1–10 ms), so the fixed-step methods keep Python work and allocations out of their inner loops
(stage buffers are reused, matrices are cached by ``(key, h)``).

Methods (see ``INTEGRATORS``):

- ``rk4``: classic explicit RK4. Cheap, but only stable for ``h·|λ| ≤ 2.83`` on the imaginary
  axis: at the gyro nutation (≈ 800 rad/s) it needs ``h ≲ 3.5 ms``, at 1e4 rad/s ``h ≲ 0.28 ms``.
- ``dop853``, ``rk45``, ``radau``: scipy's ``OdeSolver`` step API with warm-started step size.
- ``implicit_midpoint``: A-stable, symplectic, keeps quadratic invariants (e.g. the Jacobi
  integral ``T2 = ½ ẋᵀA*ẋ`` of the torque-free gyro) to round-off. Stage solved by simplified
  Newton to round-off (2 eps relative, 2-norm).
- ``etd2``, ``etd4``: exponential integrators for ``f(t, y) = A y + g(t, y)`` with ``A`` from
  ``system.linear_part()`` (ETD2RK of Cox–Matthews, ETDRK4 of Krogstad). Exact for linear
  systems with constant input, unconditionally stable for the undamped (imaginary) modes of A.

Non-finite results are never returned: every method raises
``gyro_platform.errors.SimulationError("non-finite state after <method> step at t=…")``.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, Hashable, Protocol

import numpy as np
import scipy.integrate
import scipy.linalg

from .errors import SimulationError

__all__ = ["OdeSystem", "StepStats", "Integrator", "make_integrator", "INTEGRATORS"]

_EPS = np.finfo(float).eps
_CACHE_SIZE = 64          # (key, h) entries kept per integrator; h takes few values per run
_NEWTON_TOL = 2 * _EPS    # implicit midpoint: Newton to round-off (relative, 2-norm), so
                          # quadratic invariants drift by round-off only, not by 1e-14 per step
_NEWTON_MAXITER = 10
_MAX_HALVINGS = 12        # implicit midpoint: give up after h has been halved this often


class OdeSystem(Protocol):
    """What an integrator needs from the model.

    Required: ``rhs(t, y) -> dy/dt`` (shape (n,); t in s). Optional, found with ``getattr``:

    - ``linear_part() -> (A, key)``: ``f(t, y) = A y + g(t, y)`` with ``g`` slow/mild; ``key``
      (hashable) identifies ``A`` so that expm/φ/LU results can be cached. Needed by etd2/etd4;
      used as the Newton matrix by implicit_midpoint and as the Jacobian by radau.
    - ``jacobian(t, y) -> ∂f/∂y`` (n×n): exact Jacobian, preferred over ``linear_part``.
    """

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray: ...


@dataclass
class StepStats:
    """Work and quality of one ``advance`` call.

    ``n_steps``: accepted (sub)steps; ``n_rhs``: calls of ``system.rhs`` (including
    finite-difference Jacobians); ``error_estimate``: max-norm local error estimate of the last
    step in state units (nan if the method has no embedded estimate); ``n_halvings``: times
    implicit_midpoint halved its substep because Newton did not converge (0 otherwise).
    """

    n_steps: int
    n_rhs: int
    error_estimate: float
    n_halvings: int = 0


class Integrator(ABC):
    """Base class. Subclasses set ``name``, ``order`` and ``adaptive`` and implement ``_advance``."""

    name: str = ""
    #: the method consults ``system.linear_part()`` (so the system keeps it current per step)
    uses_linear_part: bool = False
    order: int = 0
    adaptive: bool = False

    def advance(self, system: OdeSystem, t0: float, y0: np.ndarray, t1: float
                ) -> tuple[np.ndarray, StepStats]:
        """Integrate from ``t0`` to exactly ``t1`` (s, ``t1 > t0``); ``y0`` is not modified.

        Returns ``(y1, stats)``. Raises ``ValueError`` for a bad interval or state shape and
        ``SimulationError`` if the state becomes non-finite or the method fails.
        """
        t0 = float(t0)
        t1 = float(t1)
        if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
            raise ValueError(f"{self.name}: need finite t1 > t0, got t0={t0!r}, t1={t1!r}")
        y = np.array(y0, dtype=float)          # always a copy
        if y.ndim != 1:
            raise ValueError(f"{self.name}: y0 must be 1-D, got shape {y.shape}")
        y, stats = self._advance(system, t0, y, t1)
        if not np.isfinite(y).all():
            raise SimulationError(f"non-finite state after {self.name} step at t={t1!r}")
        return y, stats

    @abstractmethod
    def _advance(self, system: OdeSystem, t0: float, y: np.ndarray, t1: float
                 ) -> tuple[np.ndarray, StepStats]:
        """Integrate in place of the owned copy ``y``; interval already checked."""

    def reset(self) -> None:
        """Forget warm-start data and caches."""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} order={self.order}>"


# --------------------------------------------------------------------------- fixed step


class _FixedStep(Integrator):
    """Fixed-step base: ``nsub = ceil((t1 - t0)/max_step)`` equal substeps per call.

    A relative overshoot of 1e-9 is tolerated, so that an interval of ``max_step`` plus
    round-off is one substep, not two.
    """

    adaptive = False

    def __init__(self, max_step: float) -> None:
        self.max_step = float(max_step)
        self._n = -1             # state size the buffers are made for
        self._cache: dict[tuple[Hashable, float], Any] = {}

    def _nsub(self, t0: float, t1: float) -> tuple[int, float]:
        nsub = max(1, math.ceil((t1 - t0) / self.max_step - 1e-9))
        return nsub, (t1 - t0) / nsub

    cache_size = _CACHE_SIZE

    def _cached(self, key: Hashable, h: float, make: Callable[[], Any]) -> Any:
        """LRU cache of matrices by (key, h); ``h`` is compared exactly (it is exact: t1 - t0)."""
        k = (key, h)
        val = self._cache.pop(k, None)
        if val is None:
            val = make()
            if len(self._cache) >= self.cache_size:
                del self._cache[next(iter(self._cache))]
        self._cache[k] = val
        return val

    def reset(self) -> None:
        self._cache.clear()
        self._n = -1


class RK4(_FixedStep):
    """Classic explicit fourth-order Runge–Kutta."""

    name, order = "rk4", 4

    def _buffers(self, n: int) -> None:
        if n != self._n:
            self._K = np.empty((4, n))
            self._tmp = np.empty(n)
            self._n = n

    def _advance(self, system, t0, y, t1):
        nsub, h = self._nsub(t0, t1)
        self._buffers(y.size)
        rhs = system.rhs
        K = self._K
        k1, k2, k3, k4 = K
        tmp = self._tmp
        hh = 0.5 * h
        w = np.array([h / 6.0, h / 3.0, h / 3.0, h / 6.0])
        mul, dot = np.multiply, np.dot
        for i in range(nsub):
            t = t0 + i * h
            k1[:] = rhs(t, y)
            mul(k1, hh, out=tmp); tmp += y
            k2[:] = rhs(t + hh, tmp)
            mul(k2, hh, out=tmp); tmp += y
            k3[:] = rhs(t + hh, tmp)
            mul(k3, h, out=tmp); tmp += y
            k4[:] = rhs(t + h, tmp)
            dot(w, K, out=tmp)
            y += tmp
        return y, StepStats(nsub, 4 * nsub, math.nan)


def _phi_blocks(Z: np.ndarray, p: int) -> list[np.ndarray]:
    """``[e^Z, φ1(Z), …, φp(Z)]`` from one expm of the augmented block matrix
    ``[[Z, I, 0…], [0, 0, I…], …]`` (size (p+1)n). No inverse of Z is needed (Z may be singular)."""
    n = Z.shape[0]
    W = np.zeros(((p + 1) * n, (p + 1) * n))
    W[:n, :n] = Z
    for k in range(p):
        W[k * n:(k + 1) * n, (k + 1) * n:(k + 2) * n] = np.eye(n)
    E = scipy.linalg.expm(W)
    return [E[:n, k * n:(k + 1) * n] for k in range(p + 1)]


class _ETD(_FixedStep):
    """Explicit exponential Runge–Kutta method for ``f = A y + g`` (A from ``linear_part``).

    Stages ``U_i = e^{c_i hA} y + h Σ_j a_ij(hA) G_j``, ``G_j = g(t + c_j h, U_j)``, output
    ``e^{hA} y + h Σ_i b_i(hA) G_i``. Because ``h Σ_j a_ij A = e^{c_i hA} − I`` this is evaluated
    as ``U_i = y + Σ_j M_ij f_j`` with ``f_j = rhs(U_j)`` and matrices ``M`` precomputed per
    (key, h): one matrix-vector product per stage, ``g`` is never formed.
    """

    uses_linear_part = True

    c: tuple[float, ...] = ()

    @staticmethod
    def _tableau(A: np.ndarray, h: float):  # -> (a, b) lists of n×n matrices (None = 0)
        raise NotImplementedError

    def _make(self, A: np.ndarray, h: float) -> list[np.ndarray]:
        a, b = self._tableau(A, h)
        s = len(b)
        M: list[list[np.ndarray]] = [[] for _ in range(s)]
        out = []
        for i in range(1, s + 1):
            row = a[i] if i < s else b
            Mi = []
            for k in range(i):
                m = h * row[k] if row[k] is not None else np.zeros_like(A)
                for j in range(k + 1, i):
                    if row[j] is not None:
                        m = m - h * (row[j] @ (A @ M[j][k]))
                Mi.append(m)
            if i < s:
                M[i] = Mi
            out.append(np.ascontiguousarray(np.hstack(Mi)))
        return out          # out[i-1]: n × i·n, for stage i (i < s) and the output (i = s)

    def _advance(self, system, t0, y, t1):
        lp = getattr(system, "linear_part", None)
        if lp is None:
            raise TypeError(f"integrator {self.name!r} needs system.linear_part() -> (A, key)")
        A, key = lp()
        nsub, h = self._grid_step(t0, t1)
        n = y.size
        Ms = self._cached(key, h, lambda: self._make(self._check_A(A, n), h))
        s = len(self.c)
        if n != self._n:
            self._Kf = np.empty(s * n)
            self._Kv = [self._Kf[j * n:(j + 1) * n] for j in range(s)]
            self._Kp = [self._Kf[:j * n] for j in range(s + 1)]
            self._U = np.empty(n)
            self._n = n
        Kv, Kp, U = self._Kv, self._Kp, self._U
        rhs, dot = system.rhs, np.dot
        ch = [ci * h for ci in self.c]
        for i in range(nsub):
            t = t0 + i * h
            Kv[0][:] = rhs(t, y)
            for j in range(1, s):
                dot(Ms[j - 1], Kp[j], out=U)
                U += y
                Kv[j][:] = rhs(t + ch[j], U)
            dot(Ms[s - 1], Kp[s], out=U)
            y += U
        return y, StepStats(nsub, s * nsub, math.nan)

    #: exponential steps are multiples of max_step / GRID, so a few matrices serve all steps
    GRID = 256
    #: room for every grid step of one- and two-substep intervals (bounded by construction)
    cache_size = 2 * GRID + 16

    def _grid_step(self, t0: float, t1: float) -> tuple[int, float]:
        """(nsub, h) with h on the grid q = max_step/GRID. Every new step size would need a new
        matrix exponential (~ms), and real sample times jitter, so the step is rounded to the
        grid and the rounding remainder is carried into the next call: the state lags the
        requested time by at most nsub·q/2 (2 µs per substep at max_step = 1 ms) and the lag
        never grows.
        Uniform sampling at max_step is exact (h = max_step, no remainder)."""
        dt = (t1 - t0) + self._carry
        q = self.max_step / self.GRID
        nsub = max(1, math.ceil(dt / self.max_step - 1e-9))
        h = max(q, round(dt / nsub / q) * q)
        self._carry = dt - nsub * h
        return nsub, h

    def reset(self) -> None:
        super().reset()
        self._carry = 0.0

    _carry = 0.0

    def _check_A(self, A, n: int) -> np.ndarray:
        A = np.asarray(A, dtype=float)
        if A.shape != (n, n):
            raise ValueError(f"{self.name}: linear_part A has shape {A.shape}, state has {n}")
        return A


class ETD2(_ETD):
    """ETD2RK (Cox & Matthews 2002): order 2, exact for constant g."""

    name, order, c = "etd2", 2, (0.0, 1.0)

    @staticmethod
    def _tableau(A, h):
        E, p1, p2 = _phi_blocks(h * A, 2)
        return [[], [p1]], [p1 - p2, p2]


class ETD4(_ETD):
    """ETDRK4 of Krogstad (2005): classical order 4, stiff order 3, exact for constant g."""

    name, order, c = "etd4", 4, (0.0, 0.5, 0.5, 1.0)

    @staticmethod
    def _tableau(A, h):
        E, p1, p2, p3 = _phi_blocks(h * A, 3)
        Eh, p1h, p2h = _phi_blocks(0.5 * h * A, 2)
        a = [[],
             [0.5 * p1h],
             [0.5 * p1h - p2h, p2h],
             [p1 - 2.0 * p2, None, 2.0 * p2]]
        b = [p1 - 3.0 * p2 + 4.0 * p3, 2.0 * p2 - 4.0 * p3, 2.0 * p2 - 4.0 * p3, -p2 + 4.0 * p3]
        return a, b


class ImplicitMidpoint(_FixedStep):
    """Implicit midpoint rule ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)``.

    The midpoint stage ``Y = y0 + (h/2) f(t + h/2, Y)`` is solved by simplified Newton with the
    matrix ``(I − h/2 J)⁻¹`` (J: ``system.jacobian`` at (t0, y0) per call, else ``linear_part``
    A cached by (key, h), else a forward-difference Jacobian per call), until the increment, or
    the remainder estimated from the contraction rate, is ≤ 2 eps·‖Y‖₂ (or the iteration has
    stalled within 100× that, i.e. at round-off). Then quadratic invariants drift by round-off
    only. If Newton fails within 10 iterations the substep is halved for the rest of the
    call (``StepStats.n_halvings``); after 12 halvings ``SimulationError`` is raised.
    """

    uses_linear_part = True

    name, order = "implicit_midpoint", 2

    def _advance(self, system, t0, y, t1):
        n = y.size
        if n != self._n:
            self._Y = np.empty(n)
            self._r = np.empty(n)
            self._d = np.empty(n)
            self._fp = np.zeros(n)              # last f: predictor Y ≈ y + (h/2) f
            self._n = n
        Y, r, d, fp = self._Y, self._r, self._d, self._fp
        rhs, dot, mul, sqrt = system.rhs, np.dot, np.multiply, math.sqrt
        nrhs = 0
        jac = getattr(system, "jacobian", None)
        lp = getattr(system, "linear_part", None)
        if jac is not None:
            J, key = np.asarray(jac(t0, y), dtype=float), None
        elif lp is not None:
            J, key = lp()
            J = np.asarray(J, dtype=float)
        else:
            J, key = _fd_jacobian(rhs, t0, y), None
            nrhs += n

        def newton_matrix(h):
            make = lambda: _inv(np.eye(n) - 0.5 * h * J)
            return make() if key is None else self._cached(key, h, make)

        nsub, h = self._nsub(t0, t1)
        Minv = newton_matrix(h)
        t, i, steps, halvings = t0, 0, 0, 0
        while i < nsub:
            tm = t + (i + 0.5) * h
            hh = 0.5 * h
            mul(fp, hh, out=Y)
            Y += y
            dprev = math.inf
            ok = nonfinite = False
            for _ in range(_NEWTON_MAXITER):
                f = rhs(tm, Y)
                nrhs += 1
                np.subtract(Y, y, out=r)
                mul(f, hh, out=d)
                r -= d                          # residual of Y − y − (h/2) f(Y)
                dot(Minv, r, out=d)
                Y -= d
                dn = sqrt(dot(d, d))
                tol = _NEWTON_TOL * sqrt(dot(Y, Y))
                if dn <= tol:
                    ok = True
                    break
                if not math.isfinite(dn):
                    nonfinite = True
                    break
                if dprev < math.inf:
                    theta = dn / dprev          # contraction rate of the simplified Newton
                    if theta < 1.0 and theta * dn <= (1.0 - theta) * tol:
                        ok = True               # estimated remaining error is below tol
                        break
                    if theta >= 0.5 and dn <= 100.0 * tol:
                        ok = True               # no longer contracting: at round-off level
                        break
                dprev = dn
            else:
                ok = not nonfinite and dn <= 100.0 * tol    # out of iterations at round-off level
            if ok:
                fp[:] = f
                mul(Y, 2.0, out=r)
                np.subtract(r, y, out=y)        # y1 = 2Y − y0
                i += 1
                steps += 1
                continue
            fp[:] = 0.0
            halvings += 1
            if halvings > _MAX_HALVINGS:
                why = "non-finite state" if nonfinite else "Newton iteration did not converge"
                raise SimulationError(f"{why} in {self.name} step at t={t + i * h!r} "
                                      f"even with h={h!r} s")
            t = t + i * h                       # restart the rest of the interval at h/2
            nsub, i = 2 * (nsub - i), 0
            h = (t1 - t) / nsub
            Minv = newton_matrix(h)
        return y, StepStats(steps, nrhs, math.nan, halvings)


def _inv(M: np.ndarray) -> np.ndarray:
    """Inverse via LU (used once per (key, h) or per call, never in the step loop)."""
    return scipy.linalg.lu_solve(scipy.linalg.lu_factor(M), np.eye(M.shape[0]))


def _fd_jacobian(rhs, t: float, y: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian (n extra rhs calls); accurate enough for Newton."""
    f0 = np.asarray(rhs(t, y), dtype=float).copy()
    n = y.size
    J = np.empty((n, n))
    scale = max(np.abs(y).max(), 1e-8) * 1e-3
    yp = y.copy()
    for j in range(n):
        dj = math.sqrt(_EPS) * max(abs(y[j]), scale)
        yp[j] = y[j] + dj
        J[:, j] = (np.asarray(rhs(t, yp), dtype=float) - f0) / (yp[j] - y[j])
        yp[j] = y[j]
    return J


# --------------------------------------------------------------------------- adaptive (scipy)


class _Scipy(Integrator):
    """Adaptive method through scipy's ``OdeSolver`` step API, one solver per call.

    The step size proposed at the end of a call is the first step of the next call (warm
    start); a last step shortened to hit ``t1`` does not shrink it. Steps never pass ``t1``
    and are otherwise chosen by the tolerances only (``max_step`` applies to fixed-step methods).
    """

    adaptive = True
    solver_cls: type = scipy.integrate.OdeSolver

    def __init__(self, rtol: float, atol: float) -> None:
        self.rtol, self.atol = float(rtol), float(atol)
        self._h: float | None = None

    def reset(self) -> None:
        self._h = None

    def _solver_kwargs(self, system) -> dict:
        return {}

    def _error_estimate(self, solver) -> float:
        try:
            err = solver._estimate_error(solver.K, solver.h_previous)
            return float(np.abs(err).max())
        except (AttributeError, TypeError):
            return math.nan

    def _advance(self, system, t0, y, t1):
        h = self._h
        solver = self.solver_cls(system.rhs, t0, y, t1, rtol=self.rtol, atol=self.atol,
                                 first_step=None if h is None else min(h, t1 - t0),
                                 **self._solver_kwargs(system))
        steps = 0
        proposal = solver.h_abs if h is None else max(h, solver.h_abs)
        while solver.status == "running":
            t_before = solver.t
            msg = solver.step()
            if solver.status == "failed":
                raise SimulationError(f"{self.name} failed at t={float(solver.t)!r}: {msg} "
                                      "(non-finite or too stiff right-hand side?)")
            steps += 1
            if solver.t == t1 and proposal > t1 - t_before:
                # last step cut short to t1 (and so accepted at its first try): do not let
                # the short step shrink the proposal
                self._h = max(proposal, solver.h_abs)
            else:
                self._h = solver.h_abs
            proposal = solver.h_abs
        return solver.y, StepStats(steps, solver.nfev, self._error_estimate(solver))


class DOP853(_Scipy):
    """Dormand–Prince 8(5,3) (scipy ``DOP853``)."""

    name, order, solver_cls = "dop853", 8, scipy.integrate.DOP853


class RK45(_Scipy):
    """Dormand–Prince 5(4) (scipy ``RK45``)."""

    name, order, solver_cls = "rk45", 5, scipy.integrate.RK45


class Radau(_Scipy):
    """Radau IIA order 5 (scipy ``Radau``); Jacobian from ``system.jacobian``, else the constant
    ``linear_part`` A, else scipy's finite differences. No error estimate is exposed (nan)."""

    uses_linear_part = True

    name, order, solver_cls = "radau", 5, scipy.integrate.Radau

    def _solver_kwargs(self, system):
        jac = getattr(system, "jacobian", None)
        if jac is None and getattr(system, "linear_part", None) is not None:
            jac = np.asarray(system.linear_part()[0], dtype=float)
        return {"jac": jac}

    def _error_estimate(self, solver) -> float:
        return math.nan


# --------------------------------------------------------------------------- registry

INTEGRATORS: dict[str, str] = {
    "rk4": "classic explicit Runge-Kutta 4, fixed step max_step (stable only for h*|lambda| <= 2.8)",
    "dop853": "Dormand-Prince 8(5,3), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "rk45": "Dormand-Prince 5(4), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "radau": "Radau IIA order 5, implicit adaptive (rtol/atol), for stiff damped systems",
    "implicit_midpoint": "implicit midpoint, fixed step, A-stable, symplectic, keeps quadratic invariants",
    "etd2": "exponential ETD2RK (Cox-Matthews), fixed step, needs linear_part; exact for linear + const input",
    "etd4": "exponential ETDRK4 (Krogstad), fixed step, needs linear_part; exact for linear + const input",
}

_CLASSES: dict[str, type[Integrator]] = {
    "rk4": RK4, "dop853": DOP853, "rk45": RK45, "radau": Radau,
    "implicit_midpoint": ImplicitMidpoint, "etd2": ETD2, "etd4": ETD4,
}


def make_integrator(name: str, *, max_step: float = 1e-3, rtol: float = 1e-8,
                    atol: float = 1e-12) -> Integrator:
    """A new integrator by name (see ``INTEGRATORS``).

    ``max_step`` (s): substep bound of the fixed-step methods; ``rtol``, ``atol`` (state units):
    tolerances of the adaptive methods. Raises ``ValueError`` for an unknown name or bad values.
    """
    cls = _CLASSES.get(name)
    if cls is None:
        raise ValueError(f"unknown integrator {name!r}; known: {', '.join(INTEGRATORS)}")
    if issubclass(cls, _FixedStep):
        if not (0.0 < max_step < math.inf):
            raise ValueError(f"{name}: max_step must be a positive finite time in s, got {max_step!r}")
        return cls(max_step)
    if not (rtol > 0.0 and atol > 0.0):
        raise ValueError(f"{name}: rtol and atol must be positive, got {rtol!r}, {atol!r}")
    return cls(rtol, atol)
