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

"""Engine against the test oracles of shared/spec/PHYSICS.md section 12 (NAV-1 parameters)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.simulator import Simulator
from gyro_platform.errors import GimbalLockError, PrecessionInvalidError
from gyro_platform.physics.model import GIMBAL_AXES, rest_matrices
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.physics.system import PlatformSystem
from gyro_platform.physics.tree import tree_inverse_dynamics, TreeWork

L = NAV1.L[0]
J = NAV1.lumped()
UNIT_A = [0, 1, 2]
UNIT_B = [3, 4]


def carried(fidelity="full", effects=("rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration"),
            params=NAV1, **kw):
    return PlatformSystem(params, ModelOptions.make("carried", fidelity, effects, **kw))


def gimbal_jacobian(sys_, Om, q0=np.zeros(5)):
    """Jacobian of (q, q̇) ↦ (q̇, q̈) at q0, q̇ = 0, constant vehicle rate Om (carried)."""
    sys_.set_input(0.0, 1.0, Om, Om)
    y0 = sys_.rest_state()
    y0[0:5] = q0
    n = 10
    A = np.zeros((n, n))
    for j in range(n):
        h = 1e-7
        yp, ym = y0.copy(), y0.copy()
        yp[j] += h
        ym[j] -= h
        A[:, j] = (sys_.rhs(0.0, yp)[:10] - sys_.rhs(0.0, ym)[:10]) / (2 * h)
    return A


def sub_eigs(A, keep):
    idx = list(keep) + [5 + k for k in keep]
    return np.linalg.eigvals(A[np.ix_(idx, idx)])


def nonzero(ev, tol=1e-6):
    return ev[np.abs(ev) > tol]


# ---- matrices and nutation (O1) ---------------------------------------------------------

def test_lumped_moments_match_spec():
    expect = {"J4": 1.84e-4, "J5": 4.2e-5, "J7": 4.2e-5, "J9": 1.02e-4, "J10": 4.2e-5, "Jx4": 2.30e-4, "Jz4": 2.34e-4,
              "Jx9": 1.22e-4, "Jy9": 1.20e-4}
    for k, v in expect.items():
        assert J[k] == pytest.approx(v, rel=1e-12), k


def test_rest_matrices_are_spec_M0_G0():
    M0, G0 = rest_matrices(NAV1)
    J1, J2, J3 = 0.080312, 0.090284, 0.100336
    C = 2e-5
    M = np.zeros((8, 8))
    M[0, 0], M[1, 1], M[2, 2] = J1 + 2 * C, J2 + C, J3
    M[0, 1] = M[1, 0] = 1e-3
    M[0, 2] = M[2, 0] = -5e-4
    M[1, 2] = M[2, 1] = 8e-4
    for k, (r, val) in enumerate([(1, J["J4"]), (2, J["J5"]), (2, -J["J7"]), (2, J["J9"]), (0, J["J10"])]):
        M[3 + k, 3 + k] = abs(val) if k != 2 else J["J7"]
        M[r, 3 + k] = M[3 + k, r] = val
    np.testing.assert_allclose(M0, M, rtol=1e-12, atol=1e-18)
    G = np.zeros((8, 8))
    G[0, 2] = G[0, 6] = -L
    G[1, 4] = G[1, 5] = L
    G[2, 0] = G[2, 7] = L
    G[3, 4] = G[3, 5] = L
    G[4, 1] = G[4, 3] = -L
    G[5, 1] = G[5, 3] = -L
    G[6, 0] = G[6, 7] = L
    G[7, 2] = G[7, 6] = -L
    np.testing.assert_allclose(G0, G, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(G0, -G0.T, atol=1e-15)


def test_O1e_free_platform_nutation_eigenvalues():
    M0, G0 = rest_matrices(NAV1)
    A = np.zeros((16, 16))
    A[:8, 8:] = np.eye(8)
    A[8:, 8:] = -np.linalg.solve(M0, G0)
    ev = np.linalg.eigvals(A)
    nz = np.sort(np.abs(nonzero(ev, 1e-3).imag))
    np.testing.assert_allclose(nz, [767.9715, 767.9715, 808.6327, 808.6327], rtol=1e-7)
    assert np.max(np.abs(nonzero(ev, 1e-3).real)) < 1e-8
    assert np.sum(np.abs(ev) < 1e-6) == 12


@pytest.mark.parametrize("fidelity", ["linear", "full"])
def test_O1abc_nutation_frequencies(fidelity):
    A = gimbal_jacobian(carried(fidelity), np.zeros(3))
    eb = np.abs(nonzero(sub_eigs(A, UNIT_B)).imag)
    ea = np.abs(nonzero(sub_eigs(A, UNIT_A)).imag)
    ec = np.abs(nonzero(sub_eigs(A, [0, 1])).imag)   # β7 caged
    np.testing.assert_allclose(eb, 767.9715, rtol=1e-7)
    np.testing.assert_allclose(ea, 808.6327, rtol=1e-7)
    np.testing.assert_allclose(ec, 571.7897, rtol=1e-7)
    assert np.sum(np.abs(sub_eigs(A, UNIT_A)) < 1e-6) == 4   # s⁴ factor of O1 b


# ---- precession under constant torque (O2) ------------------------------------------------

def test_O2_step_torque_exact_solution_linear_and_full():
    Q10 = 1e-4
    p = NAV1.with_(bias_torque=(0, 0, 0, 0, Q10))
    wn = L / math.sqrt(J["J9"] * J["J10"])
    t = np.linspace(0, 0.05, 201)
    exact_a9 = -(Q10 / L) * (t - np.sin(wn * t) / wn)
    exact_b10 = Q10 * J["J9"] / L**2 * (1 - np.cos(wn * t))
    for fid, eff, tol in (("linear", ("rotor_gyroscopic", "bias_torque"), 1e-13),
                          ("full", ("rotor_gyroscopic", "coriolis", "bias_torque"), 1e-12)):
        s = carried(fid, eff, params=p)
        s.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
        sol = solve_ivp(s.rhs, (0, 0.05), s.rest_state(), method="DOP853", rtol=1e-12, atol=1e-16, t_eval=t)
        assert np.max(np.abs(sol.y[3] - exact_a9)) < tol, fid
        assert np.max(np.abs(sol.y[4] - exact_b10)) < tol, fid
    assert np.max(exact_b10) == pytest.approx(8.074032e-6, rel=1e-6)
    assert -Q10 / L == pytest.approx(-1.9894368e-3, rel=1e-7)


def test_O2_steady_precession_at_tilt_is_exact_equilibrium():
    Q10, beta = 1e-4, math.radians(60)
    p = NAV1.with_(bias_torque=(0, 0, 0, 0, Q10))
    s = carried("full", ("rotor_gyroscopic", "coriolis", "bias_torque"), params=p)
    s.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))

    def accel(w):
        y = s.rest_state()
        y[4] = beta
        y[3] = 0.3
        y[5 + 3] = w
        return s.rhs(0.0, y)[5:10]

    w_exact = -3.978873032e-3
    assert np.max(np.abs(accel(w_exact))) < 1e-8
    assert abs(accel(-3.978873577e-3)[4]) > 1e-7   # the leading-order rate is measurably off


# ---- gyroscopic restraint (O3) -------------------------------------------------------------

def test_O3a_single_axis_restraint_stable_and_unstable():
    for Om2, kind in ((0.1, "osc"), (-0.1, "grow")):
        A = gimbal_jacobian(carried("linear", ("rotor_gyroscopic",)), np.array([0.0, Om2, 0.0]))
        ev = sub_eigs(A, [4])
        if kind == "osc":
            np.testing.assert_allclose(np.abs(ev.imag), 10.93982, rtol=1e-6)
            assert np.max(np.abs(ev.real)) < 1e-9
        else:
            np.testing.assert_allclose(np.sort(ev.real), [-10.93982, 10.93982], rtol=1e-6)


@pytest.mark.parametrize("coriolis,Om2,expect", [
    (False, 0.1, [0.09998568, 768.0815]), (False, -0.1, [0.10001433, 767.8615]),
    (True, 0.1, [0.09999403, 768.0143]), (True, -0.1, [0.10000597, 767.9288])])
def test_O3b_unit_B_roots_paper_and_exact_linearisation(coriolis, Om2, expect):
    eff = ("rotor_gyroscopic", "coriolis") if coriolis else ("rotor_gyroscopic",)
    A = gimbal_jacobian(carried("linear", eff), np.array([0.0, Om2, 0.0]))
    ev = sub_eigs(A, UNIT_B)
    assert np.max(np.abs(ev.real)) < 1e-7
    np.testing.assert_allclose(np.sort(np.abs(ev.imag))[[0, 2]], expect, rtol=2e-7)


def test_O3c_twin_gyro_instability_rate_tells_fidelities_apart():
    Om = np.array([0.1, 0.0, 0.0])
    ev62 = sub_eigs(gimbal_jacobian(carried("linear", ("rotor_gyroscopic",)), Om), UNIT_A)
    assert np.max(ev62.real) == pytest.approx(0.1480026, rel=1e-6)
    for fid in ("linear", "full"):
        ev61 = sub_eigs(gimbal_jacobian(carried(fid, ("rotor_gyroscopic", "coriolis")), Om), UNIT_A)
        slow = ev61[np.abs(ev61) < 1.0]
        np.testing.assert_allclose(np.sort(np.abs(slow.real)), [0.03805565] * 4, rtol=1e-5)
        np.testing.assert_allclose(np.sort(np.abs(slow.imag)), [0.02709145] * 4, rtol=1e-5)


# ---- rate gyro (O4) -------------------------------------------------------------------------

def _equilibrium(fid, Om, keep):
    s = carried(fid, ("rotor_gyroscopic", "coriolis", "gimbal_springs"))
    s.set_input(0.0, 1.0, Om, Om)

    def res(x):
        y = s.rest_state()
        y[keep] = x
        return s.rhs(0.0, y)[5:10][keep]

    return fsolve(res, np.zeros(len(keep)), xtol=1e-14)


def test_O4a_rate_gyro_single_axis():
    b = _equilibrium("full", np.array([0.0, 0.1, 0.0]), [1])
    assert b[0] == pytest.approx(0.010052588, abs=2e-10)
    b = _equilibrium("full", np.array([0.05, 0.1, 0.0]), [1])
    assert b[0] == pytest.approx(0.010002297, abs=2e-10)
    assert math.sqrt(0.5 / J["J5"]) == pytest.approx(109.109, rel=1e-5)


def test_O4b_all_gimbals_linear_and_nonlinear_equilibria():
    Om = np.array([0.05, 0.1, -0.08])
    lin = _equilibrium("linear", Om, [0, 1, 2, 3, 4])
    nl = _equilibrium("full", Om, [0, 1, 2, 3, 4])
    # linear (27) values: the paper model (coriolis off) gives the printed closed forms
    s = carried("linear", ("rotor_gyroscopic", "gimbal_springs"))
    s.set_input(0.0, 1.0, Om, Om)
    # start from the closed forms of (27) (O4 b) so that the solver converges cleanly
    closed = np.array([0.0, L * Om[1] / (0.5 + L * Om[0]), L * Om[1] / (0.5 - L * Om[0]),
                       -L * Om[0] / (0.5 + L * Om[1]), L * Om[2] / (0.5 + L * Om[1])])
    lin27 = fsolve(lambda x: s.rhs(0.0, np.concatenate([x, np.zeros(5), s.rest_state()[10:]]))[5:10],
                   closed, xtol=1e-14)
    np.testing.assert_allclose(lin27, [0.0, 0.010002817, 0.010103884, -0.004976519, -0.007962430], atol=2e-9)
    np.testing.assert_allclose(nl, [-2.38e-8, 0.010002297, 0.010103387, -0.004976281, -0.007961951], atol=2e-9)
    assert np.max(np.abs(lin - nl)) < 1e-5          # 6.1 and the exact model agree to 2nd order
    assert np.max(np.abs(lin - nl)) < np.max(np.abs(lin27 - nl))


# ---- decoupling (O5) -------------------------------------------------------------------------

def test_O5_units_decouple_exactly_in_the_nonlinear_model():
    rng = np.random.default_rng(5)
    s = carried("full")
    for _ in range(5):
        Om0, Om1 = rng.normal(size=3), rng.normal(size=3)
        s.set_input(0.0, 1.0, Om0, Om1)
        y = s.rest_state()
        y[:10] = rng.normal(size=10)
        a = s.rhs(0.3, y)[5:10].copy()
        y2 = y.copy()
        y2[[3, 4, 8, 9]] = rng.normal(size=4)     # change unit B only
        a2 = s.rhs(0.3, y2)[5:10]
        assert np.max(np.abs(a2[UNIT_A] - a[UNIT_A])) <= 1e-12 * np.max(np.abs(a))
        y3 = y.copy()
        y3[[0, 1, 2, 5, 6, 7]] = rng.normal(size=6)  # change unit A only
        a3 = s.rhs(0.3, y3)[5:10]
        assert np.max(np.abs(a3[UNIT_B] - a[UNIT_B])) <= 1e-12 * np.max(np.abs(a))


# ---- free gyros keep their direction (O6) ---------------------------------------------------

@pytest.mark.parametrize("Om,j,T", [((0, 0.5, 0), 0, 6.0), ((0.7, 0, 0), 4, 4.0), ((0, 0, 0.4), 3, 4.0)])
def test_O6_free_gyro_large_angles(Om, j, T):
    opt = ModelOptions.make("carried", "full", integrator="dop853", rtol=1e-11, atol=1e-13)
    sim = Simulator(NAV1, opt)
    rate = -np.max(np.abs(Om)) * np.sign(np.sum(Om))
    err = 0.0
    for k in range(int(T / 0.01) + 1):
        sim.push(RateSample.of(k * 0.01, Om))
        q = sim.y[0:5]
        expect = np.zeros(5)
        expect[j] = rate * k * 0.01
        if j == 3:                       # α9 and β5 = −θ3, β7 = +θ3 all turn under Ω3
            expect[1], expect[2] = rate * k * 0.01, -rate * k * 0.01
        err = max(err, np.max(np.abs(q - expect)))
    assert abs(rate * T) > math.pi / 2        # large angles: through 90°
    assert err < 1e-8


# ---- gimbal lock (O7) ----------------------------------------------------------------------

@pytest.mark.parametrize("deg,wn", [(0, 767.9715), (30, 666.7190), (60, 386.8407), (80, 134.6432), (89, 13.5363)])
def test_O7a_nutation_frequency_falls_to_zero_at_lock(deg, wn):
    q0 = np.zeros(5)
    q0[4] = math.radians(deg)
    A = gimbal_jacobian(carried("full"), np.zeros(3), q0)
    ev = nonzero(sub_eigs(A, UNIT_B))
    np.testing.assert_allclose(np.abs(ev.imag), wn, rtol=2e-6)


def test_O7b_precession_model_reaches_lock_and_full_model_follows():
    tau = 0.02
    p = NAV1.with_(bias_torque=(0, 0, 0, tau, 0))
    sp = carried("precession", ("rotor_gyroscopic", "bias_torque"), params=p)
    sp.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
    t_star = L / tau
    assert t_star == pytest.approx(2.513274, rel=1e-6)
    sol = solve_ivp(sp.rhs, (0, 0.98 * t_star), sp.rest_state(), method="DOP853", rtol=1e-11, atol=1e-13,
                    dense_output=True)
    tt = np.linspace(0, 0.98 * t_star, 50)
    np.testing.assert_allclose(np.sin(sol.sol(tt)[4]), tau * tt / L, atol=1e-9)
    y_lock = sp.rest_state()
    y_lock[4] = math.pi / 2 - 1e-4
    with pytest.raises(GimbalLockError, match="gimbal lock"):
        sp.rhs(0.0, y_lock)
    # the full model (massive gimbals) follows the precession solution up to 80°
    sf = carried("full", ("rotor_gyroscopic", "coriolis", "bias_torque"), params=p)
    sf.set_input(0.0, 1.0, np.zeros(3), np.zeros(3))
    t80 = math.sin(math.radians(80)) * t_star
    tt = np.linspace(0, t80, 400)
    solf = solve_ivp(sf.rhs, (0, t80), sf.rest_state(), method="DOP853", rtol=1e-10, atol=1e-12, t_eval=tt)
    dev = np.max(np.abs(np.sin(solf.y[4]) - tau * tt / L))
    assert dev < 5.3e-4
    assert dev > 1e-6   # nutation ripple is there: the models are not the same


def test_O7c_rotor_bearing_load_one_over_cos_beta():
    tau, beta = 0.02, math.radians(80)
    p = NAV1.with_(bias_torque=(0, 0, 0, tau, 0))
    opt = ModelOptions.make("carried", "precession", ("rotor_gyroscopic", "bias_torque"))
    sim = Simulator(p, opt)
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[4] = beta
    out = sim.outputs()
    assert out.gimbal_rates[4] == pytest.approx(tau / (L * math.cos(beta)), rel=1e-12)
    assert out.gimbal_rates[3] == pytest.approx(0.0, abs=1e-15)
    assert out.bearing_torques["rotor11"][2] == pytest.approx(0.11517541, rel=1e-7)


def test_O7b_motor_torques_under_ideal_speed_control():
    sim = Simulator(NAV1, ModelOptions.make("carried", "full", integrator="dop853"))
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.push(RateSample.of(1e-6, [1e-6, 0, 0]))     # Ω̇1 = 1 rad/s²
    out = sim.outputs()
    np.testing.assert_allclose(out.motor_torques, [2e-5, -2e-5, 0.0], atol=1e-10)


# ---- bearing torques (O10) and Newton–Euler consistency -------------------------------------

def test_O10_bearing_torques_in_steady_precession():
    Q10, beta, a9, w = 1e-4, math.radians(60), 0.3, -3.978873032e-3
    p = NAV1.with_(bias_torque=(0, 0, 0, 0, Q10))
    sim = Simulator(p, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis", "bias_torque")))
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[4], sim.y[3], sim.y[8] = beta, a9, w
    sim.y[5:8] = 0.0
    out = sim.outputs()
    bt = out.bearing_torques
    np.testing.assert_allclose(bt["rotor11"], [9.999993e-5, 0, 0], atol=2e-12)
    np.testing.assert_allclose(bt["gimbal9"], [1.0e-4, 0, 0], atol=2e-12)
    np.testing.assert_allclose(bt["gimbal10"], [0, 0, 0], atol=2e-12)
    np.testing.assert_allclose(bt["support"], [9.553365e-5, 2.955202e-5, 0], atol=2e-12)
    assert out.motor_torques[2] == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(out.gimbal_axial_torques, [0, 0, 0, 0, Q10], atol=0)


def test_rotor_bearing_torque_is_precession_rate_cross_momentum():
    """Torque the housing exerts on a rotor precessing at p: p × L s (the torque the rotor
    puts on its housing is the opposite, L s × p), plus the rotor's own inertia: I_r α_h +
    p × I_r p, with α_h the housing's angular acceleration (the gimbals are free: the vehicle
    rate, already felt at the first sample, drives them)."""
    rng = np.random.default_rng(3)
    s = carried("full")
    for _ in range(3):
        Om = rng.normal(scale=0.3, size=3)
        sim = Simulator(NAV1, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis")))
        sim.push(RateSample.of(0.0, Om))
        sim.y[5:10] = 0.0                  # gimbals locked to the vehicle: housings turn with Ω
        out = sim.outputs()
        for name, sp, j in (("rotor6", np.array([1.0, 0, 0]), 0), ("rotor8", np.array([-1.0, 0, 0]), 1),
                            ("rotor11", np.array([0, 1.0, 0]), 2)):
            p_ = Om                        # housing rate = platform rate at zero angles
            Lvec = NAV1.L[j] * sp
            A, C = NAV1.rotor_A[j], NAV1.rotor_C[j]
            Ir = A * np.eye(3) + (C - A) * np.outer(sp, sp)
            qdd = sim.system.rhs(sim.t_rel, sim.y)[5:10]          # gimbal accelerations
            chain = {0: (0, 1), 1: (0, 2), 2: (3, 4)}[j]          # α4 β5 | α4 β7 | α9 β10
            alpha_h = sum(qdd[g] * GIMBAL_AXES[g] for g in chain)  # frames aligned at q = 0
            expect = Ir @ alpha_h + np.cross(p_, Lvec) + np.cross(p_, Ir @ p_)
            expect -= (expect @ sp) * sp
            np.testing.assert_allclose(out.bearing_torques[name], expect, rtol=1e-12, atol=1e-16)
    _ = s


def test_newton_euler_axial_torques_equal_applied_forces():
    rng = np.random.default_rng(11)
    p = NAV1.with_(bias_torque=tuple(rng.normal(scale=1e-4, size=5)))
    eff = ("rotor_gyroscopic", "coriolis", "gimbal_springs", "gimbal_dampers", "bias_torque", "servo",
           "support_friction")
    s = PlatformSystem(p, ModelOptions.make("stabilised", "full", eff))
    for _ in range(5):
        y = s.rest_state()
        y[0:13] = rng.normal(scale=0.5, size=13)
        s.set_input(0.0, 1.0, rng.normal(size=3), rng.normal(size=3))
        yd = s.rhs(0.2, y)
        wk = TreeWork(s.tree)
        F, f, _ = tree_inverse_dynamics(s.tree, wk, y[0:5], y[5:13], yd[5:13], np.zeros(3), np.zeros(3), p.L)
        from gyro_platform.physics import effects as fx
        Q = np.zeros(5)
        fx.gimbal_forces(s.on, s.k, s.L, y[0:5], y[8:13], np.zeros(3), Q)
        np.testing.assert_allclose(F[3:], Q, atol=1e-14)


# ---- conservation (O11) ----------------------------------------------------------------------

def test_O11_invariants_over_1000_nutation_periods():
    opt = ModelOptions.make("stabilised", "full", ("rotor_gyroscopic", "coriolis"), integrator="dop853",
                            rtol=1e-12, atol=1e-15)
    sim = Simulator(NAV1, opt)
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[0:5] = [0.1, -0.2, 0.15, 0.3, -0.25]
    sim.y[5:13] = [0.5, -0.3, 0.2, 1.0, -2.0, 0.5, 1.5, -1.0]
    i0 = sim.invariants()
    assert i0["T2"] == pytest.approx(1.611596381e-2, rel=1e-9)
    assert i0["p_norm"] == pytest.approx(3.144603264e-2, rel=1e-9)
    T = 1000 * 2 * math.pi / 767.97
    for k in range(1, 201):
        sim.push(RateSample.of(k * T / 200, [0, 0, 0]))
    i1 = sim.invariants()
    assert abs(i1["T2"] / i0["T2"] - 1) < 1e-9
    assert abs(i1["p_norm"] / i0["p_norm"] - 1) < 1e-9
    np.testing.assert_allclose(i1["p_inertial"], i0["p_inertial"], rtol=0, atol=1e-9 * i0["p_norm"])


# ---- agreement between fidelities ------------------------------------------------------------

def _run_carried(fid, amp, T=0.2):
    eff = ("rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration", "gimbal_springs", "gimbal_dampers")
    s = carried(fid, eff)
    Om = np.array([0.05, 0.1, -0.08])
    s.set_input(0.0, 1.0, Om, Om)
    y0 = s.rest_state()
    y0[0:5] = amp * np.array([1.0, -0.7, 0.5, 0.8, -0.6])
    t = np.linspace(0, T, 101)
    return solve_ivp(s.rhs, (0, T), y0, method="DOP853", rtol=1e-12, atol=1e-15, t_eval=t).y[0:5]


def test_full_and_linear_differ_by_a_second_order_amount():
    d1 = np.max(np.abs(_run_carried("full", 0.02) - _run_carried("linear", 0.02)))
    d2 = np.max(np.abs(_run_carried("full", 0.01) - _run_carried("linear", 0.01)))
    assert d1 > 1e-7
    assert d1 / d2 == pytest.approx(4.0, rel=0.12)


def test_linear_and_precession_agree_on_precession_rates():
    p = NAV1.with_(bias_torque=(2e-5, 1e-5, 1e-5, 3e-5, -4e-5), damper=(1e-3,) * 5)
    rates = {}
    for fid in ("linear", "precession"):
        eff = ("rotor_gyroscopic", "bias_torque", "gimbal_dampers")
        s = carried(fid, eff, params=p)
        Om = np.array([0.01, -0.02, 0.015])
        s.set_input(0.0, 1.0, Om, Om)
        y0 = s.rest_state()
        sol = solve_ivp(s.rhs, (0, 1.0), y0, method="DOP853", rtol=1e-10, atol=1e-14, t_eval=[0.5, 1.0])
        rates[fid] = (sol.y[[3, 4], 1] - sol.y[[3, 4], 0]) / 0.5      # unit B (α9, β10)
    np.testing.assert_allclose(rates["linear"], rates["precession"], rtol=2e-3)
    assert np.all(np.abs(rates["precession"]) > 1e-3)


def test_effect_that_contributes_nothing_changes_nothing():
    Om = np.array([0.2, -0.1, 0.3])
    base = ("rotor_gyroscopic", "coriolis")
    ys = []
    for eff, params in ((base, NAV1), (base + ("vehicle_angular_acceleration",), NAV1),
                        (base + ("gimbal_springs",), NAV1.with_(spring=(0.0,) * 5)),
                        (base + ("bias_torque",), NAV1.with_(bias_torque=(0.0,) * 5)),
                        (base + ("earth_rate",), NAV1.with_(earth_rate=0.0))):
        sim = Simulator(params, ModelOptions.make("carried", "full", eff, integrator="rk4", max_step=1e-4))
        for k in range(51):
            sim.push(RateSample.of(k * 1e-3, Om))
        ys.append(sim.y.copy())
    for y in ys[1:]:
        np.testing.assert_array_equal(y, ys[0])


# ---- refusals -----------------------------------------------------------------------------

def test_precession_refuses_rotor_at_zero_spin_while_linear_and_full_run():
    p = NAV1.with_(rotor_speed=(2513.274, 2513.274, 0.0))
    with pytest.raises(PrecessionInvalidError, match="rotor11.*det G_R = 0"):
        Simulator(p, ModelOptions.make("carried", "precession"))
    for fid in ("linear", "full"):
        sim = Simulator(p, ModelOptions.make("carried", fid))
        for k in range(20):
            sim.push(RateSample.of(k * 1e-3, [0.1, 0.2, 0.3]))
        assert np.all(np.isfinite(sim.y))


def test_precession_refuses_without_rotor_momentum_and_with_stiff_springs():
    with pytest.raises(PrecessionInvalidError, match="rotor_gyroscopic"):
        Simulator(NAV1, ModelOptions.make("carried", "precession", ("coriolis",)))
    stiff = NAV1.with_(spring=(50.0,) * 5)
    with pytest.raises(PrecessionInvalidError, match="spring frequency"):
        Simulator(stiff, ModelOptions.make("carried", "precession", ("rotor_gyroscopic", "gimbal_springs")))


# ---- the paper's matrix form agrees with the body tree -----------------------------------

def test_paper_matrices_match_the_tree():
    """[M76] builds the equations from B(q), A_R, A* = A + BᵀA_R B and the skew gyroscopic
    matrix G_R; the engine evaluates them by Newton–Euler. Both must give the same forces."""
    from gyro_platform.physics.model import paper_matrices, spin_momentum
    from gyro_platform.physics.tree import tree_mass_and_bias, TreeWork
    rng = np.random.default_rng(2)
    for _ in range(4):
        q = rng.uniform(-1.2, 1.2, size=5)
        v = rng.normal(size=8)
        m = paper_matrices(NAV1, q)
        G = m["G_R"]
        np.testing.assert_allclose(G, -G.T, atol=1e-12)
        # the exact couplings of spec 4.2
        assert G[3, 4] == pytest.approx(L * math.cos(q[1]), rel=1e-8)
        assert G[3, 5] == pytest.approx(L * math.cos(q[2]), rel=1e-8)
        assert G[6, 7] == pytest.approx(L * math.cos(q[4]), rel=1e-8)
        # B's first three columns are the spin axes h = Σ L_r e_r (spec 2.3)
        h = np.zeros(3)
        spin_momentum(NAV1.L, q, np.zeros(5), h, np.zeros(3))
        np.testing.assert_allclose(m["B"][:, :3].T @ m["L"], h, atol=1e-15)
        # A is positive definite and A* = A + Bᵀ A_R B is the tree's mass matrix
        assert np.linalg.eigvalsh(m["A"])[0] > 0
        s = PlatformSystem(NAV1, ModelOptions.make("stabilised", "full", ("rotor_gyroscopic",)))
        M, c_L = tree_mass_and_bias(s.tree, TreeWork(s.tree), q, v, np.zeros(3), np.zeros(3), NAV1.L,
                                    coriolis=False, gyroscopic=True)
        np.testing.assert_allclose(M, m["A_star"], rtol=1e-13)
        # the rotor-momentum part of the Newton–Euler bias is G_R ẋ plus Ω × Bᵀ L in the platform rows
        expect = G @ v
        expect[:3] += np.cross(v[:3], (m["B"].T @ m["L"])[:3])
        np.testing.assert_allclose(c_L, expect, rtol=1e-7, atol=1e-9)


def test_rate_sample_is_a_frozen_value_with_its_fields():
    """RateSample's own __init__ (slots set directly) keeps the dataclass behaviour: fields in
    order, default None force, equality, replace, and no assignment afterwards."""
    import dataclasses

    w = np.array([0.1, 0.2, 0.3])
    s = RateSample(1.5, w)
    assert (s.t, s.omega is w, s.specific_force) == (1.5, True, None)
    assert RateSample(t=1.5, omega=w, specific_force=None) == s
    assert dataclasses.replace(s, t=2.0).t == 2.0 and dataclasses.astuple(s)[0] == 1.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.t = 3.0
