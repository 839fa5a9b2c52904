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

"""Stabilised platform: servo loop, drift mechanisms and Earth rate (spec 9, oracle O9)."""
import math

import numpy as np
import pytest

from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1, STANDARD_GRAVITY
from gyro_platform.physics.system import PlatformSystem

L = NAV1.L[2]


def closed_loop_eigs(fid):
    s = PlatformSystem(NAV1, ModelOptions.make("stabilised", fid, ("rotor_gyroscopic", "coriolis", "servo")))
    s.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
    idx = list(range(13)) + list(range(s.layout.z.start, s.layout.z.stop))
    y0 = s.rest_state()
    A = np.zeros((len(idx), len(idx)))
    for a, j in enumerate(idx):
        yp, ym = y0.copy(), y0.copy()
        yp[j] += 1e-7
        ym[j] -= 1e-7
        A[:, a] = (s.rhs(0, yp)[idx] - s.rhs(0, ym)[idx]) / 2e-7
    return np.linalg.eigvals(A)


@pytest.mark.parametrize("fid", ["linear", "full"])
def test_O9a_servo_closed_loop_poles(fid):
    ev = closed_loop_eigs(fid)
    assert np.max(ev.real) < 1e-6
    for pole in (-26.06, -26.27, -26.49, -66.79 + 83.81j, -75.59 + 83.37j):
        assert np.min(np.abs(ev - pole)) < 0.006, pole
    np.testing.assert_allclose(np.sort(np.abs(ev[np.abs(ev.imag) > 500].imag)), [767.9715] * 2 + [808.6327] * 2,
                               rtol=1e-6)
    assert np.sum(np.abs(ev) < 1e-6) == 3       # attitude memory (3 platform angles are not states here)


def run(params, effects, T, samples_hz=200.0, omega=(0, 0, 0), f=None, fid="linear", every=10):
    opt = ModelOptions.make("stabilised", fid, effects, integrator="dop853", rtol=1e-10, atol=1e-14)
    sim = Simulator(params, opt)
    outs = []
    for k in range(int(T * samples_hz) + 1):
        sim.push(RateSample.of(k / samples_hz, omega, f))
        if k % every == 0:
            outs.append(sim.outputs())
    return sim, outs


def slope(outs, t0, t1, axis, field="drift_angle"):
    t = np.array([o.t for o in outs])
    v = np.array([getattr(o, field)[axis] for o in outs])
    m = (t >= t0) & (t <= t1)
    return np.polyfit(t[m], v[m], 1)[0]


def test_O9b_gimbal_bias_torque_drags_platform_at_minus_Q_over_L():
    p = NAV1.with_(bias_torque=(0, 0, 0, 0, 1e-4))
    # dense outputs: the undamped 122 Hz nutation ripple must not alias into the fit
    sim, outs = run(p, ("rotor_gyroscopic", "coriolis", "servo", "bias_torque"), 1.0, samples_hz=2000, every=2)
    assert slope(outs, 0.5, 1.0, 2) == pytest.approx(-1.98946e-3, rel=2e-5)
    a9 = np.mean([o.gimbal_angles[3] for o in outs if o.t >= 0.5])
    assert abs(a9) < 2e-8                                  # pick-off α9 held at ≈ 9e-9 rad on average
    assert -1e-7 / L * 180 / math.pi * 3600 == pytest.approx(-0.41035, rel=1e-4)   # nav-grade example


@pytest.mark.parametrize("ki,offset", [(3.0e4, 0.0), (0.0, 0.01 / 1500)])
def test_O9c_platform_torque_gives_offset_not_drift(ki, offset):
    # support friction against a vehicle yawing at 1 rad/s: D_s·1 + μ_s = 0.01 N m on axis 3
    p = NAV1.with_(servo_ki=ki)
    sim, outs = run(p, ("rotor_gyroscopic", "coriolis", "servo", "support_friction"), 2.0, omega=(0, 0, 1.0))
    a9 = np.array([o.gimbal_angles[3] for o in outs if o.t > 1.5])
    assert np.abs(np.mean(a9)) == pytest.approx(offset, abs=5e-9)
    assert abs(slope(outs, 1.0, 2.0, 2)) < 1e-8               # no drift
    assert abs(outs[-1].servo_torque[2]) == pytest.approx(0.01, rel=1e-3)


def test_O9d_mass_unbalance_g_sensitive_drift():
    m, ell = NAV1.gyro_mass, NAV1.unbalance
    assert m * ell / L == pytest.approx(4.97359e-8, rel=1e-5)
    assert m * ell / L * STANDARD_GRAVITY * 180 / math.pi * 3600 == pytest.approx(0.100604, rel=1e-5)
    g = STANDARD_GRAVITY
    sim, outs = run(NAV1, ("rotor_gyroscopic", "coriolis", "servo", "mass_unbalance"), 3.0, f=(0, 0, g))
    expect = m * ell / L * g                                   # about +z: ω_d = (mℓ/L) f_⊥
    assert slope(outs, 1.0, 3.0, 2) == pytest.approx(expect, rel=2e-3)
    assert abs(slope(outs, 1.0, 3.0, 0)) < 1e-3 * expect
    assert abs(slope(outs, 1.0, 3.0, 1)) < 1e-3 * expect
    # switched off: no drift at all
    sim, outs = run(NAV1, ("rotor_gyroscopic", "coriolis", "servo"), 1.0, f=(0, 0, g))
    assert np.max(np.abs(outs[-1].drift_angle)) < 1e-15


def test_O9e_anisoelastic_coefficient_and_sign():
    m, dK = NAV1.gyro_mass, NAV1.anisoelastic
    assert m**2 * dK / L == pytest.approx(9.94718e-10, rel=1e-5)
    g = STANDARD_GRAVITY
    f = np.array([0.0, 1.0, 1.0]) * g / math.sqrt(2)           # oblique to rotor 11's spin axis (y)
    sim, outs = run(NAV1, ("rotor_gyroscopic", "coriolis", "servo", "anisoelastic"), 3.0, f=f)
    fs, fperp = f[1], np.array([0, 0, f[2]])
    expect = -(m**2 * dK / L) * fs * fperp                     # ω_d = −(m² ΔK / L) f_s f_⊥
    assert slope(outs, 1.0, 3.0, 2) == pytest.approx(expect[2], rel=5e-3)


def test_O9f_earth_rate_compensation_keeps_local_level():
    lat = math.radians(45)
    w = NAV1.earth_rate * np.array([0, math.cos(lat), math.sin(lat)])
    np.testing.assert_allclose(w, [0, 5.156304e-5, 5.156304e-5], rtol=1e-6)
    sim, outs = run(NAV1, ("rotor_gyroscopic", "coriolis", "servo", "earth_rate"), 2.0)
    np.testing.assert_allclose(outs[0].gimbal_axial_torques, [0, -2.591841e-6, -2.591841e-6, 0, -2.591841e-6],
                               rtol=1e-6, atol=1e-15)
    assert np.max(np.abs(outs[-1].drift_angle)) < 1e-10
    assert np.max(np.abs(outs[-1].platform_attitude[:3])) > 1e-5   # the platform did turn with the Earth
    assert np.linalg.norm(w) * 180 / math.pi * 3600 == pytest.approx(15.0411, rel=1e-5)


def test_mount_angles_follow_vehicle_while_platform_holds():
    sim, outs = run(NAV1, ("rotor_gyroscopic", "coriolis", "servo", "support_friction"), 1.0, omega=(0.3, 0, 0))
    o = outs[-1]
    assert o.mount_angles[0] == pytest.approx(-0.3 * o.t, rel=1e-3)    # vehicle rolled, platform held
    assert np.max(np.abs(o.drift_angle)) < 1e-5
