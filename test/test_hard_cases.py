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

"""Hard cases stay numerically stable (issue: fast rotors, stiff nutation, near gimbal lock,
long runs, violent or bad input). Bounds and agreement are asserted, never time."""
import math

import numpy as np
import pytest

from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.simulator import choose_integrator, fastest_mode, Simulator
from gyro_platform.errors import GimbalLockError, InputError, PrecessionInvalidError, ToleranceError
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1

SPIN = NAV1.rotor_speed[0]


def carried_run(params, integrator, max_step, t, w, fid="full", effects=None, **kw):
    eff = ("rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration", "bias_torque") if effects is None \
        else effects
    sim = Simulator(params, ModelOptions.make("carried", fid, eff, integrator=integrator, max_step=max_step, **kw))
    outs = sim.push_many(t, w, output_every=10)
    return sim, np.array([o.gimbal_angles for o in outs])


@pytest.mark.parametrize("factor,T", [(10, 1.0), (100, 0.1)])
def test_fast_rotors_stay_bounded_and_match_reference(factor, T):
    """Spin ×10 and ×100: nutation at 8.1e3 and 8.1e4 rad/s, sampled at 1 kHz. The automatic
    choice switches to the exponential integrator (RK4 would be unstable at h·ω ≫ 2.8) and
    matches a fine-step reference."""
    # unit A torqued consistently (Q5/L6 = Q7/L8, spec 9.4): otherwise its null mode runs away
    p = NAV1.with_(rotor_speed=(SPIN * factor,) * 3, bias_torque=(1e-4, 2e-4, 2e-4, 3e-4, -2e-4))
    opt = ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration",
                                                "bias_torque"))
    assert fastest_mode(p, opt) * 1e-3 > 5.0
    assert choose_integrator(opt, p).name == "auto:etd4+exprb"
    t = np.arange(0.0, T + 1e-9, 1e-3)
    w = np.column_stack([0.2 * np.sin(3.0 * t), 0.1 * np.cos(2.0 * t), 0.05 + 0 * t])
    _, g = carried_run(p, "auto", 1e-3, t, w)
    _, g_ref = carried_run(p, "etd4", 1e-3 / 16, t, w)
    assert np.all(np.isfinite(g)) and np.max(np.abs(g)) < 1.0
    # ~1e-5 rad at gimbal swings of ~0.1 rad: the nonlinear remainder is second order in etd2
    assert np.max(np.abs(g - g_ref)) < 1e-5
    # RK4 at the sample period is unstable here (h·ω ≫ 2.8): held to the tolerance it must
    # substep past its stability limit (the reason the automatic choice differs), and with a
    # budget of one substep per sample it refuses instead of blowing up
    sim, g_rk4 = carried_run(p, "rk4", 1e-3, t[:21], w[:21])
    assert sim.n_steps / (sim.n_samples - 1) >= fastest_mode(p, opt) * 1e-3 / 2.8
    np.testing.assert_allclose(g_rk4, g_ref[:len(g_rk4)], atol=1e-6)
    with pytest.raises(ToleranceError, match="rk4 cannot meet the tolerance"):
        carried_run(p, "rk4", 1e-3, t, w, max_substeps=1)


def test_gimbal_held_near_lock_full_model_stays_regular_precession_refuses():
    """β10 at 89.9°: the full model (massive gimbals) stays finite and conserves T2; the
    precession model reports gimbal lock instead of returning Inf/NaN."""
    opt = ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis"), integrator="dop853",
                            rtol=1e-11, atol=1e-14)
    sim = Simulator(NAV1, opt)
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[4] = math.radians(89.9)
    sim.y[8], sim.y[9] = 0.01, -0.02
    T0 = sim.invariants()["T2"]
    for k in range(1, 201):
        sim.push(RateSample.of(k * 1e-3, [0, 0, 0]))
    assert np.all(np.isfinite(sim.y))
    assert abs(sim.invariants()["T2"] / T0 - 1) < 1e-9
    assert sim.outputs().status["gimbal_lock_margin"] < 0.01
    sp = Simulator(NAV1.with_(bias_torque=(0, 0, 0, 1e-4, 0)),
                   ModelOptions.make("carried", "precession", ("rotor_gyroscopic", "bias_torque")))
    sp.push(RateSample.of(0.0, [0, 0, 0]))
    sp.y[4] = math.radians(89.99)
    y_before = sp.y.copy()
    with pytest.raises(GimbalLockError, match="gimbal lock"):
        sp.push(RateSample.of(1e-3, [0, 0, 0]))
    np.testing.assert_array_equal(sp.y, y_before)           # nothing computed is lost


def test_one_hour_without_dissipation_keeps_energy():
    """One hour with every dissipative effect off (no friction, dampers, servo) and the
    nutation of unit B excited, 3.6e6 steps of 1 ms: the gimbal energy T2 = ½ q̇ᵀA*q̇ stays
    constant to 1e-6 and the gyro stays in place (etd2 integrates the fast gyroscopic part
    exactly; RK4 at the same step damps the nutation numerically by (hω)⁶/72 per step — also
    asserted). Unit A is left at rest: its antisymmetric mode β5 = −β7 has no gyroscopic
    restraint, and a long conservative run with its nutation excited is a limit of the explicit
    methods (README, Hard cases)."""
    opt = ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis"), integrator="etd2",
                            max_step=1e-3)
    sim = Simulator(NAV1, opt)
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[5:10] = [0.0, 0.0, 0.0, 0.5, -0.4]          # rad/s: nutation amplitude ~ 7e-4 rad
    T0 = sim.invariants()["T2"]
    t = np.arange(1, 3600 * 100 + 1) * 1e-2           # 100 Hz input, 1 ms steps: 3.6e6 steps
    for chunk in np.array_split(t, 12):
        sim.push_many(chunk, np.zeros((len(chunk), 3)))
    assert sim.t == pytest.approx(3600.0)
    assert abs(sim.invariants()["T2"] / T0 - 1) < 1e-6
    assert np.max(np.abs(sim.y[3:5])) < 5e-3
    # RK4 as a bare 1 ms map (tolerance so loose it never substeps): bounded, but the nutation
    # energy is damped away numerically, as its stability function predicts
    rk = Simulator(NAV1, opt.with_(integrator="rk4", rtol=0.99, atol=0.99))
    rk.push(RateSample.of(0.0, [0, 0, 0]))
    rk.y[5:10] = [0.0, 0.0, 0.0, 0.5, -0.4]
    rk.push_many(t[:20], np.zeros((20, 3)))           # 0.2 s = 200 steps
    h_w = 1e-3 * 767.9715
    expect = (1 - h_w ** 6 / 72) ** 200               # |R(ihω)|² ≈ 1 − (hω)⁶/72 per step: 0.565
    assert rk.invariants()["T2"] / T0 == pytest.approx(expect, rel=0.05)
    # held to the default tolerance, RK4 substeps until its local error is ≤ rtol: the damping
    # over the same 0.2 s (24 nutation periods), extrapolated to 1000 periods, stays below 0.1 %
    held = Simulator(NAV1, opt.with_(integrator="rk4"))
    held.push(RateSample.of(0.0, [0, 0, 0]))
    held.y[5:10] = [0.0, 0.0, 0.0, 0.5, -0.4]
    held.push_many(t[:20], np.zeros((20, 3)))
    periods = 0.2 * 767.9715 / (2 * np.pi)
    assert abs(held.invariants()["T2"] / T0 - 1) * 1000 / periods < 1e-3


@pytest.mark.parametrize("mode", ["carried", "stabilised"])
def test_violent_rate_step(mode):
    """A 5 rad/s step in vehicle rate. Carried: free gyros keep their direction (exact angles
    −Ω t after the step). Stabilised: the servo saturates at its limit and the platform holds
    (drift stays bounded) while the vehicle spins away."""
    t = np.arange(0.0, 0.6 + 1e-9, 1e-3)
    w = np.zeros((len(t), 3))
    w[t >= 0.1, 2] = 5.0
    opt = ModelOptions.make(mode)
    sim = Simulator(NAV1, opt)
    outs = sim.push_many(t, w, output_every=50)
    assert np.all(np.isfinite(sim.y))
    if mode == "carried":
        # the ramp between the two samples around the step is what the sampled input means
        turned = 5.0 * (t[-1] - 0.1) + 5.0 * 0.5e-3
        np.testing.assert_allclose(sim.y[[3, 1, 2]], [-turned, -turned, turned], atol=1e-6)
    else:
        o = outs[-1]
        assert np.max(np.abs(o.servo_torque)) <= NAV1.servo_limit + 1e-12
        assert np.max(np.abs(o.drift_angle)) < 1e-3
        assert abs(o.mount_angles[2]) > 2.0                  # the vehicle yawed ~2.5 rad under it


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("integrator", ["etd2", "etd4"])
def test_rate_step_between_jittered_samples_ends_each_interval_exactly(integrator, compiled):
    """Carried, the default etd path, a 5 rad/s yaw step between samples jittered ±5 % of 1 ms:
    the free gyros keep their direction (angles ∓ the turned yaw, exact). The exponential
    methods step on the grid max_step/256 and end each interval with a short last step; with
    the remainder carried instead, the interval's angular acceleration acted over the wrong
    span and the excess stayed in the gimbal rates (1.8e-3 rad off at 0.6 s, while the error
    estimates summed to < 2e-4 of that)."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 0.6 + 1e-9, 1e-3)
    t[1:] += 0.05e-3 * rng.uniform(-1, 1, len(t) - 1)
    w = np.zeros((len(t), 3))
    w[t >= 0.1, 2] = 5.0
    turned = np.sum(0.5 * (w[1:, 2] + w[:-1, 2]) * np.diff(t))     # the piecewise-linear input
    sim = Simulator(NAV1, ModelOptions.make("carried", integrator=integrator), compiled=compiled)
    sim.push_many(t, w)
    err = np.max(np.abs(sim.y[[3, 1, 2]] - [-turned, -turned, turned]))
    assert err < 1e-9                                   # atol of the default tolerance
    assert sim.stats["max_error_norm"] <= 1.0
    assert err <= sim.n_steps * sim.stats["max_error_estimate"]    # the estimates account for it


def test_fast_rotor_keeps_nutation_energy_over_jittered_samples():
    """Spin ×100 (nutation 8.1e4 rad/s), nothing dissipative, 10 s of samples jittered ±5 % of
    1 ms: every interval ends with a short etd2 step whose linear part is exact (φ-functions by
    Taylor series), so the gimbal energy T2 stays as constant as with uniform samples (an RK4
    last step damps it: −6.4e-5, with 0.6 rejections per sample)."""
    p = NAV1.with_(rotor_speed=(SPIN * 100,) * 3)
    rng = np.random.default_rng(5)
    t = np.cumsum(1e-3 * (1 + 0.05 * rng.uniform(-1, 1, 10000)))
    T2 = {}
    for name, ts in (("jittered", t), ("uniform", np.arange(1, 10001) * 1e-3)):
        sim = Simulator(p, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis"), integrator="etd2"))
        sim.push(RateSample.of(0.0, [0, 0, 0]))
        sim.y[5:10] = [0.0, 0.0, 0.0, 0.5, -0.4]
        T0 = sim.invariants()["T2"]
        sim.push_many(ts, np.zeros((len(ts), 3)))
        assert sim.n_rejected == 0
        T2[name] = sim.invariants()["T2"] / T0 - 1
    assert abs(T2["uniform"]) < 1e-8
    assert abs(T2["jittered"]) < 1e-8


def test_rotor_at_zero_spin():
    p = NAV1.with_(rotor_speed=(SPIN, SPIN, 0.0))
    with pytest.raises(PrecessionInvalidError, match="det G_R = 0"):
        Simulator(p, ModelOptions.make("carried", "precession"))
    t = np.arange(0.0, 0.5, 1e-3)
    w = np.column_stack([0.1 + 0 * t, 0.2 * np.sin(t), 0 * t])
    ys = {}
    for fid in ("linear", "full"):
        sim = Simulator(p, ModelOptions.make("carried", fid))
        sim.push_many(t, w)
        assert np.all(np.isfinite(sim.y))
        ys[fid] = sim.y[0:5].copy()
    # no torque acts and the consistent start leaves the stopped housing 10 inertially at
    # rest: β10 ≈ −Ω1 t; and the two fidelities differ by a second-order amount only
    assert ys["full"][4] == pytest.approx(-0.1 * t[-1], abs=2e-3)
    assert np.max(np.abs(ys["full"] - ys["linear"])) < 5e-3


@pytest.mark.parametrize("integrator", ["auto", "etd2", "rk4"])
def test_half_second_gap_integrates_across(integrator):
    """A 0.5 s hole in a 1 kHz stream: the interval is integrated with the input interpolated
    across it, giving the same state as the unbroken stream when the motion is linear there."""
    t = np.arange(0.0, 1.5 + 1e-9, 1e-3)
    w = np.column_stack([0.3 + 0.1 * t, -0.2 + 0 * t, 0.1 * t])
    hole = (t > 0.5) & (t < 1.0)
    _, g_full = carried_run(NAV1, integrator, 1e-3, t, w)
    sim = Simulator(NAV1, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis",
                                                                "vehicle_angular_acceleration", "bias_torque"),
                                            integrator=integrator, max_step=1e-3))
    sim.push_many(t[~hole], w[~hole])
    ref = Simulator(NAV1, sim.options)
    ref.push_many(t, w)
    assert np.all(np.isfinite(sim.y))
    np.testing.assert_allclose(sim.y[0:5], ref.y[0:5], atol=1e-6)
    assert np.max(np.abs(g_full)) > 0.1        # the gyros did move through the hole


def test_bad_samples_are_refused_without_touching_the_state():
    sim = Simulator(NAV1, ModelOptions.make("stabilised"))
    sim.push(RateSample.of(0.0, [0.1, 0, 0]))
    sim.push(RateSample.of(1e-3, [0.1, 0, 0]))
    y = sim.y.copy()
    for bad in (RateSample.of(2e-3, [np.nan, 0, 0]), RateSample.of(2e-3, [np.inf, 0, 0]),
                RateSample.of(1e-3, [0.1, 0, 0]), RateSample.of(0.5e-3, [0.1, 0, 0])):
        with pytest.raises(InputError):
            sim.push(bad)
        np.testing.assert_array_equal(sim.y, y)
    with pytest.raises(InputError, match="index 2"):
        sim.push_many([2e-3, 3e-3, 2.5e-3], np.zeros((3, 3)))
    np.testing.assert_array_equal(sim.y, y)


def test_twin_gyro_nutation_pumps_its_unrestrained_mode():
    """Unit A with undamped nutation is parametrically unstable: its antisymmetric mode
    (β5 − β7; no gyroscopic restraint, spec 7.2) grows exponentially from a 1e-6 seed while the
    energy T2 is conserved — physics, not numerics: two independent integrators agree on the
    growth, and a mirror-symmetric start stays symmetric. (Real instruments have dampers.)"""
    growth = {}
    for integ, h in (("etd4", 2.5e-4), ("rk4", 1e-4)):
        sim = Simulator(NAV1, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis"),
                                                integrator=integ, max_step=h))
        sim.push(RateSample.of(0.0, [0, 0, 0]))
        sim.y[5:10] = [0.0, 0.3 + 1e-6, 0.3, 0.0, 0.0]
        T0 = sim.invariants()["T2"]
        d = []
        for k in range(3):
            t = np.arange(k * 1000 + 1, (k + 1) * 1000 + 1) * 1e-2
            sim.push_many(t, np.zeros((1000, 3)))
            d.append(sim.y[1] - sim.y[2])
        growth[integ] = d[2] / d[1]
        if integ == "etd4":
            assert abs(sim.invariants()["T2"] / T0 - 1) < 1e-9
    assert growth["etd4"] > 5.0                                  # per 10 s: exponential growth
    assert growth["rk4"] == pytest.approx(growth["etd4"], rel=0.01)
    sym = Simulator(NAV1, ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis"),
                                            integrator="etd4", max_step=2.5e-4))
    sym.push(RateSample.of(0.0, [0, 0, 0]))
    sym.y[5:10] = [0.0, 0.3, 0.3, 0.0, 0.0]
    t = np.arange(1, 3001) * 1e-2
    sym.push_many(t, np.zeros((3000, 3)))
    assert abs(sym.y[1] - sym.y[2]) < 1e-9
