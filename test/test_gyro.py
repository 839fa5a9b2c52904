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

"""The single gimballed gyro with massive gimbals ([MBB] section 7, oracles O1d, O7d, O8)."""
import math

import numpy as np
import pytest

from gyro_platform.errors import GimbalLockError
from gyro_platform.physics.gyro import GimballedGyro, GyroModel
from gyro_platform.physics.params import ParameterError

A, C = 1.2e-5, 2.0e-5
SPIN = 2513.274
MASSLESS = GimballedGyro(C=C, A=A, inner=(0, 0, 0), outer=(0, 0, 0))
MASSIVE = GimballedGyro(C=C, A=A)


@pytest.mark.parametrize("deg", [0, 30, 60, 85, 89])
def test_O7d_mass_matrix_determinants(deg):
    b = math.radians(deg)
    assert np.linalg.det(GyroModel(MASSLESS).mass_matrix([0.2, b])) == pytest.approx(A**2 * C * math.cos(b)**2,
                                                                                     rel=1e-9)
    H = MASSIVE.inner
    F9z = MASSIVE.outer[2]
    expect = C * (A + H[0]) * (F9z + (A + H[2]) * math.cos(b)**2 + H[1] * math.sin(b)**2)
    assert np.linalg.det(GyroModel(MASSIVE).mass_matrix([0.2, b])) == pytest.approx(expect, rel=1e-9)


def test_massless_limit_is_eulers_free_top():
    """Torque-free with massless rings: the rotor's angular momentum is fixed in space and its
    kinetic energy constant, i.e. Euler's equations of the free symmetric top hold."""
    m = GyroModel(MASSLESS)
    y0 = np.array([0.1, 0.3, 2.0, -1.5, SPIN])
    sol = m.simulate(y0, 0.02, rtol=1e-11, atol=1e-13, t_eval=np.linspace(0, 0.02, 9))
    H0 = m.rotor_state(sol.y[:2, 0], sol.y[2:, 0])[1]
    for k in range(sol.y.shape[1]):
        w, H = m.rotor_state(sol.y[:2, k], sol.y[2:, k])
        np.testing.assert_allclose(H, H0, rtol=0, atol=1e-10 * np.linalg.norm(H0))
        # spin component constant (symmetric top: C ω̇_s = 0)
        assert w[1] == pytest.approx(m.rotor_state(sol.y[:2, 0], sol.y[2:, 0])[0][1], rel=1e-9)


def _nutation(model):
    y0 = np.array([0.0, 0.0, 0.0, 0.0, SPIN])
    n = 4
    Jac = np.zeros((n, n))
    for j in range(n):
        yp, ym = y0.copy(), y0.copy()
        yp[j] += 1e-7
        ym[j] -= 1e-7
        Jac[:, j] = (model.rhs(0, yp)[:4] - model.rhs(0, ym)[:4]) / 2e-7
    ev = np.linalg.eigvals(Jac)
    return np.sort(np.abs(ev.imag))[-1]


def test_O1d_O8_nutation_foppl_limit_and_massive_rings():
    assert _nutation(GyroModel(MASSLESS)) == pytest.approx(C / A * SPIN, rel=1e-7)   # 4188.790 rad/s
    assert C / A * SPIN == pytest.approx(4188.790, rel=1e-6)
    H, F = MASSIVE.inner, MASSIVE.outer
    J9 = F[2] + H[2] + A
    J10 = H[0] + A
    assert _nutation(GyroModel(MASSIVE)) == pytest.approx(C * SPIN / math.sqrt(J9 * J10), rel=1e-7)


def test_gimbal_lock_reported_for_massless_rings_not_for_massive():
    y = np.array([0.0, math.pi / 2 - 1e-9, 0.1, 0.1, SPIN])
    with pytest.raises(GimbalLockError, match="gimbal lock"):
        GyroModel(MASSLESS).rhs(0.0, y)
    ydot = GyroModel(MASSIVE).rhs(0.0, y)
    assert np.all(np.isfinite(ydot))


def test_bad_gyro_parameters_rejected():
    with pytest.raises(ParameterError, match="'inner'"):
        GimballedGyro(inner=(-1e-5, 1e-5, 1e-5))
    with pytest.raises(ParameterError, match="C ≤ 2A|need 0 < C"):
        GimballedGyro(C=5e-5, A=1e-5)
