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

"""The three-gyro platform of Magnus (1976): geometry, fidelities and equations of motion.

Bodies (spec section 1): platform P (root), frame 4 (α4 about P +2), housing 5 (β5 about 4 +3,
rotor 6 spins +1), housing 7 (β7 about 4 −3, rotor 8 spins −1), frame 9 (α9 about P +3),
housing 10 (β10 about 9 +1, rotor 11 spins +2). Rotors are held at constant relative speed
(ideal speed control); their relative momenta are ``L = C φ̇``.

Fidelities:

* ``full``: exact nonlinear equations (spec 4) by the body tree (``tree``): ``A*(q) ẍ + c = F``;
* ``linear``: first order in the gimbal quantities — carried mode: spec 6.1 (exact in the
  vehicle rate Ω; with ``coriolis`` off it is the paper's eq. (27), spec 6.2); stabilised mode:
  spec 6.3 (small oscillations about rest, constant ``M0``, ``G0``: the servo holds Ω ≈ 0);
* ``precession``: massless gimbals (spec 7): the gimbal rates follow from ``L ṡ = τ⊥``.
  Valid only with ``det G_R ≠ 0``: unit A (three coordinates, a skew 3×3 G_R) is singular, so in
  this fidelity β7 is caged (held at 0, its bearing carries the torque), as spec 7.2 advises.

State vector ``y`` (``StateLayout``): gimbal angles q (5, rad), then the generalised velocities
(stabilised: platform rate Ω (3, rad/s, platform axes); gimbal rates q̇ (5) unless precession),
then the platform attitude ``q_IP`` (4, stabilised), the vehicle attitude ``q_IB`` (4) and the
servo integrals (3, rad s, stabilised).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
import math

import numpy as np

from .jit import cached_array, njit
from .options import ModelOptions
from .params import PlatformParams
from .tree import BodyTree, generalised, kinematics, mass_matrix, newton_euler, REVOLUTE, ROOT, TreeWork
from ..errors import PrecessionInvalidError

E1, E2, E3 = np.eye(3)
GIMBAL_AXES = np.array([E2, E3, -E3, E3, E1])  # joint axes of α4, β5, β7, α9, β10 (child axes)
SPIN_AXES = np.array([E1, -E1, E2])            # rotors 6, 8, 11 in housing axes
#: body index of each gimbal's child body and of each rotor's housing in ``platform_tree``
BODY_OF_GIMBAL = (1, 2, 3, 4, 5)
ROTOR_HOSTS = (2, 3, 5)
#: cos β below which the precession model reports gimbal lock
LOCK_COS = 1e-3


def platform_tree(p: PlatformParams, root_dynamic: bool) -> BodyTree:
    """The nine-body platform as a ``BodyTree`` (rotors frozen into their housings)."""
    K = p.frozen()
    names = ("platform", "frame4", "housing5", "housing7", "frame9", "housing10")
    off = 3 if root_dynamic else 0
    inertia = np.zeros((6, 3, 3))
    inertia[0] = p.platform_tensor
    inertia[1] = np.diag(p.frame4)
    inertia[2] = np.diag(K["K5"])
    inertia[3] = np.diag(K["K7"])
    inertia[4] = np.diag(p.frame9)
    inertia[5] = np.diag(K["K10"])
    return BodyTree(
        names=names,
        parent=np.array([-1, 0, 1, 1, 0, 4], dtype=np.int64),
        jtype=np.array([ROOT, REVOLUTE, REVOLUTE, REVOLUTE, REVOLUTE, REVOLUTE], dtype=np.int64),
        axis=np.vstack([np.zeros(3), GIMBAL_AXES]),
        qidx=np.array([-1, 0, 1, 2, 3, 4], dtype=np.int64),
        vidx=np.array([-1, off, off + 1, off + 2, off + 3, off + 4], dtype=np.int64),
        inertia=inertia,
        rotor_host=np.array(ROTOR_HOSTS, dtype=np.int64),
        rotor_axis=SPIN_AXES.copy(),
        rotor_C=np.asarray(p.rotor_C, float),
        rotor_A=np.asarray(p.rotor_A, float),
        root_dynamic=root_dynamic,
        nq=5,
        nv=off + 5,
    )


# the kernels' layout index row I[0]: [Om, qd, qIP, qIB, z, stabilised, nv] (start indices, −1: absent)
LAY_OM, LAY_QD, LAY_QIP, LAY_QIB, LAY_Z, LAY_STAB, LAY_NV = range(7)
# the kernels' input interval row ``seg`` (SEG_N floats): [t0, dt, w0(3), w1(3), f0(3), f1(3)], offsets of its
# fields: interval start (s), length (s), vehicle rate (rad/s) and specific force (m/s²) at its start and end
# (vehicle axes; the input is linear in time over the interval)
SEG_T0, SEG_DT, SEG_W0, SEG_W1, SEG_F0, SEG_F1 = 0, 1, 2, 5, 8, 11
SEG_N = 14


@njit(cache=True, inline="always")
def seg_at(seg, t, k):
    """The input of the interval ``seg`` at time t (s), linear over the interval: the three
    values from slot ``k`` (``SEG_W0``: vehicle rate, rad/s; ``SEG_F0``: specific force, m/s²;
    vehicle axes; the end values are three slots on). The start value when it has no length."""
    dt = seg[SEG_DT]
    s = (t - seg[SEG_T0]) / dt if dt > 0.0 else 0.0
    return (seg[k] + s * (seg[k + 3] - seg[k]), seg[k + 1] + s * (seg[k + 4] - seg[k + 1]),
            seg[k + 2] + s * (seg[k + 5] - seg[k + 2]))


@njit(cache=True, inline="always")
def seg_slope(seg, k):
    """d/dt of :func:`seg_at` (per second; 0 on an interval of no length)."""
    dt = seg[SEG_DT]
    inv_dt = 1.0 / dt if dt > 0.0 else 0.0
    return ((seg[k + 3] - seg[k]) * inv_dt, (seg[k + 4] - seg[k + 1]) * inv_dt, (seg[k + 5] - seg[k + 2]) * inv_dt)


#: pieces of an input interval in :func:`vehicle_attitude_over` (local error ∝ pieces⁻⁴)
MAGNUS_PIECES = 4


@njit(cache=True, inline="always")
def vehicle_attitude_over(y0, y1, i, seg):
    """``y1[i:i+4]`` = the vehicle attitude q_IB at the end of the input interval ``seg`` from
    ``y0[i:i+4]`` at its start: ``q̇ = ½ q ⊗ (ω, 0)`` for the vehicle rate ω linear over the
    interval (vehicle axes), by the fourth-order Magnus expansion over each of
    ``MAGNUS_PIECES`` equal pieces (ω0 → ω1 in h s): ``q ⊗ exp(θ/2)``, ``θ = h (ω0 + ω1)/2 +
    h²/12 ω0 × ω1`` (rad; local error O(h⁵ |ω|² |ω̇|) a piece: ~1e-14 rad at 10 rad/s and
    350 rad/s² over 1 ms). The vehicle attitude is a quadrature of the input with nothing to
    damp its errors: a method of order 2 adds one local error a step to it unseen (etd2: 1e-3
    rad of mount angle in 10 s at rtol 1e-6), so etd2 commits this value instead of its own.
    Not normalised."""
    h = seg[SEG_DT] / MAGNUS_PIECES
    c = h * h / 12.0
    x, y, z, w = y0[i], y0[i + 1], y0[i + 2], y0[i + 3]
    b0, b1, b2 = seg_at(seg, seg[SEG_T0], SEG_W0)
    for p in range(MAGNUS_PIECES):
        a0, a1, a2 = b0, b1, b2                         # the rate at the piece's start, then its end
        b0, b1, b2 = seg_at(seg, seg[SEG_T0] + (p + 1) * h, SEG_W0)
        t0 = 0.5 * h * (a0 + b0) + c * (a1 * b2 - a2 * b1)
        t1 = 0.5 * h * (a1 + b1) + c * (a2 * b0 - a0 * b2)
        t2 = 0.5 * h * (a2 + b2) + c * (a0 * b1 - a1 * b0)
        th = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        k = math.sin(0.5 * th) / th if th > 1e-4 else 0.5 - th * th / 48.0     # sin(θ/2)/θ
        ex, ey, ez, ew = k * t0, k * t1, k * t2, math.cos(0.5 * th)
        x, y, z, w = (w * ex + x * ew + y * ez - z * ey, w * ey - x * ez + y * ew + z * ex,
                      w * ez + x * ey - y * ex + z * ew, w * ew - x * ex - y * ey - z * ez)
    y1[i], y1[i + 1], y1[i + 2], y1[i + 3] = x, y, z, w


@njit(cache=True, inline="always")
def _normalise(y, i):
    if i >= 0:
        s = math.sqrt(y[i] * y[i] + y[i + 1] * y[i + 1] + y[i + 2] * y[i + 2] + y[i + 3] * y[i + 3])
        for k in range(i, i + 4):
            y[k] /= s


@njit(cache=True, inline="always")
def commit_attitudes(y0, y1, qa, qp, seg, quadrature):
    """The quaternions of a step's end state ``y1`` (from ``y0`` over the input interval
    ``seg``) as committed, by the compiled and the Python paths alike: the vehicle attitude (at
    ``qa``) by :func:`vehicle_attitude_over` when ``quadrature`` (etd2), then it and the
    platform attitude (at ``qp``) normalised (−1: absent)."""
    if quadrature and qa >= 0:
        vehicle_attitude_over(y0, y1, qa, seg)
    _normalise(y1, qa)
    _normalise(y1, qp)


@dataclass(frozen=True)
class StateLayout:
    """Slices of the state vector for one mode/fidelity."""

    q: slice
    v: slice          # generalised velocities (Ω then q̇ when present); empty for carried precession
    Om: slice | None  # platform rate (stabilised)
    qd: slice | None  # gimbal rates (not in precession)
    quat_IP: slice | None
    quat_IB: slice
    z: slice | None   # servo integrals
    n: int

    @staticmethod
    def make(stabilised: bool, precession: bool) -> "StateLayout":
        i = 5
        Om = slice(i, i + 3) if stabilised else None
        i += 3 if stabilised else 0
        qd = None if precession else slice(i, i + 5)
        i += 0 if precession else 5
        v = slice(5, i)
        qIP = slice(i, i + 4) if stabilised else None
        i += 4 if stabilised else 0
        qIB = slice(i, i + 4)
        i += 4
        z = slice(i, i + 3) if stabilised else None
        i += 3 if stabilised else 0
        return StateLayout(slice(0, 5), v, Om, qd, qIP, qIB, z, i)


# ---------------------------------------------------------------------------------------------
# linear fidelity, carried mode: spec 6.1 (diagonal gimbal inertia)

@njit(cache=True)
def linear_gimbal_accel(c, L, q, qd, Om, Omd, Q, gyro, coriolis, veh_acc, out):
    """Gimbal accelerations of spec 6.1 (first order in the gimbal quantities, exact in Ω).

    ``c`` = (J4, J5, J7, J9, J10, Jx4−Jz4, K5x−K5y, K5x−K5y−K5z, K7x−K7y, K7x−K7y−K7z,
    Jx9−Jy9, K10y−K10z, K10y−K10x−K10z); ``Q`` applied gimbal torques (N m)."""
    a4, b5, b7, a9, b10 = q[0], q[1], q[2], q[3], q[4]
    da4, db5, db7, da9, db10 = qd[0], qd[1], qd[2], qd[3], qd[4]
    O1, O2, O3 = Om[0], Om[1], Om[2]
    D1, D2, D3 = Omd[0], Omd[1], Omd[2]
    J4, J5, J7, J9, J10 = c[0], c[1], c[2], c[3], c[4]
    r4 = Q[0]
    r5 = Q[1]
    r7 = Q[2]
    r9 = Q[3]
    r10 = Q[4]
    if gyro:
        L6, L8, L11 = L[0], L[1], L[2]
        r4 -= L6 * (db5 + O3 + O1 * a4) + L8 * (db7 - O3 - O1 * a4)
        r5 += L6 * (da4 + O2 - O1 * b5)
        r7 += L8 * (da4 + O2 + O1 * b7)
        r9 -= L11 * (db10 + O1 + O2 * a9)
        r10 += L11 * (da9 + O3 - O2 * b10)
    if veh_acc:
        r4 -= J4 * D2 + c[6] * D1 * b5 - c[8] * D1 * b7
        r5 -= J5 * (D3 + D1 * a4)
        r7 += J7 * (D3 + D1 * a4)
        r9 -= J9 * D3 + c[11] * D2 * b10
        r10 -= J10 * (D1 + D2 * a9)
    if coriolis:
        r4 -= (c[5] * (O1 * O3 + (O1 * O1 - O3 * O3) * a4) + c[7] * O1 * db5 + c[6] * O2 * O3 * b5
               - c[9] * O1 * db7 - c[8] * O2 * O3 * b7)
        r5 -= J5 * O1 * da4 - c[6] * (O1 * O2 + O1 * da4 - (O1 * O1 - O2 * O2) * b5 - O2 * O3 * a4)
        r7 -= -J7 * O1 * da4 + c[8] * (O1 * O2 + O1 * da4 + (O1 * O1 - O2 * O2) * b7 - O2 * O3 * a4)
        r9 -= -c[10] * (O1 * O2 - (O1 * O1 - O2 * O2) * a9) + c[11] * O1 * O3 * b10 + c[12] * O2 * db10
        r10 -= J10 * O2 * da9 - c[11] * (O2 * O3 + O2 * da9 - (O2 * O2 - O3 * O3) * b10 - O1 * O3 * a9)
    out[0] = r4 / J4
    out[1] = r5 / J5
    out[2] = r7 / J7
    out[3] = r9 / J9
    out[4] = r10 / J10


def linear_coefficients(p: PlatformParams) -> np.ndarray:
    J = p.lumped()
    K = p.frozen()
    K5, K7, K10 = K["K5"], K["K7"], K["K10"]
    return np.array([
        J["J4"], J["J5"], J["J7"], J["J9"], J["J10"], J["Jx4"] - J["Jz4"],
        K5[0] - K5[1], K5[0] - K5[1] - K5[2], K7[0] - K7[1], K7[0] - K7[1] - K7[2],
        J["Jx9"] - J["Jy9"], K10[1] - K10[2], K10[1] - K10[0] - K10[2],
    ])


# ---------------------------------------------------------------------------------------------
# precession fidelity: spec 7.1 (unit B explicit; unit A with β7 caged)

@njit(cache=True)
def _gyro_pair_rates(d_outer, d_inner, g, r1, r2):
    """Rates (outer, inner) of one two-axis gyro in the precession model: the 2×2 system
    [d_o, g; −g, d_i] [ṙ_o; ṙ_i] = [r1; r2] (g = L cos β, d = viscous dampers)."""
    det = d_outer * d_inner + g * g
    return (r1 * d_inner - g * r2) / det, (d_outer * r2 + g * r1) / det


@njit(cache=True)
def precession_rates(L, q, Om, Q, dvisc, out):
    """Gimbal rates (rad/s) of the precession model. ``Q`` applied torques without the viscous
    part ``dvisc`` (N m s/rad, per gimbal), which is solved for implicitly (2×2 per unit).
    β7 is caged (rate 0). Returns the smallest |cos| of the inner gimbal angles."""
    a4, b5, a9, b10 = q[0], q[1], q[3], q[4]
    O1, O2, O3 = Om[0], Om[1], Om[2]
    # unit B:  L cβ (β̇ + u) = Q9 − d9 α̇ ;  −L (cβ (α̇ + Ω3) + sβ w) = Q10 − d10 β̇
    cb, sb = math.cos(b10), math.sin(b10)
    ca, sa = math.cos(a9), math.sin(a9)
    u = O1 * ca + O2 * sa
    w = O1 * sa - O2 * ca
    g = L[2] * cb
    # [d9, g; -g, d10] [α̇; β̇] = [Q9 − g u; Q10 + g Ω3 + L sβ w]
    out[3], out[4] = _gyro_pair_rates(dvisc[3], dvisc[4], g, Q[3] - g * u, Q[4] + g * O3 + L[2] * sb * w)
    # unit A, β7 caged:  L6 cβ5 (β̇5 + v) − L8 v = Q4 − d4 α̇4 ; −L6 (cβ5 (α̇4 + Ω2) − sβ5 x) = Q5 − d5 β̇5
    cb5, sb5 = math.cos(b5), math.sin(b5)
    ca4, sa4 = math.cos(a4), math.sin(a4)
    v = O1 * sa4 + O3 * ca4
    x = O1 * ca4 - O3 * sa4
    g5 = L[0] * cb5
    out[0], out[1] = _gyro_pair_rates(dvisc[0], dvisc[1], g5, Q[0] - g5 * v + L[1] * v,
                                      Q[1] + g5 * O2 - L[0] * sb5 * x)
    out[2] = 0.0
    return min(abs(cb), abs(cb5))


@njit(cache=True)
def spin_momentum(L, q, qd, h, hd):
    """Rotor momentum h = Σ L_r e_r(q) (N m s, platform axes) and its rate along q̇."""
    a4, b5, b7, a9, b10 = q[0], q[1], q[2], q[3], q[4]
    ca4, sa4 = math.cos(a4), math.sin(a4)
    cb5, sb5 = math.cos(b5), math.sin(b5)
    cb7, sb7 = math.cos(b7), math.sin(b7)
    ca9, sa9 = math.cos(a9), math.sin(a9)
    cb10, sb10 = math.cos(b10), math.sin(b10)
    da4, db5, db7, da9, db10 = qd[0], qd[1], qd[2], qd[3], qd[4]
    L6, L8, L11 = L[0], L[1], L[2]
    # e6 = (cα4 cβ5, sβ5, −sα4 cβ5); e8 = (−cα4 cβ7, sβ7, sα4 cβ7); e11 = (−sα9 cβ10, cα9 cβ10, sβ10)
    h[0] = L6 * ca4 * cb5 - L8 * ca4 * cb7 - L11 * sa9 * cb10
    h[1] = L6 * sb5 + L8 * sb7 + L11 * ca9 * cb10
    h[2] = -L6 * sa4 * cb5 + L8 * sa4 * cb7 + L11 * sb10
    hd[0] = (L6 * (-sa4 * cb5 * da4 - ca4 * sb5 * db5) - L8 * (-sa4 * cb7 * da4 - ca4 * sb7 * db7)
             - L11 * (ca9 * cb10 * da9 - sa9 * sb10 * db10))
    hd[1] = L6 * cb5 * db5 + L8 * cb7 * db7 + L11 * (-sa9 * cb10 * da9 - ca9 * sb10 * db10)
    hd[2] = (-L6 * (ca4 * cb5 * da4 - sa4 * sb5 * db5) + L8 * (ca4 * cb7 * da4 - sa4 * sb7 * db7)
             + L11 * cb10 * db10)


def check_precession_valid(p: PlatformParams, options: ModelOptions) -> None:
    """Refuse the precession fidelity where it is invalid (spec 7.2)."""
    if not options.has("rotor_gyroscopic"):
        raise PrecessionInvalidError(
            "fidelity 'precession' needs the effect 'rotor_gyroscopic': without rotor momentum "
            "the gyroscopic matrix G_R is zero (det G_R = 0)")
    L = p.L
    for name, Lr in (("rotor6 (unit A)", L[0]), ("rotor11 (unit B)", L[2])):
        if abs(Lr) < 1e-12:
            raise PrecessionInvalidError(
                f"fidelity 'precession' is invalid: {name} has zero spin momentum L = {Lr:g} N m s, "
                "so det G_R = 0 (use fidelity 'full' or 'linear' for a rotor at rest)")
    J = p.lumped()
    # repeated roots / frequency separation: the nutation frequency must dominate the restraint
    if options.has("gimbal_springs"):
        c = np.asarray(p.spring)
        for lab, Lr, j, k, jb in (("unit B", L[2], 3, 4, (J["J9"], J["J10"])),
                                  ("unit A", L[0], 0, 1, (J["J4"], J["J5"]))):
            wn = abs(Lr) / math.sqrt(jb[0] * jb[1])
            wspring = math.sqrt(max(c[j] / jb[0], c[k] / jb[1]))
            if wspring > 0.3 * wn:
                raise PrecessionInvalidError(
                    f"fidelity 'precession' is invalid for {lab}: spring frequency {wspring:.3g} rad/s is "
                    f"not well below the nutation frequency {wn:.3g} rad/s (need < 0.3·ω_n; the "
                    "precession and nutation roots would nearly coincide)")


# ---------------------------------------------------------------------------------------------
# linear fidelity, stabilised mode: spec 6.3 (constant M0, G0 from the exact tree at rest)

def rest_matrices(p: PlatformParams) -> tuple[np.ndarray, np.ndarray]:
    """(M0, G0) of spec 6.3: mass matrix A*(0) and gyroscopic matrix (the ẋ-linear part of c
    at q = 0, ẋ → 0), both 8×8 over (Ω1..3, α̇4, β̇5, β̇7, α̇9, β̇10), from the exact tree.

    A process's first call reads them from the kernel cache when an earlier process computed
    them for the same parameters and code (``jit.cached_array``): the four tree kernels they
    need (~30-60 ms to load) are then not loaded; once they are, computing (~0.2 ms) is cheaper
    than a file and nothing more is written (a Monte Carlo sweep leaves one file per process)."""
    if getattr(kinematics, "signatures", True):     # loaded (or NUMBA_DISABLE_JIT: nothing to load)
        MG = _rest_matrices(p)
    else:
        MG = cached_array("rest_matrices", _exact_key(p), (2, 8, 8), lambda: _rest_matrices(p))
    return MG[0].copy(), MG[1].copy()


def _exact_key(p: PlatformParams) -> str:
    """Every parameter's name and float64 bytes: equal keys, equal parameters (a repr may round)."""
    return ";".join(f"{f.name}={np.asarray(getattr(p, f.name), dtype=float).tobytes().hex()}" for f in fields(p))


def _rest_matrices(p: PlatformParams) -> np.ndarray:
    """(M0, G0) stacked (2 × 8 × 8), computed on the tree."""
    tree = platform_tree(p, root_dynamic=True)
    wk = TreeWork(tree)
    q = np.zeros(5)
    L = p.L
    v = np.zeros(8)
    kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, True, q, v, np.zeros(3),
               wk.R, wk.w, wk.J)
    M0 = np.zeros((8, 8))
    mass_matrix(wk.J, tree.inertia, M0)
    G0 = np.zeros((8, 8))
    for j in range(8):
        v[:] = 0.0
        v[j] = 1.0
        kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, True, q, v, np.zeros(3),
                   wk.R, wk.w, wk.J)
        newton_euler(tree.parent, tree.jtype, tree.axis, tree.vidx, tree.inertia, True, tree.rotor_host,
                     tree.rotor_axis, L, v, np.zeros(8), np.zeros(3), wk.R, wk.w, False, True,
                     np.zeros((6, 3)), wk.wd, wk.f)
        generalised(tree.jtype, tree.axis, tree.vidx, True, wk.f, G0[:, j])
    return np.stack((M0, G0))


# ---------------------------------------------------------------------------------------------
# the paper's matrix form ([M76] eqs. 2, 3, 12–14), for analysis and as a cross-check of the tree

def structure_matrix(q) -> np.ndarray:
    """B(q) (3 × 8): row r is the carrier rate about rotor r's spin axis per unit ẋ,
    ``w_r = b_r ẋ`` (spec 2.3, exact), rotors 6, 8, 11; ẋ = (Ω1..3, α̇4, β̇5, β̇7, α̇9, β̇10)."""
    a4, b5, b7, a9, b10 = q
    c, s = math.cos, math.sin
    return np.array([
        [c(a4) * c(b5), s(b5), -s(a4) * c(b5), s(b5), 0.0, 0.0, 0.0, 0.0],
        [-c(a4) * c(b7), s(b7), s(a4) * c(b7), s(b7), 0.0, 0.0, 0.0, 0.0],
        [-s(a9) * c(b10), c(a9) * c(b10), s(b10), 0.0, 0.0, 0.0, s(b10), 0.0],
    ])


def paper_matrices(p: PlatformParams, q) -> dict[str, np.ndarray]:
    """The matrices the paper builds the equations from, at gimbal angles q (rad):

    ``B`` structure matrix (3 × 8), ``A_R`` = diag(C6, C8, C11), ``A_star`` = A* (8 × 8, frozen
    rotors, from the body tree), ``A`` = A* − Bᵀ A_R B (rotors' axial inertia removed),
    ``L`` relative rotor momenta, and ``G_R`` (8 × 8, skew) with the gyroscopic forces
    ``G_R ẋ`` of ``T1 = Lᵀ B(q) ẋ``: ``G_R[i, j] = ∂β_i/∂x_j − ∂β_j/∂x_i``, β = Bᵀ L, where only
    the gimbal angles are coordinates (the platform rates are quasi-velocities)."""
    q = np.asarray(q, dtype=float)
    tree = platform_tree(p, root_dynamic=True)
    wk = TreeWork(tree)
    kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, True, q, np.zeros(8), np.zeros(3),
               wk.R, wk.w, wk.J)
    A_star = np.zeros((8, 8))
    mass_matrix(wk.J, tree.inertia, A_star)
    B = structure_matrix(q)
    A_R = np.diag(p.rotor_C)
    L = p.L
    dbeta = np.zeros((8, 8))                       # dbeta[i, 3 + k] = ∂β_i/∂q_k
    for k in range(5):
        h = 1e-6
        qp, qm = q.copy(), q.copy()
        qp[k] += h
        qm[k] -= h
        dbeta[:, 3 + k] = (structure_matrix(qp).T @ L - structure_matrix(qm).T @ L) / (2 * h)
    G_R = dbeta - dbeta.T
    return {"B": B, "A_R": A_R, "A_star": A_star, "A": A_star - B.T @ A_R @ B, "L": L, "G_R": G_R}
