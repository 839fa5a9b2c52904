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

"""The view-free right-hand side of the linear stabilised model (``physics.rhs_linear``) is the
general kernel's physics: checked against the general kernel itself, reached by switching on
an effect that forces it (``mass_unbalance`` with zero unbalance, or ``earth_rate`` with zero
Earth rate: the same forces, the general code path), over every combination of the gimbal and
platform effects, random states with the servo saturated or not and mount axes inside and
outside the friction's linear zone, and random input intervals."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from gyro_platform.physics.options import ModelOptions
from gyro_platform.physics.params import NAV1
from gyro_platform.physics.rhs_linear import takes_linear_path
from gyro_platform.physics.system import FIDELITY_CODE, PlatformSystem

SWITCHABLE = ("gimbal_springs", "gimbal_dampers", "gimbal_friction", "bias_torque", "support_friction", "servo",
              "rotor_gyroscopic")
COMBOS = [frozenset(c) for r in (0, 1, 3, len(SWITCHABLE)) for c in itertools.combinations(SWITCHABLE, r)]
PARAMS = NAV1.with_(unbalance=0.0, earth_rate=0.0, bias_torque=(1e-7, -2e-7, 3e-7, 0.0, 5e-7),
                    gimbal_coulomb=(1e-6,) * 5)


def _random_state(sys_: PlatformSystem, rng: np.random.Generator) -> np.ndarray:
    lay = sys_.layout
    y = np.zeros(lay.n)
    y[lay.q] = rng.normal(0.0, 3e-3, 5) * rng.choice([1e-3, 1.0, 30.0])       # servo saturates at the top
    y[lay.Om] = rng.normal(0.0, 1e-4, 3)                                        # in and out of the ε zone
    y[lay.qd] = rng.normal(0.0, 1e-3, 5) * rng.choice([1e-4, 1.0])              # friction zone of the gimbals
    for sl in (lay.quat_IP, lay.quat_IB):
        q = rng.normal(size=4)
        y[sl] = q / np.linalg.norm(q) * rng.uniform(0.98, 1.02)                 # not quite unit: as mid-step
    y[lay.z] = rng.normal(0.0, 1e-5, 3)
    return y


@pytest.mark.parametrize("effects", COMBOS, ids=lambda e: "+".join(sorted(e)) or "none")
def test_linear_path_equals_general_kernel(effects):
    rng = np.random.default_rng(len(effects) * 7919 + sum(map(hash, sorted(effects))) % 1000)
    fast = PlatformSystem(PARAMS, ModelOptions.make("stabilised", "linear", effects))
    assert takes_linear_path(True, fast.I)
    for forcing in ("mass_unbalance", "earth_rate"):
        general = PlatformSystem(PARAMS, ModelOptions.make("stabilised", "linear", effects | {forcing}))
        assert not takes_linear_path(True, general.I)
        for _ in range(40):
            y = _random_state(fast, rng)
            w0, w1 = rng.normal(0.0, 1e-4, 3) * rng.choice([1.0, 100.0]), rng.normal(0.0, 1e-4, 3)
            f0, f1 = np.array([0.0, 0.0, 9.81]) + rng.normal(size=3), np.array([0.0, 0.0, 9.81])
            t0, dt = rng.uniform(0.0, 10.0), rng.uniform(1e-4, 0.05)
            t = t0 + rng.uniform(0.0, dt)
            for s in (fast, general):
                s.set_input(t0, t0 + dt, w0, w1, f0, f1)
            got, ref = fast.rhs(t, y), general.rhs(t, y)
            np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-13 * np.max(np.abs(ref)))


def test_other_models_keep_the_general_kernel():
    """Full and precession fidelity, the carried mode and the g-sensitive effects do not take it."""
    for mode, fid, extra in (("stabilised", "full", ()), ("stabilised", "precession", ()), ("carried", "linear", ()),
                             ("stabilised", "linear", ("anisoelastic",))):
        opts = ModelOptions.make(mode, fid)
        s = PlatformSystem(NAV1, opts.with_(effects=opts.effects | set(extra)))
        assert not takes_linear_path(FIDELITY_CODE[fid] == 1, s.I)
