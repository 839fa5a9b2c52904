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

"""``auto``'s chain: primary, fallback (exprb) and rescue (rk4) in that order, the
method that delivered first at the next hard stretch, the last refusal raised when none
delivers; and on the model: a driven stabilised platform at rtol 1e-10, which etd4 and exprb
refuse (they step over the support friction's regime changes; without the friction they
deliver): RK4 is auto's primary there, with fast rotors too, against a tight RK4 reference.
The rescue's order is tested on stand-in methods (no physical case of the catalogue reaches it
on a platform with the mount friction any more)."""
import numpy as np
import pytest

from gyro_platform.bench.roughness import OUT_EVERY, run_surface, surfaces
from gyro_platform.engine.integrators import Auto, AUTO_STICKY, Integrator, make_integrator, StepStats
from gyro_platform.engine.simulator import auto_primary, regime_switches, Simulator
from gyro_platform.errors import ToleranceError
from gyro_platform.physics.options import DEFAULT_EFFECTS, ModelOptions
from gyro_platform.physics.params import NAV1


class Scripted(Integrator):
    """A method that refuses the intervals starting at the times in ``refuses`` and otherwise
    adds its ``mark`` to the state (so the result tells which method did an interval)."""

    def __init__(self, name: str, mark: float, refuses=()):
        super().__init__()
        self.name, self.mark, self.refuses, self.calls = name, mark, set(refuses), []

    def _advance(self, system, t0, y, t1):
        self.calls.append(t0)
        if t0 in self.refuses:
            raise ToleranceError(f"{self.name} refuses t={t0}")
        return y + self.mark, StepStats(1, 1, 0.0, 0.0)


def chain(primary_refuses=(), fallback_refuses=(), rescue_refuses=()):
    p, f, r = Scripted("p", 1.0, primary_refuses), Scripted("f", 10.0, fallback_refuses), \
        Scripted("r", 100.0, rescue_refuses)
    return Auto(p, f, r), p, f, r


def step(a, t):
    return float(a.advance(None, float(t), np.zeros(1), t + 1.0)[0][0])


def test_fallback_then_rescue_and_the_one_that_delivered_goes_first():
    a, p, f, r = chain(primary_refuses={0.0}, fallback_refuses={0.0})
    assert a.name == "auto:p+f"
    assert step(a, 0.0) == 100.0                      # primary and fallback refused: the rescue
    assert (p.calls, f.calls, r.calls) == ([0.0], [0.0], [0.0])
    assert (a.n_fallback, a.n_rescue, a.sticky) == (1, 1, AUTO_STICKY - 1)
    assert step(a, 1.0) == 100.0 and f.calls == [0.0]  # the stretch stays with the rescue
    for t in range(2, AUTO_STICKY):
        step(a, float(t))
    assert a.sticky == 0 and a.n_fallback == AUTO_STICKY
    assert step(a, 1000.0) == 1.0                     # then the primary again
    assert (a.n_fallback, a.n_rescue) == (AUTO_STICKY, AUTO_STICKY)


def test_without_a_rescue_the_fallback_alone():
    p, f = Scripted("p", 1.0, {0.0}), Scripted("f", 10.0, {0.0})
    a = Auto(p, f)
    with pytest.raises(ToleranceError, match="f refuses"):
        step(a, 0.0)
    assert step(a, 1.0) == 1.0 and a.others == [f]


def test_a_refusal_of_every_method_is_raised_and_leaves_no_stretch():
    a, p, f, r = chain(primary_refuses={0.0}, fallback_refuses={0.0}, rescue_refuses={0.0})
    with pytest.raises(ToleranceError, match="r refuses"):
        step(a, 0.0)
    assert a.sticky == 0 and a.n_fallback == 0
    assert step(a, 1.0) == 1.0


def test_a_refusal_inside_a_stretch_tries_the_other_method():
    a, p, f, r = chain(primary_refuses={0.0}, fallback_refuses={1.0})
    assert step(a, 0.0) == 10.0
    assert step(a, 1.0) == 100.0                      # the fallback refused inside its stretch
    assert step(a, 2.0) == 100.0 and a.others[0] is r
    a.reset()
    assert a.others == [f, r] and a.sticky == 0 and a.n_fallback == 0


def test_a_primary_refused_by_the_caller_is_not_run_again():
    a, p, f, r = chain()
    a.primary_refused = True
    assert step(a, 0.0) == 10.0 and p.calls == []
    assert not a.primary_refused
    assert step(a, 1.0) == 10.0                       # the stretch, not the primary
    assert p.calls == []


def test_the_registry_builds_the_chain():
    a = make_integrator("auto", rtol=1e-10, atol=1e-13, fastest_rate=100.0)
    assert (a.primary.name, [m.name for m in a.others]) == ("etd4", ["exprb", "rk4"])
    a = make_integrator("auto", rtol=1e-6, atol=1e-9, fastest_rate=100.0)
    assert (a.primary.name, [m.name for m in a.others]) == ("rk4", ["exprb"]) and a.rescue is None
    a = make_integrator("auto", rtol=1e-10, atol=1e-13, fastest_rate=100.0, switches=True)
    assert (a.primary.name, [m.name for m in a.others]) == ("rk4", ["exprb"]) and a.rescue is None
    a = make_integrator("auto", rtol=1e-10, atol=1e-13, fastest_rate=3000.0, switches=True)
    assert a.primary.name == "rk4"          # substeps for the fastest mode: the others refuse the changes
    a = make_integrator("auto", rtol=1e-10, atol=1e-13, fastest_rate=3000.0)
    assert a.primary.name == "etd4"                   # RK4 would not resolve the fastest mode
    for rtol in (1e-4, 1e-6):
        a = make_integrator("auto", rtol=rtol, atol=rtol * 1e-3, fastest_rate=3000.0, switches=True)
        assert a.primary.name == "rk4"               # etd2 steps over the changes blind (test_switching)
        a = make_integrator("auto", rtol=rtol, atol=rtol * 1e-3, fastest_rate=100.0, switches=True)
        assert a.primary.name == "rk4"


@pytest.mark.parametrize("mode, effects, switches", [
    ("stabilised", DEFAULT_EFFECTS["stabilised"], True),
    ("stabilised", DEFAULT_EFFECTS["stabilised"] - {"support_friction"}, False),
    ("carried", DEFAULT_EFFECTS["carried"], False),
])
def test_the_model_says_whether_it_has_regime_changes(mode, effects, switches):
    opt = ModelOptions.make(mode, "linear", effects, rtol=1e-10, atol=1e-13)
    assert regime_switches(opt) is switches
    assert (auto_primary(opt) == "rk4") is switches


@pytest.mark.parametrize("surface", ["smooth", "vibrating"])
def test_a_driven_platform_at_rtol_1e_10_steps_with_rk4(surface):
    """The stabilised linear model on the 1 kHz vehicle IMU (and with the 37 Hz vibration) at
    rtol 1e-10: etd4 refuses at the support friction's first regime change even at steps of
    max_step/4096; auto's primary there is RK4 (the model has regime changes), which delivers
    within 1e-11 rad of RK4 at rtol 1e-13 with no interval left to the chain, as RK4 alone does."""
    imu = surfaces(0.3)[surface]
    with pytest.raises(ToleranceError, match="etd4 cannot meet the tolerance"):
        run_surface(imu, "etd4", 1e-10, 1e-13)
    ref, _ = run_surface(imu, "rk4", 1e-13, 1e-16, 1e-4, 1 << 16)
    got, st = run_surface(imu, "auto", 1e-10, 1e-13)
    assert st["integrator"] == "auto:rk4+exprb" and st["n_fallback"] == 0
    assert st["max_error_norm"] <= 1.0
    assert np.abs(got - ref).max() < 1e-11
    alone, st_rk4 = run_surface(imu, "rk4", 1e-10, 1e-13)
    np.testing.assert_array_equal(got, alone)
    assert st["n_rhs"] == st_rk4["n_rhs"]


@pytest.mark.parametrize("surface", ["smooth", "vibrating"])
def test_fast_rotors_at_rtol_1e_10_step_with_rk4(surface):
    """Rotors at ×3 (the nutation beyond what RK4 resolves in one 1 ms step), the same driven
    platform at rtol 1e-10: etd4, the exponential choice there, refuses at the friction's regime
    changes (every interval would go down the chain to the rescue, in Python); auto's primary is
    RK4, which substeps for the nutation and delivers within 1e-11 rad of RK4 at rtol 1e-13,
    with no interval left to the chain, as RK4 alone does."""
    imu = surfaces(0.3)[surface]
    fast = NAV1.with_(rotor_speed=tuple(3.0 * x for x in NAV1.rotor_speed))
    with pytest.raises(ToleranceError, match="etd4 cannot meet the tolerance"):
        run_surface(imu, "etd4", 1e-10, 1e-13, params=fast)
    ref, _ = run_surface(imu, "rk4", 1e-13, 1e-16, 1e-4, 1 << 16, params=fast)
    got, st = run_surface(imu, "auto", 1e-10, 1e-13, params=fast)
    assert st["integrator"] == "auto:rk4+exprb" and st["n_fallback"] == 0
    assert st["max_error_norm"] <= 1.0
    assert np.abs(got - ref).max() < 1e-11
    alone, _ = run_surface(imu, "rk4", 1e-10, 1e-13, params=fast)
    np.testing.assert_array_equal(got, alone)


@pytest.mark.parametrize("integrator", ["etd4", "exprb"])
def test_the_exponential_methods_refuse_rtol_1e_10_only_with_the_support_friction(integrator):
    """Why the rescue: etd4 and exprb step over the friction's regime changes (only RK4 ends its
    steps there); on the same input without the support friction they deliver rtol 1e-10."""
    imu = surfaces(0.15)["smooth"]
    effects = DEFAULT_EFFECTS["stabilised"]

    def run(eff):
        opt = ModelOptions.make("stabilised", "linear", eff, integrator=integrator, rtol=1e-10, atol=1e-13,
                                max_step=1e-3, max_substeps=4096)
        sim = Simulator(NAV1, opt)
        sim.push_many(imu.t, imu.omega, imu.force, output_every=OUT_EVERY)
        return sim.stats

    with pytest.raises(ToleranceError, match=f"{integrator} cannot meet the tolerance"):
        run(effects)
    assert run(effects - {"support_friction"})["max_error_norm"] <= 1.0
