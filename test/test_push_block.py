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

"""The compiled stepping (``push`` = one compiled call, ``push_block`` per chunk) against the
Python integrators, and the engine's reliability contract (issue 17): a reset is a fresh
start, a refused sample or block leaves state and outputs untouched, bad input is an
``InputError``, numerical failures are ``SimulationError``s, absurd options and parameters are
refused at construction. Property tests with hypothesis."""
from __future__ import annotations

import math

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from gyro_platform.engine.buffers import J_LEVEL
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.simulator import Simulator
from gyro_platform.errors import InputError, NonFiniteOutputError, SimulationError
from gyro_platform.physics.options import ModelOptions, OptionsError
from gyro_platform.physics.params import NAV1, ParameterError, PlatformParams

SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
CASES = [("stabilised", "auto"), ("stabilised", "etd2"), ("carried", "rk4"), ("carried", "etd4")]


def _signal(n: int, seed: int, dt: float = 1e-3, jitter: float = 2e-4, t0: float = 1.7e9):
    """Jittered sample times (s, bag-like epoch), rates (rad/s) and specific forces (m/s²)."""
    rng = np.random.default_rng(seed)
    t = t0 + np.cumsum(dt + jitter * rng.random(n))
    w = 0.3 * np.sin(np.outer(t - t0, [3.0, 5.0, 7.0]) + rng.random(3)) + 0.01 * rng.standard_normal((n, 3))
    f = np.array([0.0, 0.0, 9.81]) + 0.2 * rng.standard_normal((n, 3))
    return t, w, f


def _rows(outs) -> np.ndarray:
    return np.array([list(o.as_row().values()) for o in outs])


def _push_all(sim, t, w, f=None):
    outs = []
    for i in range(len(t)):
        sim.push(RateSample(float(t[i]), w[i].copy(), None if f is None else f[i].copy()))
        outs.append(sim.outputs())
    return outs


@pytest.mark.parametrize("dt,jitter", [(2.5e-3, 2e-4), (0.95e-3, 1e-4), (1.0e-3, 2e-4)])
@pytest.mark.parametrize("mode,integ", CASES + [("carried", "etd2")])
def test_compiled_push_equals_python_integrators(mode, integ, dt, jitter):
    """One compiled call per sample gives the Python integrators' states (same controller,
    same grid chunks and last short step of etd) to round-off, with the same work counted.
    Jittered samples: 2–3 chunks per interval (the chunk controller), or 1–2 around max_step
    and around (1 + STEP_SLACK)·max_step."""
    t, w, f = _signal(150, 1, dt=dt, jitter=jitter)
    opt = ModelOptions.make(mode, integrator=integ)
    fast, ref = Simulator(options=opt), Simulator(options=opt, compiled=False)
    for i in range(len(t)):
        s = RateSample(float(t[i]), w[i].copy(), f[i].copy())
        fast.push(s)
        ref.push(s)
        np.testing.assert_allclose(fast.y, ref.y, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(ref.y))))
    assert fast.n_steps == ref.n_steps and fast.n_rejected == ref.n_rejected
    assert fast.max_error_norm == pytest.approx(ref.max_error_norm, rel=1e-9)


@pytest.mark.parametrize("mode,integ", [("stabilised", "rk4"), ("carried", "etd4")])
def test_compiled_step_plan_is_the_python_controllers(mode, integ):
    """The compiled kernel steps by the plan of ``integrators.base.Controlled`` (the reference):
    sample by sample the same substeps, rejections and controller level as the Python integrator,
    on samples 0.4–2 max_step apart (1–2 chunks per interval; etd4: short tails) with a rate
    step that makes the level move up and back (2 rad/s: the support friction's kinks no longer
    do, the steps end at them)."""
    t, w, f = _signal(160, 4, dt=1.2e-3, jitter=8e-4)
    w[80:] += np.array([2.0, -1.5, 1.0])
    opt = ModelOptions.make(mode, integrator=integ, rtol=1e-10)
    fast, ref = Simulator(options=opt), Simulator(options=opt, compiled=False)
    levels = set()
    for i in range(len(t)):
        s = RateSample(float(t[i]), w[i].copy(), f[i].copy())
        fast.push(s)
        ref.push(s)
        assert (fast.n_steps, fast.n_rejected) == (ref.n_steps, ref.n_rejected), f"sample {i}"
        assert int(fast.engine.ih[J_LEVEL]) == ref.integrator.level, f"sample {i}"
        levels.add(ref.integrator.level)
    assert len(levels) > 1, "the level never moved: the case does not exercise the controller"


@pytest.mark.parametrize("mode,integ", [("stabilised", "auto"), ("carried", "rk4"), ("carried", "etd4")])
def test_specific_force_reaches_every_compiled_path_as_the_python_one(mode, integ):
    """The g-sensitive effects (mass unbalance, anisoelasticity) feel all three axes of the
    specific force alike through ``push`` (arrays), ``push_plain`` (floats: the node) and
    ``push_block``, and as the Python integrator does (to round-off)."""
    from gyro_platform.physics.options import DEFAULT_EFFECTS

    t, w, f = _signal(150, 3)
    f = f + np.array([1.5, -2.0, 0.0]) * np.sin(3.0 * (t - t[0]))[:, None]      # every axis varies
    opt = ModelOptions.make(mode, integrator=integ,
                            effects=DEFAULT_EFFECTS[mode] | {"mass_unbalance", "anisoelastic"})
    ref, arrays, floats, block = (Simulator(options=opt, compiled=c) for c in (False, True, True, True))
    for i in range(len(t)):
        arrays.push(RateSample(float(t[i]), w[i].copy(), f[i].copy()))
        floats.push_plain(float(t[i]), tuple(w[i].tolist()), tuple(f[i].tolist()))
        ref.push(RateSample(float(t[i]), w[i].copy(), f[i].copy()))
    block.push_block(t, w, f)
    np.testing.assert_array_equal(floats.y, arrays.y)
    np.testing.assert_array_equal(block.y, arrays.y)
    np.testing.assert_allclose(arrays.y, ref.y, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(ref.y))))
    no_force = Simulator(options=ModelOptions.make(mode, integrator=integ))
    no_force.push_block(t, w, f)
    assert np.max(np.abs(no_force.y[:5] - ref.y[:5])) > 1e-9       # the effects are felt here


@pytest.mark.parametrize("mode,integ", CASES)
def test_push_block_equals_push_one_by_one(mode, integ):
    """Outputs at out_idx and the final state of one push_block equal push + outputs()."""
    t, w, f = _signal(120, 2)
    opt = ModelOptions.make(mode, integrator=integ)
    one, blk = Simulator(options=opt), Simulator(options=opt)
    ref = _push_all(one, t, w, f)
    idx = np.array([0, 1, 7, 50, 119])
    block = blk.push_block(t[:60], w[:60], f[:60], idx[idx < 60])
    block2 = blk.push_block(t[60:], w[60:], f[60:], idx[idx >= 60] - 60)
    got = [block[i] for i in range(len(block))] + [block2[i] for i in range(len(block2))]
    np.testing.assert_array_equal(blk.y, one.y)
    np.testing.assert_allclose(_rows(got), _rows([ref[i] for i in idx]), rtol=1e-12, atol=1e-15)
    assert blk.n_samples == one.n_samples == len(t)


def test_husky_rate_intervals_pay_fine_steps_only_where_needed():
    """A 30 Hz interval with a reversal of the mount friction inside: the chunk controller
    refines only the chunks that need it (the tolerance is still met: norm ≤ 1)."""
    t, w, _ = _signal(40, 3, dt=1 / 30, jitter=1e-4)
    w[:, 2] = 0.02 * np.sin(20 * (t - t[0]))               # yaw rate through zero: friction flips
    sim = Simulator(options=ModelOptions.make("stabilised", integrator="rk4"))
    sim.push_block(t, w)
    st_ = sim.stats
    assert st_["max_error_norm"] <= 1.0
    # a whole-interval grid at the finest level met would cost 34·2^level steps per sample
    assert st_["n_steps"] / st_["n_samples"] < 34 * 4


# ---- issue 17: state after errors and resets ----------------------------------------------
samples_st = st.lists(
    st.tuples(st.floats(1e-4, 0.04), st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
              st.lists(st.floats(-20.0, 20.0), min_size=3, max_size=3)),
    min_size=1, max_size=12)


def _materialise(seq, t0):
    t = t0 + np.cumsum([d for d, _, _ in seq])
    return t, np.array([w for _, w, _ in seq], float), np.array([f for _, _, f in seq], float)


@SETTINGS
@given(before=samples_st, after=samples_st, jump=st.floats(-50.0, 50.0),
       case=st.sampled_from(CASES + [("stabilised", "exprb")]))
def test_reset_is_a_fresh_start(before, after, jump, case):
    """After reset(), every output equals that of a fresh simulator fed the same samples."""
    mode, integ = case
    opt = ModelOptions.make(mode, integrator=integ, effects=None)
    used = Simulator(options=opt)
    tb, wb, fb = _materialise(before, 100.0)
    try:
        used.push_block(tb, wb, fb)
    except SimulationError:
        pass
    used.reset()
    fresh = Simulator(options=opt)
    ta, wa, fa = _materialise(after, 100.0 + jump)
    try:
        ref = _push_all(fresh, ta, wa, fa)
    except SimulationError:
        return                                   # both must refuse alike: checked below
    got = _push_all(used, ta, wa, fa)
    np.testing.assert_array_equal(_rows(got), _rows(ref))
    np.testing.assert_array_equal(used.y, fresh.y)


BAD_OMEGA = [np.array([1.0, 2.0]), np.array([1.0, 2.0, 3.0, 4.0]), np.array([1j, 0, 0]), "abc", ["a", "b", "c"],
             None, np.array([np.nan, 0.0, 0.0]), np.array([0.0, np.inf, 0.0]), [[1.0, 2.0], [3.0, 4.0]], object()]


def _state(sim):
    return sim.y.copy(), sim.t, sim.n_samples, sim.n_steps, sim.outputs().as_row()


def _same(a, b):
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1:4] == b[1:4]
    assert a[4].keys() == b[4].keys()
    np.testing.assert_array_equal(np.array(list(a[4].values())), np.array(list(b[4].values())))


@pytest.mark.parametrize("bad", BAD_OMEGA, ids=[f"omega{i}" for i in range(len(BAD_OMEGA))])
def test_bad_omega_is_an_input_error_and_changes_nothing(bad):
    sim = Simulator()
    t, w, _ = _signal(5, 4)
    sim.push_block(t, w)
    before = _state(sim)
    with pytest.raises(InputError):
        sim.push(RateSample(float(t[-1] + 1e-3), bad))
    with pytest.raises(InputError):
        sim.push_block([t[-1] + 1e-3], [bad] if not isinstance(bad, np.ndarray) else bad[None])
    _same(before, _state(sim))


@pytest.mark.parametrize("bad_t", [math.nan, math.inf, "1.0", 1j, None])
def test_bad_time_is_an_input_error(bad_t):
    sim = Simulator()
    t, w, _ = _signal(3, 5)
    sim.push_block(t, w)
    before = _state(sim)
    with pytest.raises(InputError):
        sim.push(RateSample(bad_t, np.zeros(3)))
    _same(before, _state(sim))


@SETTINGS
@given(seq=samples_st, swap=st.integers(0, 11), case=st.sampled_from(CASES))
def test_bad_blocks_leave_the_simulator_untouched(seq, swap, case):
    """Non-monotonic times or mismatched shapes: InputError, nothing changed (also on a fresh
    simulator: no time base, no sample left behind)."""
    mode, integ = case
    opt = ModelOptions.make(mode, integrator=integ)
    t, w, f = _materialise(seq, 10.0)
    for started in (False, True):
        sim = Simulator(options=opt)
        if started:
            sim.push_block([9.0], [[0.1, 0.0, 0.0]], [[0.0, 0.0, 9.8]])
        y0, t_start, n0 = sim.y.copy(), sim.t_start, sim.n_samples
        tb = t.copy()
        k = swap % len(tb)
        tb[k] = tb[k - 1] if k > 0 else 8.0        # a repeated time, or one before the start
        bad_blocks = [(tb, w, f), (t, w[:, :2], f), (t, w, f[:-1] if len(f) > 1 else f[:, :1]),
                      (t[None, :], w, f)]
        if not started and k == 0:
            bad_blocks = bad_blocks[1:]            # a fresh simulator takes any first time
        for bt, bw, bf in bad_blocks:
            with pytest.raises(InputError):
                sim.push_block(bt, bw, bf, [0])
            with pytest.raises(InputError):
                sim.push_many(bt, bw, bf, output_every=1)
            assert sim.t_start == t_start and sim.n_samples == n0
            np.testing.assert_array_equal(sim.y, y0)
        with pytest.raises(InputError):
            sim.push_block(t, w, f, [len(t)])        # index outside the block
        with pytest.raises(InputError):
            sim.push_block(t, w, f, [0, 0])          # not increasing
        assert sim.n_samples == n0


def test_refused_integration_keeps_state_input_and_outputs():
    """A sample the integrator cannot take (tolerance not met within a tiny budget) raises a
    SimulationError and leaves the state, the input and outputs() exactly as before; the next
    good sample goes on as if the bad one never came."""
    opt = ModelOptions.make("carried", integrator="rk4", max_substeps=2)
    sim, ref = Simulator(options=opt), Simulator(options=opt)
    t, w, _ = _signal(6, 6)
    sim.push_block(t[:3], w[:3])
    ref.push_block(t[:3], w[:3])
    before = _state(sim)
    with pytest.raises(SimulationError) as e:
        sim.push(RateSample(float(t[3]), np.array([500.0, -400.0, 300.0])))
    assert not isinstance(e.value, InputError)
    _same(before, _state(sim))
    sim.push_block(t[3:], w[3:])
    ref.push_block(t[3:], w[3:])
    _same(_state(ref), _state(sim))


def test_failing_block_hands_back_what_was_done():
    """push_block stops at the failing sample: ``.n_done`` samples taken, ``.block`` holds the
    outputs before it, the state is that after the last good sample."""
    opt = ModelOptions.make("carried", integrator="rk4", max_substeps=2)
    t, w, _ = _signal(8, 7)
    w[5] = [500.0, -400.0, 300.0]
    sim, ref = Simulator(options=opt), Simulator(options=opt)
    with pytest.raises(SimulationError) as e:
        sim.push_block(t, w, None, np.arange(8))
    assert e.value.n_done == 5 and len(e.value.block) == 5
    outs = _push_all(ref, t[:5], w[:5])
    np.testing.assert_array_equal(sim.y, ref.y)
    np.testing.assert_array_equal(_rows([e.value.block[i] for i in range(5)]), _rows(outs))


@pytest.mark.parametrize("integ", ["rk4", "etd2", "auto"])
def test_long_steps_fail_as_simulation_errors(integ):
    """max_step 0.5 s (allowed) on a fast carried platform: whatever happens is a result or a
    SimulationError (no ZeroDivisionError or other exception from the kernels)."""
    opt = ModelOptions.make("carried", integrator=integ, max_step=0.5, max_substeps=8)
    sim = Simulator(options=opt)
    t = np.arange(6) * 0.5
    w = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 3.0], [50.0, 9.0, -3.0], [0.0, 0.0, 0.0], [7.0, 7.0, 7.0], [0, 0, 1.0]])
    try:
        sim.push_block(t, w)
    except SimulationError:
        pass
    assert np.all(np.isfinite(sim.y))


# ---- absurd options and parameters: refused at construction --------------------------------
@pytest.mark.parametrize("kw", [{"max_step": 1e-12}, {"max_step": 0.0}, {"max_step": 2.0}, {"max_step": math.nan},
                                {"rtol": 1e-20}, {"rtol": True}, {"atol": 0.0}, {"atol": "1e-9"},
                                {"max_substeps": 0}, {"max_substeps": 2.5}])
def test_absurd_options_are_refused_with_the_reason(kw):
    with pytest.raises(OptionsError, match=next(iter(kw))):
        ModelOptions(**kw)


def test_massless_gimbals_are_refused_at_construction():
    zero = {
        "frame4": (0.0,) * 3,
        "housing5": (0.0,) * 3,
        "housing7": (0.0,) * 3,
        "rotor_A": (0.0,) * 3,
        "rotor_C": (0.0,) * 3,
    }
    with pytest.raises(ParameterError, match="gimbal inertia J4"):
        PlatformParams(**zero)
    with pytest.raises(ParameterError, match="gimbal inertia"):
        PlatformParams.from_dict({k: list(v) for k, v in zero.items()})
    assert NAV1.lumped()["J4"] > 0      # the reference set passes


def test_precession_without_rotor_momentum_is_refused_alike_everywhere():
    from gyro_platform.errors import PrecessionInvalidError
    p = NAV1.with_(rotor_speed=(0.0, 0.0, 0.0))
    for mode in ("stabilised", "carried"):
        with pytest.raises(PrecessionInvalidError, match="zero spin momentum"):
            Simulator(p, ModelOptions.make(mode, "precession"))


def test_auto_keeps_a_carried_platforms_angles_over_a_long_run():
    """Carried: the free gyros integrate every step's error. Ship motion (roll 10°, pitch 5° at
    0.1 Hz) at 1 kHz for 10 s, default tolerance, against RK4 at rtol 1e-12: etd2's local errors
    add up far beyond its largest local estimate; auto steps with etd4, which stays near the
    tolerance while integrating the excited nutation exactly."""
    t = np.arange(0.0, 10.0 + 1e-9, 1e-3)
    a = 2 * np.pi * 0.1
    w = np.column_stack([np.radians(10) * a * np.cos(a * t), np.radians(5) * a * np.cos(a * t + 1.0), 0 * t])
    idx = np.arange(0, len(t), 100)

    def angles(integ: str, rtol: float = 1e-6):
        sim = Simulator(options=ModelOptions.make("carried", integrator=integ, rtol=rtol, atol=rtol * 1e-3))
        return sim, sim.push_block(t, w, out_idx=idx).gimbal_angles

    _, ref = angles("rk4", 1e-12)
    sim, got = angles("auto")
    assert sim.stats["integrator"].startswith("auto:etd4")
    assert np.max(np.abs(got - ref)) < 1e-8
    sim2, etd2 = angles("etd2")
    assert np.max(np.abs(etd2 - ref)) > 30 * sim2.stats["max_error_estimate"]    # why not etd2


@pytest.mark.parametrize("compiled", [True, False])
def test_an_interval_up_to_slack_past_max_step_is_one_rk4_step(compiled):
    """STEP_SLACK: with max_step 1 ms, intervals of 1.05 ms are one RK4 step each (a 1 kHz
    driver's jittered stamps), intervals of 1.15 ms two; the same in the compiled and Python
    controllers. A vehicle at rest keeps the controller at level 0."""
    from gyro_platform.engine.integrators import STEP_SLACK

    assert STEP_SLACK == pytest.approx(0.1)
    opt = ModelOptions.make("stabilised", integrator="rk4")
    for dt, per_interval in ((1.05e-3, 1), (1.15e-3, 2)):
        sim = Simulator(options=opt, compiled=compiled)
        n = 50
        for i in range(n + 1):
            sim.push(RateSample(i * dt, np.zeros(3), None))
        assert sim.n_steps == n * per_interval


def test_failed_outputs_carry_what_the_caller_needs_to_go_on():
    """Outputs that fail (1e200 m/s² with anisoelastic: not finite) do not stop the block's
    integration; the error says how far it went (``n_done``), which recorded instant failed,
    and carries those instants (``snapshots``) so that the outputs after it can be computed."""
    eff = ("rotor_gyroscopic", "coriolis", "anisoelastic", "servo")
    t = np.arange(4) * 1e-3
    w = np.zeros((4, 3))
    f = np.tile([0.0, 0.0, 9.81], (4, 1))
    f[0] = (1e200, 5e199, -1e200)
    sim = Simulator(NAV1, ModelOptions.make("stabilised", "full", eff))
    with pytest.raises(NonFiniteOutputError) as ei:         # outputs only: every sample taken
        sim.push_block(t[:1], w[:1], f[:1], [0])
    e = ei.value
    assert (e.n_done, e.output_failed, len(e.block), len(e.snapshots)) == (1, 0, 0, 1) and e.output_error is e
    sim = Simulator(NAV1, ModelOptions.make("stabilised", "full", eff))
    with pytest.raises(SimulationError) as ei:              # then the next interval fails too
        sim.push_block(t, w, f, [0, 1, 2, 3])
    e = ei.value
    assert not isinstance(e, NonFiniteOutputError) and e.n_done == 1
    assert e.output_failed == 0 and isinstance(e.output_error, NonFiniteOutputError) and len(e.snapshots) == 1
