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

"""Rigid-body trees with revolute joints and spinning rotors: kinematics, mass matrix and
recursive Newton–Euler (spec sections 2, 4.3 and 8; [MBB] sections 6–7).

A tree is a root body (index 0) and bodies ``1..nb-1`` listed parents-first. Body ``i`` hangs
from ``parent[i]`` by a joint about the unit axis ``axis[i]`` (child axes). Joint types:

* ``REVOLUTE``: a generalised coordinate θ (``q[qidx[i]]``), ``R_pc = Rot(axis, θ)``;
* ``SPIN``: an axisymmetric body spinning about ``axis`` with a free rate (a velocity DOF,
  no angle needed: rotating a body about its symmetry axis leaves its inertia unchanged, so
  its quantities are taken in the carrier's axes, ``R_pc = 1``).

The root turns with the body rate ``w0``: either prescribed (carried mode, ``w0`` and its
derivative are inputs) or the first three generalised velocities (a free platform; these are
quasi-velocities, so the root row is Euler's law, i.e. Euler–Poincaré).

Rotors held at constant relative speed by ideal speed controllers are *attachments*: their
inertia is frozen into the host body (``K = I_h + A 1 + (C−A) s sᵀ``) and their relative momentum
``L s`` adds the gyroscopic torque ``ω_h × L s`` on the host (exact, spec 4.1 and 8).

Everything here is a numba kernel on plain arrays; ``BodyTree`` holds the arrays.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .jit import njit

ROOT, REVOLUTE, SPIN = 0, 1, 2


@dataclass(frozen=True)
class BodyTree:
    """Arrays describing a tree. ``inertia[i]`` is body i's inertia tensor in its own axes
    (kg m², with frozen ideal rotors included); ``rotor_*`` describe ideal-rotor attachments."""

    names: tuple[str, ...]
    parent: np.ndarray      # int64 (nb,)
    jtype: np.ndarray       # int64 (nb,)
    axis: np.ndarray        # float64 (nb, 3), joint axis in child axes
    qidx: np.ndarray        # int64 (nb,), index into q (REVOLUTE) else -1
    vidx: np.ndarray        # int64 (nb,), index into the generalised velocity (REVOLUTE/SPIN) else -1
    inertia: np.ndarray     # float64 (nb, 3, 3)
    rotor_host: np.ndarray  # int64 (nr,)
    rotor_axis: np.ndarray  # float64 (nr, 3), spin axis in host axes
    rotor_C: np.ndarray     # float64 (nr,)
    rotor_A: np.ndarray     # float64 (nr,)
    root_dynamic: bool      # root rate is a DOF (first 3 velocities)
    nq: int
    nv: int

    @property
    def nb(self) -> int:
        return len(self.names)


# ---------------------------------------------------------------------------------------------
# small vector helpers (numba)

@njit(cache=True, inline="always")
def _rotation(x, y, z, th):
    """The nine entries (row by row) of Rot(n, th), the rotation by th (rad) about the unit
    vector n = (x, y, z) (Rodrigues)."""
    c = math.cos(th)
    s = math.sin(th)
    v = 1.0 - c
    return (c + x * x * v, x * y * v - z * s, x * z * v + y * s,
            y * x * v + z * s, c + y * y * v, y * z * v - x * s,
            z * x * v - y * s, z * y * v + x * s, c + z * z * v)


@njit(cache=True, fastmath=False)
def rot_axis(n, th, out):
    """out = Rot(n, th): rotation by th (rad) about the unit vector n (Rodrigues)."""
    r = _rotation(n[0], n[1], n[2], th)
    for k in range(9):
        out[k // 3, k % 3] = r[k]


@njit(cache=True, inline="always")
def _joint_rotation_at(jt, axis, i, q, qi, R):
    """``R[i]`` = R_pc of body i's joint of type ``jt``: Rot(n_i, q[qi]) for ``REVOLUTE``, else
    the identity (``q`` is then not read: ``qi`` is -1 there). Indexes ``axis`` and ``R`` in
    place: no view a body, no call a joint (with the shared formula, the full model's right-hand
    side ~1.45 µs in the stepping kernel, was 1.5–2.7; the same results bit for bit; performance
    history, session 38)."""
    if jt == REVOLUTE:
        r = _rotation(axis[i, 0], axis[i, 1], axis[i, 2], q[qi])
        for k in range(9):
            R[i, k // 3, k % 3] = r[k]
    else:
        for a in range(3):
            for b in range(3):
                R[i, a, b] = 1.0 if a == b else 0.0


@njit(cache=True, inline="always")
def _cross3(a0, a1, a2, b0, b1, b2):
    """a × b of two 3-vectors given as scalars (the kernels allocate no work arrays)."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, inline="always")
def _matT_vec3_at(R, i, v, p):
    """``R[i]ᵀ v[p]`` as three scalars (indexed in place, no views)."""
    return (R[i, 0, 0] * v[p, 0] + R[i, 1, 0] * v[p, 1] + R[i, 2, 0] * v[p, 2],
            R[i, 0, 1] * v[p, 0] + R[i, 1, 1] * v[p, 1] + R[i, 2, 1] * v[p, 2],
            R[i, 0, 2] * v[p, 0] + R[i, 1, 2] * v[p, 1] + R[i, 2, 2] * v[p, 2])


@njit(cache=True, inline="always")
def _mat_vec3_at(R, i, v, p):
    """``R[i] v[p]`` as three scalars (indexed in place, no views)."""
    return (R[i, 0, 0] * v[p, 0] + R[i, 0, 1] * v[p, 1] + R[i, 0, 2] * v[p, 2],
            R[i, 1, 0] * v[p, 0] + R[i, 1, 1] * v[p, 1] + R[i, 1, 2] * v[p, 2],
            R[i, 2, 0] * v[p, 0] + R[i, 2, 1] * v[p, 1] + R[i, 2, 2] * v[p, 2])


@njit(cache=True, inline="always")
def _body_rotation_rate(jtype, axis, qidx, vidx, q, v, i, p, R, w):
    """Body ``i`` with parent ``p``: ``R[i] = R_p,i`` and its rate ``w[i] = R[i]ᵀ w[p] + q̇_i n_i``
    (rad/s, body axes)."""
    _joint_rotation_at(jtype[i], axis, i, q, qidx[i], R)
    rate = v[vidx[i]]
    t0, t1, t2 = _matT_vec3_at(R, i, w, p)
    w[i, 0] = t0 + rate * axis[i, 0]
    w[i, 1] = t1 + rate * axis[i, 1]
    w[i, 2] = t2 + rate * axis[i, 2]


# ---------------------------------------------------------------------------------------------
# kernels

@njit(cache=True)
def kinematics(parent, jtype, axis, qidx, vidx, root_dynamic, q, v, w0, R, w, J):
    """Rotations ``R[i] = R_parent,i``, body rates ``w[i]`` (rad/s, body axes) and velocity
    Jacobians ``J[i]`` (3 × nv, ω_i = J_i v + affine root part) for all bodies."""
    nb = parent.shape[0]
    nv = J.shape[2]
    for k in range(3):
        R[0, k, 0] = 0.0
        R[0, k, 1] = 0.0
        R[0, k, 2] = 0.0
        R[0, k, k] = 1.0
        for j in range(nv):
            J[0, k, j] = 0.0
    if root_dynamic:
        for k in range(3):
            w[0, k] = v[k]
            J[0, k, k] = 1.0
    else:
        for k in range(3):
            w[0, k] = w0[k]
    for i in range(1, nb):
        p = parent[i]
        _body_rotation_rate(jtype, axis, qidx, vidx, q, v, i, p, R, w)
        for j in range(nv):
            for k in range(3):
                J[i, k, j] = R[i, 0, k] * J[p, 0, j] + R[i, 1, k] * J[p, 1, j] + R[i, 2, k] * J[p, 2, j]
        for k in range(3):
            J[i, k, vidx[i]] += axis[i, k]


@njit(cache=True)
def kinematics_rw(parent, jtype, axis, qidx, vidx, root_dynamic, q, v, w0, R, w):
    """``kinematics`` without the velocity Jacobians and without allocation: rotations ``R``
    and body rates ``w`` only (the same arithmetic), for inverse dynamics at output instants."""
    nb = parent.shape[0]
    for k in range(3):
        R[0, k, 0] = 0.0
        R[0, k, 1] = 0.0
        R[0, k, 2] = 0.0
        R[0, k, k] = 1.0
        w[0, k] = v[k] if root_dynamic else w0[k]
    for i in range(1, nb):
        p = parent[i]
        _body_rotation_rate(jtype, axis, qidx, vidx, q, v, i, p, R, w)


@njit(cache=True)
def mass_matrix(J, inertia, M):
    """M = Σ_i J_iᵀ I_i J_i (the frozen-rotor mass matrix A*, kg m²); column b of I_i J_i as three
    scalars (no work array: the right-hand side allocates nothing)."""
    nb = J.shape[0]
    nv = J.shape[2]
    for a in range(nv):
        for b in range(nv):
            M[a, b] = 0.0
    for i in range(nb):
        for b in range(nv):
            ij0 = inertia[i, 0, 0] * J[i, 0, b] + inertia[i, 0, 1] * J[i, 1, b] + inertia[i, 0, 2] * J[i, 2, b]
            ij1 = inertia[i, 1, 0] * J[i, 0, b] + inertia[i, 1, 1] * J[i, 1, b] + inertia[i, 1, 2] * J[i, 2, b]
            ij2 = inertia[i, 2, 0] * J[i, 0, b] + inertia[i, 2, 1] * J[i, 1, b] + inertia[i, 2, 2] * J[i, 2, b]
            for a in range(b + 1):
                M[a, b] += J[i, 0, a] * ij0 + J[i, 1, a] * ij1 + J[i, 2, a] * ij2
    for a in range(nv):
        for b in range(a):
            M[a, b] = M[b, a]


@njit(cache=True)
def newton_euler(parent, jtype, axis, vidx, inertia, root_dynamic, rotor_host, rotor_axis, rotor_L,
                 v, a, wd0, R, w, coriolis, gyroscopic, tau_ext, wd, f):
    """Recursive Newton–Euler, torques only (all mass centres on the joint axes).

    Given rates ``w`` and rotations ``R`` from ``kinematics``, generalised accelerations ``a``
    and (prescribed root) root acceleration ``wd0``: body accelerations ``wd`` and the torque
    ``f[i]`` (N m, child axes) that the parent exerts on body i through its joint
    (``f[0]``: torque on the root from outside, root axes). ``coriolis``/``gyroscopic`` switch
    the velocity-product terms of the frozen system and the rotor-momentum terms; ``tau_ext``
    (nb, 3) are applied body torques (body axes)."""
    nb = parent.shape[0]
    if root_dynamic:
        for k in range(3):
            wd[0, k] = a[k]
    else:
        for k in range(3):
            wd[0, k] = wd0[k]
    for i in range(1, nb):
        p = parent[i]
        t0, t1, t2 = _matT_vec3_at(R, i, wd, p)
        acc = a[vidx[i]]
        wd[i, 0] = t0 + acc * axis[i, 0]
        wd[i, 1] = t1 + acc * axis[i, 1]
        wd[i, 2] = t2 + acc * axis[i, 2]
        if coriolis:
            u0, u1, u2 = _matT_vec3_at(R, i, w, p)
            rate = v[vidx[i]]
            c0, c1, c2 = _cross3(u0, u1, u2, rate * axis[i, 0], rate * axis[i, 1], rate * axis[i, 2])
            wd[i, 0] += c0
            wd[i, 1] += c1
            wd[i, 2] += c2
    # body torques
    for i in range(nb):
        for k in range(3):
            f[i, k] = (inertia[i, k, 0] * wd[i, 0] + inertia[i, k, 1] * wd[i, 1] + inertia[i, k, 2] * wd[i, 2]
                       - tau_ext[i, k])
        if coriolis:
            h0, h1, h2 = _mat_vec3_at(inertia, i, w, i)
            c0, c1, c2 = _cross3(w[i, 0], w[i, 1], w[i, 2], h0, h1, h2)
            f[i, 0] += c0
            f[i, 1] += c1
            f[i, 2] += c2
    if gyroscopic:
        for r in range(rotor_host.shape[0]):
            h = rotor_host[r]
            c0, c1, c2 = _cross3(w[h, 0], w[h, 1], w[h, 2], rotor_L[r] * rotor_axis[r, 0],
                                 rotor_L[r] * rotor_axis[r, 1], rotor_L[r] * rotor_axis[r, 2])
            f[h, 0] += c0
            f[h, 1] += c1
            f[h, 2] += c2
    # backward pass: children pass their joint torque to the parent
    for i in range(nb - 1, 0, -1):
        p = parent[i]
        t0, t1, t2 = _mat_vec3_at(R, i, f, i)
        f[p, 0] += t0
        f[p, 1] += t1
        f[p, 2] += t2


@njit(cache=True)
def generalised(jtype, axis, vidx, root_dynamic, f, out):
    """Project joint torques on the joint axes: out[v] = n_i · f_i; root rows = f_0."""
    if root_dynamic:
        for k in range(3):
            out[k] = f[0, k]
    for i in range(1, jtype.shape[0]):
        out[vidx[i]] = axis[i, 0] * f[i, 0] + axis[i, 1] * f[i, 1] + axis[i, 2] * f[i, 2]


@njit(cache=True)
def rotor_torques(rotor_host, rotor_axis, rotor_C, rotor_A, rotor_L, w, wd, tau):
    """Torque each ideal rotor's housing exerts on it (N m, housing axes), spec 8 step 2
    (φ̈ = 0): τ = C(s·ω̇)s + A(ω̇ − (s·ω̇)s) + ω × H, H = C(s·ω)s + A(ω − (s·ω)s) + L s."""
    for r in range(rotor_host.shape[0]):
        h = rotor_host[r]
        s = rotor_axis[r]
        C = rotor_C[r]
        A = rotor_A[r]
        sw = s[0] * w[h, 0] + s[1] * w[h, 1] + s[2] * w[h, 2]
        swd = s[0] * wd[h, 0] + s[1] * wd[h, 1] + s[2] * wd[h, 2]
        H0 = C * sw * s[0] + A * (w[h, 0] - sw * s[0]) + rotor_L[r] * s[0]
        H1 = C * sw * s[1] + A * (w[h, 1] - sw * s[1]) + rotor_L[r] * s[1]
        H2 = C * sw * s[2] + A * (w[h, 2] - sw * s[2]) + rotor_L[r] * s[2]
        c0, c1, c2 = _cross3(w[h, 0], w[h, 1], w[h, 2], H0, H1, H2)
        tau[r, 0] = C * swd * s[0] + A * (wd[h, 0] - swd * s[0]) + c0
        tau[r, 1] = C * swd * s[1] + A * (wd[h, 1] - swd * s[1]) + c1
        tau[r, 2] = C * swd * s[2] + A * (wd[h, 2] - swd * s[2]) + c2


class TreeWork:
    """Preallocated work arrays for one tree (reuse per evaluation: no allocation in the loop)."""

    def __init__(self, tree: BodyTree):
        nb, nv = tree.nb, tree.nv
        self.R = np.zeros((nb, 3, 3))
        self.w = np.zeros((nb, 3))
        self.wd = np.zeros((nb, 3))
        self.J = np.zeros((nb, 3, nv))
        self.f = np.zeros((nb, 3))
        self.M = np.zeros((nv, nv))
        self.c = np.zeros(nv)
        self.tau_ext = np.zeros((nb, 3))
        self.zero_v = np.zeros(nv)
        self.rotor_tau = np.zeros((len(tree.rotor_host), 3))


def tree_mass_and_bias(tree: BodyTree, work: TreeWork, q, v, w0, wd0, rotor_L,
                       coriolis: bool = True, gyroscopic: bool = True, tau_ext=None):
    """(M, c) of ``M a + c = F`` at (q, v) for this tree (Python wrapper over the kernels)."""
    kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, tree.root_dynamic,
               q, v, w0, work.R, work.w, work.J)
    mass_matrix(work.J, tree.inertia, work.M)
    te = work.tau_ext if tau_ext is None else tau_ext
    if tau_ext is None:
        te[:] = 0.0
    newton_euler(tree.parent, tree.jtype, tree.axis, tree.vidx, tree.inertia, tree.root_dynamic,
                 tree.rotor_host, tree.rotor_axis, rotor_L, v, work.zero_v, wd0, work.R, work.w,
                 coriolis, gyroscopic, te, work.wd, work.f)
    generalised(tree.jtype, tree.axis, tree.vidx, tree.root_dynamic, work.f, work.c)
    return work.M, work.c


def tree_inverse_dynamics(tree: BodyTree, work: TreeWork, q, v, a, w0, wd0, rotor_L, tau_ext=None):
    """Full inverse dynamics: joint torques ``f`` (nb, 3), generalised forces and rotor torques.
    Returns (F, f, rotor_tau) — views into ``work`` (copy them to keep)."""
    kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, tree.root_dynamic,
               q, v, w0, work.R, work.w, work.J)
    te = work.tau_ext if tau_ext is None else tau_ext
    if tau_ext is None:
        te[:] = 0.0
    newton_euler(tree.parent, tree.jtype, tree.axis, tree.vidx, tree.inertia, tree.root_dynamic,
                 tree.rotor_host, tree.rotor_axis, rotor_L, v, a, wd0, work.R, work.w,
                 True, True, te, work.wd, work.f)
    generalised(tree.jtype, tree.axis, tree.vidx, tree.root_dynamic, work.f, work.c)
    rotor_torques(tree.rotor_host, tree.rotor_axis, tree.rotor_C, tree.rotor_A, rotor_L,
                  work.w, work.wd, work.rotor_tau)
    return work.c, work.f, work.rotor_tau
