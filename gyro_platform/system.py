"""The platform as an ODE system ``ẏ = f(t, y)`` for one scene: model (only the effects that
are on) + the current input interval. This is what the integrators step.

The vehicle input over an interval ``[t0, t0 + dt]`` is linear in time (rates rad/s and specific
force m/s², vehicle axes), so its angular acceleration is constant on the interval.
All work happens in one numba kernel (``platform_rhs``) on preallocated arrays.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import effects as fx
from .errors import GimbalLockError, SimulationError
from .model import (LOCK_COS, StateLayout, check_precession_valid, linear_coefficients,
                    linear_gimbal_accel, platform_tree, precession_rates, rest_matrices, spin_momentum)
from .options import ModelOptions
from .params import PlatformParams
from .rotations import quat_rate, quat_to_matrix
from .tree import TreeWork, kinematics, mass_matrix, newton_euler, generalised, rot_axis

FULL, LINEAR, PRECESSION = 0, 1, 2
FIDELITY_CODE = {"full": FULL, "linear": LINEAR, "precession": PRECESSION}
# layout index array: [Om, qd, qIP, qIB, z, stabilised, nv]
LAY_OM, LAY_QD, LAY_QIP, LAY_QIB, LAY_Z, LAY_STAB, LAY_NV = range(7)
# segment array: [t0, dt, w0(3), w1(3), f0(3), f1(3)]
SEG_N = 14
STATUS_OK, STATUS_LOCK, STATUS_NOT_PD = 0, 1, 2


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


@njit(cache=True)
def platform_rhs(t, y, yd, lay, fid, on, k, L, lc, M0inv, G0, Ifz, Ifz_inv,
                 parent, jtype, axis, qidx, vidx, inertia, rhost, raxis,
                 seg, R_PBm, wIN,
                 R, w, wd, J, f, M, c, tau_ext, fb, chol, F, a, Q, scratch):
    """ẏ of the platform (see module doc). Writes ``yd``; returns a status code
    (0 ok, 1 precession gimbal lock, 2 mass matrix not positive definite).

    ``scratch`` (≥ 40 floats) holds small temporaries so nothing is allocated here."""
    stab = lay[LAY_STAB] == 1
    nv = lay[LAY_NV]
    status = 0
    # --- input at time t (linear over the interval) ---------------------------------------
    dt = seg[1]
    s = (t - seg[0]) / dt if dt > 0.0 else 0.0
    wB = scratch[0:3]
    wdB = scratch[3:6]
    fB = scratch[6:9]
    for i in range(3):
        wB[i] = seg[2 + i] + s * (seg[5 + i] - seg[2 + i])
        wdB[i] = (seg[5 + i] - seg[2 + i]) / dt if dt > 0.0 else 0.0
        fB[i] = seg[8 + i] + s * (seg[11 + i] - seg[8 + i])
    iqb = lay[LAY_QIB]
    quat_rate(y[iqb:iqb + 4], wB, yd[iqb:iqb + 4])
    q = y[0:5]
    for i in range(5):
        yd[i] = 0.0
    Rtmp = scratch[9:18].reshape((3, 3))
    R_PB = scratch[18:27].reshape((3, 3))
    Om = scratch[27:30]
    Omd = scratch[30:33]
    fP = scratch[33:36]
    wBP = scratch[36:39]
    wc = scratch[39:42]
    tmp = scratch[42:45]
    MP = scratch[45:48]
    if stab:
        # R_PB = R_IPᵀ R_IB
        iqp = lay[LAY_QIP]
        quat_to_matrix(y[iqp:iqp + 4], Rtmp)          # R_IP
        R_IB3 = scratch[48:57].reshape((3, 3))
        quat_to_matrix(y[iqb:iqb + 4], R_IB3)
        for i in range(3):
            for j in range(3):
                R_PB[i, j] = Rtmp[0, i] * R_IB3[0, j] + Rtmp[1, i] * R_IB3[1, j] + Rtmp[2, i] * R_IB3[2, j]
        io = lay[LAY_OM]
        for i in range(3):
            Om[i] = y[io + i]
            Omd[i] = 0.0
    else:
        for i in range(3):
            for j in range(3):
                R_PB[i, j] = R_PBm[i, j]
    for i in range(3):
        wBP[i] = R_PB[i, 0] * wB[0] + R_PB[i, 1] * wB[1] + R_PB[i, 2] * wB[2]
        fP[i] = R_PB[i, 0] * fB[0] + R_PB[i, 1] * fB[1] + R_PB[i, 2] * fB[2]
        if not stab:
            Om[i] = wBP[i]
            Omd[i] = R_PB[i, 0] * wdB[0] + R_PB[i, 1] * wdB[1] + R_PB[i, 2] * wdB[2]
    # --- Earth rate: commanded precession ω_c = R_PI R_IC(t) ω_IN ---------------------------
    for i in range(3):
        wc[i] = 0.0
    if on[fx.EARTH]:
        wn = math.sqrt(wIN[0] ** 2 + wIN[1] ** 2 + wIN[2] ** 2)
        R_IC = scratch[57:66].reshape((3, 3))
        if wn > 0.0:
            for i in range(3):
                tmp[i] = wIN[i] / wn
            rot_axis(tmp, wn * t, R_IC)
        else:
            for i in range(3):
                for j in range(3):
                    R_IC[i, j] = 1.0 if i == j else 0.0
        for i in range(3):   # tmp = R_IC ω_IN  (inertial axes)
            tmp[i] = R_IC[i, 0] * wIN[0] + R_IC[i, 1] * wIN[1] + R_IC[i, 2] * wIN[2]
        if stab:             # R_IP = Rtmp
            for i in range(3):
                wc[i] = Rtmp[0, i] * tmp[0] + Rtmp[1, i] * tmp[1] + Rtmp[2, i] * tmp[2]
        else:                # R_PI = R_PB R_BI
            R_IB3 = scratch[48:57].reshape((3, 3))
            quat_to_matrix(y[iqb:iqb + 4], R_IB3)
            for i in range(3):
                u = R_IB3[0, i] * tmp[0] + R_IB3[1, i] * tmp[1] + R_IB3[2, i] * tmp[2]  # (R_BI ω)_i
                scratch[66 + i] = u
            for i in range(3):
                wc[i] = R_PB[i, 0] * scratch[66] + R_PB[i, 1] * scratch[67] + R_PB[i, 2] * scratch[68]
    # --- gimbal rates --------------------------------------------------------------------
    iqd = lay[LAY_QD]
    qd = scratch[70:75]
    if fid != 2:
        for i in range(5):
            qd[i] = y[iqd + i]
    # g-sensitive torques need body rotations
    g_sens = on[fx.UNBALANCE] or on[fx.ANISO]
    for i in range(tau_ext.shape[0]):
        for j in range(3):
            tau_ext[i, j] = 0.0
    need_kin = fid == 0 or g_sens
    v = scratch[75:75 + nv]
    if need_kin:
        # velocity vector of the tree: [Ω (stab)] + q̇ (zeros in precession: only R is used there)
        if stab:
            for i in range(3):
                v[i] = Om[i]
        for i in range(5):
            v[nv - 5 + i] = qd[i] if fid != 2 else 0.0
        kinematics(parent, jtype, axis, qidx, vidx, stab, q, v, Om, R, w, J)
        if g_sens:
            fx.body_specific_force(R, parent, fP, fb)
            fx.g_sensitive_torques(k, on[fx.UNBALANCE], on[fx.ANISO], rhost, raxis, fb, tau_ext)
    # --- platform torque (stabilised): servo + support friction --------------------------
    for i in range(3):
        MP[i] = 0.0
    if stab:
        iz = lay[LAY_Z]
        if on[fx.SERVO]:
            yp = scratch[85:88]
            ydp = scratch[88:91]
            yp[0], yp[1], yp[2] = q[4], q[0], q[3]
            if fid == 2:
                ydp[0], ydp[1], ydp[2] = 0.0, 0.0, 0.0   # filled after the precession rates below
            else:
                ydp[0], ydp[1], ydp[2] = qd[4], qd[0], qd[3]
            if fid != 2:
                mask = fx.servo_torque(k, yp, ydp, y[iz:iz + 3], tmp)
                for i in range(3):
                    MP[i] += tmp[i]
                    yd[iz + i] = 0.0 if (mask >> i) & 1 else yp[i]
        else:
            for i in range(3):
                yd[iz + i] = 0.0
        if on[fx.SUPPORT]:
            fx.support_friction(k, Om, wBP, MP)
    # --- fidelities ----------------------------------------------------------------------
    if fid == 0:
        mass_matrix(J, inertia, M)
        zero_a = scratch[91:91 + nv]
        for i in range(nv):
            zero_a[i] = 0.0
        wd0 = Omd if (on[fx.VEHICLE_ACC] and not stab) else scratch[100:103]
        if not (on[fx.VEHICLE_ACC] and not stab):
            for i in range(3):
                wd0[i] = 0.0
        newton_euler(parent, jtype, axis, vidx, inertia, stab, rhost, raxis, L, v, zero_a, wd0,
                     R, w, on[fx.CORIOLIS], on[fx.GYRO], tau_ext, wd, f)
        generalised(jtype, axis, vidx, stab, f, c)
        fx.gimbal_forces(on, k, L, q, qd, wc, Q)
        off = nv - 5
        for i in range(3):
            if stab:
                F[i] = MP[i] - c[i]
        for i in range(5):
            F[off + i] = Q[i] - c[off + i]
        if not chol_solve(M, F[0:nv], a[0:nv], chol[0:nv, 0:nv]):
            status = 2
            for i in range(nv):
                a[i] = 0.0
    elif fid == 1:
        fx.gimbal_forces(on, k, L, q, qd, wc, Q)
        if g_sens:   # generalised force of the body torques: Σ J_hᵀ τ_h (gimbal columns)
            _add_body_torques(J, tau_ext, nv, stab, Q, MP)
        if stab:
            for i in range(3):
                F[i] = MP[i]
            for i in range(5):
                F[3 + i] = Q[i]
            if on[fx.GYRO]:
                for i in range(8):
                    sacc = 0.0
                    for j in range(8):
                        sacc += G0[i, j] * y[5 + j]
                    F[i] -= sacc
            for i in range(8):
                sacc = 0.0
                for j in range(8):
                    sacc += M0inv[i, j] * F[j]
                a[i] = sacc
        else:
            linear_gimbal_accel(lc, L, q, qd, Om, Omd, Q, on[fx.GYRO], on[fx.CORIOLIS],
                                on[fx.VEHICLE_ACC], a)
    else:
        # precession: Q without dampers (solved implicitly) and with friction by fixed point
        dvisc = scratch[103:108]
        for i in range(5):
            dvisc[i] = k[fx.K_DAMPER + i] if on[fx.DAMPERS] else 0.0
            qd[i] = 0.0
        saved_d = on[fx.DAMPERS]
        saved_f = on[fx.FRICTION]
        on[fx.DAMPERS] = 0
        on[fx.FRICTION] = 0
        fx.gimbal_forces(on, k, L, q, qd, wc, Q)
        on[fx.DAMPERS] = saved_d
        on[fx.FRICTION] = saved_f
        if g_sens:
            _add_body_torques(J, tau_ext, nv, stab, Q, MP)
        Qf = scratch[120:125]
        iters = 6 if saved_f else 1
        cmin = 1.0
        for it in range(iters):
            for i in range(5):
                Qf[i] = Q[i]
            if saved_f:
                fx.gimbal_friction(k, qd, Qf)
            cmin = precession_rates(L, q, Om, Qf, dvisc, qd)
        if cmin < LOCK_COS:
            status = 1
        if stab:
            h = scratch[125:128]
            hd = scratch[128:131]
            spin_momentum(L, q, qd, h, hd)
            if on[fx.SERVO]:
                yp = scratch[85:88]
                ydp = scratch[88:91]
                ydp[0], ydp[1], ydp[2] = qd[4], qd[0], qd[3]
                iz = lay[LAY_Z]
                mask = fx.servo_torque(k, yp, ydp, y[iz:iz + 3], tmp)
                for i in range(3):
                    MP[i] += tmp[i]
                    yd[iz + i] = 0.0 if (mask >> i) & 1 else yp[i]
            # Ifz Ω̇ = M − Ω × (Ifz Ω + h) − ḣ
            for i in range(3):
                tmp[i] = Ifz[i, 0] * Om[0] + Ifz[i, 1] * Om[1] + Ifz[i, 2] * Om[2] + h[i]
            r0 = MP[0] - (Om[1] * tmp[2] - Om[2] * tmp[1]) - hd[0]
            r1 = MP[1] - (Om[2] * tmp[0] - Om[0] * tmp[2]) - hd[1]
            r2 = MP[2] - (Om[0] * tmp[1] - Om[1] * tmp[0]) - hd[2]
            for i in range(3):
                a[i] = Ifz_inv[i, 0] * r0 + Ifz_inv[i, 1] * r1 + Ifz_inv[i, 2] * r2
    # --- assemble ẏ ----------------------------------------------------------------------
    for i in range(5):
        yd[i] = qd[i]
    if fid == 2:
        if stab:
            io = lay[LAY_OM]
            for i in range(3):
                yd[io + i] = a[i]
    else:
        for i in range(nv):
            yd[5 + i] = a[i]
    if stab:
        iqp = lay[LAY_QIP]
        quat_rate(y[iqp:iqp + 4], Om, yd[iqp:iqp + 4])
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
        self.layout = StateLayout.make(self.stabilised, self.fid == PRECESSION)
        self.tree = platform_tree(params, root_dynamic=self.stabilised)
        self.work = TreeWork(self.tree)
        lay = self.layout
        self.nv = self.tree.nv
        self.lay = np.array([
            lay.Om.start if lay.Om else -1, lay.qd.start if lay.qd else -1,
            lay.quat_IP.start if lay.quat_IP else -1, lay.quat_IB.start, lay.z.start if lay.z else -1,
            1 if self.stabilised else 0, self.nv], dtype=np.int64)
        self.on = fx.flags(options.effects)
        self.k = fx.coefficients(params)
        self.L = np.asarray(params.L, float) if options.has("rotor_gyroscopic") else np.zeros(3)
        self.L_true = np.asarray(params.L, float)
        self.lc = linear_coefficients(params)
        M0, G0 = rest_matrices(params)
        self.M0, self.G0 = M0, G0
        self.M0inv = np.linalg.inv(M0)
        self.Ifz = M0[:3, :3].copy()
        self.Ifz_inv = np.linalg.inv(self.Ifz)
        from scipy.spatial.transform import Rotation
        self.R_BP = Rotation.from_quat(params.mounting).as_matrix()   # platform → vehicle
        self.R_PB = np.ascontiguousarray(self.R_BP.T)
        lat = params.latitude
        self.w_IN = (params.earth_rate * np.array([0.0, math.cos(lat), math.sin(lat)])
                     if options.has("earth_rate") else np.zeros(3))
        self.seg = np.zeros(SEG_N)
        self.seg[1] = 1.0
        n = self.nv
        self._F = np.zeros(max(n, 8))
        self._a = np.zeros(max(n, 8))
        self._Q = np.zeros(5)
        self._chol = np.zeros((max(n, 8), max(n, 8)))
        self._fb = np.zeros((self.tree.nb, 3))
        self._scratch = np.zeros(160)
        self.n_rhs = 0
        self.last_status = 0
        self._lin = None

    # ---- input -------------------------------------------------------------------------
    def set_input(self, t0: float, t1: float, w0, w1, f0=None, f1=None) -> None:
        """Input over [t0, t1]: vehicle rate (rad/s) and specific force (m/s²), vehicle axes,
        linear in time."""
        seg = self.seg
        seg[0] = t0
        seg[1] = t1 - t0
        seg[2:5] = w0
        seg[5:8] = w1
        if f0 is None:
            seg[8:14] = 0.0
        else:
            seg[8:11] = f0
            seg[11:14] = f0 if f1 is None else f1

    # ---- ODE ---------------------------------------------------------------------------
    def rhs_into(self, t: float, y: np.ndarray, out: np.ndarray) -> int:
        wk = self.work
        self.n_rhs += 1
        st = platform_rhs(t, y, out, self.lay, self.fid, self.on, self.k, self.L, self.lc, self.M0inv,
                          self.G0, self.Ifz, self.Ifz_inv, self.tree.parent, self.tree.jtype, self.tree.axis,
                          self.tree.qidx, self.tree.vidx, self.tree.inertia, self.tree.rotor_host,
                          self.tree.rotor_axis, self.seg, self.R_PB, self.w_IN, wk.R, wk.w, wk.wd, wk.J,
                          wk.f, wk.M, wk.c, wk.tau_ext, self._fb, self._chol, self._F, self._a, self._Q,
                          self._scratch)
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

    def rest_state(self) -> np.ndarray:
        y = np.zeros(self.layout.n)
        y[self.layout.quat_IB.start + 3] = 1.0
        if self.layout.quat_IP is not None:
            y[self.layout.quat_IP.start + 3] = 1.0
        return y

    def linear_part(self):
        """(A, key): Jacobian of ẏ at rest (zero input, q = 0, ẋ = 0, unit quaternions), with
        Coulomb friction and the attitude/vehicle rows left to the nonlinear remainder."""
        if self._lin is None:
            saved = self.on.copy(), self.seg.copy()
            self.on[fx.EARTH] = 0
            self.k_saved = self.k.copy()
            self.k[fx.K_COULOMB:fx.K_COULOMB + 5] = 0.0
            self.k[fx.K_MUS] = 0.0
            self.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
            y0 = self.rest_state()
            n = y0.size
            A = np.zeros((n, n))
            f0 = self.rhs(0.0, y0)
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
            self.on[:], self.seg[:] = saved
            self.k[:] = self.k_saved
            self.n_rhs -= 2 * n + 1
            _ = f0
            self._lin = (A, ("platform-rest", id(self)))
        return self._lin
