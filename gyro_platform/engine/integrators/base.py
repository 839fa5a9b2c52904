"""Time integrators for the simulator: one ``advance(system, t0, y0, t1)`` per input sample.

All methods integrate ``dy/dt = system.rhs(t, y)`` from ``t0`` to exactly ``t1`` (s) and return
the new state and a ``StepStats``. The simulator calls ``advance`` once per input-sample interval
(1–10 ms).

**Accuracy is an input.** Every method is given ``rtol``/``atol`` and estimates its local error
at every (sub)step; the weighted norm ``‖err‖ = RMS(err_i / (atol + rtol·max(|y0_i|, |y1_i|)))``
must be ≤ 1 for a step to be accepted (the scipy convention). ``max_step`` (s) is always an
upper bound of the step. The budget is ``max_substeps``: no step shorter than
``max_step / max_substeps``. A method that cannot meet the tolerance within the budget raises
``SimulationError`` naming the time, the method, the estimate and the tolerance; ``y0`` is
untouched (the caller keeps its state).

Methods (see ``INTEGRATORS``):

- ``rk4``: classic RK4 with an embedded third-order estimate (the FSAL stage f(t+h, y1):
  ``err = h/6 (k4 − k5)``). Explicit: at h·ω > 2.8 it must substep; it damps nutation by
  ≈ (hω)⁶/72 per step, which the tolerance bounds.
- ``etd2``, ``etd4``: exponential integrators for ``f(t, y) = A y + g(t, y)`` with ``A`` from
  ``system.linear_part()`` (the model at rest: ETD2RK of Cox–Matthews, ETDRK4 of Krogstad),
  estimate = difference to the embedded lower-order stage at c = 1. Exact for the undamped
  gyroscopic modes; at large angles the remainder grows, and they substep or refuse.
- ``exprb``: exponential Rosenbrock exprb32 (Hochbruck–Ostermann–Schweitzer 2009), order 3,
  re-linearised at every step (``system.jacobian`` and ∂f/∂t), embedded order-2 estimate.
  Valid at large angles and for fast rotors: its cost does not depend on the spin.
- ``implicit_midpoint``: A-stable, symplectic, keeps quadratic invariants to round-off;
  estimate by step doubling (the two half steps are kept, ``err = (y_½½ − y_1)/3``).
- ``dop853``, ``rk45``, ``radau``: scipy's ``OdeSolver`` step API, warm-started step size,
  bounded by ``max_step`` and the budget.

The fixed-grid methods (rk4, etd*, exprb, implicit_midpoint) use one step-size controller: the
interval is cut into ``nsub·2^level`` equal substeps; an interval with a rejected substep is
redone at a finer level (``level += max(1, ceil(log2 ‖err‖ / (q+1)))``, q the estimator's
order), and after an interval whose worst substep was ≤ ``0.5·2^-(q+1)`` the next interval
tries one level coarser. The compiled batch loop (``fastpath``) runs the same controller.

Non-finite results are never returned: ``SimulationError``.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, Hashable, Protocol

import numpy as np
import scipy.integrate
import scipy.linalg
from numba import njit

from ..errors import SimulationError, ToleranceError

__all__ = ["OdeSystem", "StepStats", "Integrator", "make_integrator", "INTEGRATORS", "error_norm",
           "MAX_SUBSTEPS"]

_EPS = np.finfo(float).eps
_CACHE_SIZE = 64          # (key, h) entries kept per integrator; h takes few values per run
_NEWTON_TOL = 2 * _EPS    # implicit midpoint: Newton to round-off (relative, 2-norm), so
                          # quadratic invariants drift by round-off only, not by 1e-14 per step
_NEWTON_MAXITER = 10
#: default budget: no step shorter than max_step / MAX_SUBSTEPS (0.24 µs at 1 ms)
MAX_SUBSTEPS = 4096
#: controller: after an interval whose worst normalised error is ≤ COARSEN·2^-(q+1), the next
#: interval tries a level coarser (2× the step); a rejection jumps at most MAX_JUMP levels
COARSEN = 0.5
MAX_JUMP = 4


def error_norm(err: np.ndarray, y0: np.ndarray, y1: np.ndarray, rtol: float, atol: float) -> float:
    """Weighted RMS norm of a local error estimate (≤ 1: within tolerance; scipy's convention)."""
    sc = atol + rtol * np.maximum(np.abs(y0), np.abs(y1))
    return float(np.sqrt(np.mean((err / sc) ** 2)))


def next_level(level: int, norm: float, q1: int) -> int:
    """Level after a rejected interval with worst normalised error ``norm`` (q1 = q + 1)."""
    if not norm < math.inf:                     # nan or inf: non-finite, Newton failure
        return level + 1
    return level + min(MAX_JUMP, max(1, math.ceil(math.log2(norm) / q1)))


def coarser_level(level: int, norm: float, q1: int) -> int:
    """Level for the next interval after an accepted one."""
    return level - 1 if level > 0 and norm * 2.0 ** q1 <= COARSEN else level


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
    finite-difference Jacobians); ``error_estimate``: largest local error estimate (max-norm,
    state units: rad, rad/s, …) of the accepted steps; ``error_norm``: largest weighted norm of
    those estimates (≤ 1 = within rtol/atol); ``n_rejected``: rejected (redone) steps or
    intervals; ``level``: substep level used (substeps = ceil(dt/max_step)·2^level).
    """

    n_steps: int
    n_rhs: int
    error_estimate: float
    error_norm: float = math.nan
    n_rejected: int = 0
    level: int = 0


class Integrator(ABC):
    """Base class. Subclasses set ``name``, ``order`` and ``adaptive`` and implement ``_advance``.

    ``max_step`` (s): upper bound of every step; ``rtol``, ``atol``: tolerances (state units);
    ``max_substeps``: budget, the shortest step allowed is ``max_step / max_substeps``."""

    name: str = ""
    #: the method consults ``system.linear_part()`` (so the system keeps it current per step)
    uses_linear_part: bool = False
    order: int = 0
    #: every method adapts its step to the tolerance; kept for the scipy family's warm start
    adaptive: bool = True

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        self.max_step = float(max_step)
        self.rtol, self.atol = float(rtol), float(atol)
        self.max_substeps = int(max_substeps)
        self.max_level = max(0, int(math.floor(math.log2(self.max_substeps))))

    def advance(self, system: OdeSystem, t0: float, y0: np.ndarray, t1: float
                ) -> tuple[np.ndarray, StepStats]:
        """Integrate from ``t0`` to exactly ``t1`` (s, ``t1 > t0``); ``y0`` is not modified.

        Returns ``(y1, stats)``. Raises ``ValueError`` for a bad interval or state shape and
        ``SimulationError`` if the state becomes non-finite or the tolerance cannot be met.
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

    def refuse(self, t: float, estimate: float, norm: float, h: float, why: str = "") -> ToleranceError:
        """The error raised when the tolerance cannot be met within the budget (t: the
        integration time of the failing step, s)."""
        if not norm < math.inf:
            why = why or " (non-finite state or failed stage)"
        return ToleranceError(
            f"{self.name} cannot meet the tolerance at t={t!r} s: error estimate {estimate:.3g} "
            f"({norm:.3g}× the tolerance rtol={self.rtol:g}, atol={self.atol:g}) even with steps of "
            f"{h:.3g} s (budget: max_step/{self.max_substeps}){why}; state kept at the interval start")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} order={self.order}>"


# --------------------------------------------------------------------------- controlled (fixed grid)


class _Controlled(Integrator):
    """Methods on a grid of ``nsub·2^level`` equal substeps per interval (see module doc).

    Subclasses implement ``_substeps(system, t0, y0, nsub, h)`` returning ``(y1, norm, est,
    n_rhs, t_bad)``: the worst normalised error and max-norm estimate over the substeps, and
    the start of the first rejected substep (the run stops there; ``norm`` > 1 or nan)."""

    #: order + 1 of the local error the estimator measures (err ∝ h^q1)
    q1: int = 2
    #: the method substeps on a grid; the step level is carried between calls
    level: int = 0

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        super().__init__(max_step, rtol, atol, max_substeps)
        self._n = -1
        self._cache: dict[tuple[Hashable, float], Any] = {}
        self.level = 0

    cache_size = _CACHE_SIZE

    def _base(self, t0: float, t1: float) -> tuple[int, float]:
        """(nsub, h): ``ceil((t1 − t0)/max_step)`` equal steps. A relative overshoot of 1e-9 is
        tolerated, so that an interval of ``max_step`` plus round-off is one substep, not two."""
        nsub = max(1, math.ceil((t1 - t0) / self.max_step - 1e-9))
        return nsub, (t1 - t0) / nsub

    def _cached(self, key: Hashable, h: float, make: Callable[[], Any]) -> Any:
        """LRU cache of matrices by (key, h); ``h`` is compared exactly."""
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
        self.level = 0

    def _prepare(self, system, t0: float, y0: np.ndarray) -> int:
        """Per-call setup (Jacobians, linear part); returns the rhs calls it made."""
        return 0

    def _norm(self, err, y0, y1) -> float:
        return error_norm(err, y0, y1, self.rtol, self.atol)

    def _advance(self, system, t0, y, t1):
        nsub0, h0 = self._base(t0, t1)
        nrhs = self._prepare(system, t0, y)
        level, rejected = self.level, 0
        while True:
            nsub = nsub0 << level
            h = h0 / (1 << level)
            y1, norm, est, n, t_bad = self._substeps(system, t0, y, nsub, h)
            nrhs += n
            if norm <= 1.0:
                break
            rejected += 1
            new = next_level(level, norm, self.q1)
            if not norm < math.inf:
                new = level + MAX_JUMP
            if new > self.max_level:
                if level < self.max_level:
                    new = self.max_level               # try the budget's own limit once
                else:
                    raise self.refuse(t_bad, est, norm, h)
            level = new
        self.level = coarser_level(level, norm, self.q1)
        return y1, StepStats(nsub, nrhs, est, norm, rejected, level)

    @abstractmethod
    def _substeps(self, system, t0: float, y0: np.ndarray, nsub: int, h: float):
        ...


def _bad(norm: float) -> bool:
    return not norm <= 1.0


class RK4(_Controlled):
    """Classic explicit RK4; embedded third-order estimate ``h/6 (k4 − k5)``, k5 = f(t+h, y1)
    (first same as last: k5 is the next substep's k1)."""

    name, order, q1 = "rk4", 4, 4

    def _substeps(self, system, t0, y0, nsub, h):
        rhs = system.rhs
        hh, h6 = 0.5 * h, h / 6.0
        y = y0.copy()
        k1 = np.array(rhs(t0, y), dtype=float)
        nrhs, worst, est = 1, 0.0, 0.0
        for i in range(nsub):
            t = t0 + i * h
            k2 = rhs(t + hh, y + hh * k1)
            k3 = rhs(t + hh, y + hh * k2)
            k4 = rhs(t + h, y + h * k3)
            y1 = y + h6 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            k5 = np.array(rhs(t + h, y1), dtype=float)
            nrhs += 4
            err = h6 * (k4 - k5)
            nrm = self._norm(err, y, y1)
            est = max(est, float(np.abs(err).max()))
            worst = max(worst, nrm) if nrm == nrm else math.nan
            if _bad(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y, k1 = y1, k5
        return y, worst, est, nrhs, t0


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


@njit(cache=True)
def _matmul(A, B, out):
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.0
        for k in range(n):
            a = A[i, k]
            if a != 0.0:
                for j in range(n):
                    out[i, j] += a * B[k, j]


@njit(cache=True)
def _expm_small(W):
    """e^W for a small matrix: scaling and squaring (‖W/2^s‖₁ ≤ 1/8) with a Taylor polynomial
    of degree 12 by Horner (truncation < 1e-17). Loops only, no BLAS (on a shared machine the
    threaded BLAS costs more than it saves at n ≈ 20). The cost grows like log‖W‖, so a fast
    rotor (large ‖hJ‖) costs only a few more squarings."""
    n = W.shape[0]
    norm = 0.0
    for j in range(n):
        c = 0.0
        for i in range(n):
            c += abs(W[i, j])
        norm = max(norm, c)
    s = 0
    while norm > 0.125:
        norm *= 0.5
        s += 1
    X = W * (0.5 ** s)
    E = np.eye(n)
    T = np.empty((n, n))
    for k in range(12, 0, -1):          # E = I + X/k · E  (Horner)
        _matmul(X, E, T)
        for i in range(n):
            for j in range(n):
                E[i, j] = T[i, j] / k + (1.0 if i == j else 0.0)
    for _ in range(s):
        _matmul(E, E, T)
        for i in range(n):
            for j in range(n):
                E[i, j] = T[i, j]
    return E


def _phi_apply(Z: np.ndarray, bs: list) -> np.ndarray:
    """``Σ_j φ_j(Z) b_j`` (j = 1…p, ``bs = [b_1, …, b_p]``, None = 0) as the last column of the
    exponential of the augmented matrix ``[[Z, B], [0, K]]`` of size n + p (Al-Mohy & Higham
    2011, Thm 2.1; B = [b_p … b_1], K the shift)."""
    n, p = Z.shape[0], len(bs)
    W = np.zeros((n + p, n + p))
    W[:n, :n] = Z
    for j, b in enumerate(bs, start=1):
        if b is not None:
            W[:n, n + p - j] = b
    for k in range(p - 1):
        W[n + k, n + k + 1] = 1.0
    return _expm_small(W)[:n, n + p - 1]


class _ETD(_Controlled):
    """Explicit exponential Runge–Kutta method for ``f = A y + g`` (A from ``linear_part``).

    Stages ``U_i = e^{c_i hA} y + h Σ_j a_ij(hA) G_j``, ``G_j = g(t + c_j h, U_j)``, output
    ``e^{hA} y + h Σ_i b_i(hA) G_i``. Because ``h Σ_j a_ij A = e^{c_i hA} − I`` this is evaluated
    as ``U_i = y + Σ_j M_ij f_j`` with ``f_j = rhs(U_j)`` and matrices ``M`` precomputed per
    (key, h): one matrix-vector product per stage, ``g`` is never formed. The last stage has
    c = 1 and is a lower-order solution: ``err = y1 − U_last``.
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

    def matrices(self, A: np.ndarray, key: Hashable, h: float) -> list[np.ndarray]:
        """Stage matrices for step h (cached by (key, h))."""
        return self._cached(key, h, lambda: self._make(self._check_A(A, A.shape[0]), h))

    def _prepare(self, system, t0, y0):
        lp = getattr(system, "linear_part", None)
        if lp is None:
            raise TypeError(f"integrator {self.name!r} needs system.linear_part() -> (A, key)")
        A, key = lp()
        self._A, self._key = self._check_A(A, y0.size), key
        return 0

    #: estimate by the defect ``(h/3)(f(t+h, y1) − f(U) − A(y1 − U))`` (one more rhs, first same
    #: as last; order h³ like the method's own error) instead of ``y1 − U``
    defect = False

    def _substeps(self, system, t0, y0, nsub, h):
        Ms = self.matrices(self._A, self._key, h)
        A = self._A
        n, s = y0.size, len(self.c)
        K = np.empty((s, n))
        Kf = K.reshape(-1)
        rhs = system.rhs
        y = y0.copy()
        worst = est = 0.0
        nrhs = 0
        have_k1 = False
        for i in range(nsub):
            t = t0 + i * h
            if not have_k1:
                K[0] = rhs(t, y)
                nrhs += 1
            U = y
            for j in range(1, s):
                U = y + Ms[j - 1] @ Kf[:j * n]
                K[j] = rhs(t + self.c[j] * h, U)
            nrhs += s - 1
            y1 = y + Ms[s - 1] @ Kf
            if self.defect:
                k5 = np.asarray(rhs(t + h, y1), dtype=float)
                nrhs += 1
                err = h / 3.0 * (k5 - K[s - 1] - A @ (y1 - U))
            else:
                err = y1 - U
            nrm = self._norm(err, y, y1)
            est = max(est, float(np.abs(err).max()))
            worst = max(worst, nrm)
            if _bad(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y = y1
            if self.defect:
                K[0] = k5
                have_k1 = True
        return y, worst, est, nrhs, t0

    #: exponential steps are multiples of max_step / GRID, so a few matrices serve all steps
    GRID = 256
    #: room for every grid step of one- and two-substep intervals and a few levels
    cache_size = 4 * GRID + 64

    def _base(self, t0: float, t1: float) -> tuple[int, float]:
        """(nsub, h) with h on the grid q = max_step/GRID. Every new step size would need a new
        matrix exponential (~ms), and real sample times jitter, so the step is rounded to the
        grid and the rounding remainder is carried into the next call: the state lags the
        requested time by at most nsub·q/2 (2 µs per substep at max_step = 1 ms) and the lag
        never grows. Uniform sampling at max_step is exact (h = max_step, no remainder)."""
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

    def _advance(self, system, t0, y, t1):
        carry = self._carry
        try:
            return super()._advance(system, t0, y, t1)
        except SimulationError:
            self._carry = carry              # the interval was not done: its remainder neither
            raise

    def _check_A(self, A, n: int) -> np.ndarray:
        A = np.asarray(A, dtype=float)
        if A.shape != (n, n):
            raise ValueError(f"{self.name}: linear_part A has shape {A.shape}, state has {n}")
        return A


class ETD2(_ETD):
    """ETD2RK (Cox & Matthews 2002): order 2, exact for constant g (and for g linear in t);
    estimate by the defect of the FSAL stage (order h³)."""

    name, order, q1, c, defect = "etd2", 2, 3, (0.0, 1.0), True

    @staticmethod
    def _tableau(A, h):
        E, p1, p2 = _phi_blocks(h * A, 2)
        return [[], [p1]], [p1 - p2, p2]


class ETD4(_ETD):
    """ETDRK4 of Krogstad (2005): classical order 4, stiff order 3, exact for constant g;
    estimate against its fourth stage (c = 1, order 2)."""

    name, order, q1, c = "etd4", 4, 3, (0.0, 0.5, 0.5, 1.0)

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


def _jacobian(system, t: float, y: np.ndarray) -> tuple[np.ndarray, int]:
    """(∂f/∂y, rhs calls): ``system.jacobian`` if it has one, else forward differences."""
    jac = getattr(system, "jacobian", None)
    if jac is not None:
        return np.asarray(jac(t, y), dtype=float), 0
    return _fd_jacobian(system.rhs, t, y), y.size


class ExpRosenbrock(_Controlled):
    """exprb32 (Hochbruck, Ostermann & Schweitzer 2009), re-linearised at every substep.

    With ``J = ∂f/∂y`` and ``v = ∂f/∂t`` at (t, y): ``U = y + hφ1(hJ) f + h²φ2(hJ) v``,
    ``D = f(t+h, U) − f − J(U − y) − h v``, ``y1 = U + 2hφ3(hJ) D`` (order 3); the embedded
    solution is U (exponential Rosenbrock–Euler, order 2), so ``err = 2hφ3(hJ) D``. The linear
    part of the motion at the current state, however fast (nutation at any spin), is integrated
    exactly; only the change of the Jacobian over a step is approximated."""

    name, order, q1 = "exprb", 3, 3

    def _substeps(self, system, t0, y0, nsub, h):
        rhs = system.rhs
        y = y0.copy()
        worst = est = 0.0
        nrhs = 0
        dt = 1e-3 * h
        for i in range(nsub):
            t = t0 + i * h
            f0 = np.array(rhs(t, y), dtype=float)
            J, nj = _jacobian(system, t, y)
            v = (np.asarray(rhs(t + dt, y)) - np.asarray(rhs(t - dt, y))) / (2.0 * dt)
            nrhs += 3 + nj
            Z = h * J
            U = y + _phi_apply(Z, [h * f0, h * h * v])
            D = np.asarray(rhs(t + h, U)) - f0 - J @ (U - y) - h * v
            nrhs += 1
            err = _phi_apply(Z, [None, None, 2.0 * h * D])
            y1 = U + err
            nrm = self._norm(err, y, y1)
            est = max(est, float(np.abs(err).max()))
            worst = max(worst, nrm)
            if _bad(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y = y1
        return y, worst, est, nrhs, t0


class ImplicitMidpoint(_Controlled):
    """Implicit midpoint rule ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)``, by step doubling.

    Each substep is taken once with h and twice with h/2; the two half steps are kept (so the
    map stays a composition of midpoint steps: symplectic, quadratic invariants to round-off)
    and ``err = (y_½½ − y_1)/3``. The midpoint stage ``Y = y0 + (h/2) f(t + h/2, Y)`` is solved by
    simplified Newton with ``(I − h/2 J)⁻¹`` (J: ``system.jacobian`` at (t0, y0) per call, else
    ``linear_part`` A cached by (key, h), else a forward-difference Jacobian per call), until
    the increment, or the remainder estimated from the contraction rate, is ≤ 2 eps·‖Y‖₂ (or the
    iteration has stalled within 100× that). A stage that does not converge in 10 iterations
    rejects the interval (it is redone with smaller substeps).
    """

    uses_linear_part = True

    name, order, q1 = "implicit_midpoint", 2, 3

    def _prepare(self, system, t0, y0):
        jac = getattr(system, "jacobian", None)
        lp = getattr(system, "linear_part", None)
        nrhs = 0
        if jac is not None:
            self._J, self._key = np.asarray(jac(t0, y0), dtype=float), None
        elif lp is not None:
            J, self._key = lp()
            self._J = np.asarray(J, dtype=float)
        else:
            self._J, self._key = _fd_jacobian(system.rhs, t0, y0), None
            nrhs = y0.size
        self._call_cache: dict[float, np.ndarray] = {}
        return nrhs

    def _newton_matrix(self, h: float) -> np.ndarray:
        J, key, n = self._J, self._key, self._J.shape[0]
        make = lambda: _inv(np.eye(n) - 0.5 * h * J)
        if key is not None:
            return self._cached(key, h, make)
        M = self._call_cache.get(h)
        if M is None:
            M = self._call_cache[h] = make()
        return M

    def _stage(self, rhs, t: float, y: np.ndarray, h: float, fp: np.ndarray):
        """One midpoint step; returns (y1, f at the midpoint, rhs calls) or (None, None, calls)."""
        Minv = self._newton_matrix(h)
        hh = 0.5 * h
        Y = y + hh * fp
        tm = t + hh
        dprev = math.inf
        dot, sqrt = np.dot, math.sqrt
        for it in range(_NEWTON_MAXITER):
            f = np.asarray(rhs(tm, Y))
            d = Minv @ (Y - y - hh * f)
            Y = Y - d
            dn = sqrt(dot(d, d))
            tol = _NEWTON_TOL * sqrt(dot(Y, Y))
            if not math.isfinite(dn):
                return None, None, it + 1
            if dn <= tol:
                return 2.0 * Y - y, f, it + 1
            if dprev < math.inf:
                theta = dn / dprev              # contraction rate of the simplified Newton
                if theta < 1.0 and theta * dn <= (1.0 - theta) * tol:
                    return 2.0 * Y - y, f, it + 1
                if theta >= 0.5 and dn <= 100.0 * tol:
                    return 2.0 * Y - y, f, it + 1
            dprev = dn
        if dn <= 100.0 * tol:
            return 2.0 * Y - y, f, _NEWTON_MAXITER
        return None, None, _NEWTON_MAXITER

    def _substeps(self, system, t0, y0, nsub, h):
        rhs = system.rhs
        y = y0.copy()
        fp = np.zeros_like(y)
        worst = est = 0.0
        nrhs = 0
        for i in range(nsub):
            t = t0 + i * h
            y_full, _, n1 = self._stage(rhs, t, y, h, fp)
            ya, fa, n2 = self._stage(rhs, t, y, 0.5 * h, fp) if y_full is not None else (None, None, 0)
            yb, fb, n3 = self._stage(rhs, t + 0.5 * h, ya, 0.5 * h, fa) if ya is not None else (None, None, 0)
            nrhs += n1 + n2 + n3
            if yb is None:
                return y, math.inf, math.nan, nrhs, t
            err = (yb - y_full) / 3.0
            nrm = self._norm(err, y, yb)
            est = max(est, float(np.abs(err).max()))
            worst = max(worst, nrm)
            if _bad(nrm):
                return yb, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y, fp = yb, fb
        return y, worst, est, nrhs, t0


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
    start); a last step shortened to hit ``t1`` does not shrink it. Steps never pass ``t1`` or
    ``max_step``; a proposed step below ``max_step / max_substeps`` is refused.
    """

    solver_cls: type = scipy.integrate.OdeSolver

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        super().__init__(max_step, rtol, atol, max_substeps)
        self._h: float | None = None

    def reset(self) -> None:
        self._h = None

    def _solver_kwargs(self, system) -> dict:
        return {}

    def _estimates(self, solver) -> tuple[float, float]:
        """(max-norm error estimate, weighted norm) of the step just accepted."""
        scale = self.atol + self.rtol * np.maximum(np.abs(solver.y_old), np.abs(solver.y))
        try:       # the norm scipy accepted the step with (DOP853 blends its 5th/3rd-order estimates)
            nrm = float(solver._estimate_error_norm(solver.K, solver.h_previous, scale))
        except (AttributeError, TypeError):
            return math.nan, math.nan
        return nrm * float(np.max(scale)), nrm

    def _advance(self, system, t0, y, t1):
        h = self._h
        h = None if h is None else min(h, t1 - t0, self.max_step)
        solver = self.solver_cls(system.rhs, t0, y, t1, rtol=self.rtol, atol=self.atol, first_step=h,
                                 max_step=self.max_step, **self._solver_kwargs(system))
        steps = 0
        est = worst = 0.0
        h_min = self.max_step / self.max_substeps
        proposal = solver.h_abs if h is None else max(h, solver.h_abs)
        while solver.status == "running":
            t_before = solver.t
            msg = solver.step()
            if solver.status == "failed":
                raise SimulationError(f"{self.name} failed at t={float(solver.t)!r}: {msg} "
                                      "(non-finite or too stiff right-hand side?)")
            steps += 1
            e, nrm = self._estimates(solver)
            est, worst = max(est, e), max(worst, nrm)
            if solver.t == t1 and proposal > t1 - t_before:
                # last step cut short to t1 (and so accepted at its first try): do not let
                # the short step shrink the proposal
                self._h = max(proposal, solver.h_abs)
            else:
                self._h = solver.h_abs
                if solver.status == "running" and solver.h_abs < h_min:
                    raise self.refuse(float(solver.t), e, nrm if nrm == nrm else 1.0, solver.h_abs,
                                      " (its step collapsed: non-finite or too stiff right-hand side?)")
            proposal = solver.h_abs
        return solver.y, StepStats(steps, solver.nfev, est, worst)


class DOP853(_Scipy):
    """Dormand–Prince 8(5,3) (scipy ``DOP853``)."""

    name, order, solver_cls = "dop853", 8, scipy.integrate.DOP853


class RK45(_Scipy):
    """Dormand–Prince 5(4) (scipy ``RK45``)."""

    name, order, solver_cls = "rk45", 5, scipy.integrate.RK45


class Radau(_Scipy):
    """Radau IIA order 5 (scipy ``Radau``); Jacobian from ``system.jacobian``, else the constant
    ``linear_part`` A, else scipy's finite differences. scipy keeps its error estimate to itself:
    the reported estimate is the acceptance bound (norm 1, ``atol + rtol·|y|``)."""

    uses_linear_part = True

    name, order, solver_cls = "radau", 5, scipy.integrate.Radau

    def _solver_kwargs(self, system):
        jac = getattr(system, "jacobian", None)
        if jac is None and getattr(system, "linear_part", None) is not None:
            jac = np.asarray(system.linear_part()[0], dtype=float)
        return {"jac": jac}

    def _estimates(self, solver) -> tuple[float, float]:
        return float(np.max(self.atol + self.rtol * np.abs(solver.y))), 1.0


class Auto(Integrator):
    """``auto``: a cheap primary method (compiled batch path); an interval it cannot bring within
    the tolerance within the budget is done by the fallback (exprb, re-linearised at every
    step), and so are the next ``AUTO_STICKY`` intervals (the hard stretch usually lasts), then
    the primary is tried again. Both honour rtol/atol."""

    def __init__(self, primary: "_Controlled", fallback: Integrator) -> None:
        super().__init__(fallback.max_step, fallback.rtol, fallback.atol, fallback.max_substeps)
        self.primary, self.fallback = primary, fallback
        self.name = f"auto:{primary.name}+{fallback.name}"
        self.order = primary.order
        self.uses_linear_part = primary.uses_linear_part
        self.n_fallback = 0
        self.sticky = 0

    def _advance(self, system, t0, y, t1):
        if self.sticky == 0:
            try:
                return self.primary._advance(system, t0, y.copy(), t1)
            except ToleranceError:
                self.sticky = AUTO_STICKY
        self.sticky -= 1
        self.n_fallback += 1
        if hasattr(self.primary, "_carry"):
            self.primary._carry = 0.0          # the fallback reaches t1 exactly
        return self.fallback._advance(system, t0, y, t1)

    def reset(self) -> None:
        self.primary.reset()
        self.fallback.reset()
        self.n_fallback = 0
        self.sticky = 0


#: intervals auto gives to its fallback after the primary refused one
AUTO_STICKY = 100


# --------------------------------------------------------------------------- registry

INTEGRATORS: dict[str, str] = {
    "rk4": "classic explicit Runge-Kutta 4 with embedded 3rd-order estimate, substeps to rtol/atol "
           "(explicit: needs h*|lambda| < 2.8)",
    "dop853": "Dormand-Prince 8(5,3), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "rk45": "Dormand-Prince 5(4), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "radau": "Radau IIA order 5, implicit adaptive (rtol/atol), for stiff damped systems",
    "implicit_midpoint": "implicit midpoint, step doubling to rtol/atol, A-stable, symplectic, keeps quadratic invariants",
    "etd2": "exponential ETD2RK (Cox-Matthews) about the rest state, embedded estimate, substeps to rtol/atol",
    "etd4": "exponential ETDRK4 (Krogstad) about the rest state, embedded estimate, substeps to rtol/atol",
    "exprb": "exponential Rosenbrock exprb32, re-linearised every step, embedded estimate; large angles, fast rotors",
}

_CLASSES: dict[str, type[Integrator]] = {
    "rk4": RK4, "dop853": DOP853, "rk45": RK45, "radau": Radau,
    "implicit_midpoint": ImplicitMidpoint, "etd2": ETD2, "etd4": ETD4, "exprb": ExpRosenbrock,
}


def make_integrator(name: str, *, max_step: float = 1e-3, rtol: float = 1e-8,
                    atol: float = 1e-12, max_substeps: int = MAX_SUBSTEPS) -> Integrator:
    """A new integrator by name (see ``INTEGRATORS``).

    ``max_step`` (s): step bound; ``rtol``, ``atol`` (state units): local error tolerance;
    ``max_substeps``: budget (shortest step ``max_step/max_substeps``). Raises ``ValueError``
    for an unknown name or bad values.
    """
    cls = _CLASSES.get(name)
    if cls is None:
        raise ValueError(f"unknown integrator {name!r}; known: {', '.join(INTEGRATORS)}")
    if not (0.0 < max_step < math.inf):
        raise ValueError(f"{name}: max_step must be a positive finite time in s, got {max_step!r}")
    if not (rtol > 0.0 and atol > 0.0):
        raise ValueError(f"{name}: rtol and atol must be positive, got {rtol!r}, {atol!r}")
    if not (int(max_substeps) >= 1):
        raise ValueError(f"{name}: max_substeps must be ≥ 1, got {max_substeps!r}")
    return cls(max_step, rtol, atol, int(max_substeps))
