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

"""Tests of gyro_platform.engine.integrators: orders, exactness, stability, invariants, contract.

Expected numbers come from theory (orders 2^p, stability functions, exact solutions by expm),
never from this module's own output.
"""
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from gyro_platform.engine.integrators import Integrator, INTEGRATORS, make_integrator, StepStats
from gyro_platform.errors import SimulationError, ToleranceError

ALL = sorted(INTEGRATORS)
FIXED = ["rk4", "implicit_midpoint", "etd2", "etd4", "exprb"]
#: a tolerance so loose that the step controller never refines: the method's own map at
#: h = max_step (for tests of orders, stability functions and invariants of the bare method)
LOOSE = {"rtol": 0.5, "atol": 10.0}


# --------------------------------------------------------------------------- test systems


class Manufactured:
    """Smooth nonlinear non-autonomous y' = A y + g(t, y) with known solution y_ex(t)."""

    W = 3.0
    A = np.array([[0.0, W], [-W, 0.0]])

    @staticmethod
    def exact(t):
        return np.array([math.cos(t) + 0.3 * math.sin(2 * t), 0.5 * math.sin(t) - 0.2 * math.cos(3 * t)])

    @staticmethod
    def dexact(t):
        return np.array([-math.sin(t) + 0.6 * math.cos(2 * t), 0.5 * math.cos(t) + 0.6 * math.sin(3 * t)])

    @staticmethod
    def N(y):
        return np.array([0.5 * y[1] ** 2, -y[0] * y[1]])

    def rhs(self, t, y):
        ye = self.exact(t)
        return self.A @ y + self.dexact(t) - self.A @ ye - self.N(ye) + self.N(y)

    def linear_part(self):
        return self.A, "manufactured"


class Linear:
    """y' = A y + b; counts rhs calls."""

    def __init__(self, A, b=None, key="lin"):
        self.A = np.asarray(A, float)
        self.b = np.zeros(len(A)) if b is None else np.asarray(b, float)
        self.key = key
        self.calls = 0

    def rhs(self, t, y):
        self.calls += 1
        return self.A @ y + self.b

    def linear_part(self):
        return self.A, self.key

    def exact(self, t, y0):
        n = len(self.A)
        W = np.zeros((n + 1, n + 1))
        W[:n, :n] = self.A * t
        W[:n, n] = self.b * t
        E = scipy.linalg.expm(W)
        return E[:n, :n] @ y0 + E[:n, n]


class RhsOnly:
    """Hide linear_part/jacobian of another system."""

    def __init__(self, sys):
        self.rhs = sys.rhs


def gyro_2dof(w1, w2, m1=1.0, m2=2.0):
    """M ẍ + G ẋ + K x = 0, G skew, K SPD, undamped, with nutation w1 and precession w2 (rad/s).

    With K = diag(m1, m2)·w1·w2 and g = sqrt(m1 m2)(w1 − w2) the characteristic polynomial
    m1 m2 s⁴ + (m1 k2 + m2 k1 + g²) s² + k1 k2 has roots s² = −w1², −w2².
    Returns (A of the first-order system [x, ẋ], M, K).
    """
    M = np.diag([m1, m2])
    K = np.diag([m1, m2]) * w1 * w2
    g = math.sqrt(m1 * m2) * (w1 - w2)
    G = np.array([[0.0, g], [-g, 0.0]])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ G]])
    return A, M, K


def energy(y, M, K):
    x, v = y[:2], y[2:]
    return 0.5 * v @ M @ v + 0.5 * x @ K @ x


def rk4_amplification(z):
    """Stability function of classic RK4, R(z) = 1 + z + z²/2 + z³/6 + z⁴/24."""
    return 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24


def run(integ, system, y0, t_end, dt):
    """Consecutive advance calls of length dt (like the simulator's sample intervals)."""
    y, t, n_rhs, n = np.array(y0, float), 0.0, 0, int(round(t_end / dt))
    for k in range(n):
        t1 = (k + 1) * dt
        y, st = integ.advance(system, t, y, t1)
        n_rhs += st.n_rhs
        t = t1
    return y, n_rhs


# --------------------------------------------------------------------------- convergence order


@pytest.mark.parametrize("name,order,hs", [
    ("rk4", 4, (0.05, 0.025, 0.0125)),
    ("implicit_midpoint", 2, (0.05, 0.025, 0.0125)),
    ("etd2", 2, (0.05, 0.025, 0.0125)),
    ("etd4", 4, (0.05, 0.025, 0.0125)),
    ("exprb", 3, (0.05, 0.025, 0.0125)),
])
def test_convergence_order(name, order, hs):
    sys = Manufactured()
    T = 2.0
    errs = []
    for h in hs:
        integ = make_integrator(name, max_step=h, **LOOSE)
        y, st = integ.advance(sys, 0.0, sys.exact(0.0), T)
        assert st.n_steps == round(T / h)
        errs.append(np.abs(y - sys.exact(T)).max())
    ratios = [errs[i] / errs[i + 1] for i in range(len(errs) - 1)]
    assert integ.order == order
    # the last ratio is the most asymptotic; all must be within 15 % of 2^p
    assert ratios[-1] == pytest.approx(2.0 ** order, rel=0.15), ratios
    assert min(ratios) > 0.8 * 2.0 ** order, ratios


def test_etd4_order_at_least_3p5():
    """Krogstad's ETDRK4 reaches its classical order 4 on a non-stiff problem (≥ 3.5 asked)."""
    sys = Manufactured()
    e = []
    for h in (0.02, 0.01):
        y, _ = make_integrator("etd4", max_step=h, **LOOSE).advance(sys, 0.0, sys.exact(0.0), 1.0)
        e.append(np.abs(y - sys.exact(1.0)).max())
    assert math.log2(e[0] / e[1]) >= 3.5


# --------------------------------------------------------------------------- exactness of ETD


@pytest.mark.parametrize("name", ["etd2", "etd4"])
def test_etd_exact_for_linear_constant_input(name):
    """y' = A y + b with A a 4×4 undamped gyroscopic matrix, eigenvalues ±1e4 i, ±10 i, h = 5 ms
    (h·|λ| = 50): ETD is exact up to round-off."""
    A, _, _ = gyro_2dof(1e4, 10.0)
    lam = np.sort(np.abs(np.linalg.eigvals(A)))
    assert lam == pytest.approx([10, 10, 1e4, 1e4], rel=1e-9)
    assert np.abs(np.linalg.eigvals(A).real).max() < 1e-6
    sys = Linear(A, b=[0.0, 0.0, 0.3, -0.7])
    y0 = np.array([1e-3, -2e-3, 0.5, 0.2])
    h, n = 5e-3, 40
    integ = make_integrator(name, max_step=h)
    y, t = y0, 0.1                      # start away from t = 0 (time must not matter)
    for _ in range(n):
        y, st = integ.advance(sys, t, y, t + h)
        assert st.n_steps == 1
        t += h
    ye = sys.exact(n * h, y0)
    assert np.abs(y - ye).max() <= 1e-10 * np.abs(ye).max()


# --------------------------------------------------------------------------- stability at h·ω ≫ 1


class Oscillator:
    """x'' + ω² x = F sin t, state [x, v]; A = [[0, 1], [−ω², 0]], g = [0, F sin t]."""

    def __init__(self, w, F):
        self.w, self.F = w, F
        self.A = np.array([[0.0, 1.0], [-w * w, 0.0]])

    def rhs(self, t, y):
        return np.array([y[1], -self.w * self.w * y[0] + self.F * math.sin(t)])

    def linear_part(self):
        return self.A, ("osc", self.w)

    def exact(self, t, x0, v0):
        w, F = self.w, self.F
        C, D = x0, (v0 - F / (w * w - 1)) / w
        return np.array([C * math.cos(w * t) + D * math.sin(w * t) + F * math.sin(t) / (w * w - 1),
                         -C * w * math.sin(w * t) + D * w * math.cos(w * t) + F * math.cos(t) / (w * w - 1)])

    def amplitude(self, y):
        """sqrt(2E) in the energy norm: |(ω x, v)|."""
        return math.hypot(self.w * y[0], y[1])


def _oscillator_run(name, F, t_end=10.0, dt=1e-3, **tol):
    osc = Oscillator(1e4, F)
    x0, v0 = 1e-3, 0.0
    integ = make_integrator(name, max_step=dt, **tol)
    y, t = np.array([x0, v0]), 0.0
    max_state_err = max_amp_err = 0.0
    for k in range(int(round(t_end / dt))):
        t1 = (k + 1) * dt
        y, _ = integ.advance(osc, t, y, t1)
        t = t1
        ye = osc.exact(t, x0, v0)
        a = osc.amplitude(ye)
        max_state_err = max(max_state_err, math.hypot(osc.w * (y[0] - ye[0]), y[1] - ye[1]) / a)
        max_amp_err = max(max_amp_err, abs(osc.amplitude(y) - a) / a)
    return max_state_err, max_amp_err, osc


@pytest.mark.parametrize("name", ["etd2", "etd4"])
def test_exponential_stable_and_accurate_at_sample_period(name):
    """ω = 1e4 rad/s, h = 1 ms (h ω = 10), forcing sin t, 10 s: state (and amplitude) error < 1e-8."""
    state_err, amp_err, _ = _oscillator_run(name, F=1.0)
    assert amp_err < 1e-8
    assert state_err < 1e-8


def test_implicit_midpoint_keeps_amplitude_at_sample_period():
    """Unforced: the midpoint map is a Cayley transform, orthogonal in the energy norm, so the
    amplitude is kept to round-off over 1e4 steps although the phase is wrong (2·atan(5) per
    step instead of 10 rad)."""
    state_err, amp_err, _ = _oscillator_run("implicit_midpoint", F=0.0, **LOOSE)
    assert amp_err < 1e-12
    assert state_err > 0.1             # phase is wrong at h ω = 10: that is expected
    # forced: stays bounded. The free part keeps its norm ω x0 = 10 exactly; the quasi-static
    # forced response (numerical and exact) is ≈ F/ω = 1e-4 in the energy norm, so the
    # amplitudes differ by at most ≈ 2 F/ω (asserted with 50 % slack)
    _, amp_err, osc = _oscillator_run("implicit_midpoint", F=1.0, **LOOSE)
    assert amp_err < 3 * (1.0 / osc.w) / (osc.w * 1e-3)


def test_rk4_unstable_at_sample_period():
    """RK4 at h ω = 10 amplifies the energy norm by |R(10i)| ≈ 400 per step (the bare map,
    loose tolerance); within 10 s it overflows and the integrator raises instead of returning
    inf/NaN."""
    osc = Oscillator(1e4, F=0.0)
    y0 = np.array([1e-3, 0.0])
    integ = make_integrator("rk4", max_step=1e-3, rtol=1e30, atol=1e30)
    y, t = y0, 0.0
    for k in range(3):
        y, _ = integ.advance(osc, t, y, t + 1e-3)
        t += 1e-3
    growth = osc.amplitude(y) / osc.amplitude(y0)
    expected = abs(rk4_amplification(10j)) ** 3
    assert growth > 1e6
    assert growth == pytest.approx(expected, rel=1e-9)
    with np.errstate(all="ignore"), pytest.raises(SimulationError, match="non-finite"):
        run(integ, osc, y0, 10.0, 1e-3)


def test_rk4_held_to_tolerance_substeps_to_stability_and_accuracy():
    """The same oscillator (h ω = 10 at the sample period) with rtol 1e-8: the embedded
    estimate sees the instability and the controller substeps until the local error meets the
    tolerance: the result is accurate. With a budget of one substep it refuses instead, naming
    the method and the tolerance, and the caller's state is untouched."""
    osc = Oscillator(1e4, F=1.0)
    x0, v0 = 1e-3, 0.0
    integ = make_integrator("rk4", max_step=1e-3, rtol=1e-8, atol=1e-12)
    y, t = np.array([x0, v0]), 0.0
    for k in range(20):
        y, st = integ.advance(osc, t, y, t + 1e-3)
        t += 1e-3
        assert st.error_norm <= 1.0 and st.n_steps >= 10 * 1e-3 * osc.w / 2.8
    ye = osc.exact(t, x0, v0)
    assert math.hypot(osc.w * (y[0] - ye[0]), y[1] - ye[1]) < 1e-5 * osc.amplitude(ye)
    tight = make_integrator("rk4", max_step=1e-3, rtol=1e-8, atol=1e-12, max_substeps=1)
    y0 = np.array([x0, v0])
    with pytest.raises(ToleranceError, match=r"rk4 cannot meet the tolerance at t=0\.0 s.*rtol=1e-08, atol=1e-12"):
        tight.advance(osc, 0.0, y0, 1e-3)
    assert np.array_equal(y0, [x0, v0])


def test_a_non_finite_state_is_named_not_quoted_as_an_infinite_ratio():
    """A system that returns NaN: the refusal says the state is non-finite (it said "error
    estimate 0 (inf× the tolerance …)", found by an audit)."""
    class Nan(Oscillator):
        def rhs(self, t, y):
            return np.full_like(y, np.nan)

    integ = make_integrator("rk4", max_step=1e-3, rtol=1e-8, atol=1e-12, max_substeps=4)
    with pytest.raises(ToleranceError) as e:
        integ.advance(Nan(1e2, 1.0), 0.0, np.array([1.0, 0.0]), 1e-3)
    assert "is non-finite" in str(e.value) and "inf×" not in str(e.value) and "error estimate" not in str(e.value)


# --------------------------------------------------------------------------- quadratic invariants


def test_implicit_midpoint_keeps_gyroscopic_energy():
    """M ẍ + G ẋ + K x = 0 (G skew, K SPD), 1e5 steps: E = ½ẋᵀMẋ + ½xᵀKx kept to 1e-11."""
    A, M, K = gyro_2dof(50.0, 3.0)
    sys = Linear(A)
    y0 = np.array([0.01, -0.02, 0.3, 0.1])
    integ = make_integrator("implicit_midpoint", max_step=1e-3, **LOOSE)
    y, _ = run(integ, sys, y0, 100.0, 1e-2)          # 1e4 calls × 10 substeps × 2 half steps
    E0 = energy(y0, M, K)
    assert abs(energy(y, M, K) - E0) <= 1e-11 * E0


def test_rk4_energy_drift_matches_theory_and_exceeds_midpoint():
    """For a linear system RK4 multiplies the energy of mode k by |R(i h ω_k)|² per step
    (modes are orthogonal in the energy inner product), so E_N = Σ E_k |R(i h ω_k)|^{2N}."""
    w1, w2, h, N = 50.0, 3.0, 1e-3, 100_000
    A, M, K = gyro_2dof(w1, w2)
    y0 = np.array([0.01, -0.02, 0.3, 0.1])
    # modal decomposition of y0: y0 = V c, mode k's real part is 2 Re(c_k v_k) for Im λ_k > 0
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, y0)
    E_pred = 0.0
    for k in np.nonzero(lam.imag > 0)[0]:
        yk = 2 * np.real(c[k] * V[:, k])
        E_pred += energy(yk, M, K) * abs(rk4_amplification(1j * h * lam[k].imag)) ** (2 * N)
    E0 = energy(y0, M, K)
    assert w1 * h < 2.8                                # RK4 is stable here
    y_rk4, _ = make_integrator("rk4", max_step=h, **LOOSE).advance(Linear(A), 0.0, y0, N * h)
    y_mid, _ = make_integrator("implicit_midpoint", max_step=h, **LOOSE).advance(Linear(A), 0.0, y0, N * h)
    drift_rk4 = abs(energy(y_rk4, M, K) - E0) / E0
    drift_mid = abs(energy(y_mid, M, K) - E0) / E0
    assert drift_rk4 == pytest.approx(abs(E_pred - E0) / E0, rel=1e-3)
    assert drift_rk4 > 1e-6                            # ≈ N (h w1)^6 / 72 · (share of mode 1)
    assert drift_mid < 1e-3 * drift_rk4


class RigidBody:
    """Euler's equations I ω̇ = (I ω) × ω: |Iω|² and ωᵀIω are quadratic invariants."""

    I = np.array([1.0, 2.0, 3.5])

    def __init__(self, with_jacobian):
        if with_jacobian:
            self.jacobian = self._jacobian

    def rhs(self, t, w):
        L = self.I * w
        return np.cross(L, w) / self.I

    def _jacobian(self, t, w):
        I1, I2, I3 = self.I
        a, b, c = (I2 - I3) / I1, (I3 - I1) / I2, (I1 - I2) / I3
        return np.array([[0, a * w[2], a * w[1]], [b * w[2], 0, b * w[0]], [c * w[1], c * w[0], 0]])


@pytest.mark.parametrize("with_jacobian", [True, False])
def test_implicit_midpoint_nonlinear_quadratic_invariants(with_jacobian):
    """Nonlinear case (exact Jacobian, or finite differences when none is given). Newton is
    iterated to round-off, so over 1000 steps the invariants may drift by ~1000 × a few eps
    at most, not by the 1e-14-per-step a looser Newton tolerance would give."""
    body = RigidBody(with_jacobian)
    w0 = np.array([0.3, 1.0, -0.4])
    integ = make_integrator("implicit_midpoint", max_step=0.01, **LOOSE)
    w, t = w0, 0.0
    for k in range(200):
        w, st = integ.advance(body, t, w, t + 0.05)
        t += 0.05
        assert st.n_rejected == 0
        if not with_jacobian:
            assert st.n_rhs >= 3 + st.n_steps      # FD Jacobian costs n = 3 calls per advance
    I = body.I
    assert np.sum((I * w) ** 2) == pytest.approx(np.sum((I * w0) ** 2), rel=1e-12)
    assert np.sum(I * w * w) == pytest.approx(np.sum(I * w0 * w0), rel=1e-12)


def test_implicit_midpoint_halves_step_when_newton_fails():
    """With a useless Newton matrix (A = 0 → fixed-point iteration, contraction h/2·λ) the
    iteration diverges at h λ = 3; the interval is redone with finer substeps until it
    converges, reported in the stats (``n_rejected``)."""
    lam = 3000.0

    class Decay:
        def rhs(self, t, y):
            return -lam * y

        def linear_part(self):
            return np.zeros((1, 1)), "zero"

    integ = make_integrator("implicit_midpoint", max_step=1e-3, **LOOSE)
    y, st = integ.advance(Decay(), 0.0, np.array([1.0]), 1e-3)
    assert st.n_rejected >= 1 and st.level >= 1
    # the result is the midpoint rule at the refined step (each substep kept as two half
    # steps): R(z) = (1 + z/2)/(1 − z/2), z = −λh, h = 1 ms / (2 n_steps)
    h = 1e-3 / (2 * st.n_steps)
    R = (1 - lam * h / 2) / (1 + lam * h / 2)
    assert y[0] == pytest.approx(R ** (2 * st.n_steps), rel=1e-12)


# --------------------------------------------------------------------------- adaptive methods


def test_dop853_warm_start_accuracy_and_work():
    """Oscillator at the nutation rate (800 rad/s), 1000 calls of 1 ms, rtol 1e-10.

    Each call needs at most the steps of an uninterrupted run over the same interval plus one
    step cut short at t1, so n_rhs ≤ calls·1 (initial f) + 12·(N_continuous + calls)."""
    w = 800.0
    sys = Linear([[0.0, w], [-w, 0.0]])

    def exact(t):
        return np.array([math.cos(w * t), -math.sin(w * t)])
    integ = make_integrator("dop853", rtol=1e-10, atol=1e-12)
    assert integ.adaptive and integ.order == 8
    y, t, total, err = exact(0.0), 0.0, 0, 0.0
    calls, dt = 1000, 1e-3
    for k in range(calls):
        y, st = integ.advance(sys, t, y, (k + 1) * dt)
        t = (k + 1) * dt
        total += st.n_rhs
        err = max(err, np.abs(y - exact(t)).max())
        assert 0.0 <= st.error_estimate < 1e-9            # accepted: of order rtol·|y| = 1e-10
    assert err < 1e-8
    solver = scipy.integrate.DOP853(sys.rhs, 0.0, exact(0.0), calls * dt, rtol=1e-10, atol=1e-12)
    n_cont = 0
    while solver.status == "running":
        solver.step()
        n_cont += 1
    assert total <= calls + 12 * (n_cont + calls)
    # cold start each call (reset) costs more: initial-step selection and ramp-up every time
    cold = make_integrator("dop853", rtol=1e-10, atol=1e-12)
    y, t, total_cold = exact(0.0), 0.0, 0
    for k in range(calls):
        cold.reset()
        y, st = cold.advance(sys, t, y, (k + 1) * dt)
        t = (k + 1) * dt
        total_cold += st.n_rhs
    assert total < total_cold


def test_dop853_one_step_per_call_when_the_natural_step_is_longer():
    """Smooth slow problem: once warm, each 1 ms call is one DOP853 step = 12 rhs + 1 initial f
    (bound from the brief: < 3 × 12 per call)."""
    sys = Manufactured()
    integ = make_integrator("dop853", rtol=1e-10, atol=1e-12)
    y, t, total = sys.exact(0.0), 0.0, 0
    for k in range(500):
        y, st = integ.advance(sys, t, y, (k + 1) * 1e-3)
        t = (k + 1) * 1e-3
        if k > 0:
            assert st.n_steps == 1 and st.n_rhs == 13
        total += st.n_rhs
    assert total < 3 * 500 * 12
    assert np.abs(y - sys.exact(t)).max() < 1e-8


def test_reset_forgets_warm_start():
    sys = Manufactured()
    y0 = sys.exact(0.0)
    fresh = make_integrator("dop853", rtol=1e-10, atol=1e-12)
    y_fresh, st_fresh = fresh.advance(sys, 0.0, y0, 1e-3)
    integ = make_integrator("dop853", rtol=1e-10, atol=1e-12)
    for k in range(10):
        integ.advance(sys, k * 1e-3, y0, (k + 1) * 1e-3)
    _, st_warm = integ.advance(sys, 0.0, y0, 1e-3)
    integ.reset()
    y_reset, st_reset = integ.advance(sys, 0.0, y0, 1e-3)
    assert st_warm.n_rhs < st_fresh.n_rhs                 # warm: no initial-step selection
    assert st_reset.n_rhs == st_fresh.n_rhs
    assert np.array_equal(y_reset, y_fresh)


@pytest.mark.parametrize("name", ["rk45", "radau"])
def test_other_adaptive_methods_accurate(name):
    sys = Manufactured()
    integ = make_integrator(name, rtol=1e-10, atol=1e-12)
    y, _ = run(integ, sys, sys.exact(0.0), 0.2, 1e-3)
    assert np.abs(y - sys.exact(0.2)).max() < 1e-8


def test_radau_handles_stiff_decay_with_linear_part_jacobian():
    """y' = −λ (y − cos t) − sin t, λ = 1e5, exact y = cos t. An explicit method needs
    h ≲ 3.3/λ (≥ 30 steps per ms); Radau, with A = −λ as Jacobian, needs about one."""
    lam = 1e5

    class Stiff:
        calls = 0

        def rhs(self, t, y):
            Stiff.calls += 1
            return -lam * (y - math.cos(t)) - math.sin(t)

        def linear_part(self):
            return np.array([[-lam]]), "stiff"

    y, n_radau = run(make_integrator("radau", rtol=1e-8, atol=1e-12), Stiff(), [1.0], 0.05, 1e-3)
    assert abs(y[0] - math.cos(0.05)) < 1e-8
    _, n_rk45 = run(make_integrator("rk45", rtol=1e-8, atol=1e-12), Stiff(), [1.0], 0.05, 1e-3)
    # RK45's stability interval on the negative real axis is about [-3.3, 0]: ≥ λT/3.4 steps
    assert n_rk45 >= 6 * lam * 0.05 / 3.4
    assert n_radau < n_rk45 / 10


# --------------------------------------------------------------------------- contract


@pytest.mark.parametrize("name", ALL)
def test_attributes_and_stats(name):
    integ = make_integrator(name)
    assert isinstance(integ, Integrator)
    assert integ.name == name and integ.order >= 2
    assert integ.adaptive                           # every method is held to rtol/atol
    sys = Manufactured()
    y, st = integ.advance(sys, 0.0, sys.exact(0.0), 2.5e-3)
    assert isinstance(st, StepStats) and st.n_steps >= 1 and st.n_rhs >= st.n_steps
    assert st.error_estimate >= 0.0 and st.error_norm <= 1.0      # achieved accuracy is reported
    if name in FIXED:
        assert st.n_steps % 3 == 0                   # ceil(2.5 ms / 1 ms) · 2^level


@pytest.mark.parametrize("name", ALL)
def test_does_not_modify_y0(name):
    sys = Manufactured()
    y0 = sys.exact(0.0)
    keep = y0.copy()
    y1, _ = make_integrator(name).advance(sys, 0.0, y0, 5e-3)
    assert np.array_equal(y0, keep)
    assert y1 is not y0 and not np.shares_memory(y1, y0)


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("t1", [0.0, -1e-3, math.nan])
def test_bad_interval_raises(name, t1):
    sys = Manufactured()
    with pytest.raises(ValueError):
        make_integrator(name).advance(sys, 0.0, sys.exact(0.0), t1)


@pytest.mark.parametrize("name", ALL)
def test_non_finite_raises_simulation_error(name):
    class Bad(Manufactured):
        def rhs(self, t, y):
            out = super().rhs(t, y)
            if t > 1.5e-3:
                out[0] = math.nan
            return out

    sys = Bad()
    with np.errstate(all="ignore"), pytest.raises(SimulationError, match="non-finite|failed"):
        run(make_integrator(name), sys, sys.exact(0.0), 5e-3, 1e-3)


def test_unknown_name_lists_known():
    with pytest.raises(ValueError) as e:
        make_integrator("euler")
    for name in INTEGRATORS:
        assert name in str(e.value)


@pytest.mark.parametrize("name", ["etd2", "etd4"])
def test_etd_needs_linear_part(name):
    with pytest.raises(TypeError, match=name):
        make_integrator(name).advance(RhsOnly(Manufactured()), 0.0, np.zeros(2), 1e-3)


def test_interval_of_max_step_plus_roundoff_is_one_substep():
    """t1 − t0 for float sample times is max_step ± a few ulp; that must not give 2 substeps."""
    t0 = 3600.0
    t1 = t0 + 1e-3
    assert (t1 - t0) / 1e-3 > 1.0                     # round-off makes it slightly above 1 here
    _, st = make_integrator("rk4", max_step=1e-3, **LOOSE).advance(Manufactured(), t0, np.ones(2), t1)
    assert st.n_steps == 1


@pytest.mark.parametrize("name,n_expm", [("etd2", 1), ("etd4", 2)])
def test_etd_caches_expm_by_key_and_h(monkeypatch, name, n_expm):
    calls = []
    real = scipy.linalg.expm
    monkeypatch.setattr(scipy.linalg, "expm", lambda M: calls.append(1) or real(M))
    A, _, _ = gyro_2dof(800.0, 1.0)
    sys = Linear(A)
    integ = make_integrator(name, max_step=1e-3)
    y = np.ones(4)
    for _ in range(50):                                # same interval: one expm set in all
        y, _ = integ.advance(sys, 0.0, y, 1e-3)
    assert len(calls) == n_expm
    # sample times k·dt: t1 − t0 takes a few ulp-different values; they all round to the same
    # grid step (the sub-grid remainder is carried, so the clock does not drift): one expm set
    n_h = len({(k + 1) * 1e-3 - k * 1e-3 for k in range(100)})
    assert 1 < n_h < 16
    run(integ, sys, np.ones(4), 0.1, 1e-3)
    assert len(calls) == n_expm
    calls.clear()
    sys.key = "other"                                  # a new key means a new A
    integ.advance(sys, 0.0, np.ones(4), 1e-3)
    integ.advance(sys, 0.0, np.ones(4), 1e-3)
    assert len(calls) == n_expm
    integ.reset()
    integ.advance(sys, 0.0, np.ones(4), 1e-3)
    assert len(calls) == 2 * n_expm


def test_implicit_midpoint_uses_jacobian_when_given():
    class WithJac(Manufactured):
        njac = 0

        def jacobian(self, t, y):
            WithJac.njac += 1
            J = self.A.copy()
            J += np.array([[0.0, y[1]], [-y[1], -y[0]]])
            return J

    sys = WithJac()
    make_integrator("implicit_midpoint", max_step=1e-3).advance(sys, 0.0, sys.exact(0.0), 5e-3)
    assert WithJac.njac == 1                            # once per advance call


@pytest.mark.parametrize("name", ["etd2", "etd4"])
def test_etd_jittered_samples_reuse_grid_matrices_and_end_exactly(monkeypatch, name):
    """Real sample times jitter: the steps are whole grid steps max_step/256 (a bounded set of
    matrices serves every step) and a last short step (φ-functions by Taylor series, no new
    expm) ends every interval exactly at t1: with a forcing that ramps in time (like the
    input between two samples) the state equals the exact solution at the sample time, also
    after intervals shorter than one grid step. (The grid with the remainder carried to the next
    interval lagged by up to half a grid step: 1e-3 off here.)"""
    calls = []
    real = scipy.linalg.expm
    monkeypatch.setattr(scipy.linalg, "expm", lambda M: calls.append(1) or real(M))
    A, _, _ = gyro_2dof(800.0, 1.0)
    b0, b1 = np.array([0.3, -0.2, 1.0, 0.5]), np.array([0.0, 0.0, 40.0, -25.0])

    class Ramp(Linear):
        def rhs(self, t, y):
            return self.A @ y + b0 + b1 * t

    sys = Ramp(A)
    integ = make_integrator(name, max_step=1e-3)
    rng = np.random.default_rng(7)
    t, y0 = 0.0, np.ones(4)
    y = y0.copy()
    for k in range(2000):
        dt = 2e-6 if k % 100 == 50 else 1e-3 * (1 + 0.2 * rng.uniform(-1, 1))
        y, st = integ.advance(sys, t, y, t + dt)
        assert st.error_norm <= 1.0
        t += dt
    n_sets = len(calls) // (1 if name == "etd2" else 2)
    # ±20 % jitter: one-chunk steps span ≤ 0.2·256 grid values, two-chunk ones ≤ 0.1·256 + 1
    assert n_sets <= 0.3 * 256 + 4
    Z = np.zeros((6, 6))                      # [y, τ, 1]: τ' = 1, y' = A y + b0 + b1 τ
    Z[:4, :4], Z[:4, 4], Z[:4, 5], Z[4, 5] = A, b1, b0, 1.0
    exact = (scipy.linalg.expm(Z * t) @ np.concatenate([y0, [0.0, 1.0]]))[:4]
    np.testing.assert_allclose(y, exact, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", ["etd2", "etd4"])
@pytest.mark.parametrize("w", [2e6, 5e7])
def test_etd_last_short_step_exact_for_fast_rotation(name, w):
    """The last short step integrates the linear part exactly however fast it turns: at
    ω·r = 6 its Taylor series converges; at ω·r = 150 it does not within TAYLOR_MAX terms and
    the step is split (a rejection) until it does. Amplitude and phase stay exact."""
    A = np.array([[0.0, w], [-w, 0.0]])
    integ = make_integrator(name, max_step=1e-3)
    dt = 1e-3 + 3e-6
    y, st = integ.advance(Linear(A), 0.0, np.array([1.0, 0.0]), dt)
    np.testing.assert_allclose(y, [math.cos(w * dt), -math.sin(w * dt)], rtol=0, atol=1e-9)
    assert st.n_steps >= 2 and st.error_norm <= 1.0
    assert (st.n_rejected > 0) == (w > 1e7)
