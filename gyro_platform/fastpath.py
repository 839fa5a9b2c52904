"""Compiled batch stepping: many input samples → many integration steps in one numba loop.

The Python ``Simulator.push`` costs tens of µs per sample in call overhead alone. When the
samples are already at hand (replay, scenes, benchmarks) ``run_batch`` steps them inside one
compiled loop that calls the right-hand-side kernel directly: one input sample → one (or a
few equal) integration steps, no Python call and no allocation per sample.

Methods: explicit RK4, and explicit exponential Runge–Kutta methods (``etd2``, ``etd4``) given
their stage matrices ``M_i`` (``U_i = y + Σ_j M_ij f_j``; see ``integrators._ETD``). The
results are identical (to round-off) to ``Simulator.push`` with the same integrator.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .system import FASTMATH, platform_rhs, support_regime

RK4, EXPRK = 0, 1
NEED_REGIME = 8   # run_batch status: matrices for a new friction regime are needed


@njit(cache=True)
def _normalise(y, a, b):
    if a < 0:
        return
    s = 0.0
    for i in range(a, b):
        s += y[i] * y[i]
    s = math.sqrt(s)
    for i in range(a, b):
        y[i] /= s


@njit(cache=True, fastmath=FASTMATH)
def run_batch(method, max_step, reg_of, Mptr_all, Midx, Mdat, c, t_rel, w, f, y, out_idx, y_out, first, need,
              fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, wb, wd, J, fo, Mm, cc, tau_ext, fb, chol, F, a,
              Q, RR, V, W):
    """Step ``y`` through the samples ``t_rel[i]`` (s, relative), ``w[i]`` (rad/s),
    ``f[i]`` (m/s²). Stores a copy of y after sample ``out_idx[j]`` in ``y_out[j]``.
    ``Mptr_all[set], Midx, Mdat`` are the exponential stage matrices in CSR form, one set per
    support-friction regime (``reg_of[regime]`` = set index, −1 = not built yet: the loop then
    stops with status ``NEED_REGIME`` and ``need[0]`` = regime, and is resumed from the sample it
    reached once Python has built the set). ``c`` are the stage nodes. Starts after sample
    ``first``. Returns (index of the last sample reached, status): status ≠ 0 stops the loop
    with ``y`` at the last good sample."""
    n = y.shape[0]
    s = c.shape[0]
    K = np.empty((s, n))
    Kf = K.reshape(s * n)
    U = np.empty(n)
    y0 = np.empty(n)
    qa = I[0, 3]
    qp = I[0, 2]
    j_out = 0
    nout = out_idx.shape[0]
    while j_out < nout and out_idx[j_out] <= first:
        j_out += 1
    status = 0
    last = first
    Mptr = Mptr_all[0]
    for i in range(first + 1, t_rel.shape[0]):
        t0 = t_rel[i - 1]
        t1 = t_rel[i]
        seg[0] = t0
        seg[1] = t1 - t0
        for m in range(3):
            seg[2 + m] = w[i - 1, m]
            seg[5 + m] = w[i, m]
            seg[8 + m] = f[i - 1, m]
            seg[11 + m] = f[i, m]
        nsub = int(math.ceil((t1 - t0) / max_step - 1e-9))
        if nsub < 1:
            nsub = 1
        h = (t1 - t0) / nsub
        for m in range(n):
            y0[m] = y[m]
        if method == EXPRK:
            r = support_regime(y, I, P, seg, RR)
            sidx = reg_of[r]
            if sidx < 0:
                need[0] = r
                return last, NEED_REGIME
            Mptr = Mptr_all[sidx]
        for sub in range(nsub):
            t = t0 + sub * h
            # one call site of the (inlined) right-hand side: stage j evaluates f at U_j
            for j in range(s):
                if j == 0:
                    for m in range(n):
                        U[m] = y[m]
                elif method == RK4:
                    cj = c[j] * h
                    for m in range(n):
                        U[m] = y[m] + cj * K[j - 1, m]
                else:
                    for r in range(n):
                        acc = 0.0
                        for e in range(Mptr[j - 1, r], Mptr[j - 1, r + 1]):
                            acc += Mdat[e] * Kf[Midx[e]]
                        U[r] = y[r] + acc
                status |= platform_rhs(t + c[j] * h, U, K[j], fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                                       R, wb, wd, J, fo, Mm, cc, tau_ext, fb, chol, F, a, Q, RR, V, W)
            if method == RK4:
                for m in range(n):
                    y[m] += h / 6.0 * (K[0, m] + 2.0 * K[1, m] + 2.0 * K[2, m] + K[3, m])
            else:
                # output: y += M_s [f_0 … f_{s−1}]  (U_j above is y + M_j [f_0 … f_{j−1}])
                for r in range(n):
                    acc = 0.0
                    for e in range(Mptr[s - 1, r], Mptr[s - 1, r + 1]):
                        acc += Mdat[e] * Kf[Midx[e]]
                    y[r] += acc
        _normalise(y, qa, qa + 4)
        _normalise(y, qp, qp + 4)
        ok = status == 0
        for m in range(n):
            if not math.isfinite(y[m]):
                ok = False
        if not ok:
            for m in range(n):
                y[m] = y0[m]
            if status == 0:
                status = 4
            return last, status
        last = i
        while j_out < nout and out_idx[j_out] == i:
            for m in range(n):
                y_out[j_out, m] = y[m]
            j_out += 1
    return last, status


def stage_matrices(integrator, system, h: float):
    """(method code, CSR stage matrices (ptr (s, n+1), idx, data), nodes c) for an integrator
    by name. Stage j's matrix maps the stacked stage derivatives [f_0 … f_{j−1}] to U_j − y."""
    n = system.layout.n
    if integrator.name == "rk4":
        return RK4, (np.zeros((4, 1), np.int64), np.zeros(1, np.int64), np.zeros(1)), \
            np.array([0.0, 0.5, 0.5, 1.0])
    if integrator.name in ("etd2", "etd4"):
        A, key = system.linear_part()
        Ms = integrator._cached(key, h, lambda: integrator._make(integrator._check_A(A, n), h))
        s = len(Ms)
        ptr = np.zeros((s, n + 1), np.int64)
        idx: list[int] = []
        dat: list[float] = []
        for j, Mj in enumerate(Ms):
            for r in range(n):
                cols = np.nonzero(Mj[r])[0]
                ptr[j, r] = len(idx)
                idx.extend(cols.tolist())
                dat.extend(Mj[r, cols].tolist())
            ptr[j, n] = len(idx)
            # rows are numbered per stage: restart offsets at each stage's first row
        return EXPRK, (ptr, np.asarray(idx, np.int64), np.asarray(dat, float)), np.asarray(integrator.c, float)
    raise ValueError(f"integrator {integrator.name!r} has no compiled batch path (rk4, etd2, etd4 have)")


class RegimeMatrices:
    """CSR stage matrices of an exponential method, one set per support-friction regime
    (built on demand: a scene meets only a few of the 8 regimes)."""

    def __init__(self, integrator, system, h: float):
        self.integrator, self.system, self.h = integrator, system, h
        n = system.layout.n
        self.reg_of = -np.ones(8, dtype=np.int64)
        self.ptr = np.zeros((1, 4, n + 1), np.int64)
        self.idx = np.zeros(1, np.int64)
        self.dat = np.zeros(1)
        self._sets: list = []
        if integrator.name in ("etd2", "etd4"):
            self.add(system.regime)

    def add(self, regime: int) -> None:
        saved = self.system.regime
        self.system.regime = regime
        try:
            _, (ptr, idx, dat), _ = stage_matrices(self.integrator, self.system, self.h)
        finally:
            self.system.regime = saved
        off = sum(len(s[1]) for s in self._sets)
        self._sets.append((ptr + off, idx, dat))
        self.reg_of[regime] = len(self._sets) - 1
        s_max = max(p.shape[0] for p, _, _ in self._sets)
        n1 = ptr.shape[1]
        self.ptr = np.zeros((len(self._sets), s_max, n1), np.int64)
        for k, (p, _, _) in enumerate(self._sets):
            self.ptr[k, :p.shape[0]] = p
        self.idx = np.concatenate([s[1] for s in self._sets])
        self.dat = np.concatenate([s[2] for s in self._sets])
