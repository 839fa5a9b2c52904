"""Compiled batch stepping: many input samples → many integration steps in one numba loop.

The Python ``Simulator.push`` costs tens of µs per sample in call overhead alone. When the
samples are already at hand (replay, scenes, benchmarks) ``run_batch`` steps them inside one
compiled loop that calls the right-hand-side kernel directly: no Python call and no allocation
per sample.

Methods: explicit RK4 (embedded third-order estimate, FSAL), and explicit exponential
Runge–Kutta methods (``etd2``, ``etd4``) given their stage matrices ``M_i`` (``U_i = y + Σ_j
M_ij f_j``; see ``integrators.exponential``; estimate ``y1 − U_last``). The step-size controller is the
one of ``integrators.base.Controlled`` (levels of ``nsub·2^level`` substeps per interval, the same
acceptance test, the same level updates), so the results equal ``Simulator.push`` with the
same integrator to round-off, and the failures are the same.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .integrators import COARSEN, MAX_JUMP
from ..physics.system import FASTMATH, platform_rhs, support_regime

RK4, EXPRK, EXPRK_D = 0, 1, 2
#: run_batch status bits: 1 gimbal lock (precession), 2 mass matrix not positive definite,
#: 4 non-finite state, 8 matrices for a new (regime, level) needed, 16 tolerance not met within
#: the budget
ST_LOCK, ST_NOT_PD, ST_NONFINITE, NEED_REGIME, ST_TOLERANCE = 1, 2, 4, 8, 16
# info slots (float64 array): worst accepted estimate and norm, rejections, and for a refusal:
# time, estimate, norm, step
I_EST, I_NORM, I_REJ, I_T, I_EBAD, I_NBAD, I_H, I_STEPS = range(8)
N_INFO = 8
#: integrators with a compiled batch path → method code
COMPILED = {"rk4": RK4, "etd2": EXPRK_D, "etd4": EXPRK}


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


@njit(cache=True)
def _quat_ok(u, a):
    """The quaternion u[a:a+4] can be turned into a matrix (finite, non-zero)."""
    if a < 0:
        return True
    s = u[a] * u[a] + u[a + 1] * u[a + 1] + u[a + 2] * u[a + 2] + u[a + 3] * u[a + 3]
    return s > 0.0 and s < math.inf


@njit(cache=True, fastmath=FASTMATH)
def _csr(Mptr, row, Midx, Mdat, x, y, out):
    """out = y + M_row x for the CSR matrix ``row`` of a set."""
    for r in range(y.shape[0]):
        acc = 0.0
        for e in range(Mptr[row, r], Mptr[row, r + 1]):
            acc += Mdat[e] * x[Midx[e]]
        out[r] = y[r] + acc


@njit(cache=True, fastmath=FASTMATH)
def _csr_mv(Mptr, row, Midx, Mdat, x, out):
    """out = M_row x."""
    for r in range(out.shape[0]):
        acc = 0.0
        for e in range(Mptr[row, r], Mptr[row, r + 1]):
            acc += Mdat[e] * x[Midx[e]]
        out[r] = acc


@njit(cache=True, fastmath=FASTMATH)
def run_batch(method, max_step, rtol, atol, q1, max_level, lev, info, reg_of, Mptr_all, Midx, Mdat, c, t_rel, w,
              f, y, out_idx, y_out, first, need, prog,
              fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, wb, wd, J, fo, Mm, cc, tau_ext, fb, chol, F, a,
              Q, RR, V, W):
    """Step ``y`` through the samples ``t_rel[i]`` (s, relative), ``w[i]`` (rad/s), ``f[i]``
    (m/s²), starting after sample ``first``. Stores a copy of y after sample ``out_idx[j]`` in
    ``y_out[j]``.

    Controller: ``lev[0]`` is the substep level (in and out), ``rtol``/``atol`` the tolerance,
    ``q1`` the estimator's order + 1, ``max_level`` the budget. ``info`` accumulates the worst
    accepted estimate/norm and the rejections, and describes a refusal.
    ``Mptr_all[set], Midx, Mdat``: exponential stage matrices in CSR form, one set per (support
    friction regime, level) (``reg_of[regime, level]`` = set index, −1 = not built yet: the loop
    then stops with status ``NEED_REGIME`` and ``need`` = (regime, level), and is resumed from
    the sample it reached once Python has built the set). ``c``: stage nodes.
    ``y`` changes only when a sample is accepted, and ``prog[0]`` then holds its index, so an
    exception escaping the loop leaves (y, prog) at the last good sample.
    Returns (index of the last sample reached, status): status ≠ 0 stops the loop with ``y`` at
    the last good sample."""
    n = y.shape[0]
    s = c.shape[0]
    K = np.empty((s, n))
    Kf = K.reshape(s * n)
    k5 = np.empty(n)
    U = np.empty(n)
    Ul = np.empty(n)
    AU = np.empty(n)
    yw = np.empty(n)
    y1 = np.empty(n)
    qa = I[0, 3]
    qp = I[0, 2]
    j_out = 0
    nout = out_idx.shape[0]
    while j_out < nout and out_idx[j_out] <= first:
        j_out += 1
    last = first
    prog[0] = first
    Mptr = Mptr_all[0]
    r = 0
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
        nsub0 = int(math.ceil((t1 - t0) / max_step - 1e-9))
        if nsub0 < 1:
            nsub0 = 1
        h0 = (t1 - t0) / nsub0
        if method != RK4:
            r = support_regime(y, I, P, seg, RR)
        level = lev[0]
        level_start = level
        while True:
            if method != RK4:
                sidx = reg_of[r, level]
                if sidx < 0:
                    need[0] = r
                    need[1] = level
                    lev[0] = level
                    return last, NEED_REGIME
                Mptr = Mptr_all[sidx]
            nsub = nsub0 << level
            h = h0 / (1 << level)
            for m in range(n):
                yw[m] = y[m]
            worst = 0.0
            est = 0.0
            bad = False
            status = 0
            have_k1 = False
            t_bad = t0
            nrm = 0.0
            for sub in range(nsub):
                t = t0 + sub * h
                # one call site of the (inlined) right-hand side: stage j evaluates f at U_j
                for j in range(s + 1):
                    if j == 0:
                        if have_k1:
                            continue
                        for m in range(n):
                            U[m] = yw[m]
                    elif j == s:
                        if method == EXPRK:
                            break
                        if method == RK4:
                            for m in range(n):
                                y1[m] = yw[m] + h / 6.0 * (K[0, m] + 2.0 * K[1, m] + 2.0 * K[2, m] + K[3, m])
                        else:
                            _csr(Mptr, s - 1, Midx, Mdat, Kf, yw, y1)
                        for m in range(n):   # FSAL stage k5 = f(t + h, y1); Ul keeps the last stage
                            Ul[m] = U[m]
                            U[m] = y1[m]
                    elif method == RK4:
                        cj = c[j] * h
                        for m in range(n):
                            U[m] = yw[m] + cj * K[j - 1, m]
                    else:
                        _csr(Mptr, j - 1, Midx, Mdat, Kf, yw, U)
                    if not (_quat_ok(U, qa) and _quat_ok(U, qp)):
                        status |= ST_NONFINITE
                        break
                    status |= platform_rhs(t + (h if j == s else c[j] * h), U, k5 if j == s else K[j], fid, I, P,
                                           seg, mats, axis, inertia, rhost, raxis, R, wb, wd, J, fo, Mm, cc,
                                           tau_ext, fb, chol, F, a, Q, RR, V, W)
                if status & (ST_LOCK | ST_NOT_PD):
                    break
                if status & ST_NONFINITE:
                    nrm = math.inf
                    bad = True
                    t_bad = t
                    break
                if method == EXPRK:
                    # output y1 = y + M_s [f_0 … f_{s−1}]; U holds the last stage (c = 1)
                    _csr(Mptr, s - 1, Midx, Mdat, Kf, yw, y1)
                elif method == EXPRK_D:
                    # defect estimate (h/3)(f(y1) − f(U) − A (y1 − U)); A is matrix row s
                    for m in range(n):
                        U[m] = y1[m] - Ul[m]
                    _csr_mv(Mptr, s, Midx, Mdat, U, AU)
                # error estimate and its weighted RMS norm
                acc = 0.0
                emax = 0.0
                for m in range(n):
                    if method == RK4:
                        ee = h / 6.0 * (K[3, m] - k5[m])
                    elif method == EXPRK_D:
                        ee = h / 3.0 * (k5[m] - K[s - 1, m] - AU[m])
                    else:
                        ee = y1[m] - U[m]
                    sc = atol + rtol * max(abs(yw[m]), abs(y1[m]))
                    acc += (ee / sc) ** 2
                    if abs(ee) > emax:
                        emax = abs(ee)
                    if not math.isfinite(ee):
                        emax = math.inf
                nrm = math.sqrt(acc / n)
                if emax > est:
                    est = emax
                if not nrm <= 1.0:
                    if not math.isfinite(nrm):
                        nrm = math.inf
                    bad = True
                    t_bad = t
                    break
                if nrm > worst:
                    worst = nrm
                for m in range(n):
                    yw[m] = y1[m]
                if method != EXPRK:
                    for m in range(n):
                        K[0, m] = k5[m]
                    have_k1 = True
            if status & (ST_LOCK | ST_NOT_PD):
                lev[0] = level_start          # as the Python controller: the level is not updated
                return last, status & (ST_LOCK | ST_NOT_PD)
            if not bad:
                break
            info[I_REJ] += 1.0
            if nrm < math.inf:
                jump = int(math.ceil(math.log2(nrm) / q1))
                new = level + min(MAX_JUMP, max(1, jump))
            else:
                new = level + MAX_JUMP
            if new > max_level:
                if level < max_level:
                    new = max_level
                else:
                    lev[0] = level_start
                    info[I_T] = t_bad
                    info[I_EBAD] = est
                    info[I_NBAD] = nrm
                    info[I_H] = h
                    return last, ST_TOLERANCE if nrm < math.inf else ST_NONFINITE | ST_TOLERANCE
            level = new
        # accepted: normalise, check, commit
        _normalise(yw, qa, qa + 4)
        _normalise(yw, qp, qp + 4)
        for m in range(n):
            if not math.isfinite(yw[m]):
                lev[0] = level_start
                return last, ST_NONFINITE
        info[I_STEPS] += nsub
        if level > 0 and worst * 2.0 ** q1 <= COARSEN:
            level -= 1
        lev[0] = level
        if est > info[I_EST]:
            info[I_EST] = est
        if worst > info[I_NORM]:
            info[I_NORM] = worst

        for m in range(n):
            y[m] = yw[m]
        last = i
        prog[0] = i
        while j_out < nout and out_idx[j_out] == i:
            for m in range(n):
                y_out[j_out, m] = y[m]
            j_out += 1
    return last, 0


def stage_matrices(integrator, system, h: float):
    """(method code, CSR stage matrices (ptr (s, n+1), idx, data), nodes c) for an integrator
    by name. Stage j's matrix maps the stacked stage derivatives [f_0 … f_{j−1}] to U_j − y."""
    n = system.layout.n
    if integrator.name not in COMPILED:
        raise ValueError(f"integrator {integrator.name!r} has no compiled batch path (rk4, etd2, etd4 have)")
    if integrator.name == "rk4":
        return RK4, (np.zeros((4, 1), np.int64), np.zeros(1, np.int64), np.zeros(1)), \
            np.array([0.0, 0.5, 0.5, 1.0])
    if integrator.name in ("etd2", "etd4"):
        A, key = system.linear_part()
        Ms = list(integrator.matrices(np.asarray(A, float), key, h))
        if integrator.defect:
            Ms.append(np.asarray(A, float))          # for the defect estimate
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
        return COMPILED[integrator.name], (ptr, np.asarray(idx, np.int64), np.asarray(dat, float)), \
            np.asarray(integrator.c, float)


class RegimeMatrices:
    """CSR stage matrices of an exponential method, one set per (support-friction regime,
    substep level), built on demand (a scene meets only a few of the 8 regimes and levels)."""

    def __init__(self, integrator, system, h: float):
        self.integrator, self.system, self.h = integrator, system, h
        n = system.layout.n
        self.reg_of = -np.ones((8, integrator.max_level + 1), dtype=np.int64)
        self.ptr = np.zeros((1, 4, n + 1), np.int64)
        self.idx = np.zeros(1, np.int64)
        self.dat = np.zeros(1)
        self._sets: list = []

    def add(self, regime: int, level: int) -> None:
        saved = self.system.regime
        self.system.regime = regime
        try:
            _, (ptr, idx, dat), _ = stage_matrices(self.integrator, self.system, self.h / (1 << level))
        finally:
            self.system.regime = saved
        off = sum(len(s[1]) for s in self._sets)
        self._sets.append((ptr + off, idx, dat))
        self.reg_of[regime, level] = len(self._sets) - 1
        s_max = max(p.shape[0] for p, _, _ in self._sets)
        n1 = ptr.shape[1]
        self.ptr = np.zeros((len(self._sets), s_max, n1), np.int64)
        for k, (p, _, _) in enumerate(self._sets):
            self.ptr[k, :p.shape[0]] = p
        self.idx = np.concatenate([s[1] for s in self._sets])
        self.dat = np.concatenate([s[2] for s in self._sets])
