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

"""Physical parameters of the three-gyro platform (SI units), NAV-1 defaults of the spec.

Axes: platform axes 1, 2, 3 = x, y, z of frame ``platform``; every body's principal axes are
parallel to them in the normal position (all gimbal angles zero). Housings are given
*without* their rotors. See ``shared/spec/PHYSICS.md`` sections 1–3.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
import math
from typing import Any

import numpy as np

RPM = 2.0 * math.pi / 60.0
EARTH_RATE = 7.292115e-5  # rad/s, sidereal
STANDARD_GRAVITY = 9.80665  # m/s²


class ParameterError(ValueError):
    """A parameter is outside its allowed range; the message names it and the range."""


def _vec(v: Any, n: int) -> tuple[float, ...]:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != n:
        raise ParameterError(f"expected {n} values, got {a.size}")
    return tuple(float(x) for x in a)


@dataclass(frozen=True)
class PlatformParams:
    """Inertias (kg m²), rotor speeds (rad/s) and effect coefficients of the platform.

    Gimbal-indexed tuples are ordered ``(alpha4, beta5, beta7, alpha9, beta10)``; rotor-indexed
    tuples ``(rotor6, rotor8, rotor11)``.
    """

    # rotors (axial C, equatorial A, relative spin speed about their listed spin axes)
    rotor_C: tuple[float, float, float] = (2.0e-5, 2.0e-5, 2.0e-5)
    rotor_A: tuple[float, float, float] = (1.2e-5, 1.2e-5, 1.2e-5)
    rotor_speed: tuple[float, float, float] = (24000 * RPM,) * 3
    # housings without rotor (principal moments about x, y, z)
    housing5: tuple[float, float, float] = (2.0e-5, 3.0e-5, 3.0e-5)
    housing7: tuple[float, float, float] = (2.0e-5, 3.0e-5, 3.0e-5)
    housing10: tuple[float, float, float] = (3.0e-5, 2.0e-5, 3.0e-5)
    frame4: tuple[float, float, float] = (1.5e-4, 1.0e-4, 1.5e-4)
    frame9: tuple[float, float, float] = (8.0e-5, 8.0e-5, 6.0e-5)
    # platform tensor elements P11, P22, P33, P12, P13, P23 (P12 = -∫xy dm)
    platform: tuple[float, float, float, float, float, float] = (0.080, 0.090, 0.100, 1.0e-3, -5.0e-4, 8.0e-4)
    # gimbal restraints (per gimbal axis): spring N m/rad, viscous N m s/rad, Coulomb N m
    spring: tuple[float, float, float, float, float] = (0.5,) * 5
    damper: tuple[float, float, float, float, float] = (1.0e-4,) * 5
    gimbal_coulomb: tuple[float, float, float, float, float] = (1.0e-8,) * 5
    gimbal_viscous_friction: tuple[float, float, float, float, float] = (0.0,) * 5
    bias_torque: tuple[float, float, float, float, float] = (0.0,) * 5
    friction_rate_eps: float = 1.0e-6  # rad/s, regularisation of sign() in gimbal Coulomb friction
    # rad/s, regularisation of the mount (support) Coulomb friction. Wider than the gimbals':
    # this friction only offsets the servo (no drift, O9 c) and a 1e-6 rad/s zone makes the
    # platform flip between stick and slip every step on quiet axes (stiffness μ/ε = 5e3 N m s).
    support_rate_eps: float = 1.0e-4
    # platform servo (pick-offs y = (beta10, alpha4, alpha9) -> mount torquers, platform axes)
    servo_kp: float = 1500.0
    servo_kd: float = 16.0
    servo_ki: float = 3.0e4
    servo_limit: float = 2.0
    # platform support (vehicle mount) friction
    support_viscous: float = 5.0e-3
    support_coulomb: float = 5.0e-3
    # g-sensitive effects (per housing + rotor assembly)
    gyro_mass: float = 0.1            # kg
    unbalance: float = 25e-9          # m, CG offset along the spin axis
    anisoelastic: float = 5e-9        # m/N, compliance along minus across the spin axis
    # Earth
    latitude: float = math.radians(45.0)  # rad
    earth_rate: float = EARTH_RATE        # rad/s
    # vehicle → platform mounting (quaternion x, y, z, w), carried mode and mount zero
    mounting: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        validate(self)

    # ---- derived quantities -------------------------------------------------------------
    @property
    def L(self) -> np.ndarray:
        """Relative rotor angular momenta L_r = C_r φ̇_r (N m s), rotors 6, 8, 11."""
        return np.asarray(self.rotor_C) * np.asarray(self.rotor_speed)

    @property
    def platform_tensor(self) -> np.ndarray:
        """3×3 platform inertia tensor (kg m²)."""
        p11, p22, p33, p12, p13, p23 = self.platform
        return np.array([[p11, p12, p13], [p12, p22, p23], [p13, p23, p33]])

    def frozen(self) -> dict[str, np.ndarray]:
        """Frozen housing+rotor moments K5, K7, K10 (principal, kg m²), spec 3.1."""
        C, A = self.rotor_C, self.rotor_A
        return {
            "K5": np.array(self.housing5) + np.array([C[0], A[0], A[0]]),
            "K7": np.array(self.housing7) + np.array([C[1], A[1], A[1]]),
            "K10": np.array(self.housing10) + np.array([A[2], C[2], A[2]]),
        }

    def lumped(self) -> dict[str, float]:
        """Lumped moments J4, J5, J7, J9, J10, Jx4, Jz4, Jx9, Jy9 of [M76] (spec 3.1)."""
        K = self.frozen()
        F4, F9 = self.frame4, self.frame9
        return {
            "J4": F4[1] + K["K5"][1] + K["K7"][1],
            "J5": K["K5"][2],
            "J7": K["K7"][2],
            "J9": F9[2] + K["K10"][2],
            "J10": K["K10"][0],
            "Jx4": F4[0] + K["K5"][0] + K["K7"][0],
            "Jz4": F4[2] + K["K5"][2] + K["K7"][2],
            "Jx9": F9[0] + K["K10"][0],
            "Jy9": F9[1] + K["K10"][1],
        }

    def with_(self, **changes: Any) -> "PlatformParams":
        """Copy with changes (validated)."""
        return replace(self, **changes)

    @staticmethod
    def from_dict(d: dict[str, Any]) -> "PlatformParams":
        """Build from a mapping; unknown keys are rejected with their names."""
        known = {f.name: f for f in fields(PlatformParams)}
        unknown = sorted(set(d) - set(known))
        if unknown:
            raise ParameterError(f"unknown parameter(s) {unknown}; known: {sorted(known)}")
        kw: dict[str, Any] = {}
        for k, v in d.items():
            default = getattr(PlatformParams, k, None)
            if isinstance(default, tuple):
                try:
                    if np.ndim(v) == 0:
                        v = (float(v),) * len(default)
                    kw[k] = _vec(v, len(default))
                except (ParameterError, TypeError, ValueError) as e:
                    raise ParameterError(f"parameter '{k}': {e}") from None
            else:
                try:
                    kw[k] = float(v)
                except (TypeError, ValueError):
                    raise ParameterError(f"parameter '{k}' must be a number, got {v!r}") from None
        return PlatformParams(**kw)


#: lumped inertia of each gimbal about its axis (``PlatformParams.lumped``) and what it sums
GIMBAL_INERTIAS = {"J4": "frame4[1] + housings 5, 7 and their rotors about y", "J5": "housing5[2] + rotor_A[0]",
                   "J7": "housing7[2] + rotor_A[1]", "J9": "frame9[2] + housing10 and its rotor about z",
                   "J10": "housing10[0] + rotor_A[2]"}
MIN_GIMBAL_INERTIA = 1e-12


def _check(name: str, values, lo: float, hi: float = math.inf, *, lo_open: bool = False) -> None:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    for i, x in enumerate(arr):
        where = name if arr.size == 1 else f"{name}[{i}]"
        if not math.isfinite(x):
            raise ParameterError(f"parameter '{where}' = {x} is not finite; allowed range "
                                 f"{'(' if lo_open else '['}{lo}, {hi}]")
        if (x <= lo if lo_open else x < lo) or x > hi:
            raise ParameterError(f"parameter '{where}' = {x:g} is outside its allowed range "
                                 f"{'(' if lo_open else '['}{lo:g}, {hi:g}]")


#: why a rotor needs polar inertia (spec 3: L_r = C_r φ̇_r; section 1: the platform is a gyro)
NO_POLAR_INERTIA = ("a rotor without polar inertia has no spin momentum (L = C·φ̇ = 0): the platform is no gyro "
                    "(no precession, no stabilisation); a rotor at rest is rotor_speed 0")


def check_rotor_momentum(p: PlatformParams) -> None:
    """Every rotor has polar inertia ``C_r > 0`` (a rotor at rest, ``rotor_speed`` 0, is a
    gyro switched off and allowed; a rotor without ``C_r`` is no gyro at any speed)."""
    for i, C in enumerate(p.rotor_C):
        if not C > 0.0:
            raise ParameterError(f"parameter 'rotor_C[{i}]' = {C:g} is outside its allowed range (0, 1000]: "
                                 + NO_POLAR_INERTIA)


def validate(p: PlatformParams) -> None:
    """Reject unphysical parameters with a message naming the parameter and its range."""
    for name in ("rotor_C", "rotor_A", "housing5", "housing7", "housing10", "frame4", "frame9"):
        _check(name, getattr(p, name), 0.0, 1e3)
    _check("rotor_speed", p.rotor_speed, -1e6, 1e6)
    # rigid-body triangle inequality for every principal-moment triple
    for name in ("housing5", "housing7", "housing10", "frame4", "frame9"):
        a, b, c = getattr(p, name)
        if a > b + c + 1e-15 or b > a + c + 1e-15 or c > a + b + 1e-15:
            raise ParameterError(f"parameter '{name}' = {getattr(p, name)} violates the triangle "
                                 "inequality of principal moments (each ≤ sum of the other two)")
    for i, (C, A) in enumerate(zip(p.rotor_C, p.rotor_A)):
        if C > 2 * A + 1e-15:
            raise ParameterError(f"parameter 'rotor_C[{i}]' = {C:g} must be ≤ 2·rotor_A[{i}] "
                                 f"= {2 * A:g} (axisymmetric rigid body)")
    # every gimbal needs inertia about its own axis, or the mass matrix is singular
    for name, value in p.lumped().items():
        if name in GIMBAL_INERTIAS and not value > MIN_GIMBAL_INERTIA:
            raise ParameterError(f"gimbal inertia {name} = {value:g} kg m² (from {GIMBAL_INERTIAS[name]}) must be "
                                 f"> {MIN_GIMBAL_INERTIA:g} kg m²: a gimbal without inertia about its axis makes the "
                                 "mass matrix singular")
    check_rotor_momentum(p)
    _check("platform[0:3]", p.platform[:3], 0.0, 1e4, lo_open=True)
    _check("platform[3:6]", p.platform[3:], -1e4, 1e4)
    eig = np.linalg.eigvalsh(p.platform_tensor)
    if eig[0] <= 0:
        raise ParameterError(f"parameter 'platform' = {p.platform} is not positive definite "
                             f"(eigenvalues {eig})")
    for name in ("spring", "damper", "gimbal_coulomb", "gimbal_viscous_friction"):
        _check(name, getattr(p, name), 0.0, 1e6)
    _check("bias_torque", p.bias_torque, -1e3, 1e3)
    _check("friction_rate_eps", p.friction_rate_eps, 0.0, 1.0, lo_open=True)
    _check("support_rate_eps", p.support_rate_eps, 0.0, 1.0, lo_open=True)
    for name in ("servo_kp", "servo_kd", "servo_ki", "support_viscous", "support_coulomb",
                 "gyro_mass", "unbalance", "anisoelastic"):
        _check(name, getattr(p, name), 0.0 if name != "unbalance" else -1.0, 1e9)
    _check("servo_limit", p.servo_limit, 0.0, 1e6, lo_open=True)
    _check("latitude", p.latitude, -math.pi / 2, math.pi / 2)
    _check("earth_rate", p.earth_rate, 0.0, 1e-2)
    q = np.asarray(p.mounting, dtype=float)
    _check("mounting", q, -1.0 - 1e-9, 1.0 + 1e-9)
    if abs(np.linalg.norm(q) - 1.0) > 1e-6:
        raise ParameterError(f"parameter 'mounting' = {p.mounting} is not a unit quaternion "
                             f"(norm {np.linalg.norm(q):.9g}; allowed |q| = 1 ± 1e-6)")


#: the reference parameter set NAV-1 of the spec (section 3.2)
NAV1 = PlatformParams()
