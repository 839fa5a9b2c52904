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

from .system import platform_rhs

RK4, EXPRK = 0, 1


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
def run_batch(method, nsub_max, max_step, M, c, t_rel, w, f, y, out_idx, y_out,
              lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv,
              parent, jtype, axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN,
              R, wb, wd, J, fo, Mm, cc, tau_ext, fb, chol, F, a, Q, scratch):
    """Step ``y`` through the samples ``t_rel[i]`` (s, relative), ``w[i]`` (rad/s),
    ``f[i]`` (m/s²). Stores a copy of y after sample ``out_idx[j]`` in ``y_out[j]``.
    ``M`` (s, n, s·n) are the exponential stage matrices (unused for RK4), ``c`` the stage
    nodes. Returns (index of the last sample reached, status): status ≠ 0 stops the loop
    with ``y`` at the last good sample."""
    n = y.shape[0]
    s = c.shape[0]
    K = np.empty((s, n))
    Kf = K.reshape(s * n)
    U = np.empty(n)
    y0 = np.empty(n)
    qa = lay[3]
    qp = lay[2]
    j_out = 0
    nout = out_idx.shape[0]
    status = 0
    last = 0
    for i in range(1, t_rel.shape[0]):
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
        for sub in range(nsub):
            t = t0 + sub * h
            if method == RK4:
                st = platform_rhs(t, y, K[0], lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv, parent, jtype,
                                  axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN, R, wb, wd, J, fo,
                                  Mm, cc, tau_ext, fb, chol, F, a, Q, scratch)
                status |= st
                for m in range(n):
                    U[m] = y[m] + 0.5 * h * K[0, m]
                st = platform_rhs(t + 0.5 * h, U, K[1], lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv, parent,
                                  jtype, axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN, R, wb, wd, J,
                                  fo, Mm, cc, tau_ext, fb, chol, F, a, Q, scratch)
                status |= st
                for m in range(n):
                    U[m] = y[m] + 0.5 * h * K[1, m]
                st = platform_rhs(t + 0.5 * h, U, K[2], lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv, parent,
                                  jtype, axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN, R, wb, wd, J,
                                  fo, Mm, cc, tau_ext, fb, chol, F, a, Q, scratch)
                status |= st
                for m in range(n):
                    U[m] = y[m] + h * K[2, m]
                st = platform_rhs(t + h, U, K[3], lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv, parent,
                                  jtype, axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN, R, wb, wd, J,
                                  fo, Mm, cc, tau_ext, fb, chol, F, a, Q, scratch)
                status |= st
                for m in range(n):
                    y[m] += h / 6.0 * (K[0, m] + 2.0 * K[1, m] + 2.0 * K[2, m] + K[3, m])
            else:
                st = platform_rhs(t, y, K[0], lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv, parent, jtype,
                                  axis, qidx, vidx, inertia, rhost, raxis, seg, R_PBm, wIN, R, wb, wd, J, fo,
                                  Mm, cc, tau_ext, fb, chol, F, a, Q, scratch)
                status |= st
                for j in range(1, s + 1):
                    Mj = M[j - 1]
                    width = j * n
                    for r in range(n):
                        acc = 0.0
                        for col in range(width):
                            acc += Mj[r, col] * Kf[col]
                        U[r] = acc
                    if j < s:
                        for r in range(n):
                            U[r] += y[r]
                        st = platform_rhs(t + c[j] * h, U, K[j], lay, fid, on, k, L, lc, M0inv, G0, Ifz,
                                          Ifz_inv, parent, jtype, axis, qidx, vidx, inertia, rhost, raxis,
                                          seg, R_PBm, wIN, R, wb, wd, J, fo, Mm, cc, tau_ext, fb, chol, F, a,
                                          Q, scratch)
                        status |= st
                    else:
                        for r in range(n):
                            y[r] += U[r]
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


def stage_matrices(integrator, system, h: float) -> tuple[int, np.ndarray, np.ndarray]:
    """(method code, padded stage matrices (s, n, s·n), nodes c) for an integrator by name."""
    n = system.layout.n
    if integrator.name == "rk4":
        return RK4, np.zeros((4, 1, 1)), np.array([0.0, 0.5, 0.5, 1.0])
    if integrator.name in ("etd2", "etd4"):
        A, key = system.linear_part()
        Ms = integrator._cached(key, h, lambda: integrator._make(integrator._check_A(A, n), h))
        s = len(Ms)
        M = np.zeros((s, n, s * n))
        for i, Mi in enumerate(Ms):
            M[i, :, :Mi.shape[1]] = Mi
        return EXPRK, M, np.asarray(integrator.c, float)
    raise ValueError(f"integrator {integrator.name!r} has no compiled batch path (rk4, etd2, etd4 have)")
