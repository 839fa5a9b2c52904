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

"""Vehicle motions: body rates, attitude and specific force must be one consistent kinematics."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp, trapezoid
from scipy.spatial.transform import Rotation

from gyro_platform.engine.inputs import RateSample
from gyro_platform.physics.params import EARTH_RATE
from gyro_platform.scenes import motions as m

G = 9.80665


def _motions():
    return {
        "constant": (m.ConstantRate([0.1, -0.2, 0.3], Rotation.from_euler("ZYX", [0.3, 0.1, -0.2])), 10.0, ()),
        "earth_fixed": (m.EarthFixed(math.radians(45.0), math.radians(30.0)), 3600.0, ()),
        "sinusoidal": (m.Sinusoidal(roll=m.Sine(math.radians(10), 0.1), pitch=m.Sine(math.radians(3), 0.125, 0.5),
                                    yaw=m.Sine(math.radians(20), 0.05, 1.0), heading=0.7,
                                    heave=m.Sine(1.0, 0.1)), 20.0, ()),
        "coordinated_turn": (m.CoordinatedTurn(60.0, math.radians(30), roll_time=3.0, start=1.0, hold=4.0), 15.0,
                             (1.0, 4.0, 8.0, 11.0)),
        "coning": (m.Coning(math.radians(5), 2 * math.pi * 1.0, axis=1, phase=0.3,
                            initial=Rotation.from_euler("ZYX", [0.2, 0.0, 0.1])), 5.0, ()),
        "rate_steps": (m.RateSteps([0.5, 0.6, 1.0], [[0, 0, 5], [0, 0, 0], [1, 2, 3]]), 2.0, (0.5, 0.6, 1.0)),
        "rate_steps_ramped": (m.RateSteps([0.2, 0.4, 0.7], [[0, 0, 5], [0, 0, -1], [0, 0, 3]], rise_time=0.05),
                              1.2, (0.2, 0.25, 0.4, 0.45, 0.7, 0.75)),
        "random": (m.RandomMotion(3, np.radians([5, 3, 8]), (0.1, 2.0), accel_rms=0.5), 10.0, ()),
    }


MOTIONS = _motions()


def integrate_attitude(motion, T, knots=(), n_eval=41, rates=None):
    """Integrate q̇ = ½ q ⊗ (ω, 0) from the motion's own attitude at 0 (DOP853, tight tolerances,
    restarted at the rate's kinks). Returns (t, Rotation)."""
    rates = rates or motion.omega
    t_eval = np.linspace(0.0, T, n_eval)

    def f(t, q):
        w = rates(t)[0]
        v, s = q[:3], q[3]
        return np.r_[0.5 * (s * w + np.cross(v, w)), -0.5 * (v @ w)]

    edges = [0.0, *sorted(k for k in knots if 0 < k < T), T]
    q = motion.attitude(0.0)[0].as_quat()
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        te = np.unique(np.r_[t_eval[(t_eval >= a) & (t_eval <= b)], b])  # state at b carries on
        sol = solve_ivp(f, (a, b), q, t_eval=te, rtol=1e-12, atol=1e-14, method="DOP853",
                        max_step=(b - a) / 50)
        for i, t in enumerate(sol.t):
            if not out or t > out[-1][0]:
                out.append((t, sol.y[:, i]))
        q = sol.y[:, -1] / np.linalg.norm(sol.y[:, -1])
    ts = np.array([o[0] for o in out])
    return ts, Rotation.from_quat(np.array([o[1] for o in out]))


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_integrated_rates_reproduce_attitude(name):
    motion, T, knots = MOTIONS[name]
    ts, R_int = integrate_attitude(motion, T, knots)
    err = (motion.attitude(ts).inv() * R_int).magnitude()
    assert err.max() < 1e-8, f"{name}: attitude from integrated rates differs by {err.max():.3g} rad"


def test_attitude_check_is_sensitive_to_wrong_rates():
    """Using the Euler-angle derivatives as if they were body rates must fail the check."""
    motion = m.Sinusoidal(roll=m.Sine(math.radians(10), 0.1), pitch=m.Sine(math.radians(3), 0.125),
                          yaw=m.Sine(math.radians(20), 0.05))

    def naive(t):
        psi, theta, phi, dpsi, dtheta, dphi = motion.euler(np.atleast_1d(t))
        return np.stack([dphi, dtheta, dpsi], axis=-1)

    ts, R_int = integrate_attitude(motion, 20.0, rates=naive)
    assert (motion.attitude(ts).inv() * R_int).magnitude().max() > 1e-3


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_specific_force_is_gravity_plus_acceleration_in_body_axes(name):
    """f_B = R_NBᵀ (a_N − g_N): without translation |f| = g; the turn and heave add a_N."""
    motion, T, _ = MOTIONS[name]
    t = np.linspace(0.0, T, 57)
    f = motion.specific_force(t)
    R = motion.attitude(t)
    f_n = R.apply(f)  # back to navigation axes: a_N + (0, 0, g)
    if name == "coordinated_turn":
        psi = R.as_euler("ZYX")[:, 0]
        dpsi = motion.euler(t)[3]
        a = 60.0 * dpsi[:, None] * np.stack([-np.sin(psi), np.cos(psi), 0 * psi], axis=-1)
    elif name == "sinusoidal":
        a = np.zeros((t.size, 3))
        a[:, 2] = -1.0 * (2 * math.pi * 0.1) ** 2 * np.sin(2 * math.pi * 0.1 * t)
    elif name == "random":
        a = motion.accel_n(t)
        # the acceleration is the second derivative of a bounded position: check by differencing
        h = 1e-4
        v = lambda tt: (motion._sum(slice(3, 6), tt)[1]).T  # noqa: E731  (velocity)
        assert np.allclose((v(t + h) - v(t - h)) / (2 * h), a, atol=1e-6)
    elif name == "earth_fixed":
        # N is inertial and aligned with local level at t = 0; f stays the local vertical
        f0 = motion.specific_force(0.0)[0]
        assert np.allclose(f, f0)
        assert np.allclose(R[0].apply(f0), [0, 0, G])
        return
    else:
        a = np.zeros((t.size, 3))
    assert np.allclose(f_n, a + [0, 0, G], atol=1e-9)


def test_coordinated_turn_specific_force_and_rates():
    V, bank = 60.0, math.radians(30)
    turn = m.CoordinatedTurn(V, bank, roll_time=3.0, start=1.0, hold=4.0)
    t = np.linspace(0.0, 12.0, 241)
    f = turn.specific_force(t)
    phi = turn.attitude(t).as_euler("ZYX")[:, 2]
    assert np.allclose(f[:, 0], 0.0, atol=1e-12), "no longitudinal specific force at constant speed"
    assert np.allclose(f[:, 1], 0.0, atol=1e-12), "coordinated: no lateral specific force (ball centred)"
    assert np.allclose(np.linalg.norm(f, axis=1), G / np.cos(phi), rtol=1e-12)
    # steady part: bank φ, turn rate −g tanφ/V (right bank = clockwise), load factor 1/cos φ
    steady = (t > 4.0 + 1e-9) & (t < 8.0 - 1e-9)
    assert np.allclose(phi[steady], bank, atol=1e-12)
    assert np.allclose(np.linalg.norm(f[steady], axis=1), G / math.cos(bank), rtol=1e-12)
    r = -G * math.tan(bank) / V
    assert turn.turn_rate == pytest.approx(r)
    w = turn.omega(t[steady])
    assert np.allclose(w, [0.0, r * math.sin(bank), r * math.cos(bank)], atol=1e-12)
    # heading change: ramps count half each
    psi_end = turn.attitude(12.0).as_euler("ZYX")[0, 0]
    expected = r * (4.0 + 3.0)
    assert math.remainder(psi_end - expected, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # before the turn and after roll-out: straight and level
    assert np.allclose(turn.omega([0.0, 0.5, 11.5]), 0.0, atol=1e-15)


def test_coning_rectified_rate_and_periodic_attitude():
    theta, f_hz = math.radians(3.0), 2.0
    Om = 2 * math.pi * f_hz
    for axis in range(3):
        c = m.Coning(theta, Om, axis=axis)
        T = 1.0 / f_hz
        t = np.linspace(0.0, T, 2001)
        w = c.omega(t)
        rect = -2.0 * Om * math.sin(theta / 2) ** 2
        assert c.rectified_rate == pytest.approx(rect)
        assert np.allclose(w[:, axis], rect, rtol=1e-14)
        # mean over a period: only the rectified term survives (trapezoid is exact for sines)
        mean = trapezoid(w, t, axis=0) / T     # scipy's: numpy 1.26 (ROS Jazzy) has no np.trapezoid
        others = [i for i in range(3) if i != axis]
        assert mean[axis] == pytest.approx(rect, rel=1e-12)
        assert np.allclose(mean[others], 0.0, atol=1e-12)
        # …yet the attitude is periodic: no net rotation over a period
        assert (c.attitude(0.0).inv() * c.attitude(T)).magnitude()[0] < 1e-14
        # |ω| = 2Ω sin(θ/2) (constant), small-angle rectified term ≈ −Ω θ²/2
        assert np.allclose(np.linalg.norm(w, axis=1), 2 * Om * math.sin(theta / 2), rtol=1e-12)
        assert rect == pytest.approx(-Om * theta ** 2 / 2, rel=1e-3)


def test_rate_steps_values_and_pulse_angle():
    rs = m.RateSteps([0.2, 0.3], [[0, 0, 5.0], [0, 0, 0]], rise_time=0.01)
    w = rs.omega([0.0, 0.2, 0.205, 0.21, 0.25, 0.3, 0.305, 0.31, 0.5])[:, 2]
    assert np.allclose(w, [0, 0, 2.5, 5, 5, 5, 2.5, 0, 0])
    # a 5 rad/s pulse of 0.1 s (ramps included) turns the body by exactly 0.5 rad about z
    rv = rs.attitude(0.6).as_rotvec()[0]
    assert np.allclose(rv, [0, 0, 0.5], atol=1e-14)
    with pytest.raises(ValueError, match="parallel"):
        m.RateSteps([0.1, 0.2], [[0, 0, 1], [1, 0, 0]], rise_time=0.01)
    with pytest.raises(ValueError):
        m.RateSteps([0.1, 0.105], [[0, 0, 1], [0, 0, 2]], rise_time=0.01)  # ramps overlap


def test_earth_fixed_rate():
    e = m.EarthFixed(math.radians(45.0))
    w = e.omega(0.0)[0]
    assert np.allclose(w, [0.0, 5.156304e-5, 5.156304e-5], rtol=1e-6)  # spec O9 f
    assert np.allclose(e.specific_force(5.0), [0, 0, G])
    e90 = m.EarthFixed(math.radians(45.0), heading=math.radians(90.0))  # body x North
    assert np.allclose(e90.omega(0.0)[0], [EARTH_RATE / math.sqrt(2), 0.0, EARTH_RATE / math.sqrt(2)])
    # one sidereal day brings the vehicle back to its attitude
    assert e.attitude(2 * math.pi / EARTH_RATE).magnitude()[0] < 1e-9


def test_random_motion_reproducible_band_limited():
    a = m.RandomMotion(7, math.radians(4), (0.2, 1.0), accel_rms=0.3)
    b = m.RandomMotion(7, math.radians(4), (0.2, 1.0), accel_rms=0.3)
    c = m.RandomMotion(8, math.radians(4), (0.2, 1.0), accel_rms=0.3)
    t = np.linspace(0, 50, 5001)
    assert np.array_equal(a.omega(t), b.omega(t))
    assert np.array_equal(a.specific_force(t), b.specific_force(t))
    assert not np.allclose(a.omega(t), c.omega(t))
    # Euler angles live in the band: no spectral content below 0.2 Hz or above 1 Hz
    T, n = 400.0, 2 ** 15
    tt = np.arange(n) * (T / n)
    roll = a.euler(tt)[2] * np.hanning(n)
    spec = np.abs(np.fft.rfft(roll)) ** 2
    fr = np.fft.rfftfreq(n, T / n)
    inside = (fr >= 0.18) & (fr <= 1.02)
    assert spec[~inside].sum() < 1e-6 * spec[inside].sum()
    # RMS as asked (equal amplitudes, random frequencies: RMS exact up to beat terms)
    assert np.sqrt(np.mean(a.euler(tt)[2] ** 2)) == pytest.approx(math.radians(4), rel=0.15)


def test_random_motion_sums_in_blocks_of_time_are_those_of_one_block(monkeypatch):
    """The sums are made over blocks of times (bounded memory for long scenes): block after
    block, they are the single-block sums bit for bit, with a ragged last block."""
    mo = m.RandomMotion(3, [0.02, 0.03, 0.05], (0.1, 3.0), components=40, accel_rms=0.2)
    t = np.linspace(0, 30, 3001)
    whole = (mo.omega(t), mo.specific_force(t), mo.quaternion(t))
    monkeypatch.setattr(m.RandomMotion, "SUM_FLOATS", 3 * 40 * 7)        # 7 times per block
    blocks = (mo.omega(t), mo.specific_force(t), mo.quaternion(t))
    for a, b in zip(whole, blocks):
        assert np.array_equal(a, b)
    with pytest.raises(ValueError, match="components ≤ 256"):
        m.RandomMotion(3, 0.01, components=257)


def test_samples_are_rate_samples_on_the_grid():
    s = m.Sinusoidal(roll=m.Sine(math.radians(10), 0.1)).samples(2.0, 50.0)
    assert len(s) == 101
    assert all(isinstance(x, RateSample) for x in s)
    assert s[0].t == 0.0 and s[-1].t == pytest.approx(2.0)
    assert np.allclose(np.diff([x.t for x in s]), 0.02)
    assert s[10].specific_force is not None and np.linalg.norm(s[10].specific_force) == pytest.approx(G)
    with pytest.raises(ValueError):
        m.sample_times(0.0, 10.0)
