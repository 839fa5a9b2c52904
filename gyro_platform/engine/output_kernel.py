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

"""Outputs in compiled code: K state snapshots in, K output rows out, in one call.

``output_rows`` (numba) evaluates, for each instant, everything ``Outputs`` reports — gimbal
angles and rates (precession: from the model), axial gimbal torques, platform rate and attitude,
drift angle and rate (carried mode: of the gyros' own inertial reference), the Newton–Euler
bearing torques with the g-sensitive body torques, motor torques, mount angles and rates, servo
torque and the status figures — into preallocated rows (layout ``outputs.C_*``).
``output_row`` is the one-instant entry of the same code (``Simulator.outputs()``). The loop over
the instants is inside one compiled function and the linear stabilised model's right-hand side
is inlined there: a call per instant with ~40 array arguments, and the general right-hand side's
28, cost more than the outputs (5.2 -> 2.4 µs per instant, default model).

An instant whose outputs are not all finite (a state that is finite can still give an overflow,
e.g. anisoelastic torques under |f| ≥ 1e30 m/s²) stops the evaluation there:
``NonFiniteOutputError`` names the quantity and the time, and carries the block of the
instants before it. The kernels never hand a NaN or Inf on.
"""
from __future__ import annotations

import math

import numpy as np

from .outputs import (C_ANG, C_AXIAL, C_BEAR, C_DRATE, C_DRIFT, C_MARGIN, C_MAXANG, C_MOTOR, C_MOUNT, C_MRATE, C_NSTEPS,
                      C_OM, C_QUAT, C_RATE, C_ROTOR, C_SERVO, C_T, COLUMN_NAMES, N_COL, OutputBlock, Outputs,
                      outputs_of_row)
from .views import borrow
from ..errors import NonFiniteOutputError, SimulationError
from ..physics import effects as fx
from ..physics.jit import njit, plain
from ..physics.options import NEEDS_SPECIFIC_FORCE
from ..physics.rhs_linear import takes_linear_path
from ..physics.rotations import (euler_xyz_into, euler_xyz_rates_into, matrix_rotvec_into, quat_to_matrix_at,
                                 rotvec_matrix_into)
from ..physics.system import (LAY_NV, LAY_OM, LAY_QIB, LAY_QIP, LAY_STAB, LAY_Z, LINEAR, model_rhs, PlatformSystem,
                              PRECESSION, SEG_DT, SEG_F1, SEG_N, SEG_W0, SEG_W1, unpack_tables)
from ..physics.tree import kinematics_rw, newton_euler, rotor_torques

#: step (s) of the central difference that gives the gimbal accelerations in precession
PRECESSION_EPS = 1e-6
# return codes of the kernels (per call: code, instant, detail)
OK, RHS_FAILED, NON_FINITE, REFERENCE_UNDEFINED = 0, 1, 2, 3
#: carried mode: the gyros' reference triad is refused when the spin axes of rotors 6 and 11
#: are this close to parallel (sine of their angle; ~0.06°): its rotation about rotor 11's
#: axis, read from rotor 6's axis, is undefined there
MIN_SPIN_AXES_SINE = 1e-3
# offsets in the float constants CF: rotor momenta for the outputs (true L, or 0 without
# rotor_gyroscopic), rotor C, A, speeds, tree axes (nb, 3), inertias (nb, 3, 3), spin axes (nr, 3)
F_L, F_C, F_A, F_SPEED, F_AXIS = 0, 3, 6, 9, 12
# rows of the small-vector work X and the 3×3 work MM of one instant
N_X, N_MM = 21, 6
# int constants OI: fidelity, needs specific force, nb, nr, rotor hosts (nr)
I_FID, I_NEEDS_F, I_NB, I_NR, I_HOST = 0, 1, 2, 3, 4


# ---- small 3×3 helpers (no allocation) ------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _mm(A, B, out):
    """out = A B (3×3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, error_model="numpy")
def _mtm(A, B, out):
    """out = Aᵀ B (3×3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[0, i] * B[0, j] + A[1, i] * B[1, j] + A[2, i] * B[2, j]


@njit(cache=True, error_model="numpy")
def _mv(A, x, out):
    """out = A x."""
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@njit(cache=True, error_model="numpy")
def _mtv(A, x, out):
    """out = Aᵀ x."""
    for i in range(3):
        out[i] = A[0, i] * x[0] + A[1, i] * x[1] + A[2, i] * x[2]


@njit(cache=True, error_model="numpy")
def _cross_into(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


# ---- the model's right-hand side (one compiled function, called up to three times; gen: model_rhs) ---

@njit(cache=True, error_model="numpy")
def _rhs(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, w, wd, J, f, M, c, tau_ext, fb,
         chol, F, a, Q, RR, V, W):
    return model_rhs(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, w, wd, J, f, M, c,
                     tau_ext, fb, chol, F, a, Q, RR, V, W)


# ---- the instants ------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _instants(T, TR, NS, Y, SEG, OUT, I, P, mats, CF, OI, yd, yp, ym, ydp, ydm, v, acc, R, w, wd, J, f,
              M, c, tau_ext, fb, chol, F, a, Q, RR, V, W, rtau, X, MM, E, gen, carried):
    """Outputs of K instants into the rows of ``OUT`` (K, N_COL) (arguments: ``output_rows``;
    the loop over the instants is in here: a call per instant with its ~40 array arguments
    cost more than the outputs themselves). Returns (done, code, detail) as ``output_rows``;
    RHS_FAILED with the failing right-hand side's (t, y) in ``E`` (E[0] = t, E[1:] = y)."""
    fid = OI[I_FID]
    nb = OI[I_NB]
    nr = OI[I_NR]
    rhost = OI[I_HOST:I_HOST + nr]
    axis = CF[F_AXIS:F_AXIS + 3 * nb].reshape((nb, 3))
    o = F_AXIS + 3 * nb
    inertia = CF[o:o + 9 * nb].reshape((nb, 3, 3))
    o += 9 * nb
    raxis = CF[o:o + 3 * nr].reshape((nr, 3))
    Lout = CF[F_L:F_L + 3]
    lay, on, parent, jtype, qidx, vidx, k, Lsys, _, wIN = unpack_tables(I, P, nb)
    stab = lay[LAY_STAB] == 1
    yes = nb > 0        # True, typed bool: newton_euler's one signature (a literal True would be another)
    nv = lay[LAY_NV]
    n = Y.shape[1]
    for kk in range(Y.shape[0]):
        t, t_rel, n_steps = T[kk], TR[kk], NS[kk]
        y, seg, out = Y[kk], SEG[kk], OUT[kk]
        # --- generalised velocities and accelerations of the tree (Simulator._accelerations) ----
        st = _rhs(gen, t_rel, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, w, wd, J, f, M, c,
                  tau_ext, fb, chol, F, a, Q, RR, V, W)
        if st != 0:
            E[0] = t_rel
            for i in range(n):
                E[1 + i] = y[i]
            return kk, RHS_FAILED, 0
        if fid != PRECESSION:
            for i in range(nv):
                v[i] = y[5 + i]
                acc[i] = yd[5 + i]
        elif gen is None:                   # (not reached: the linear model; pruned at compile time)
            pass
        else:
            # q̇ from the model, q̈ by a central difference along the motion
            eps = PRECESSION_EPS
            for i in range(n):
                yp[i] = y[i] + eps * yd[i]
                ym[i] = y[i] - eps * yd[i]
            for sgn in range(2):
                tt = t_rel + eps if sgn == 0 else t_rel - eps
                yy = yp if sgn == 0 else ym
                st = _rhs(gen, tt, yy, ydp if sgn == 0 else ydm, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                          R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)
                if st != 0:
                    E[0] = tt
                    for i in range(n):
                        E[1 + i] = yy[i]
                    return kk, RHS_FAILED, 0
            off = nv - 5
            if stab:
                io = lay[LAY_OM]
                for i in range(3):
                    v[i] = y[io + i]
                    acc[i] = yd[io + i]
            for i in range(5):
                v[off + i] = yd[i]
                acc[off + i] = (ydp[i] - ydm[i]) / (2 * eps)
        qd = v[nv - 5:nv]
        # --- frames: X rows are 3-vectors, MM 3×3 matrices ----------------------------------------
        wB = seg[SEG_W1:SEG_W1 + 3]
        fB = seg[SEG_F1:SEG_F1 + 3]
        R_IB = MM[0]
        R_IP = MM[1]
        R_PB = mats[4, :3, :3]
        T1 = MM[2]
        T2 = MM[3]
        R_IC = MM[4]
        quat_to_matrix_at(y, lay[LAY_QIB], MM, 0)
        if stab:
            quat_to_matrix_at(y, lay[LAY_QIP], MM, 1)
        else:
            for i in range(3):              # R_IP = R_IB R_BP, R_BP = R_PBᵀ
                for j in range(3):
                    R_IP[i, j] = R_IB[i, 0] * R_PB[j, 0] + R_IB[i, 1] * R_PB[j, 1] + R_IB[i, 2] * R_PB[j, 2]
        for i in range(3):
            X[0, i] = wIN[i] * t_rel
        rotvec_matrix_into(X[0], R_IC)
        Om = X[1]                           # platform rate (platform axes)
        w0 = X[2]
        wd0 = X[3]
        if stab:
            io = lay[LAY_OM]
            for i in range(3):
                Om[i] = y[io + i]
                w0[i] = 0.0
                wd0[i] = 0.0
        else:
            _mv(R_PB, wB, Om)
            for i in range(3):
                w0[i] = Om[i]
                X[4, i] = (seg[SEG_W1 + i] - seg[SEG_W0 + i]) / seg[SEG_DT] if seg[SEG_DT] > 0 else 0.0
            _mv(R_PB, X[4], wd0)
        # --- axial gimbal torques of the effects ---------------------------------------------------
        wc = X[5]
        if on[fx.EARTH]:
            _mv(R_IC, wIN, X[4])
            _mtv(R_IP, X[4], wc)
        else:
            wc[0] = wc[1] = wc[2] = 0.0
        fx.gimbal_forces(on, k, Lsys, y, qd, wc, Q)
        for i in range(5):
            out[C_AXIAL + i] = Q[i]
        # --- Newton–Euler with the full tree, true rotor momenta, g-sensitive body torques ---------
        for b in range(nb):
            for i in range(3):
                tau_ext[b, i] = 0.0
        if OI[I_NEEDS_F]:
            kinematics_rw(parent, jtype, axis, qidx, vidx, stab, y, v, Om, R, w)
            _mv(R_IB, fB, X[4])
            _mtv(R_IP, X[4], X[6])          # f in platform axes
            fx.body_specific_force(R, parent, X[6], fb)
            fx.g_sensitive_torques(k, on[fx.UNBALANCE], on[fx.ANISO], rhost, raxis, fb, tau_ext)
        kinematics_rw(parent, jtype, axis, qidx, vidx, stab, y, v, w0, R, w)
        newton_euler(parent, jtype, axis, vidx, inertia, stab, rhost, raxis, Lout, v, acc, wd0, R, w,
                     yes, yes, tau_ext, wd, f)
        rotor_torques(rhost, raxis, CF[F_C:F_C + 3], CF[F_A:F_A + 3], Lout, w, wd, rtau)
        for i in range(3):
            out[C_BEAR + i] = f[0, i]
        for g in range(5):                  # joint torque minus its axial part
            b = g + 1
            nf = _dot(axis[b], f[b])
            for i in range(3):
                out[C_BEAR + 3 + 3 * g + i] = f[b, i] - nf * axis[b, i]
        for r in range(nr):
            s = raxis[r]
            m = _dot(s, rtau[r])
            out[C_MOTOR + r] = m
            for i in range(3):
                out[C_BEAR + 18 + 3 * r + i] = rtau[r, i] - m * s[i]
        # --- drift, mount, servo -------------------------------------------------------------------
        if stab:
            _mtm(R_IC, R_IP, T1)            # R_CP
            d = X[17]
            matrix_rotvec_into(T1, d)
            _mtv(T1, wIN, X[4])
            for i in range(3):
                out[C_DRIFT + i] = d[i]
                out[C_DRATE + i] = Om[i] - X[4, i]
                out[C_SERVO + i] = 0.0
            if on[fx.SERVO]:
                iz = lay[LAY_Z]
                for ax in range(3):
                    gi = fx.servo_pickoff(ax)
                    out[C_SERVO + ax] = fx.servo_axis(k, y[gi], qd[gi], y[iz + ax])[0]
            _mtm(R_IB, R_IP, T2)            # R_BP (actual)
            _mm(R_PB, T2, T1)
            mount = X[16]
            euler_xyz_into(T1, mount)
            _mv(R_IB, wB, X[4])
            _mtv(R_IP, X[4], X[6])
            for i in range(3):
                X[6, i] = Om[i] - X[6, i]
            euler_xyz_rates_into(mount, X[6], X[7])
            for i in range(3):
                out[C_MOUNT + i] = mount[i]
                out[C_MRATE + i] = X[7, i]
        elif carried is None:               # (not reached: a stabilised platform; pruned at compile time)
            pass
        else:
            if not _gyro_reference_drift(R, w, raxis, R_IP, R_IC, wIN, T1, T2, MM[5], X, out):
                return kk, REFERENCE_UNDEFINED, 0
            for i in range(3):
                out[C_MOUNT + i] = 0.0
                out[C_MRATE + i] = 0.0
                out[C_SERVO + i] = 0.0
        # --- the rest --------------------------------------------------------------------------
        d = X[17]
        matrix_rotvec_into(R_IP, d)
        th = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if th < 1e-300:
            out[C_QUAT], out[C_QUAT + 1], out[C_QUAT + 2], out[C_QUAT + 3] = 0.0, 0.0, 0.0, 1.0
        else:
            sh = math.sin(th / 2)
            for i in range(3):
                out[C_QUAT + i] = d[i] / th * sh
            out[C_QUAT + 3] = math.cos(th / 2)
        out[C_T] = t
        mx = 0.0
        for i in range(5):
            out[C_ANG + i] = y[i]
            out[C_RATE + i] = qd[i]
            mx = max(mx, abs(y[i]))
        for i in range(3):
            out[C_OM + i] = Om[i]
            out[C_ROTOR + i] = CF[F_SPEED + i]
        out[C_MARGIN] = min(abs(math.cos(y[1])), abs(math.cos(y[2])), abs(math.cos(y[4])))
        out[C_MAXANG] = mx
        out[C_NSTEPS] = n_steps
        j = _first_bad(out)
        if j >= 0:
            return kk, NON_FINITE, j
    return Y.shape[0], OK, 0


@njit(cache=True, error_model="numpy")
def _gyro_reference_drift(R, w, raxis, R_IP, R_IC, wIN, T1, T2, G, X, out):
    """Carried mode: drift (rad) and drift rate (rad/s) of the gyros' own inertial reference
    relative to where it started: the triad whose y axis is the spin axis of rotor 11 (unit B:
    its direction holds the x and z axes, as unit B's pick-offs hold them in stabilised mode) and
    whose x axis is the spin axis of rotor 6 made normal to it (unit A: the rotation about y).
    False (nothing written) when the two spin axes are within ``MIN_SPIN_AXES_SINE`` of
    parallel: the rotation about y is undefined there. Uses ``R``, ``w`` of the tree kinematics;
    T1, T2, G (3×3) and rows 8..15, 17..20 of X are work."""
    e6, e11, w5, w10, xv, z, xd, ydv = X[8], X[9], X[10], X[11], X[12], X[13], X[14], X[15]
    d, zd, s, wig = X[17], X[18], X[19], X[20]
    _mm(R[1], R[2], T1)                 # R_P5
    _mm(R[4], R[5], T2)                 # R_P10
    _mv(T1, raxis[0], e6)               # spin axes of rotors 6 and 11, platform axes
    _mv(T2, raxis[2], e11)
    _mv(T1, w[2], w5)
    _mv(T2, w[5], w10)
    y = e11
    p = _dot(e6, y)
    for i in range(3):
        xv[i] = e6[i] - p * y[i]
    nrm = math.sqrt(xv[0] * xv[0] + xv[1] * xv[1] + xv[2] * xv[2])
    if not nrm >= MIN_SPIN_AXES_SINE:
        return False
    for i in range(3):
        xv[i] /= nrm
    _cross_into(xv, y, z)
    for i in range(3):                  # G_P = R_PG: columns x, y, z
        T2[i, 0], T2[i, 1], T2[i, 2] = xv[i], y[i], z[i]
    _mtm(R_IC, R_IP, T1)                # R_CP
    _mm(T1, T2, G)                      # R_CG
    matrix_rotvec_into(G, d)
    # ω_IG ≈ ½ Σ b × ḃ (b: triad in platform axes; ẏ = ω_10 × e11 exactly, ẋ ≈ ω_5 × e6)
    _cross_into(w5, e6, xd)
    _cross_into(w10, e11, ydv)
    _cross_into(xd, y, zd)
    _cross_into(xv, ydv, s)
    for i in range(3):
        zd[i] += s[i]
    _cross_into(xv, xd, s)
    for i in range(3):
        wig[i] = s[i]
    _cross_into(y, ydv, s)
    for i in range(3):
        wig[i] += s[i]
    _cross_into(z, zd, s)
    for i in range(3):
        wig[i] = 0.5 * (wig[i] + s[i])
    _mtv(T2, wig, s)                    # ω_IG in G axes
    _mtv(G, wIN, wig)
    for i in range(3):
        out[C_DRIFT + i] = d[i]
        out[C_DRATE + i] = s[i] - wig[i]
    return True


# ---- entries: work arrays once per call ---------------------------------------------------

@njit(cache=True, error_model="numpy")
def _first_bad(out):
    """Index of the first non-finite column of ``out``, or −1."""
    for j in range(out.shape[0]):
        x = out[j]
        if not (x - x == 0.0):
            return j
    return -1


@njit(cache=True)
def work_size(n, nb, nv, nr):
    """Floats of the work buffer ``output_rows`` carves its arrays from."""
    return 5 * n + 2 * 8 + nb * 9 + 5 * nb * 3 + nb * 3 * nv + 2 * nv * nv + 2 * nv + 8 + 5 + 4 * 9 + 9 * 3 \
        + 5 * 8 + nr * 3 + N_X * 3 + N_MM * 9


@njit(cache=True, error_model="numpy", nogil=True)
def output_rows(T, TR, NS, Y, SEG, OUT, I, P, mats, CF, OI, E, WK, gen, carried):
    """Outputs of K instants (t (K,) s, t_rel (K,) s, n_steps (K,), states Y (K, n), input
    segments SEG (K, 14)) into OUT (K, N_COL); WK: work (``work_size`` floats). Returns
    (done, code, detail): the instants ``[0, done)`` are written and finite; code OK,
    RHS_FAILED (the model refused the state of instant ``done``; its (t, y) in E) or
    NON_FINITE (column ``detail`` of instant ``done``). ``gen``: None when the model is the
    linear stabilised one (``takes_linear_path``), else 0 (``_rhs`` → ``physics.system.model_rhs``
    takes that model's right-hand side only); ``carried``: None for a stabilised platform, else
    0 — numba prunes the code a None rules out before typing it (a kernel per combination: a
    command compiles what its model needs)."""
    # borrowed (engine.views): the views made per instant below count no references
    T, TR, NS, Y, SEG, OUT = borrow(T), borrow(TR), borrow(NS), borrow(Y), borrow(SEG), borrow(OUT)
    I, P, mats, CF, OI, E, WK = borrow(I), borrow(P), borrow(mats), borrow(CF), borrow(OI), borrow(E), borrow(WK)
    n = Y.shape[1]
    nb = OI[I_NB]
    nr = OI[I_NR]
    nv = I[0, LAY_NV]
    o = 0
    yd = WK[o:o + n]
    yp = WK[o + n:o + 2 * n]
    ym = WK[o + 2 * n:o + 3 * n]
    ydp = WK[o + 3 * n:o + 4 * n]
    ydm = WK[o + 4 * n:o + 5 * n]
    o += 5 * n
    v = WK[o:o + 8]
    acc = WK[o + 8:o + 16]
    o += 16
    R = WK[o:o + 9 * nb].reshape((nb, 3, 3))
    o += 9 * nb
    w = WK[o:o + 3 * nb].reshape((nb, 3))
    wd = WK[o + 3 * nb:o + 6 * nb].reshape((nb, 3))
    f = WK[o + 6 * nb:o + 9 * nb].reshape((nb, 3))
    fb = WK[o + 9 * nb:o + 12 * nb].reshape((nb, 3))
    tau_ext = WK[o + 12 * nb:o + 15 * nb].reshape((nb, 3))
    o += 15 * nb
    J = WK[o:o + 3 * nb * nv].reshape((nb, 3, nv))
    o += 3 * nb * nv
    M = WK[o:o + nv * nv].reshape((nv, nv))
    chol = WK[o + nv * nv:o + 2 * nv * nv].reshape((nv, nv))
    o += 2 * nv * nv
    c = WK[o:o + nv]
    F = WK[o + nv:o + 2 * nv]
    o += 2 * nv
    a = WK[o:o + 8]
    Q = WK[o + 8:o + 13]
    o += 13
    RR = WK[o:o + 36].reshape((4, 3, 3))
    V = WK[o + 36:o + 63].reshape((9, 3))
    W = WK[o + 63:o + 103].reshape((5, 8))
    o += 103
    rtau = WK[o:o + 3 * nr].reshape((nr, 3))
    o += 3 * nr
    X = WK[o:o + 3 * N_X].reshape((N_X, 3))
    MM = WK[o + 3 * N_X:o + 3 * N_X + 9 * N_MM].reshape((N_MM, 3, 3))
    return _instants(T, TR, NS, Y, SEG, OUT, I, P, mats, CF, OI, yd, yp, ym, ydp, ydm, v, acc, R, w, wd, J, f, M,
                     c, tau_ext, fb, chol, F, a, Q, RR, V, W, rtau, X, MM, E, gen, carried)


@njit(cache=True, error_model="numpy")
def output_row(t, t_rel, n_steps, y, seg, out, I, P, mats, CF, OI, E, WK, gen, carried):
    """``output_rows`` for one instant (scalars t, t_rel, n_steps; y (n,), seg (14,), out
    (N_COL,)). Returns (done, code, detail)."""
    T = np.empty(3)
    T[0], T[1], T[2] = t, t_rel, n_steps
    return output_rows(T[0:1], T[1:2], T[2:3], y.reshape((1, y.shape[0])), seg.reshape((1, seg.shape[0])),
                       out.reshape((1, out.shape[0])), I, P, mats, CF, OI, E, WK, gen, carried)


# ---- Python side ------------------------------------------------------------------------------

class OutputKernel:
    """The output code of one simulator's system: ``row`` (one instant -> ``Outputs``) and
    ``block`` (K instants -> ``OutputBlock``), both by the compiled kernels above.

    An instant the model refuses (precession gimbal lock, mass matrix not positive definite)
    raises the model's ``SimulationError``; non-finite outputs raise ``NonFiniteOutputError``.
    From ``block`` either error carries ``.block``: the outputs of the instants before it."""

    def __init__(self, system: PlatformSystem):
        tree = system.tree
        opts = system.options
        self.system = system
        self.stabilised = bool(system.stabilised)
        L = np.asarray(system.L_true, float) if opts.has("rotor_gyroscopic") else np.zeros(3)
        self.CF = np.concatenate([L, tree.rotor_C, tree.rotor_A, np.asarray(system.params.rotor_speed, float),
                                  tree.axis.ravel(), tree.inertia.ravel(), tree.rotor_axis.ravel()]).astype(float)
        needs_f = bool(opts.effects & NEEDS_SPECIFIC_FORCE)
        self.OI = np.array([system.fid, int(needs_f), tree.nb, len(tree.rotor_host), *tree.rotor_host],
                           dtype=np.int64)
        self.E = np.zeros(1 + system.layout.n)
        self.WK = np.zeros(work_size(system.layout.n, tree.nb, tree.nv, len(tree.rotor_host)))
        #: the kernels' compile-time switches (output_rows)
        self.gen = None if plain(takes_linear_path)(system.fid == LINEAR, system.I) else 0
        self.carried = None if system.I[0, LAY_STAB] == 1 else 0

    def row(self, t: float, t_rel: float, n_steps: float, y: np.ndarray, seg: np.ndarray) -> Outputs:
        """Outputs at one instant: time t (s), t_rel (s since the first sample), accepted
        substeps so far, state y (n,), input segment seg (14,) ending at the instant."""
        return outputs_of_row(self.values(t, t_rel, n_steps, y, seg), self.stabilised)

    def values(self, t: float, t_rel: float, n_steps: float, y: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """The numbers of :meth:`row` as one new row (N_COL,), layout ``outputs.C_*`` (no
        ``Outputs`` object: the node's per-instant path)."""
        out = np.empty(N_COL)
        self._row_into(out, t, t_rel, n_steps, y, seg)
        return out

    def _row_into(self, out, t, t_rel, n_steps, y, seg) -> None:
        s = self.system
        try:
            _, code, detail = output_row(t, t_rel, n_steps, y, seg, out, s.I, s.P, s.mats, self.CF, self.OI,
                                         self.E, self.WK, self.gen, self.carried)
        except ArithmeticError as e:       # inside a model kernel (python error model)
            raise self._numeric(e, t) from e
        if code != OK:
            self._raise(code, detail, out, t, seg)

    def block(self, t, t_rel, n_steps, y, seg) -> OutputBlock:
        """Outputs at K instants: t, t_rel (K,) s, n_steps (K,), y (K, n), seg (K, 14)."""
        s = self.system
        T = np.ascontiguousarray(t, dtype=float)
        TR = np.ascontiguousarray(t_rel, dtype=float)
        NS = np.ascontiguousarray(n_steps, dtype=float)
        Y = np.ascontiguousarray(y, dtype=float)
        SEG = np.ascontiguousarray(seg, dtype=float)
        K = len(T)
        if TR.shape != (K,) or NS.shape != (K,) or Y.shape != (K, s.layout.n) or SEG.shape != (K, SEG_N):
            raise ValueError(f"output snapshots: t {T.shape}, t_rel {TR.shape}, n_steps {NS.shape}, "
                             f"y {Y.shape} (n = {s.layout.n}), seg {SEG.shape} do not fit")
        OUT = np.empty((K, N_COL))
        try:
            done, code, detail = output_rows(T, TR, NS, Y, SEG, OUT, s.I, s.P, s.mats, self.CF, self.OI, self.E,
                                             self.WK, self.gen, self.carried)
        except ArithmeticError:
            # a model kernel raised: find the instant one by one (rare path)
            for k in range(K):
                try:
                    self._row_into(OUT[k], float(T[k]), float(TR[k]), float(NS[k]), Y[k], SEG[k])
                except SimulationError as e:
                    e.block = OutputBlock(OUT[:k], self.stabilised)
                    raise
            done, code, detail = K, OK, 0
        block = OutputBlock(OUT if done == K else OUT[:done], self.stabilised)
        if code != OK:
            try:
                self._raise(code, detail, OUT[done], T[done], SEG[done])
            except SimulationError as e:
                e.block = block
                raise
        return block

    def _raise(self, code: int, detail: int, out: np.ndarray, t: float, seg: np.ndarray):
        if code == NON_FINITE:
            name = COLUMN_NAMES[detail]
            raise NonFiniteOutputError(
                f"output {name} is {float(out[detail])} at t = {float(t)!r} s (an input or effect drives the "
                "model beyond floating point there): not published", name, float(t))
        if code == REFERENCE_UNDEFINED:
            raise SimulationError(
                f"carried mode: the spin axes of rotors 6 and 11 are within {math.degrees(MIN_SPIN_AXES_SINE):.2g}° "
                f"of parallel at t = {float(t)!r} s: the gyros' reference triad, whose drift the carried mode "
                "reports, is undefined there (one has precessed about 90° towards the other)")
        # the model refused the state it was evaluated at: let it say why (same message as stepping)
        sys_ = self.system
        saved, n_rhs = sys_.seg.copy(), sys_.n_rhs
        try:
            sys_.seg[:] = seg
            sys_.rhs_into(float(self.E[0]), self.E[1:].copy(), np.empty(len(self.E) - 1))
        finally:
            sys_.seg[:] = saved
            sys_.n_rhs = n_rhs
        raise SimulationError(f"the model refused the state at t = {t!r} s while computing outputs")

    @staticmethod
    def _numeric(e: ArithmeticError, t: float) -> NonFiniteOutputError:
        return NonFiniteOutputError(f"outputs at t = {t!r} s failed numerically ({type(e).__name__}: {e}); "
                                    "not published", "", float(t))
