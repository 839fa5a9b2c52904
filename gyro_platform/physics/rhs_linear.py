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

"""The right-hand side of the linear stabilised model without arrays of its own: the path the
replay, the node and most scenes take (``mode: stabilised``, ``fidelity: linear``).

``platform_rhs`` (:mod:`.system`) hands over to ``stabilised_linear_rhs`` when the fidelity is
linear, the platform stabilised, and no effect needs body rotations or the Earth's rate
(``mass_unbalance``, ``anisoelastic``, ``earth_rate`` off). The physics is the general
kernel's for that case (spec 6.3: constant M0, G0; support friction, servo, gimbal springs,
dampers, friction and bias), evaluated on scalars and the argument arrays only: the general
kernel creates some fifteen array views per call (each was a locked reference-count round trip,
about two thirds of its time, until the kernels' views were borrowed: ``engine.views``).
Frames: platform axes for Ω, M_P; vehicle axes for ω_B. May import the physics room's kernels
only.
"""
from __future__ import annotations

from . import effects as fx
from .jit import njit
from .model import LAY_OM, LAY_QD, LAY_QIB, LAY_QIP, LAY_STAB, LAY_Z, seg_at, SEG_W0
from .rotations import quat_rate_at, rpb_elems

__all__ = ["stabilised_linear_rhs", "takes_linear_path", "rest_model_accel"]


@njit(cache=True, inline="always")
def takes_linear_path(fid_linear, I):
    """True when ``stabilised_linear_rhs`` is the model (see module doc); ``fid_linear``:
    the fidelity is linear."""
    return (fid_linear and I[0, LAY_STAB] == 1 and I[1, fx.UNBALANCE] == 0 and I[1, fx.ANISO] == 0
            and I[1, fx.EARTH] == 0)


@njit(cache=True, inline="always")
def rest_model_accel(mats, y, F, gyro, out, off):
    """Accelerations of spec 6.3, M0 v̇ = F − G0 v over v = (Ω, q̇) = y[5:13], into
    ``out[off:off + 8]`` (``mats[0]`` = M0⁻¹, ``mats[1]`` = G0; the G0 term only with ``gyro``;
    ``F`` (8,) generalised forces, changed in place)."""
    if gyro:
        for i in range(8):
            acc = 0.0
            for j in range(8):
                acc += mats[1, i, j] * y[5 + j]
            F[i] -= acc
    for i in range(8):
        acc = 0.0
        for j in range(8):
            acc += mats[0, i, j] * F[j]
        out[off + i] = acc


@njit(cache=True, inline="always")
def _row8(m, k, i, f0, f1, f2, f3, f4, f5, f6, f7):
    """Σ_j m[k, i, j] f_j over j = 0…7, summed in j order (as ``rest_model_accel``'s loops)."""
    return (m[k, i, 0] * f0 + m[k, i, 1] * f1 + m[k, i, 2] * f2 + m[k, i, 3] * f3
            + m[k, i, 4] * f4 + m[k, i, 5] * f5 + m[k, i, 6] * f6 + m[k, i, 7] * f7)


@njit(cache=True)
def stabilised_linear_rhs(t, y, yd, I, P, seg, mats, F):
    """ẏ of the linear stabilised model into ``yd`` (state layout of ``I[0]``; ``P`` packed
    coefficients, whose first block is the effect vector ``k``; ``seg`` the input interval;
    ``mats[0]`` = M0⁻¹, ``mats[1]`` = G0; ``F`` unused, kept for the kernels' signature).
    Returns 0 (no failure mode). Every value is a local scalar until the stores at the end
    (a store into ``yd`` could alias any float argument for the compiler and force reloads);
    the sums are those of ``rest_model_accel`` in the same order (bit-identical results)."""
    # vehicle rate at t (linear over the interval), vehicle axes
    wB0, wB1, wB2 = seg_at(seg, t, SEG_W0)
    io = I[0, LAY_OM]
    iqd = I[0, LAY_QD]
    iqp = I[0, LAY_QIP]
    iqb = I[0, LAY_QIB]
    iz = I[0, LAY_Z]
    Om0, Om1, Om2 = y[io], y[io + 1], y[io + 2]
    # platform torque: support friction, then the servo
    MP0, MP1, MP2 = 0.0, 0.0, 0.0
    if I[1, fx.SUPPORT]:
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rpb_elems(y, iqp, iqb)
        MP0 += fx.support_friction_axis(P, Om0 - (r00 * wB0 + r01 * wB1 + r02 * wB2))
        MP1 += fx.support_friction_axis(P, Om1 - (r10 * wB0 + r11 * wB1 + r12 * wB2))
        MP2 += fx.support_friction_axis(P, Om2 - (r20 * wB0 + r21 * wB1 + r22 * wB2))
    # gimbal axis torques (what is off costs nothing: one test for the four effects)
    springs, dampers, friction, bias = I[1, fx.SPRINGS], I[1, fx.DAMPERS], I[1, fx.FRICTION], I[1, fx.BIAS]
    Q0, Q1, Q2, Q3, Q4 = 0.0, 0.0, 0.0, 0.0, 0.0
    if springs or dampers or friction or bias:
        Q0 = fx.gimbal_axis_torque(springs, dampers, friction, bias, P, 0, y[0], y[iqd])
        Q1 = fx.gimbal_axis_torque(springs, dampers, friction, bias, P, 1, y[1], y[iqd + 1])
        Q2 = fx.gimbal_axis_torque(springs, dampers, friction, bias, P, 2, y[2], y[iqd + 2])
        Q3 = fx.gimbal_axis_torque(springs, dampers, friction, bias, P, 3, y[3], y[iqd + 3])
        Q4 = fx.gimbal_axis_torque(springs, dampers, friction, bias, P, 4, y[4], y[iqd + 4])
    z0, z1, z2 = 0.0, 0.0, 0.0
    if I[1, fx.SERVO]:
        m, z0 = fx.servo_mount_axis(P, y, y, iqd, iz, 0)
        MP0 += m
        m, z1 = fx.servo_mount_axis(P, y, y, iqd, iz, 1)
        MP1 += m
        m, z2 = fx.servo_mount_axis(P, y, y, iqd, iz, 2)
        MP2 += m
    # spec 6.3: M0 v̇ = F − G0 v over v = (Ω, q̇) = y[5:13]
    F0, F1, F2, F3, F4, F5, F6, F7 = MP0, MP1, MP2, Q0, Q1, Q2, Q3, Q4
    if I[1, fx.GYRO]:
        v0, v1, v2, v3, v4, v5, v6, v7 = y[5], y[6], y[7], y[8], y[9], y[10], y[11], y[12]
        F0 -= _row8(mats, 1, 0, v0, v1, v2, v3, v4, v5, v6, v7)
        F1 -= _row8(mats, 1, 1, v0, v1, v2, v3, v4, v5, v6, v7)
        F2 -= _row8(mats, 1, 2, v0, v1, v2, v3, v4, v5, v6, v7)
        F3 -= _row8(mats, 1, 3, v0, v1, v2, v3, v4, v5, v6, v7)
        F4 -= _row8(mats, 1, 4, v0, v1, v2, v3, v4, v5, v6, v7)
        F5 -= _row8(mats, 1, 5, v0, v1, v2, v3, v4, v5, v6, v7)
        F6 -= _row8(mats, 1, 6, v0, v1, v2, v3, v4, v5, v6, v7)
        F7 -= _row8(mats, 1, 7, v0, v1, v2, v3, v4, v5, v6, v7)
    d0 = _row8(mats, 0, 0, F0, F1, F2, F3, F4, F5, F6, F7)
    d1 = _row8(mats, 0, 1, F0, F1, F2, F3, F4, F5, F6, F7)
    d2 = _row8(mats, 0, 2, F0, F1, F2, F3, F4, F5, F6, F7)
    d3 = _row8(mats, 0, 3, F0, F1, F2, F3, F4, F5, F6, F7)
    d4 = _row8(mats, 0, 4, F0, F1, F2, F3, F4, F5, F6, F7)
    d5 = _row8(mats, 0, 5, F0, F1, F2, F3, F4, F5, F6, F7)
    d6 = _row8(mats, 0, 6, F0, F1, F2, F3, F4, F5, F6, F7)
    d7 = _row8(mats, 0, 7, F0, F1, F2, F3, F4, F5, F6, F7)
    # the stores
    quat_rate_at(y, iqb, wB0, wB1, wB2, yd)
    yd[iz], yd[iz + 1], yd[iz + 2] = z0, z1, z2
    yd[5], yd[6], yd[7], yd[8], yd[9], yd[10], yd[11], yd[12] = d0, d1, d2, d3, d4, d5, d6, d7
    for i in range(5):
        yd[i] = y[iqd + i]
    quat_rate_at(y, iqp, Om0, Om1, Om2, yd)
    return 0
