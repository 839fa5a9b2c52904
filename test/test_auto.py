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
deliver), delivered by the rescue against a tight RK4 reference."""
import numpy as np
import pytest

from gyro_platform.bench.roughness import OUT_EVERY, run_surface, surfaces
from gyro_platform.engine.integrators import Auto, AUTO_STICKY, Integrator, make_integrator, StepStats
from gyro_platform.engine.simulator import Simulator
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


@pytest.mark.parametrize("surface", ["smooth", "vibrating"])
def test_a_driven_platform_at_rtol_1e_10_is_delivered_not_refused(surface):
    """The stabilised linear model on the 1 kHz vehicle IMU (and with the 37 Hz vibration):
    etd4 (auto's primary at rtol 1e-10) refuses at the support friction's first regime change
    even at steps of max_step/4096; auto delivers through the rescue, within 1e-11 rad of RK4 at
    rtol 1e-13."""
    imu = surfaces(0.3)[surface]
    with pytest.raises(ToleranceError, match="etd4 cannot meet the tolerance"):
        run_surface(imu, "etd4", 1e-10, 1e-13)
    ref, _ = run_surface(imu, "rk4", 1e-13, 1e-16, 1e-4, 1 << 16)
    got, st = run_surface(imu, "auto", 1e-10, 1e-13)
    assert st["integrator"] == "auto:etd4+exprb" and st["n_fallback"] >= st["n_rescue"] > 0
    assert st["max_error_norm"] <= 1.0
    assert np.abs(got - ref).max() < 1e-11


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
