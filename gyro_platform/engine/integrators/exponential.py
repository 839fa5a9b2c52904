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

"""Exponential integrators and their matrix functions (φ-functions by augmented expm).

- ``etd2``, ``etd4``: exponential integrators for ``f(t, y) = A y + g(t, y)`` with ``A`` from
  ``system.linear_part()`` (the model at rest: ETD2RK of Cox–Matthews, ETDRK4 of Krogstad),
  estimate = difference to the embedded lower-order stage at c = 1. Exact for the undamped
  gyroscopic modes; at large angles the remainder grows, and they substep or refuse.
- ``exprb``: exponential Rosenbrock exprb32 (Hochbruck–Ostermann–Schweitzer 2009), order 3,
  re-linearised at every step (``system.jacobian`` and ∂f/∂t), embedded order-2 estimate.
  Valid at large angles and for fast rotors: its cost does not depend on the spin.

etd2/etd4 take whole steps of a grid max_step/256 (cached stage matrices) and end every
interval exactly at t1 with a short etd2 step whose φ-functions are Taylor series
(``_ETD._plan``, ``_ETD._tail``, ``_phi_taylor``). The stage matrices (``_ETD.matrices``) and
this plan are also what the compiled batch loop (:mod:`gyro_platform.engine.batch`) steps with.
"""
from __future__ import annotations

import math
from typing import Hashable

import numpy as np

from .base import Controlled, is_rejected
from .jacobian import jacobian_of
from ...physics.jit import njit

__all__ = ["ETD2", "ETD4", "ExpRosenbrock", "TAYLOR_MAX", "TAYLOR_TOL", "TAIL_MIN", "TAIL_ULP"]


def _phi_blocks(Z: np.ndarray, p: int) -> list[np.ndarray]:
    """``[e^Z, φ1(Z), …, φp(Z)]`` from one expm of the augmented block matrix
    ``[[Z, I, 0…], [0, 0, I…], …]`` (size (p+1)n). No inverse of Z is needed (Z may be singular)."""
    n = Z.shape[0]
    W = np.zeros(((p + 1) * n, (p + 1) * n))
    W[:n, :n] = Z
    for k in range(p):
        W[k * n:(k + 1) * n, (k + 1) * n:(k + 2) * n] = np.eye(n)
    import scipy.linalg  # here, not at import: ~0.2 s a compiled rk4 run never needs

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
    if not norm < math.inf:             # Inf or NaN in W: halving Inf never ends (a 1e160 m/s² input)
        return np.full((n, n), np.nan)
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


#: most Taylor terms ``_phi_taylor`` sums before it gives up (the tail step is then split)
TAYLOR_MAX = 48
#: ``_phi_taylor`` stops when two consecutive terms are below TAYLOR_TOL of the sum
TAYLOR_TOL = 2.0 ** -53
#: a remainder ≤ max(TAIL_MIN·max_step, TAIL_ULP·|t1|) is round-off of the sample times: no tail
TAIL_MIN = 1e-9
TAIL_ULP = 4.0 * 2.0 ** -52


def taylor_bound(A: np.ndarray) -> float:
    """``a2 = ‖|A|²·1‖∞ ≥ ‖A²‖∞``, the bound of :func:`_phi_taylor`'s stopping rule."""
    absA = np.abs(A)
    return float(np.max(absA @ absA.sum(axis=1)))


def _phi_taylor(A: np.ndarray, a2: float, h: float, v: np.ndarray, k: int):
    """``h φ_k(hA) v`` (k = 1, 2) by the series ``h Σ_j (hA)^j v/(j+k)!``, or None when not
    converged within ``TAYLOR_MAX`` terms. Summed until two consecutive terms are below 2^-53
    of the sum and the terms from there on shrink ≥ 4× every two (``h²a2 ≤ (j+k)(j+k+1)/4``,
    ``a2 = ‖|A|²·1‖∞ ≥ ‖A²‖∞``): the rest of the series is below 2^-53/3 of the sum. Only
    matrix-vector products: the step h needs no matrix exponential. The compiled kernel
    (``batch.block_kernel``) sums the same terms in the same order."""
    term = v * (h if k == 1 else 0.5 * h)
    s = term.copy()
    prev = float(np.max(np.abs(term)))
    x2 = h * h * a2
    for j in range(1, TAYLOR_MAX + 1):
        term = (h / (j + k)) * (A @ term)
        s += term
        cur = float(np.max(np.abs(term)))
        if cur + prev <= TAYLOR_TOL * float(np.max(np.abs(s))) and 4.0 * x2 <= (j + k) * (j + k + 1):
            return s
        prev = cur
    return None


class _ETD(Controlled):
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
        self._a2 = taylor_bound(self._A)
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
            nrm, est, worst = self._judge(err, y, y1, est, worst)
            if is_rejected(nrm):
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

    def _plan(self, t0: float, t1: float):
        """Chunks on the grid q = max_step/GRID and a last short step to t1 exactly.

        Every new step size would need a new matrix exponential (~ms), and real sample times
        jitter, so the interval dt is cut into ``nsub = ceil(dt/max_step)`` chunks of
        ``G = floor((dt + ε)/q)`` grid steps in all (the first ``G mod nsub`` chunks one grid
        step longer), and the rest, ``r = t1 − t0 − G·q`` in [−ε, q − ε), if above ε, is one
        more step ``_tail`` (etd2 with its φ-functions by Taylor series). ε = max(1e-9·max_step,
        4 ulp of t1) is the round-off of the sample times: samples ``k·max_step`` apart stay
        one grid chunk and no tail, as before. Floor, not nearest: the tail is a forward step
        inside the interval (nearest would halve it but step back over input beyond t1)."""
        dt = t1 - t0
        q = self.max_step / self.GRID
        eps = max(TAIL_MIN * self.max_step, TAIL_ULP * abs(t1))
        nsub = max(1, math.ceil(dt / self.max_step - 1e-9))
        G = int(math.floor((dt + eps) / q))
        hq, extra = divmod(G, nsub)
        h0 = hq * q
        chunks = []
        if G > 0:
            for c in range(nsub):
                tc = t0 + c * h0 if extra == 0 else t0 + (c * h0 + min(c, extra) * q)
                chunks.append((tc, (hq + 1) * q if c < extra else h0))
        t_tail = t0 + (nsub * h0 + extra * q)
        r = t1 - t_tail
        return chunks, ((t_tail, r) if r > eps else None)

    def _tail(self, system, t0, y0, nsub, h):
        """ETD2RK steps of any length h (φ1, φ2 applied by Taylor series, ``_phi_taylor``):
        ``U = y + hφ1 f0``, ``y1 = U + hφ2 (f(U) − f0 − A(U − y))``, the same defect
        estimate as etd2. The linear part stays exact (no damping of the nutation)."""
        A = self._A
        a2 = self._a2
        rhs = system.rhs
        y = y0.copy()
        worst = est = 0.0
        nrhs = 1
        f0 = np.asarray(rhs(t0, y), dtype=float)
        for i in range(nsub):
            t = t0 + i * h
            U = _phi_taylor(A, a2, h, f0, 1)
            if U is None:
                return y, math.inf, est, nrhs, t
            U = y + U
            f1 = np.asarray(rhs(t + h, U), dtype=float)
            d = _phi_taylor(A, a2, h, f1 - f0 - A @ (U - y), 2)
            if d is None:
                return y, math.inf, est, nrhs + 1, t
            y1 = U + d
            k5 = np.asarray(rhs(t + h, y1), dtype=float)
            nrhs += 2
            err = h / 3.0 * (k5 - f1 - A @ (y1 - U))
            nrm, est, worst = self._judge(err, y, y1, est, worst)
            if is_rejected(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y, f0 = y1, k5
        return y, worst, est, nrhs, t0

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


class ExpRosenbrock(Controlled):
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
            J, nj = jacobian_of(system, t, y)
            v = (np.asarray(rhs(t + dt, y)) - np.asarray(rhs(t - dt, y))) / (2.0 * dt)
            nrhs += 3 + nj
            Z = h * J
            with np.errstate(invalid="ignore", over="ignore"):    # non-finite: rejected by _judge
                U = y + _phi_apply(Z, [h * f0, h * h * v])
                D = np.asarray(rhs(t + h, U)) - f0 - J @ (U - y) - h * v
                err = _phi_apply(Z, [None, None, 2.0 * h * D])
            nrhs += 1
            y1 = U + err
            nrm, est, worst = self._judge(err, y, y1, est, worst)
            if is_rejected(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y = y1
        return y, worst, est, nrhs, t0
