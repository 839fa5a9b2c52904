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

"""The platform as an ODE system ``ẏ = f(t, y)`` for one scene: model (only the effects that
are on) + the current input interval. This is what the integrators step.

The vehicle input over an interval ``[t0, t0 + dt]`` is linear in time (rates rad/s and specific
force m/s², vehicle axes), so its angular acceleration is constant on the interval.
All work happens in one numba kernel (``platform_rhs``) on preallocated arrays.
"""
from __future__ import annotations

import math

from numba import types
from numba.extending import overload
import numpy as np

from . import effects as fx
from .jit import njit, plain
from .model import (check_precession_valid, LAY_NV, LAY_OM, LAY_QD, LAY_QIB, LAY_QIP, LAY_STAB, LAY_Z,
                    linear_coefficients, linear_gimbal_accel, LOCK_COS, platform_tree, precession_rates, rest_matrices,
                    seg_at, SEG_DT, SEG_F0, SEG_F1, SEG_N, seg_slope, SEG_T0, SEG_W0, SEG_W1, spin_momentum,
                    StateLayout)
from .options import ModelOptions
from .params import ParameterError, PlatformParams
from .rhs_linear import rest_model_accel, stabilised_linear_rhs, takes_linear_path
from .rotations import quat_matrix, quat_rate_at, quat_to_matrix_at
from .switching import support_switch_passed, support_switch_time
from .tree import generalised, kinematics, mass_matrix, newton_euler, rot_axis, TreeWork
from ..errors import GimbalLockError, SimulationError

FULL, LINEAR, PRECESSION = 0, 1, 2
FIDELITY_CODE = {"full": FULL, "linear": LINEAR, "precession": PRECESSION}
STATUS_OK, STATUS_LOCK, STATUS_NOT_PD = 0, 1, 2
#: LLVM fast-math flags of the hot kernels: none. Reassociation and fused multiply-add made
#: the last bits depend on how LLVM inlined a callee, i.e. on which kernels a process compiled
#: itself and which it loaded from numba's cache (outputs 1e-20 rad apart between runs, the
#: per-message and chunked replays no longer byte-identical); they gained nothing measurable
#: (1.0 µs/sample either way on the 1 kHz bench signal)
FASTMATH = False
# rows of the small-vector work array V
V_OM, V_OMD, V_WC, V_TMP, V_FP, V_MP, V_H, V_HD, V_ZERO = range(9)
N_V = 9
# offsets in the packed float parameters P
P_L = fx.N_K
P_LC = P_L + 3
P_WIN = P_LC + 13
N_P = P_WIN + 3


@njit(cache=True, inline="always")
def unpack_tables(I, P, nb):
    """Named views of the kernels' packed inputs, the one place their layout is read:
    ``I`` (int rows) → ``lay`` (``LAY_*``), ``on`` (effect flags), the tree's ``parent``,
    ``jtype``, ``qidx``, ``vidx`` (its ``nb`` bodies); ``P`` (floats, offsets ``P_*``) → ``k``
    (effect coefficients), ``L`` (rotor momenta), ``lc`` (linear coefficients), ``w_IN`` (Earth
    rate). Inlined into the compiled callers; ``PlatformSystem.rebind`` runs it as Python."""
    return (I[0], I[1], I[2, :nb], I[3, :nb], I[4, :nb], I[5, :nb],
            P[0:P_L], P[P_L:P_L + 3], P[P_LC:P_LC + 13], P[P_WIN:P_WIN + 3])


@njit(cache=True)
def chol_solve(M, b, x, work):
    """Solve M x = b for symmetric positive-definite M (n ≤ ~10) by Cholesky, in ``work``.
    Returns False if M is not (numerically) positive definite."""
    n = M.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = M[i, j]
            for k in range(j):
                s -= work[i, k] * work[j, k]
            if i == j:
                if s <= 1e-300 * abs(M[i, i]) or s <= 0.0:
                    return False
                work[i, i] = math.sqrt(s)
            else:
                work[i, j] = s / work[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= work[i, k] * x[k]
        x[i] = s / work[i, i]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= work[k, i] * x[k]
        x[i] = s / work[i, i]
    return True


@njit(cache=True, fastmath=FASTMATH)
def platform_rhs(t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                 R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
    """ẏ of the platform (see module doc). Writes ``yd``; returns a status code
    (0 ok, 1 precession gimbal lock, 2 mass matrix not positive definite).

    The linear stabilised model without body rotations (``takes_linear_path``) is
    :func:`.rhs_linear.stabilised_linear_rhs`, every other model :func:`general_rhs`. The
    compiled kernels choose between the two when they are compiled (their ``gen`` switch) and
    call one of them directly: a kernel of the general model does not compile the linear one
    (~5 s of a first run on a 2 GHz core), nor the linear kernels the general one."""
    if takes_linear_path(fid == LINEAR, I):
        return stabilised_linear_rhs(t, y, yd, I, P, seg, mats, F)
    return general_rhs(t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                       R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)


def model_rhs(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
              R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
    """``platform_rhs`` with the choice of the model made by the type of ``gen`` (None: the
    linear stabilised model, an int: :func:`general_rhs`): what the compiled kernels call, so
    that each compiles only the right-hand side it runs (numba prunes an ``if gen is None``
    only when ``gen`` is None; this overload chooses while typing, for both)."""
    if gen is None:
        return stabilised_linear_rhs(t, y, yd, I, P, seg, mats, F)
    return general_rhs(t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                       R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)


@overload(model_rhs)
def _model_rhs_typed(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                     R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
    if isinstance(gen, types.NoneType):
        def linear(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                   R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
            return stabilised_linear_rhs(t, y, yd, I, P, seg, mats, F)
        return linear

    def general(gen, t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
        return general_rhs(t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                           R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)
    return general


@njit(cache=True, fastmath=FASTMATH)
def general_rhs(t, y, yd, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W):
    """ẏ of every model but the linear stabilised one (``platform_rhs``'s arguments and status).

    One compiled function that the batch, push and output kernels call (not inlined into
    each: a first run compiled it three times, 154 s of the default scene's first run on a
    2 GHz core, now 95 s; the call's 28 array arguments cost nothing measurable against the
    ~3 µs of the tree's right-hand side: default scene 0.63–0.68 s per 20 s either way; the
    linear stabilised model keeps its inlined right-hand side in the batch kernel).
    Inputs are grouped: ``I`` int rows (layout, effect flags, tree parent/jtype/qidx/vidx),
    ``P`` packed floats (effect coefficients, L, linear coefficients, ω_IN; offsets ``P_*``),
    ``seg`` the input interval, ``mats`` (5, 8, 8): M0⁻¹, G0, I_frozen, I_frozen⁻¹, R_PB (mounting). Work arrays
    are preallocated and indexed directly (no views on the linear hot path): the tree's,
    ``RR`` (4, 3, 3) rotations R_IP, R_IB, R_PB, R_IC, ``V`` (9, 3) small vectors (rows
    ``V_*``), ``W`` rows q̇, tree v, zero a, dvisc, Qf. The linear stabilised model without
    body rotations is not computed here (``platform_rhs`` hands it to
    :func:`.rhs_linear.stabilised_linear_rhs`)."""
    nb = inertia.shape[0]
    lay, on, parent, jtype, qidx, vidx, k, L, lc, wIN = unpack_tables(I, P, nb)
    qd = W[0]
    vv = W[1]
    za = W[2]
    dvisc = W[3]
    Qf = W[4]
    stab = lay[LAY_STAB] == 1
    nv = lay[LAY_NV]
    status = 0
    # --- input at time t (linear over the interval) ---------------------------------------
    wB0, wB1, wB2 = seg_at(seg, t, SEG_W0)
    fB0, fB1, fB2 = seg_at(seg, t, SEG_F0)
    iqb = lay[LAY_QIB]
    quat_rate_at(y, iqb, wB0, wB1, wB2, yd)
    # R_PB: platform <- vehicle
    if stab:
        iqp = lay[LAY_QIP]
        quat_to_matrix_at(y, iqp, RR, 0)          # R_IP
        quat_to_matrix_at(y, iqb, RR, 1)          # R_IB
        for i in range(3):
            for j in range(3):
                RR[2, i, j] = RR[0, 0, i] * RR[1, 0, j] + RR[0, 1, i] * RR[1, 1, j] + RR[0, 2, i] * RR[1, 2, j]
        io = lay[LAY_OM]
        Om0, Om1, Om2 = y[io], y[io + 1], y[io + 2]
        Omd0, Omd1, Omd2 = 0.0, 0.0, 0.0
    else:
        for i in range(3):
            for j in range(3):
                RR[2, i, j] = mats[4, i, j]
        Om0, Om1, Om2 = 0.0, 0.0, 0.0
        Omd0, Omd1, Omd2 = 0.0, 0.0, 0.0
    wBP0 = RR[2, 0, 0] * wB0 + RR[2, 0, 1] * wB1 + RR[2, 0, 2] * wB2
    wBP1 = RR[2, 1, 0] * wB0 + RR[2, 1, 1] * wB1 + RR[2, 1, 2] * wB2
    wBP2 = RR[2, 2, 0] * wB0 + RR[2, 2, 1] * wB1 + RR[2, 2, 2] * wB2
    if not stab:
        Om0, Om1, Om2 = wBP0, wBP1, wBP2
        d0, d1, d2 = seg_slope(seg, SEG_W0)
        Omd0 = RR[2, 0, 0] * d0 + RR[2, 0, 1] * d1 + RR[2, 0, 2] * d2
        Omd1 = RR[2, 1, 0] * d0 + RR[2, 1, 1] * d1 + RR[2, 1, 2] * d2
        Omd2 = RR[2, 2, 0] * d0 + RR[2, 2, 1] * d1 + RR[2, 2, 2] * d2
    V[V_OM, 0], V[V_OM, 1], V[V_OM, 2] = Om0, Om1, Om2
    V[V_OMD, 0], V[V_OMD, 1], V[V_OMD, 2] = Omd0, Omd1, Omd2
    # --- Earth rate: commanded precession ω_c = R_PI R_IC(t) ω_IN ---------------------------
    wc0, wc1, wc2 = 0.0, 0.0, 0.0
    if on[fx.EARTH]:
        wn = math.sqrt(wIN[0] ** 2 + wIN[1] ** 2 + wIN[2] ** 2)
        for i in range(3):
            for j in range(3):
                RR[3, i, j] = 1.0 if i == j else 0.0
        if wn > 0.0:
            V[V_TMP, 0], V[V_TMP, 1], V[V_TMP, 2] = wIN[0] / wn, wIN[1] / wn, wIN[2] / wn
            rot_axis(V[V_TMP], wn * t, RR[3])
        u0 = RR[3, 0, 0] * wIN[0] + RR[3, 0, 1] * wIN[1] + RR[3, 0, 2] * wIN[2]   # R_IC ω_IN
        u1 = RR[3, 1, 0] * wIN[0] + RR[3, 1, 1] * wIN[1] + RR[3, 1, 2] * wIN[2]
        u2 = RR[3, 2, 0] * wIN[0] + RR[3, 2, 1] * wIN[1] + RR[3, 2, 2] * wIN[2]
        if not stab:   # R_IP = R_IB R_BP: ω_c = R_PB R_BI u
            quat_to_matrix_at(y, iqb, RR, 1)
            b0 = RR[1, 0, 0] * u0 + RR[1, 1, 0] * u1 + RR[1, 2, 0] * u2
            b1 = RR[1, 0, 1] * u0 + RR[1, 1, 1] * u1 + RR[1, 2, 1] * u2
            b2 = RR[1, 0, 2] * u0 + RR[1, 1, 2] * u1 + RR[1, 2, 2] * u2
            wc0 = RR[2, 0, 0] * b0 + RR[2, 0, 1] * b1 + RR[2, 0, 2] * b2
            wc1 = RR[2, 1, 0] * b0 + RR[2, 1, 1] * b1 + RR[2, 1, 2] * b2
            wc2 = RR[2, 2, 0] * b0 + RR[2, 2, 1] * b1 + RR[2, 2, 2] * b2
        else:          # ω_c = R_IPᵀ u
            wc0 = RR[0, 0, 0] * u0 + RR[0, 1, 0] * u1 + RR[0, 2, 0] * u2
            wc1 = RR[0, 0, 1] * u0 + RR[0, 1, 1] * u1 + RR[0, 2, 1] * u2
            wc2 = RR[0, 0, 2] * u0 + RR[0, 1, 2] * u1 + RR[0, 2, 2] * u2
    V[V_WC, 0], V[V_WC, 1], V[V_WC, 2] = wc0, wc1, wc2
    # --- gimbal rates --------------------------------------------------------------------
    iqd = lay[LAY_QD]
    if fid != 2:
        for i in range(5):
            qd[i] = y[iqd + i]
    else:
        for i in range(5):
            qd[i] = 0.0
    # g-sensitive torques need body rotations
    g_sens = on[fx.UNBALANCE] or on[fx.ANISO]
    need_kin = fid == 0 or g_sens
    if need_kin:
        for i in range(tau_ext.shape[0]):
            for j in range(3):
                tau_ext[i, j] = 0.0
        # tree velocities: [Ω (stab)] + q̇ (zeros in precession: only R is used there)
        if stab:
            vv[0], vv[1], vv[2] = Om0, Om1, Om2
        for i in range(5):
            vv[nv - 5 + i] = qd[i]
        kinematics(parent, jtype, axis, qidx, vidx, stab, y, vv, V[V_OM], R, w, J)
        if g_sens:
            V[V_FP, 0] = RR[2, 0, 0] * fB0 + RR[2, 0, 1] * fB1 + RR[2, 0, 2] * fB2
            V[V_FP, 1] = RR[2, 1, 0] * fB0 + RR[2, 1, 1] * fB1 + RR[2, 1, 2] * fB2
            V[V_FP, 2] = RR[2, 2, 0] * fB0 + RR[2, 2, 1] * fB1 + RR[2, 2, 2] * fB2
            fx.body_specific_force(R, parent, V[V_FP], fb)
            fx.g_sensitive_torques(k, on[fx.UNBALANCE], on[fx.ANISO], rhost, raxis, fb, tau_ext)
    # --- platform torque (stabilised): support friction; servo after the gimbal rates ------
    MP0, MP1, MP2 = 0.0, 0.0, 0.0
    if stab and on[fx.SUPPORT]:
        MP0 += fx.support_friction_axis(k, Om0 - wBP0)
        MP1 += fx.support_friction_axis(k, Om1 - wBP1)
        MP2 += fx.support_friction_axis(k, Om2 - wBP2)
    # gimbal torques of the effects (precession: dampers solved implicitly, friction iterated)
    if fid == 2:
        saved_d = on[fx.DAMPERS]
        saved_f = on[fx.FRICTION]
        on[fx.DAMPERS] = 0
        on[fx.FRICTION] = 0
        fx.gimbal_forces(on, k, L, y, qd, V[V_WC], Q)
        on[fx.DAMPERS] = saved_d
        on[fx.FRICTION] = saved_f
    else:
        fx.gimbal_forces(on, k, L, y, qd, V[V_WC], Q)
    if g_sens and fid != 0:   # generalised force of the body torques: Σ J_hᵀ τ_h
        V[V_MP, 0], V[V_MP, 1], V[V_MP, 2] = MP0, MP1, MP2
        _add_body_torques(J, tau_ext, nv, stab, Q, V[V_MP])
        MP0, MP1, MP2 = V[V_MP, 0], V[V_MP, 1], V[V_MP, 2]
    if fid == 2:
        for i in range(5):
            dvisc[i] = k[fx.K_DAMPER + i] if on[fx.DAMPERS] else 0.0
        iters = 6 if on[fx.FRICTION] else 1
        cmin = 1.0
        for it in range(iters):
            for i in range(5):
                Qf[i] = Q[i]
            if on[fx.FRICTION]:
                fx.gimbal_friction(k, qd, Qf)
            cmin = precession_rates(L, y, V[V_OM], Qf, dvisc, qd)
        if cmin < LOCK_COS:
            status = 1
    if stab:
        iz = lay[LAY_Z]
        if on[fx.SERVO]:
            # pick-offs y = (β10, α4, α9) drive mount axes 1, 2, 3 (spec 9.3)
            s0, s1, s2 = fx.servo_mount_torques(k, y, qd, 0, iz, yd)
            MP0 += s0
            MP1 += s1
            MP2 += s2
        else:
            yd[iz], yd[iz + 1], yd[iz + 2] = 0.0, 0.0, 0.0
    # --- fidelities ----------------------------------------------------------------------
    if fid == 0:
        mass_matrix(J, inertia, M)
        for i in range(nv):
            za[i] = 0.0
        veh = on[fx.VEHICLE_ACC] and not stab
        newton_euler(parent, jtype, axis, vidx, inertia, stab, rhost, raxis, L, vv, za,
                     V[V_OMD] if veh else V[V_ZERO], R, w, on[fx.CORIOLIS] != 0, on[fx.GYRO] != 0, tau_ext, wd, f)
        generalised(jtype, axis, vidx, stab, f, c)
        off = nv - 5
        if stab:
            F[0] = MP0 - c[0]
            F[1] = MP1 - c[1]
            F[2] = MP2 - c[2]
        for i in range(5):
            F[off + i] = Q[i] - c[off + i]
        if not chol_solve(M, F, a, chol):
            status = 2
            for i in range(nv):
                a[i] = 0.0
    elif fid == 1:
        if stab:
            F[0], F[1], F[2] = MP0, MP1, MP2
            for i in range(5):
                F[3 + i] = Q[i]
            rest_model_accel(mats, y, F, on[fx.GYRO], a, 0)
        else:
            linear_gimbal_accel(lc, L, y, qd, V[V_OM], V[V_OMD], Q, on[fx.GYRO], on[fx.CORIOLIS],
                                on[fx.VEHICLE_ACC], a)
    elif stab:
        # precession platform rows: Ifz Ω̇ = M − Ω × (Ifz Ω + h) − ḣ
        spin_momentum(L, y, qd, V[V_H], V[V_HD])
        h0 = mats[2, 0, 0] * Om0 + mats[2, 0, 1] * Om1 + mats[2, 0, 2] * Om2 + V[V_H, 0]
        h1 = mats[2, 1, 0] * Om0 + mats[2, 1, 1] * Om1 + mats[2, 1, 2] * Om2 + V[V_H, 1]
        h2 = mats[2, 2, 0] * Om0 + mats[2, 2, 1] * Om1 + mats[2, 2, 2] * Om2 + V[V_H, 2]
        r0 = MP0 - (Om1 * h2 - Om2 * h1) - V[V_HD, 0]
        r1 = MP1 - (Om2 * h0 - Om0 * h2) - V[V_HD, 1]
        r2 = MP2 - (Om0 * h1 - Om1 * h0) - V[V_HD, 2]
        for i in range(3):
            a[i] = mats[3, i, 0] * r0 + mats[3, i, 1] * r1 + mats[3, i, 2] * r2
    # --- assemble ẏ ----------------------------------------------------------------------
    for i in range(5):
        yd[i] = qd[i]
    if fid == 2:
        if stab:
            io = lay[LAY_OM]
            yd[io], yd[io + 1], yd[io + 2] = a[0], a[1], a[2]
    else:
        for i in range(nv):
            yd[5 + i] = a[i]
    if stab:
        quat_rate_at(y, lay[LAY_QIP], Om0, Om1, Om2, yd)
    return status


@njit(cache=True)
def _add_body_torques(J, tau_ext, nv, stab, Q, MP):
    """Q += Σ_b J_bᵀ τ_b over the gimbal columns, M_P += root columns (stabilised)."""
    off = nv - 5
    for b in range(tau_ext.shape[0]):
        for j in range(nv):
            s = J[b, 0, j] * tau_ext[b, 0] + J[b, 1, j] * tau_ext[b, 1] + J[b, 2, j] * tau_ext[b, 2]
            if j >= off:
                Q[j - off] += s
            elif stab:
                MP[j] += s


@njit(cache=True, fastmath=FASTMATH)
def fd_jacobian(t, y, Jac, fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, w, wd, J, f, M, c, tau_ext, fb,
                chol, F, a, Q, RR, V, W):
    """Central-difference Jacobian ∂ẏ/∂y at (t, y) into ``Jac`` (2n right-hand sides, steps
    ~ eps^(1/3)·max(|y_j|, 1e-3); relative accuracy ~1e-10). Returns the worst kernel status."""
    n = y.shape[0]
    yp = y.copy()
    fp = np.empty(n)
    fm = np.empty(n)
    status = 0
    for j in range(n):
        d = 6e-6 * max(abs(y[j]), 1e-3)
        yp[j] = y[j] + d
        status |= platform_rhs(t, yp, fp, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                               R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)
        yp[j] = y[j] - d
        status |= platform_rhs(t, yp, fm, fid, I, P, seg, mats, axis, inertia, rhost, raxis,
                               R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, RR, V, W)
        yp[j] = y[j]
        for i in range(n):
            Jac[i, j] = (fp[i] - fm[i]) / (2.0 * d)
    return status


@njit(cache=True)
def support_regime(y, I, P, seg, RR):
    """Bit mask of the mount axes whose support friction stays in its regularised (stick) zone
    |Ω_i − ω_B,i| < ε over the whole input interval (stabilised mode, effect on). An axis only
    passing through the zone (the vehicle rate seen from the platform turns or changes) is
    slipping: d(ω_B^P)/dt = R_PB ω̇_B − Ω × ω_B^P is used to look across the interval."""
    lay = I[0]
    if lay[LAY_STAB] != 1 or I[1, fx.SUPPORT] == 0:
        return 0
    for iq in (lay[LAY_QIP], lay[LAY_QIB]):
        nq = y[iq] ** 2 + y[iq + 1] ** 2 + y[iq + 2] ** 2 + y[iq + 3] ** 2
        if not (nq > 0.0 and nq < math.inf):
            return 0            # degenerate attitude: the step itself reports it
    quat_to_matrix_at(y, lay[LAY_QIP], RR, 0)
    quat_to_matrix_at(y, lay[LAY_QIB], RR, 1)
    eps = P[fx.K_EPS_S]
    io = lay[LAY_OM]
    dt = seg[SEG_DT]
    inv_dt = 1.0 / dt if dt > 0.0 else 0.0
    wbp0 = 0.0
    wbp1 = 0.0
    wbp2 = 0.0
    dw0 = 0.0
    dw1 = 0.0
    dw2 = 0.0
    for j in range(3):
        r0 = RR[0, 0, 0] * RR[1, 0, j] + RR[0, 1, 0] * RR[1, 1, j] + RR[0, 2, 0] * RR[1, 2, j]
        r1 = RR[0, 0, 1] * RR[1, 0, j] + RR[0, 1, 1] * RR[1, 1, j] + RR[0, 2, 1] * RR[1, 2, j]
        r2 = RR[0, 0, 2] * RR[1, 0, j] + RR[0, 1, 2] * RR[1, 1, j] + RR[0, 2, 2] * RR[1, 2, j]
        wj = seg[SEG_W0 + j]
        dj = (seg[SEG_W1 + j] - seg[SEG_W0 + j]) * inv_dt
        wbp0 += r0 * wj
        wbp1 += r1 * wj
        wbp2 += r2 * wj
        dw0 += r0 * dj
        dw1 += r1 * dj
        dw2 += r2 * dj
    O0, O1, O2 = y[io], y[io + 1], y[io + 2]
    # d(ω_B^P)/dt = R_PB ω̇_B − Ω × ω_B^P
    dw0 -= O1 * wbp2 - O2 * wbp1
    dw1 -= O2 * wbp0 - O0 * wbp2
    dw2 -= O0 * wbp1 - O1 * wbp0
    mask = 0
    if abs(O0 - wbp0) + abs(dw0) * dt < eps:
        mask |= 1
    if abs(O1 - wbp1) + abs(dw1) * dt < eps:
        mask |= 2
    if abs(O2 - wbp2) + abs(dw2) * dt < eps:
        mask |= 4
    return mask


class PlatformSystem:
    """The ODE system of one scene (``OdeSystem`` contract of ``integrators``).

    ``set_input(t0, t1, w0, w1, f0, f1)`` fixes the input interval; ``rhs(t, y)`` is then
    ``ẏ``. ``linear_part()`` is the Jacobian at rest with zero input (Coulomb friction left
    out: it is not differentiable there), constant per scene, for exponential integrators.
    """

    def __init__(self, params: PlatformParams, options: ModelOptions):
        self.params = params
        self.options = options
        self.stabilised = options.mode == "stabilised"
        self.fid = FIDELITY_CODE[options.fidelity]
        if self.fid == PRECESSION:
            check_precession_valid(params, options)
        self.layout = lay = StateLayout.make(self.stabilised, self.fid == PRECESSION)
        self.tree = platform_tree(params, root_dynamic=self.stabilised)
        self.work = TreeWork(self.tree)
        self.nv = self.tree.nv
        nb = self.tree.nb
        # packed kernel inputs; the named attributes below are numpy views into them
        self.I = np.zeros((6, max(12, fx.N_EFFECTS, 7, nb)), dtype=np.int64)
        self.I[0, :7] = [
            lay.Om.start if lay.Om else -1, lay.qd.start if lay.qd else -1,
            lay.quat_IP.start if lay.quat_IP else -1, lay.quat_IB.start, lay.z.start if lay.z else -1,
            1 if self.stabilised else 0, self.nv]
        self.I[1, :fx.N_EFFECTS] = fx.flags(options.effects)
        for row, arr in ((2, self.tree.parent), (3, self.tree.jtype), (4, self.tree.qidx), (5, self.tree.vidx)):
            self.I[row, :nb] = arr
        self.P = np.zeros(N_P)
        self.rebind(self.I)
        self.k[:] = fx.coefficients(params)
        self.L[:] = np.asarray(params.L, float) if options.has("rotor_gyroscopic") else np.zeros(3)
        self.L_true = np.asarray(params.L, float)
        self.lc[:] = linear_coefficients(params)
        M0, G0 = rest_matrices(params)
        self.M0, self.G0 = M0, G0
        self.Ifz = M0[:3, :3].copy()
        self.mats = np.zeros((5, 8, 8))
        try:
            self.mats[0] = np.linalg.inv(M0)
        except np.linalg.LinAlgError:
            raise ParameterError("the rest mass matrix of these parameters is singular (a body without "
                                 "inertia about a joint axis)") from None
        self.mats[1] = G0
        self.mats[2, :3, :3] = self.Ifz
        self.mats[3, :3, :3] = np.linalg.inv(self.Ifz)
        self.R_BP = quat_matrix(params.mounting)            # platform → vehicle (x, y, z, w)
        self.R_PB = np.ascontiguousarray(self.R_BP.T)
        self.mats[4, :3, :3] = self.R_PB
        lat = params.latitude
        self.w_IN[:] = (params.earth_rate * np.array([0.0, math.cos(lat), math.sin(lat)])
                        if options.has("earth_rate") else np.zeros(3))
        self.seg = np.zeros(SEG_N)
        self.seg[SEG_DT] = 1.0
        n = self.nv
        self._F = np.zeros(n)
        self._a = np.zeros(8)
        self._Q = np.zeros(5)
        self._chol = np.zeros((n, n))
        self._fb = np.zeros((nb, 3))
        self._RR = np.zeros((4, 3, 3))
        self._V = np.zeros((N_V, 3))
        self._W = np.zeros((5, 8))
        self.n_rhs = 0
        self.last_status = 0
        self._lin: dict[int, tuple] = {}      # linear part per friction regime
        self._A_rest: np.ndarray | None = None

    def rebind(self, I: np.ndarray) -> None:
        """Use ``I`` (same values) as the int table and re-derive the named views of ``I`` and
        ``P`` (after ``P`` was replaced by an equal array elsewhere, e.g. a packed buffer)."""
        self.I = I
        self.lay, self.on, _, _, _, _, self.k, self.L, self.lc, self.w_IN = plain(unpack_tables)(I, self.P, 0)

    # ---- input -------------------------------------------------------------------------
    def set_input(self, t0: float, t1: float, w0, w1, f0=None, f1=None) -> None:
        """Input over [t0, t1]: vehicle rate (rad/s) and specific force (m/s²), vehicle axes,
        linear in time."""
        seg = self.seg
        seg[SEG_T0] = t0
        seg[SEG_DT] = t1 - t0
        seg[SEG_W0:SEG_W0 + 3] = w0
        seg[SEG_W1:SEG_W1 + 3] = w1
        if f0 is None:
            seg[SEG_F0:SEG_F1 + 3] = 0.0
        else:
            seg[SEG_F0:SEG_F0 + 3] = f0
            seg[SEG_F1:SEG_F1 + 3] = f0 if f1 is None else f1

    # ---- ODE ---------------------------------------------------------------------------
    def kernel_args(self) -> tuple:
        """Arguments of ``platform_rhs`` after (t, y, yd, fid): model tables and work arrays."""
        wk, tr = self.work, self.tree
        return (self.I, self.P, self.seg, self.mats, tr.axis, tr.inertia, tr.rotor_host, tr.rotor_axis,
                wk.R, wk.w, wk.wd, wk.J, wk.f, wk.M, wk.c, wk.tau_ext, self._fb, self._chol, self._F,
                self._a, self._Q, self._RR, self._V, self._W)

    def rhs_into(self, t: float, y: np.ndarray, out: np.ndarray) -> int:
        self.n_rhs += 1
        st = platform_rhs(t, y, out, self.fid, *self.kernel_args())
        if st:
            self.last_status = st
            if st == 1:
                raise GimbalLockError(
                    f"gimbal lock at t = {t:.6g} s: an inner gimbal angle (β5 = {y[1]:.6g}, β10 = {y[4]:.6g} rad) "
                    f"is within {LOCK_COS:g} of ±90° in cosine, where the precession model is singular "
                    "(its rates grow like 1/cos β); use fidelity 'full', whose massive gimbals keep A* regular")
            raise SimulationError(f"mass matrix not positive definite at t = {t:.6g} s (state {y[:5]})")
        return st

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        self.rhs_into(t, y, out)
        return out

    def jacobian(self, t: float, y: np.ndarray) -> np.ndarray:
        """∂ẏ/∂y at (t, y) in the current input interval, by compiled central differences
        (counted as 2n right-hand sides). Used by exprb, implicit_midpoint and radau."""
        n = y.size
        Jac = np.empty((n, n))
        self.n_rhs += 2 * n
        st = fd_jacobian(t, np.ascontiguousarray(y, dtype=float), Jac, self.fid, *self.kernel_args())
        if st & 2:
            raise SimulationError(f"mass matrix not positive definite at t = {t:.6g} s (state {y[:5]})")
        return Jac

    def rest_state(self) -> np.ndarray:
        y = np.zeros(self.layout.n)
        y[self.layout.quat_IB.start + 3] = 1.0
        if self.layout.quat_IP is not None:
            y[self.layout.quat_IP.start + 3] = 1.0
        return y

    def update_regime(self, y: np.ndarray) -> int:
        """Set (and return) the friction regime for the coming step (see ``support_regime``)."""
        self.regime = int(support_regime(y, self.I, self.P, self.seg, self._RR))
        return self.regime

    regime = 0

    def switch_time(self, t: float, y: np.ndarray, yd: np.ndarray, t_end: float, h_min: float) -> float:
        """The next kink of ``rhs`` in (t + h_min, t_end − h_min) (s): the support friction's
        regime change predicted from ``yd`` = ẏ(t, y) (:mod:`.switching`); ``t_end`` if none."""
        return float(support_switch_time(t, np.ascontiguousarray(y, dtype=float),
                                         np.ascontiguousarray(yd, dtype=float), self.I, self.P, self.seg,
                                         t_end, h_min))

    def switch_passed(self, t: float, y: np.ndarray, yd: np.ndarray, lo: float, hi: float) -> float:
        """How long before ``t`` (s) a step ending at (t, y) passed a kink of ``rhs`` (the largest
        in (lo, hi); ``yd`` = ẏ(t, y)), 0.0 if none (:mod:`.switching`)."""
        return float(support_switch_passed(t, np.ascontiguousarray(y, dtype=float),
                                           np.ascontiguousarray(yd, dtype=float), self.I, self.P, self.seg, lo, hi))

    def linear_part(self):
        """(A, key): the linear part for exponential integrators — the Jacobian of ẏ at rest
        (zero input, q = 0, ẋ = 0, unit quaternions) with Coulomb friction and the attitude
        rows left to the remainder, plus, for every mount axis in its stick zone (``regime``),
        the slope μ_s/ε of the regularised support friction: that stiffness (~5e4 1/s) must be
        in A, or an explicit remainder turns it into a false drift. Cached per regime."""
        r = self.regime
        if r not in self._lin:
            A = self._rest_jacobian().copy()
            if r:
                lay = self.layout
                slope = self.k[fx.K_MUS] / self.k[fx.K_EPS_S]
                if self.fid == PRECESSION:
                    rows, Minv_cols = lay.Om, self.mats[3, :3, :3]
                else:
                    rows, Minv_cols = lay.v, self.mats[0][:, :3]
                for i in range(3):
                    if (r >> i) & 1:
                        A[rows, lay.Om.start + i] -= slope * Minv_cols[:, i]
            self._lin[r] = (A, ("platform", id(self), r))
        return self._lin[r]

    def _rest_jacobian(self) -> np.ndarray:
        if self._A_rest is None:
            saved = self.on.copy(), self.seg.copy(), self.k.copy(), self.n_rhs
            self.on[fx.EARTH] = 0
            self.k[fx.K_COULOMB:fx.K_COULOMB + 5] = 0.0
            self.k[fx.K_MUS] = 0.0
            self.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
            y0 = self.rest_state()
            n = y0.size
            A = np.zeros((n, n))
            for j in range(n):
                h = 1e-7
                yp = y0.copy()
                yp[j] += h
                ym = y0.copy()
                ym[j] -= h
                A[:, j] = (self.rhs(0.0, yp) - self.rhs(0.0, ym)) / (2 * h)
            # attitude rows: leave to the remainder (they are bilinear, zero at rest)
            for sl in (self.layout.quat_IB, self.layout.quat_IP):
                if sl is not None:
                    A[sl, :] = 0.0
                    A[:, sl] = 0.0
            self.on[:], self.seg[:], self.k[:] = saved[0], saved[1], saved[2]
            self.n_rhs = saved[3]
            self._A_rest = A
        return self._A_rest
