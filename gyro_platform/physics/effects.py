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

"""Effects: each switchable effect is one small kernel that adds its generalised forces.

Generalised forces act on the gimbal axes (``Q``: ``alpha4, beta5, beta7, alpha9, beta10``,
N m about each joint axis on the child body) and on the platform (``M``: N m, platform axes,
the external torque on the whole platform assembly). An effect that is off is never called
(``applied_forces`` branches on its flag), so it costs nothing. The structural effects
(``rotor_gyroscopic``, ``coriolis``, ``vehicle_angular_acceleration``) switch terms inside the
model kernels (``tree``, ``model``) instead; ``gimbal_inertia`` is the fidelity ``precession``.

Spec: PHYSICS.md sections 5 (generalised forces), 9.3 (servo), 9.4 (torquers), 10 (effects).
Modelling limits: the platform suspension is an ideal three-axis isolator (its own gimbal
geometry, inertia and lock are not modelled); all gimbal centres coincide with the mass centre
unless ``mass_unbalance``/``anisoelastic`` is on; the platform pivot does not translate.
"""
from __future__ import annotations

import numpy as np

from .jit import njit
from .options import EFFECTS

#: index of each effect in the flag array handed to the kernels
EFFECT_INDEX: dict[str, int] = {name: i for i, name in enumerate(EFFECTS)}
N_EFFECTS = len(EFFECT_INDEX)
SPRINGS = EFFECT_INDEX["gimbal_springs"]
DAMPERS = EFFECT_INDEX["gimbal_dampers"]
FRICTION = EFFECT_INDEX["gimbal_friction"]
BIAS = EFFECT_INDEX["bias_torque"]
SUPPORT = EFFECT_INDEX["support_friction"]
SERVO = EFFECT_INDEX["servo"]
EARTH = EFFECT_INDEX["earth_rate"]
UNBALANCE = EFFECT_INDEX["mass_unbalance"]
ANISO = EFFECT_INDEX["anisoelastic"]
GYRO = EFFECT_INDEX["rotor_gyroscopic"]
CORIOLIS = EFFECT_INDEX["coriolis"]
VEHICLE_ACC = EFFECT_INDEX["vehicle_angular_acceleration"]

# layout of the float coefficient vector ``k`` handed to the kernels (built by ``coefficients``)
K_SPRING, K_DAMPER, K_COULOMB, K_VISC, K_BIAS = 0, 5, 10, 15, 20
K_EPS, K_KP, K_KD, K_KI, K_LIMIT, K_DS, K_MUS, K_MASS, K_ELL, K_DK, K_EPS_S = 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35
N_K = 36


def flags(effects) -> np.ndarray:
    """int64 flag array (1 = on) for a set of effect names."""
    f = np.zeros(N_EFFECTS, dtype=np.int64)
    for name in effects:
        f[EFFECT_INDEX[name]] = 1
    return f


def coefficients(p) -> np.ndarray:
    """Pack the effect coefficients of ``PlatformParams`` into one float array."""
    k = np.zeros(N_K)
    k[K_SPRING:K_SPRING + 5] = p.spring
    k[K_DAMPER:K_DAMPER + 5] = p.damper
    k[K_COULOMB:K_COULOMB + 5] = p.gimbal_coulomb
    k[K_VISC:K_VISC + 5] = p.gimbal_viscous_friction
    k[K_BIAS:K_BIAS + 5] = p.bias_torque
    k[K_EPS] = p.friction_rate_eps
    k[K_EPS_S] = p.support_rate_eps
    k[K_KP], k[K_KD], k[K_KI], k[K_LIMIT] = p.servo_kp, p.servo_kd, p.servo_ki, p.servo_limit
    k[K_DS], k[K_MUS] = p.support_viscous, p.support_coulomb
    k[K_MASS], k[K_ELL], k[K_DK] = p.gyro_mass, p.unbalance, p.anisoelastic
    return k


@njit(cache=True)
def sat(x):
    """Regularised sign: x clipped to [−1, 1] (Coulomb friction with a linear zone)."""
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


@njit(cache=True, inline="always")
def gimbal_axis_torque(springs, dampers, friction, bias, k, i, q, qd):
    """Axial torque (N m) on gimbal ``i`` (angle q rad, rate qd rad/s) of the restraint spring
    (−c q), viscous damper (−d q̇), bearing friction (−b q̇ − μ sat(q̇/ε), a drift source) and
    g-insensitive bias (+b) whose flags are set, summed in that order."""
    Qi = 0.0
    if springs:
        Qi -= k[K_SPRING + i] * q
    if dampers:
        Qi -= k[K_DAMPER + i] * qd
    if friction:
        Qi -= k[K_VISC + i] * qd + k[K_COULOMB + i] * sat(qd / k[K_EPS])
    if bias:
        Qi += k[K_BIAS + i]
    return Qi


@njit(cache=True)
def gimbal_friction(k, qd, Q):
    """Gimbal bearing friction alone: Q_k −= b_k q̇_k + μ_k sat(q̇_k/ε) (the precession model
    iterates it)."""
    for i in range(5):
        Q[i] += gimbal_axis_torque(False, False, True, False, k, i, 0.0, qd[i])


@njit(cache=True)
def gyro_torquers(L, wc, Q):
    """Torque the gyros so that they precess at ``wc`` (rad/s, platform axes), spec 9.4:
    Q9 = L11 ωc1, Q10 = −L11 ωc3, Q5 = −L6 ωc2, Q7 = −L8 ωc2, Q4 = (L6 − L8) ωc3."""
    Q[0] += (L[0] - L[1]) * wc[2]
    Q[1] -= L[0] * wc[1]
    Q[2] -= L[1] * wc[1]
    Q[3] += L[2] * wc[0]
    Q[4] -= L[2] * wc[2]


@njit(cache=True, inline="always")
def servo_pickoff(ax):
    """Index (in q = α4, β5, β7, α9, β10) of the gimbal whose angle is mount axis ``ax``'s
    pick-off (spec 9.3): β10, α4, α9 drive mount axes 1, 2, 3."""
    return 4 if ax == 0 else (0 if ax == 1 else 3)


@njit(cache=True)
def servo_axis(k, y, yd, z):
    """PID pick-off servo of one mount axis (spec 9.3): M = sat(K_P y + K_D ẏ + K_I z) (N m),
    saturated at ±limit. Returns (M, saturated); a saturated axis stops integrating (anti-windup)."""
    lim = k[K_LIMIT]
    m = k[K_KP] * y + k[K_KD] * yd + k[K_KI] * z
    if m > lim:
        return lim, True
    if m < -lim:
        return -lim, True
    return m, False


@njit(cache=True, inline="always")
def servo_mount_axis(k, y, qd, qd_off, z_off, ax):
    """The servo of mount axis ``ax`` (spec 9.3) on state ``y``: its torque (N m, platform axis
    ``ax``) from the pick-off ``y[servo_pickoff(ax)]``, that gimbal's rate ``qd[qd_off + g]``
    and the integral ``y[z_off + ax]``, and the integral's rate (0 on a saturated axis:
    conditional integration, anti-windup)."""
    g = servo_pickoff(ax)
    m, saturated = servo_axis(k, y[g], qd[qd_off + g], y[z_off + ax])
    return m, 0.0 if saturated else y[g]


@njit(cache=True, inline="always")
def servo_mount_torques(k, y, qd, qd_off, z_off, yd):
    """:func:`servo_mount_axis` of the three mount axes: their torques (N m, platform axes 1,
    2, 3); the integrals' rates go to ``yd[z_off:z_off + 3]``."""
    m0, yd[z_off] = servo_mount_axis(k, y, qd, qd_off, z_off, 0)
    m1, yd[z_off + 1] = servo_mount_axis(k, y, qd, qd_off, z_off, 1)
    m2, yd[z_off + 2] = servo_mount_axis(k, y, qd, qd_off, z_off, 2)
    return m0, m1, m2


@njit(cache=True)
def servo_torque(k, y, yd, z, out):
    """``servo_axis`` on the three mount axes, y = (β10, α4, α9) rad. Writes out (3,) N m,
    platform axes."""
    for i in range(3):
        out[i] = servo_axis(k, y[i], yd[i], z[i])[0]


@njit(cache=True)
def support_friction_axis(k, rel):
    """Mount bearing friction about one platform axis (offset, not drift), N m:
    −D_s rel − μ_s sat(rel/ε_s), rel = Ω − ω_B (rad/s, platform axes)."""
    return -(k[K_DS] * rel + k[K_MUS] * sat(rel / k[K_EPS_S]))


@njit(cache=True)
def body_specific_force(R, parent, f_root, fb):
    """fb[i] = specific force (m/s²) in body i axes: f_i = R_p,iᵀ f_p, fb[0] = f_root."""
    for k in range(3):
        fb[0, k] = f_root[k]
    for i in range(1, parent.shape[0]):
        p = parent[i]
        for k in range(3):
            fb[i, k] = R[i, 0, k] * fb[p, 0] + R[i, 1, k] * fb[p, 1] + R[i, 2, k] * fb[p, 2]


@njit(cache=True)
def g_sensitive_torques(k, unbalance_on, aniso_on, rotor_host, rotor_axis, fb, tau_ext):
    """Add the g-sensitive torques of each housing+rotor (housing axes) to ``tau_ext``:
    mass unbalance r = ℓ s, anisoelastic r = −m ΔK (s·f) s, torque τ = −m r × f."""
    m = k[K_MASS]
    for r in range(rotor_host.shape[0]):
        h = rotor_host[r]
        s = rotor_axis[r]
        f0, f1, f2 = fb[h, 0], fb[h, 1], fb[h, 2]
        sf = s[0] * f0 + s[1] * f1 + s[2] * f2
        coef = 0.0
        if unbalance_on:
            coef += k[K_ELL]
        if aniso_on:
            coef -= m * k[K_DK] * sf
        # τ = −m coef (s × f)
        tau_ext[h, 0] -= m * coef * (s[1] * f2 - s[2] * f1)
        tau_ext[h, 1] -= m * coef * (s[2] * f0 - s[0] * f2)
        tau_ext[h, 2] -= m * coef * (s[0] * f1 - s[1] * f0)


@njit(cache=True)
def gimbal_forces(on, k, L, q, qd, wc, Q):
    """Sum of the axial gimbal torques Q (N m) of the effects that are on (``on`` flags)."""
    springs, dampers, friction, bias = on[SPRINGS], on[DAMPERS], on[FRICTION], on[BIAS]
    for i in range(5):
        Q[i] = gimbal_axis_torque(springs, dampers, friction, bias, k, i, q[i], qd[i])
    if on[EARTH]:
        gyro_torquers(L, wc, Q)
