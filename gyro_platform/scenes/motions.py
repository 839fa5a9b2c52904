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

"""Vehicle motion generators: exact body rates, specific force and attitude as functions of time.

Frames and conventions (spec sections 0 and 2.1):

* ``N`` — the motion's navigation frame, ENU (x East, y North, z Up). It is treated as
  inertial (flat, non-rotating Earth) except in :class:`EarthFixed`, where ``N`` is the
  inertial frame that coincides with local level at t = 0.
* ``B`` — vehicle body, FLU (x forward, y left, z up), REP-103.
* ``attitude(t)`` is ``R_NB`` (body → navigation) as a :class:`scipy.spatial.transform.Rotation`;
  ``quaternion(t)`` the same as ``(x, y, z, w)`` rows.
* ``omega(t)`` is the vehicle's inertial angular rate in body axes (rad/s), exactly consistent
  with the attitude history: ``Ṙ_NB = R_NB [ω]×``.
* ``specific_force(t)`` is what an accelerometer at the vehicle's reference point measures,
  in body axes (m/s²): ``f_B = R_NBᵀ (a_N − g_N)`` with ``g_N = (0, 0, −9.80665)``, i.e.
  ``+9.80665`` on z at rest (REP-145).
* Euler angles are yaw ψ, pitch θ, roll φ with ``R_NB = R3(ψ) R2(θ) R1(φ)`` (intrinsic Z-Y-X);
  yaw is measured from East, counter-clockwise seen from above (ENU). The exact body rates of
  an Euler history are::

      ω_x = φ̇ − ψ̇ sin θ
      ω_y = θ̇ cos φ + ψ̇ sin φ cos θ
      ω_z = −θ̇ sin φ + ψ̇ cos φ cos θ

All functions are vectorised over an array of times ``t`` (s) and return arrays with one row per
time. ``samples(duration, rate)`` turns a motion into the :class:`~gyro_platform.engine.inputs.RateSample`
stream that drives the simulator. The simulator interpolates the rate linearly between samples,
so a motion's rate should be smooth on the scale of the sample interval (or piecewise linear
with breakpoints on sample instants, as :class:`RateSteps` with ``rise_time``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence, TYPE_CHECKING

import numpy as np

from .. import quaternions
from ..engine.inputs import RateSample
from ..physics.params import EARTH_RATE, STANDARD_GRAVITY

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

G = STANDARD_GRAVITY
_GRAV_UP = np.array([0.0, 0.0, G])  # −g_N: specific force of a vehicle at rest, N axes


def _rotation():
    """SciPy's ``Rotation``, imported on first use: ~0.2 s that the Euler-angle motions (the
    default scene's) do without (:mod:`gyro_platform.quaternions`)."""
    from scipy.spatial.transform import Rotation

    return Rotation


def _times(t) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=float))


def euler_body_rates(phi, theta, dphi, dtheta, dpsi) -> np.ndarray:
    """Exact body rates (N, 3) rad/s of a Z-Y-X (yaw ψ, pitch θ, roll φ) Euler-angle history."""
    sphi, cphi = np.sin(phi), np.cos(phi)
    sth, cth = np.sin(theta), np.cos(theta)
    return np.stack([dphi - dpsi * sth,
                     dtheta * cphi + dpsi * sphi * cth,
                     -dtheta * sphi + dpsi * cphi * cth], axis=-1)


def sample_times(duration: float, rate: float, t0: float = 0.0) -> np.ndarray:
    """Sample instants ``t0 + k/rate`` for k = 0 … floor(duration·rate) (s)."""
    if not (duration > 0 and rate > 0):
        raise ValueError(f"duration ({duration} s) and rate ({rate} Hz) must be positive")
    n = int(math.floor(duration * rate + 1e-9))
    return t0 + np.arange(n + 1, dtype=float) / rate


class Motion:
    """Base class. Subclasses implement ``omega``, ``specific_force`` and ``attitude``."""

    #: scene-file type name
    kind = "motion"

    def omega(self, t) -> np.ndarray:
        """Body rates (N, 3) rad/s, vehicle axes."""
        raise NotImplementedError

    def specific_force(self, t) -> np.ndarray:
        """Specific force (N, 3) m/s², vehicle axes."""
        raise NotImplementedError

    def attitude(self, t) -> Rotation:
        """``R_NB`` (body → navigation) at each time."""
        raise NotImplementedError

    def quaternion(self, t) -> np.ndarray:
        """``R_NB`` as (N, 4) quaternions ``(x, y, z, w)``."""
        return self.attitude(_times(t)).as_quat()

    def arrays(self, duration: float, rate: float, t0: float = 0.0):
        """``(t, omega, specific_force)`` arrays at the sample instants of ``sample_times``."""
        t = sample_times(duration, rate, t0)
        return t, self.omega(t), self.specific_force(t)

    def samples(self, duration: float, rate: float, t0: float = 0.0) -> list[RateSample]:
        """The motion as ``RateSample`` s at ``rate`` Hz over ``[t0, t0 + duration]``."""
        t, w, f = self.arrays(duration, rate, t0)
        return [RateSample(float(t[i]), w[i].copy(), f[i].copy()) for i in range(t.size)]

    def describe(self) -> str:
        return self.kind


# --------------------------------------------------------------------------------------------
class _ExpRateMotion(Motion):
    """Helper: attitude ``R0 · exp(ω t)`` for a constant body rate ω."""

    def __init__(self, omega_b, initial: Rotation | None = None):
        self._w = np.asarray(omega_b, dtype=float).reshape(3)
        self._R0 = initial if initial is not None else _rotation().identity()

    def omega(self, t) -> np.ndarray:
        t = _times(t)
        return np.tile(self._w, (t.size, 1))

    def attitude(self, t) -> Rotation:
        t = _times(t)
        return self._R0 * _rotation().from_rotvec(np.outer(t, self._w))


class ConstantRate(_ExpRateMotion):
    """Constant body rate ``omega`` (rad/s, body axes) from the initial attitude ``initial``
    (``R_NB`` at t = 0); the vehicle does not translate, so ``f_B = R_NBᵀ (0, 0, g)`` turns
    with the body."""

    kind = "constant"

    def specific_force(self, t) -> np.ndarray:
        return self.attitude(t).inv().apply(_GRAV_UP)

    def describe(self) -> str:
        return f"constant rate {self._w.tolist()} rad/s"


class EarthFixed(_ExpRateMotion):
    """Vehicle at rest on the rotating Earth at ``latitude`` (rad), heading ``heading`` (rad,
    ENU yaw: 0 = body x East). ``N`` is the inertial frame aligned with local level at t = 0.

    Body rate (constant): ``ω_B = R_NBᵀ Ω_E (0, cos φ, sin φ)``; specific force (constant in
    body axes, centripetal term neglected): ``f_B = R_NBᵀ(0) (0, 0, g)``. At 45° and heading 0
    the rate is (0, 5.156304e-5, 5.156304e-5) rad/s (spec O9 f).
    """

    kind = "earth_fixed"

    def __init__(self, latitude: float, heading: float = 0.0, earth_rate: float = EARTH_RATE,
                 gravity: float = G):
        R0 = _rotation().from_euler("ZYX", [heading, 0.0, 0.0])
        w_n = earth_rate * np.array([0.0, math.cos(latitude), math.sin(latitude)])
        super().__init__(R0.inv().apply(w_n), R0)
        self._f = R0.inv().apply([0.0, 0.0, gravity])
        self.latitude, self.heading, self.earth_rate = latitude, heading, earth_rate

    def specific_force(self, t) -> np.ndarray:
        t = _times(t)
        return np.tile(self._f, (t.size, 1))

    def describe(self) -> str:
        return f"at rest on the Earth, latitude {math.degrees(self.latitude):g}°"


# --------------------------------------------------------------------------------------------
class EulerMotion(Motion):
    """A motion given by Euler-angle histories (Z-Y-X) and a navigation-frame acceleration.

    Subclasses implement ``euler(t) -> (psi, theta, phi, dpsi, dtheta, dphi)`` (rad, rad/s)
    and optionally ``accel_n(t)`` (N, 3) m/s².
    """

    def euler(self, t):
        raise NotImplementedError

    def accel_n(self, t) -> np.ndarray:
        return np.zeros((_times(t).size, 3))

    def omega(self, t) -> np.ndarray:
        psi, theta, phi, dpsi, dtheta, dphi = self.euler(_times(t))
        return euler_body_rates(phi, theta, dphi, dtheta, dpsi)

    def quaternion(self, t) -> np.ndarray:
        psi, theta, phi = self.euler(_times(t))[:3]
        return quaternions.from_euler_zyx(psi, theta, phi)

    def attitude(self, t) -> Rotation:
        return _rotation().from_quat(self.quaternion(t))

    def specific_force(self, t) -> np.ndarray:
        t = _times(t)
        return quaternions.rotate_inv(self.quaternion(t), self.accel_n(t) + _GRAV_UP)


@dataclass(frozen=True)
class Sine:
    """``amplitude · sin(2π frequency t + phase)``: amplitude (rad or m), frequency (Hz),
    phase (rad)."""

    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0

    def value(self, t: np.ndarray):
        w = 2.0 * math.pi * self.frequency
        a = w * t + self.phase
        return self.amplitude * np.sin(a), self.amplitude * w * np.cos(a), -self.amplitude * w * w * np.sin(a)


@dataclass(frozen=True)
class Sinusoidal(EulerMotion):
    """Sinusoidal roll, pitch and yaw about a mean heading, optionally with heave (ship motion,
    e.g. roll 10° at 0.1 Hz). Angles in rad, heave in m (along N z, up)."""

    roll: Sine = field(default_factory=Sine)
    pitch: Sine = field(default_factory=Sine)
    yaw: Sine = field(default_factory=Sine)
    heading: float = 0.0
    heave: Sine = field(default_factory=Sine)
    kind = "sinusoidal"

    def euler(self, t):
        phi, dphi, _ = self.roll.value(t)
        theta, dtheta, _ = self.pitch.value(t)
        psi, dpsi, _ = self.yaw.value(t)
        return psi + self.heading, theta, phi, dpsi, dtheta, dphi

    def accel_n(self, t) -> np.ndarray:
        a = np.zeros((t.size, 3))
        a[:, 2] = self.heave.value(t)[2]
        return a

    def describe(self) -> str:
        return (f"sinusoidal roll {math.degrees(self.roll.amplitude):g}° @ {self.roll.frequency:g} Hz, "
                f"pitch {math.degrees(self.pitch.amplitude):g}° @ {self.pitch.frequency:g} Hz, "
                f"yaw {math.degrees(self.yaw.amplitude):g}° @ {self.yaw.frequency:g} Hz")


def _ramp(tau: np.ndarray, T: float):
    """Half-cosine ramp 0 → 1 over [0, T]: value, integral from 0, derivative."""
    x = np.clip(tau / T, 0.0, 1.0)
    inside = (tau > 0) & (tau < T)
    s = 0.5 * (1.0 - np.cos(math.pi * x))
    integ = np.where(tau <= 0, 0.0,
                     np.where(tau >= T, tau - T / 2.0, 0.5 * tau - T / (2 * math.pi) * np.sin(math.pi * x)))
    ds = np.where(inside, math.pi / (2.0 * T) * np.sin(math.pi * x), 0.0)
    return s, integ, ds


class CoordinatedTurn(EulerMotion):
    """Level coordinated turn at constant airspeed ``speed`` (m/s) and steady bank ``bank``
    (rad; positive = right wing down = clockwise turn seen from above).

    Steady turn rate ``ψ̇ = −g tan(bank)/V`` (ENU yaw). The turn rate ramps in with a
    half-cosine over ``roll_time`` s starting at ``start``, holds for ``hold`` s (``None`` =
    for ever), and ramps out the same way. During the ramps the bank follows the turn rate,
    ``φ = atan(−V ψ̇/g)``, so the turn is coordinated at every instant: the specific force is
    ``(0, 0, g/cos φ)`` in body axes (no lateral component). Pitch is zero (level flight);
    velocity ``V (cos ψ, sin ψ, 0)``, acceleration ``V ψ̇ (−sin ψ, cos ψ, 0)``.
    """

    kind = "coordinated_turn"

    def __init__(self, speed: float, bank: float, roll_time: float = 2.0, start: float = 0.0,
                 hold: float | None = None, heading: float = 0.0, gravity: float = G):
        if speed <= 0 or roll_time <= 0 or not (abs(bank) < math.pi / 2):
            raise ValueError("coordinated turn needs speed > 0, roll_time > 0, |bank| < 90°")
        self.speed, self.bank, self.roll_time, self.start = speed, bank, roll_time, start
        self.hold, self.heading, self.g = hold, heading, gravity
        self.turn_rate = -gravity * math.tan(bank) / speed

    def _profile(self, t):
        T = self.roll_time
        s_in, i_in, d_in = _ramp(t - self.start, T)
        if self.hold is None:
            return s_in, i_in, d_in
        t_out = self.start + T + self.hold
        s_out, i_out, d_out = _ramp(t - t_out, T)
        return s_in - s_out, i_in - i_out, d_in - d_out

    def euler(self, t):
        s, integ, ds = self._profile(t)
        r = self.turn_rate
        dpsi, ddpsi = r * s, r * ds
        psi = self.heading + r * integ
        k = self.speed / self.g
        phi = np.arctan(-k * dpsi)
        dphi = -k * ddpsi / (1.0 + (k * dpsi) ** 2)
        z = np.zeros_like(t)
        return psi, z, phi, dpsi, z, dphi

    def accel_n(self, t) -> np.ndarray:
        psi, _, _, dpsi, _, _ = self.euler(t)
        v = self.speed
        return np.stack([-v * dpsi * np.sin(psi), v * dpsi * np.cos(psi), np.zeros_like(t)], axis=-1)

    def describe(self) -> str:
        return (f"coordinated turn V = {self.speed:g} m/s, bank {math.degrees(self.bank):g}°, "
                f"turn rate {self.turn_rate:.5g} rad/s")


class Coning(Motion):
    """Classic coning: the body's rotation vector relative to ``initial`` has constant length
    ``half_angle`` θ (rad) and turns at ``frequency`` Ω (rad/s = 2π·Hz) about the cone axis
    ``axis`` (0, 1, 2 = body x, y, z). For axis x::

        R_NB(t) = R0 · exp(θ (0, cos Ωt, sin Ωt))
        ω_B(t)  = (−2 Ω sin²(θ/2),  −Ω sin θ sin Ωt,  Ω sin θ cos Ωt)

    (other axes: cyclic permutation). The attitude is periodic, yet the body rate about the cone
    axis has the constant, rectified part ``−2Ω sin²(θ/2) = −Ω (1 − cos θ)``: summing the rate
    components (without the non-commutativity of rotations) would give a spurious drift of that
    size. The vehicle does not translate: ``f_B = R_NBᵀ (0, 0, g)``.
    """

    kind = "coning"

    def __init__(self, half_angle: float, frequency: float, axis: int = 0, phase: float = 0.0,
                 initial: Rotation | None = None):
        self.theta, self.Omega, self.axis, self.phase = half_angle, frequency, int(axis), phase
        self._R0 = initial if initial is not None else _rotation().identity()
        self._j, self._k = (self.axis + 1) % 3, (self.axis + 2) % 3

    @property
    def rectified_rate(self) -> float:
        """Constant body rate about the cone axis, ``−2 Ω sin²(θ/2)`` (rad/s)."""
        return -2.0 * self.Omega * math.sin(self.theta / 2.0) ** 2

    def _rotvec(self, t):
        a = self.Omega * t + self.phase
        v = np.zeros((t.size, 3))
        v[:, self._j] = self.theta * np.cos(a)
        v[:, self._k] = self.theta * np.sin(a)
        return v

    def omega(self, t) -> np.ndarray:
        t = _times(t)
        a = self.Omega * t + self.phase
        w = np.zeros((t.size, 3))
        w[:, self.axis] = self.rectified_rate
        w[:, self._j] = -self.Omega * math.sin(self.theta) * np.sin(a)
        w[:, self._k] = self.Omega * math.sin(self.theta) * np.cos(a)
        return w

    def attitude(self, t) -> Rotation:
        return self._R0 * _rotation().from_rotvec(self._rotvec(_times(t)))

    def specific_force(self, t) -> np.ndarray:
        return self.attitude(t).inv().apply(_GRAV_UP)

    def describe(self) -> str:
        return (f"coning half-angle {math.degrees(self.theta):g}° at {self.Omega / (2 * math.pi):g} Hz "
                f"about body {'xyz'[self.axis]} (rectified rate {self.rectified_rate:.4g} rad/s)")


class RateSteps(Motion):
    """Piecewise-constant body rates (e.g. a 5 rad/s shock): the rate is zero before
    ``times[0]`` and ``rates[k]`` (rad/s, body axes) from ``times[k]`` on.

    With ``rise_time`` T > 0 each change is a linear ramp over ``[times[k], times[k] + T]``;
    then consecutive rates must be parallel (or zero) so that the body turns about a fixed axis
    during a ramp and the attitude stays exact: ``R = R_k exp(e (a τ + (b − a) τ²/(2T)))``.
    With T = 0 the steps are ideal; note that the simulator interpolates linearly between
    samples, so an ideal step becomes a ramp over one sample interval (rotation error
    ``Δω·dt/2`` per edge, cancelling between the edges of a pulse). The vehicle does not
    translate: ``f_B = R_NBᵀ (0, 0, g)``.
    """

    kind = "rate_steps"

    def __init__(self, times: Sequence[float], rates: Sequence[Sequence[float]], rise_time: float = 0.0,
                 initial: Rotation | None = None):
        self.times = np.asarray(times, dtype=float).reshape(-1)
        self.rates = np.asarray(rates, dtype=float).reshape(-1, 3)
        self.T = float(rise_time)
        if self.times.size == 0 or self.times.size != self.rates.shape[0]:
            raise ValueError("rate steps need as many rates as times (at least one)")
        if self.T < 0:
            raise ValueError("rise_time must be ≥ 0")
        if np.any(np.diff(self.times) < self.T) or np.any(np.diff(self.times) <= 0):
            raise ValueError("step times must increase by more than rise_time")
        self._R0 = initial if initial is not None else _rotation().identity()
        prev = np.vstack([np.zeros(3), self.rates[:-1]])
        self._prev = prev
        if self.T > 0:
            for k, (a, b) in enumerate(zip(prev, self.rates)):
                na, nb = np.linalg.norm(a), np.linalg.norm(b)
                if na > 0 and nb > 0 and np.linalg.norm(np.cross(a, b)) > 1e-12 * na * nb:
                    raise ValueError(f"rate step {k}: with rise_time > 0 consecutive rates must be "
                                     "parallel (the ramp turns about a fixed axis)")
        # attitude at each step start (R_k) and at the end of its ramp (Rm_k)
        self._Rk: list[Rotation] = []
        self._Rm: list[Rotation] = []
        R = self._R0
        for k in range(self.times.size):
            if k > 0:
                R = self._Rm[k - 1] * _rotation().from_rotvec(
                    self.rates[k - 1] * (self.times[k] - self.times[k - 1] - self.T))
            self._Rk.append(R)
            self._Rm.append(R * _rotation().from_rotvec(self._ramp_rotvec(k, self.T)))

    def _ramp_rotvec(self, k: int, tau) -> np.ndarray:
        """Rotation vector accumulated τ s into ramp k (τ ≤ T)."""
        a, b = self._prev[k], self.rates[k]
        tau = np.asarray(tau, dtype=float)
        if self.T == 0:
            return np.zeros(np.shape(tau) + (3,))
        # ∫ (a + (b − a) u/T) du  from 0 to τ — exact for parallel a, b
        return np.multiply.outer(tau, a) + np.multiply.outer(tau ** 2 / (2 * self.T), b - a)

    def omega(self, t) -> np.ndarray:
        t = _times(t)
        w = np.zeros((t.size, 3))
        k = np.searchsorted(self.times, t, side="right") - 1
        on = k >= 0
        kk = np.clip(k, 0, None)
        tau = t - self.times[kk]
        if self.T > 0:
            x = np.clip(tau / self.T, 0.0, 1.0)[:, None]
            w_on = self._prev[kk] + (self.rates[kk] - self._prev[kk]) * x
        else:
            w_on = self.rates[kk]
        w[on] = w_on[on]
        return w

    def attitude(self, t) -> Rotation:
        t = _times(t)
        k = np.searchsorted(self.times, t, side="right") - 1
        out = []
        for i in range(t.size):
            ki = k[i]
            if ki < 0:
                out.append(self._R0)
                continue
            tau = t[i] - self.times[ki]
            if tau < self.T:
                out.append(self._Rk[ki] * _rotation().from_rotvec(self._ramp_rotvec(ki, tau)))
            else:
                out.append(self._Rm[ki] * _rotation().from_rotvec(self.rates[ki] * (tau - self.T)))
        return _rotation().concatenate(out)

    def specific_force(self, t) -> np.ndarray:
        return self.attitude(t).inv().apply(_GRAV_UP)

    def describe(self) -> str:
        return f"{self.times.size} rate step(s), max |ω| {np.linalg.norm(self.rates, axis=1).max():g} rad/s"


class RandomMotion(EulerMotion):
    """Seeded, band-limited random motion: each Euler angle (roll, pitch, yaw about
    ``heading``) is a sum of ``components`` sinusoids with frequencies drawn uniformly in
    ``band`` (Hz), random phases, and equal amplitudes scaled to the RMS ``angle_rms`` (rad,
    scalar or per axis roll/pitch/yaw). The navigation-frame acceleration is built the same way
    with RMS ``accel_rms`` (m/s², per axis East/North/Up). Same seed → identical motion; body
    rates are derived exactly from the Euler histories, so rates and attitude agree.
    """

    kind = "random"
    #: most sinusoids a scene may ask for per axis (the default 16 already looks random)
    MAX_COMPONENTS = 256
    #: floats in one temporary of the sums (8 MiB)
    SUM_FLOATS = 2 ** 20

    def __init__(self, seed: int, angle_rms, band=(0.05, 2.0), components: int = 16,
                 accel_rms=0.0, heading: float = 0.0):
        lo, hi = float(band[0]), float(band[1])
        if not (0 < lo < hi) or not 1 <= components <= self.MAX_COMPONENTS:
            raise ValueError(f"random motion needs 0 < band[0] < band[1] and 1 ≤ components ≤ {self.MAX_COMPONENTS}")
        rng = np.random.default_rng(int(seed))
        self.seed, self.band, self.heading = int(seed), (lo, hi), heading
        ang = np.broadcast_to(np.asarray(angle_rms, dtype=float), (3,))
        acc = np.broadcast_to(np.asarray(accel_rms, dtype=float), (3,))
        n = int(components)
        # rows: roll, pitch, yaw, accel E, N, U
        self._f = rng.uniform(lo, hi, size=(6, n)) * 2 * math.pi
        self._p = rng.uniform(0, 2 * math.pi, size=(6, n))
        rms = np.concatenate([ang, acc])
        self._a = np.tile((rms * math.sqrt(2.0 / n))[:, None], (1, n))  # RMS of n sines of amp a: a sqrt(n/2)

    def _sum(self, rows, t):
        """Value, first and second derivative of the sums of ``rows`` at times ``t``: three
        (3, N) arrays, made over blocks of times so that no temporary exceeds ``SUM_FLOATS``."""
        freq, phase, amp = self._f[rows, :, None], self._p[rows, :, None], self._a[rows, :, None]
        t = np.asarray(t, dtype=float)
        out = np.empty((3, freq.shape[0], t.size))
        step = max(1, self.SUM_FLOATS // freq.size)
        for i in range(0, t.size, step):
            a = freq * t[None, None, i:i + step] + phase
            out[0, :, i:i + step] = (amp * np.sin(a)).sum(axis=1)
            out[1, :, i:i + step] = (amp * freq * np.cos(a)).sum(axis=1)
            out[2, :, i:i + step] = (-amp * freq * freq * np.sin(a)).sum(axis=1)
        return out[0], out[1], out[2]

    def euler(self, t):
        x, dx, _ = self._sum(slice(0, 3), t)
        phi, theta, psi = x
        dphi, dtheta, dpsi = dx
        return psi + self.heading, theta, phi, dpsi, dtheta, dphi

    def accel_n(self, t) -> np.ndarray:
        return self._sum(slice(3, 6), t)[2].T

    def describe(self) -> str:
        return f"random (seed {self.seed}, band {self.band[0]:g}–{self.band[1]:g} Hz)"


__all__ = [
    "Motion", "ConstantRate", "EarthFixed", "EulerMotion", "Sine", "Sinusoidal", "CoordinatedTurn",
    "Coning", "RateSteps", "RandomMotion", "euler_body_rates", "sample_times", "G",
]
