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

"""Switch location: RK4 ends its steps at the mount friction's kinks (``physics.switching``), so
a vibrating vehicle costs about as much as a smooth one, and the accuracy asked is delivered.

The kink times are checked against the closed form of a linear input; the cost and the delivered
error on a vibrating 1 kHz IMU against a smooth one and against a tight reference (the figures
of ``gyro-platform bench roughness``); the compiled kernel's pieces against the Python
controller's on the vibrating input (also ``test_push_block.py``); every method on a vibrating
vehicle in the hard-case catalogue (``vibrating_vehicle``, ``test_accuracy_on_request.py``)."""
from __future__ import annotations

import numpy as np
import pytest

from gyro_platform.bench.roughness import parked, REFERENCE, run_surface, surfaces
from gyro_platform.engine.buffers import J_LEVEL
from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.integrators import (COARSEN, coarser_level, error_norm, finest_level, level_substeps,
                                              LOOKBACK_AIM, MAX_JUMP, next_level, piece_substeps, shortened_piece)
from gyro_platform.engine.simulator import Simulator
from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.physics.switching import _rel_and_rate
from gyro_platform.physics.system import PlatformSystem

EPS = NAV1.support_rate_eps


def _system(effects=("coriolis", "rotor_gyroscopic", "servo", "support_friction")):
    sys_ = PlatformSystem(NAV1, ModelOptions.make("stabilised", "linear", effects))
    return sys_, sys_.rest_state()


def test_predicted_switch_is_where_the_relative_rate_reaches_the_friction_zone():
    """Platform at rest (Ω = 0, Ω̇ = 0), vehicle roll rate linear from −0.01 to +0.01 rad/s over
    1 ms: rel_x = −ω_x reaches +ε at t = (0.01 − ε)/20 s and −ε at (0.01 + ε)/20 s; the
    prediction is the first, then the second from there, and nothing with the effect off."""
    s, y = _system()
    s.set_input(0.0, 1e-3, (-0.01, 0.0, 0.0), (0.01, 0.0, 0.0))
    yd = np.zeros_like(y)
    t1 = s.switch_time(0.0, y, yd, 1e-3, 1e-9)
    assert t1 == pytest.approx((0.01 - EPS) / 20.0, rel=1e-12, abs=0)
    t2 = s.switch_time(t1, y, yd, 1e-3, 1e-9)
    assert t2 == pytest.approx((0.01 + EPS) / 20.0, rel=1e-12, abs=0)
    assert s.switch_time(t2, y, yd, 1e-3, 1e-9) == 1e-3             # no third kink before the end
    off, y_off = _system(("coriolis", "rotor_gyroscopic", "servo"))
    off.set_input(0.0, 1e-3, (-0.01, 0.0, 0.0), (0.01, 0.0, 0.0))
    assert off.switch_time(0.0, y_off, yd, 1e-3, 1e-9) == 1e-3


def test_a_kink_passed_inside_a_step_is_found_from_its_end():
    """Same input: at the end of the interval (t = 1 ms, rel_x = −0.01 rad/s) the kinks lie
    (0.01 − ε)/20 s and (0.01 + ε)/20 s back; the earlier one (the larger distance) is named,
    none beyond the window ``hi``."""
    s, y = _system()
    s.set_input(0.0, 1e-3, (-0.01, 0.0, 0.0), (0.01, 0.0, 0.0))
    yd = np.zeros_like(y)
    d = s.switch_passed(1e-3, y, yd, 1e-9, 0.9e-3)
    assert d == pytest.approx(1e-3 - (0.01 - EPS) / 20.0, rel=1e-9)
    assert s.switch_passed(1e-3, y, yd, 1e-9, 1e-4) == 0.0


def test_a_piece_redone_after_it_passed_a_kink_ends_before_the_kink():
    """``shortened_piece``: a piece ``hc`` long that passed a kink ``d`` before its end is redone to
    end (LOOKBACK_AIM − 1)·d before the kink, and never further back than half the way from its
    start to the kink."""
    assert LOOKBACK_AIM > 1.0
    assert shortened_piece(1e-3, 4e-7) == pytest.approx(1e-3 - LOOKBACK_AIM * 4e-7, rel=1e-15)
    assert shortened_piece(1e-3, 0.9e-3) == pytest.approx(0.05e-3, rel=1e-12)


def _worst_interval(imu, integrator: str, rtol: float) -> tuple[float, dict]:
    """(the largest true local error of the 1 ms intervals of ``imu``, in the controller's weighted
    RMS norm at ``rtol``, atol = rtol·1e-3: ``integrator`` from the reference's state at each
    interval's start against the reference at its end; the run's stats)."""
    ref = Simulator(NAV1, ModelOptions.make("stabilised", integrator="rk4", rtol=1e-12, atol=1e-15, max_step=1e-4,
                                            max_substeps=1 << 16))
    sim = Simulator(NAV1, ModelOptions.make("stabilised", integrator=integrator, rtol=rtol, atol=rtol * 1e-3,
                                            max_step=1e-3))
    worst = 0.0
    for i in range(imu.t.size):
        y0 = ref.y.copy()
        if i:
            sim.y = y0                           # the interval starts from the reference's state
        sample = RateSample(float(imu.t[i]), imu.omega[i], imu.force[i])
        ref.push(sample)
        sim.push(sample)
        if i:
            worst = max(worst, error_norm(sim.y - ref.y, y0, ref.y, rtol, rtol * 1e-3))
    return worst, sim.stats


@pytest.mark.parametrize("vehicle, integrator, rtol", [
    ("vibrating", "rk4", 1e-6), ("vibrating", "rk4", 1e-8), ("parked", "rk4", 1e-8),
    ("smooth", "auto", 1e-4), ("parked", "auto", 1e-5)])
def test_each_interval_of_a_rough_input_is_within_the_tolerance_it_was_accepted_at(vehicle, integrator, rtol):
    """The true local error of every 1 ms interval on 0.6 s of the vibrating 1 kHz IMU, and of the
    same IMU on a parked vehicle (kinks every sample: its relative rates hover about the
    friction's zone), RK4 at ``rtol`` from the reference's state at the interval's start, against
    the reference at its end, in the controller's weighted RMS norm, is within the tolerance. A
    step that starts or ends δ from a kink is off by ~(h/6)·δ·(the friction's slope jump), linear
    in the step: when a redone piece ended where the look-back put the kink (26 ns past it), an
    interval here was 9.9× the tolerance at rtol 1e-6 (at 8 ms: true 9.4×, its estimate 0.54);
    when kinks closer than 1 ns to a piece's end were let be (``SWITCH_MIN`` 1e-6), 15× at rtol
    1e-8 (at 236 ms); parked, when a chunk's pieces were capped at 16 (``MAX_SWITCHES``) and the
    rest stepped over its kinks, 1.5× (at 284 ms; 9.1e-10 rad delivered over 10 s at rtol 1e-6
    where 32 deliver 3.7e-12). ``auto`` at loose tolerances takes RK4 on this model (it has
    regime changes): when it took etd2 there, 122× (smooth, rtol 1e-4) and 2100× (parked, 1e-5)."""
    imu = {**surfaces(0.6), "parked": parked(0.6)}[vehicle]
    worst, stats = _worst_interval(imu, integrator, rtol)
    assert stats["n_steps"] > 1.2 * imu.t.size or vehicle == "smooth"    # the kinks cut intervals into pieces
    assert worst <= 1.0, worst


def test_etd2_does_not_see_the_kinks_it_steps_over():
    """Why ``auto`` takes RK4 on a model with regime changes at every tolerance: etd2's defect
    estimate, ``(h/3)(g(t+h, y1) − g(t+h, U))``, compares the remainder at two states of the
    step's end and misses what a step across a friction kink loses. On 0.6 s of the smooth 1 kHz
    IMU at rtol 1e-6 its intervals holding a kink are > 100× the tolerance (5900× measured) while
    every step's estimate stays ≤ 1; RK4 there stays within it (the test above)."""
    worst, stats = _worst_interval(surfaces(0.6)["smooth"], "etd2", 1e-6)
    assert stats["max_error_norm"] <= 1.0
    assert worst > 100.0, worst


def test_a_piece_to_a_predicted_kink_ends_short_of_it_and_the_next_lands_on_it():
    """``aimed_switch``: a piece to a kink predicted more than ``MICRO_STEP``·max_step ahead ends
    ``SWITCH_AIM`` of its reach short of it, a nearer one at it. On the ramp of the tests above
    (two kinks) RK4 at rtol 1e-8 ends an accepted piece within 1e-12 s of each kink, judged from
    the piece's end state (|rel_i ∓ ε| / |rel̇_i|, exact to first order that close). On this clean
    ramp session 40's rule landed too; where it did not (a piece left 0.18 ns short, a prediction
    0.1 µs late) is the vibrating input of the interval test above."""
    from gyro_platform.engine.integrators import aimed_switch, MICRO_STEP, SWITCH_AIM
    assert aimed_switch(0.0, 1e-3, 1e-3) == pytest.approx(1e-3 * (1 - SWITCH_AIM), rel=1e-15)
    near = 0.5 * MICRO_STEP * 1e-3
    assert aimed_switch(0.2, 0.2 + near, 1e-3) == 0.2 + near
    rk, s, y = _kinked(1e-8)
    ends = []
    step = rk._substeps

    def spy(system, t0, y0, nsub, h):
        out = step(system, t0, y0, nsub, h)
        if out[1] <= 1.0:
            ends.append((t0 + nsub * h, out[0].copy()))
        return out
    rk._substeps = spy
    rk.advance(s, 0.0, y, 1e-3)
    landed = []
    for t, y1 in ends:                 # time from the end to the nearest kink, |rel_i ∓ ε| / |rel̇_i|
        ok, *rr = _rel_and_rate(t, y1, s.rhs(t, y1), s.I, s.seg)
        landed.append(min(abs(rr[i] - c) / abs(rr[3 + i]) for i in range(3) for c in (-EPS, EPS)))
    assert sum(d <= 1e-12 for d in landed) == 2, sorted(landed)[:4]


def test_a_vibrating_vehicle_costs_at_most_two_fifths_more_than_a_smooth_one_at_the_accuracy_asked():
    """2 s of the bench's 1 kHz vehicle IMU, smooth and with the 37 Hz engine vibration (the
    vehicle rate crosses zero ~220 times a second), auto at rtol 1e-6 (the replay's default):
    right-hand sides per sample within 1.4× of the smooth input's (×1.32; before switch location
    3×, before the Euler micro-steps ×1.44),
    and both within 1e-9 rad of RK4 at rtol 1e-12 (gimbal and drift angles; before: 1.3e-8 on the
    vibrating input, the steps across the kinks first-order accurate and the estimate blind to it)."""
    rhs, err = {}, {}
    for name, imu in surfaces(2.0).items():
        ref, _ = run_surface(imu, *REFERENCE)
        ang, st = run_surface(imu, "auto", 1e-6, 1e-9)
        assert st["integrator"].startswith("auto:rk4")
        rhs[name] = st["n_rhs"] / st["n_samples"]
        err[name] = float(np.abs(ang - ref).max())
    assert rhs["vibrating"] <= 1.4 * rhs["smooth"], rhs
    assert max(err.values()) <= 1e-9, err


def test_a_rejected_piece_is_redone_with_more_substeps_of_its_own():
    """``next_piece_level``: a 50 µs piece of a 1 ms chunk rejected at one substep with norm 2.83
    goes straight to the first level that gives it two (level 8, 24 substeps a chunk; the chunk's
    rule, ``next_level``, asks for level 1, where the piece still takes one); for a whole chunk the
    two rules agree. On a parked vehicle at rtol 1e-8 (RK4, the Python controller) no attempt after
    an error rejection takes the substeps of the attempt rejected (before: 7–9 identical redos)."""
    from gyro_platform.engine.integrators import next_piece_level

    hp, hg = 49.749e-6, 1e-3
    assert next_level(0, 2.83, 5) == 1 and piece_substeps(hp, hg, 1) == 1
    assert next_piece_level(0, 2.83, 5, hp, hg, 1) == 8
    assert piece_substeps(hp, hg, 7) == 1 and piece_substeps(hp, hg, 8) == 2
    for level in (0, 2, 5):
        for norm in (1.01, 2.0, 40.0, 1e6, np.inf):
            assert next_piece_level(level, norm, 5, hg, hg, level_substeps(level)) == next_level(level, norm, 5)
    imu = parked(0.1)
    opt = ModelOptions.make("stabilised", "linear", integrator="rk4", rtol=1e-8, atol=1e-11)
    sim = Simulator(options=opt, compiled=False)
    attempts = []
    step = sim.integrator._substeps

    def spy(system, t0, y0, nsub, h):
        out = step(system, t0, y0, nsub, h)
        attempts.append((t0, nsub * h, nsub, out[1]))
        return out
    sim.integrator._substeps = spy
    for i in range(len(imu.t)):
        sim.push(RateSample(float(imu.t[i]), imu.omega[i].copy(), imu.force[i].copy()))
    redos = [(a, b) for a, b in zip(attempts, attempts[1:])
             if not a[3] <= 1.0 and b[0] == a[0] and abs(b[1] - a[1]) <= 1e-12 * a[1]]   # the same piece again
    assert len(redos) > 10                                          # the parked input has rejections
    assert all(b[2] > a[2] for a, b in redos), [(a[2], b[2]) for a, b in redos if b[2] <= a[2]][:5]


def test_a_piece_takes_the_fewest_substeps_no_longer_than_its_levels():
    """A whole chunk takes ``level_substeps(level)`` substeps; a piece of it as many as keep each
    no longer than the level's (hg / n), and no more; the pieces a chunk is cut into at its kinks
    take at most one substep more each than their share (a 3 µs stick-zone crossing one, not n)."""
    rng = np.random.default_rng(7)
    for level in range(24):
        for hg in (1e-3, 1e-3 / 3, 0.033):
            n = level_substeps(level)
            assert piece_substeps(hg, hg, level) == n
            cuts = np.sort(rng.uniform(0.0, hg, 5))
            pieces = np.diff(np.concatenate(([0.0], cuts, [hg])))
            total = 0
            for hp in pieces:
                k = piece_substeps(hp, hg, level)
                assert k >= 1
                assert hp / k <= hg / n * (1 + 1e-5)
                assert k == 1 or hp / (k - 1) > hg / n
                total += k
            assert total <= n + len(pieces) - 1
    assert piece_substeps(3e-6, 1e-3, 4) == 1


def test_the_level_grid_steps_by_three_halves_and_four_thirds_and_the_controller_aims_at_it():
    """Levels give 1, 2, 3, 4, 6, 8, 12, … substeps (every ratio ≤ 2, two levels = ×2); a rejected
    chunk goes to the coarsest finer level whose predicted error ``norm·(n/n')^q1`` is ≤ 1 (at
    most ``MAX_JUMP`` levels, ×16 the substeps); an accepted one coarsens only while the
    prediction stays ≤ ``COARSEN``; the budget's finest level is the last within ``max_substeps``."""
    ns = [level_substeps(k) for k in range(24)]
    assert ns[:9] == [1, 2, 3, 4, 6, 8, 12, 16, 24] and ns[23] == 4096
    assert all(2 * ns[k] == ns[k + 2] for k in range(1, 22))
    q1 = 4
    for level in range(12):
        for norm in (1.0001, 1.7, 5.06, 5.07, 30.0, 1e3, 1e9):
            new = next_level(level, norm, q1)
            pred = norm * (ns[level] / ns[new]) ** q1
            assert new > level and new - level <= MAX_JUMP
            assert pred <= 1.0 + 1e-12 or new - level == MAX_JUMP, (level, norm, new)
            if new - level > 1:          # the next coarser one would not have done
                assert norm * (ns[level] / ns[new - 1]) ** q1 > 1.0
        assert next_level(level, np.inf, q1) == next_level(level, np.nan, q1) == level + MAX_JUMP
        for norm in (0.0, 1e-3, 0.05, 0.2, 0.9):
            new = coarser_level(level, norm, q1)
            assert new <= level
            assert norm * (ns[level] / ns[new]) ** q1 <= COARSEN * (1 + 1e-12) or new == level
            if new > 0:                  # one more would break the bound
                assert norm * (ns[level] / ns[new - 1]) ** q1 > COARSEN * (1 - 1e-12)
    for budget in (1, 2, 5, 4096, 1 << 22):
        top = finest_level(budget)
        assert level_substeps(top) <= budget < level_substeps(top + 1)


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
def test_compiled_kernel_plans_the_pieces_of_the_python_controller_on_a_vibrating_vehicle(rtol):
    """0.3 s of the vibrating input (~65 kinks), RK4: sample by sample the compiled kernel takes
    the same pieces, redos and levels as ``Controlled._advance`` (the reference), and the same
    state to round-off."""
    imu = surfaces(0.3)["vibrating"]
    opt = ModelOptions.make("stabilised", "linear", integrator="rk4", rtol=rtol, atol=rtol * 1e-3)
    fast, ref = Simulator(options=opt), Simulator(options=opt, compiled=False)
    for i in range(len(imu.t)):
        s = RateSample(float(imu.t[i]), imu.omega[i].copy(), imu.force[i].copy())
        fast.push(s)
        ref.push(s)
        assert (fast.n_steps, fast.n_rejected) == (ref.n_steps, ref.n_rejected), f"sample {i}"
        assert int(fast.engine.ih[J_LEVEL]) == ref.integrator.level, f"sample {i}"
    assert fast.n_rejected > 0 and fast.n_steps > len(imu.t)     # pieces and redos happened
    np.testing.assert_allclose(fast.y, ref.y, rtol=0, atol=1e-15)


def _kinked(rtol: float, effects=("coriolis", "rotor_gyroscopic", "servo", "support_friction")):
    """RK4 at ``rtol`` and the system at rest under a roll rate linear from −0.01 to +0.01 rad/s
    over 1 ms (the two kinks of the test above, ~0.495 and ~0.505 ms)."""
    from gyro_platform.engine.integrators import RK4
    s, y = _system(effects)
    s.set_input(0.0, 1e-3, (-0.01, 0.0, 0.0), (0.01, 0.0, 0.0))
    return RK4(max_step=1e-3, rtol=rtol, atol=rtol * 1e-3), s, y


def test_a_chunk_cut_at_a_kink_ends_no_coarser_than_it_began():
    """One 1 ms interval at level 3 (4 substeps): with the friction its two kinks cut it into
    three pieces, whose small errors do not lower the level; without them (effect off) the same
    small errors do."""
    for effects, holds in ((("coriolis", "rotor_gyroscopic", "servo", "support_friction"), True),
                           (("coriolis", "rotor_gyroscopic", "servo"), False)):
        rk, s, y = _kinked(1e-6, effects)
        rk.level = 3
        _, st = rk.advance(s, 0.0, y, 1e-3)
        assert st.n_rejected == 0 and st.error_norm * (4 / 3) ** 4 <= COARSEN, st   # small errors
        assert (rk.level == 3) is holds, (effects, rk.level)


def test_a_micro_step_is_an_euler_step_unless_its_estimate_exceeds_the_tolerance():
    """A one-substep attempt shorter than ``MICRO_STEP``·max_step: at rtol 1e-8 the Euler step
    y + h f (two right-hand sides, its estimate h/2 (f(t+h, y1) − f(t, y)) within the tolerance);
    at an absurdly tight tolerance the classic RK4 step from the same f(t, y) (six)."""
    from gyro_platform.engine.integrators import MICRO_STEP
    h = 0.5 * MICRO_STEP * 1e-3
    t0 = 0.49e-3                               # inside the ramp towards the first kink
    rk, s, y = _kinked(1e-8)
    y = y + 1e-3 * s.rhs(0.0, y)               # not at rest: f changes along the step
    k1 = s.rhs(t0, y)
    y1, norm, est, nrhs, _ = rk._substeps(s, t0, y, 1, h)
    assert nrhs == 2 and norm <= 1.0
    np.testing.assert_array_equal(y1, y + h * k1)
    assert est == pytest.approx(np.abs(0.5 * h * (s.rhs(t0 + h, y1) - k1)).max(), rel=1e-12)
    rk.rtol, rk.atol = 1e-13, 1e-30
    y1, norm, est, nrhs, _ = rk._substeps(s, t0, y, 1, h)
    k2 = s.rhs(t0 + h / 2, y + h / 2 * k1)
    k3 = s.rhs(t0 + h / 2, y + h / 2 * k2)
    k4 = s.rhs(t0 + h, y + h * k3)
    assert nrhs == 6
    np.testing.assert_allclose(y1, y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), rtol=0, atol=1e-18)
