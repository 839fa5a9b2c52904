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

"""Parameter and option validation: bad values are refused with the parameter named."""
import math

import pytest

from gyro_platform.physics.options import ModelOptions, OptionsError
from gyro_platform.physics.params import NAV1, ParameterError, PlatformParams


@pytest.mark.parametrize("changes,match", [
    ({"frame4": (1.5e-4, -1e-4, 1.5e-4)}, r"'frame4\[1\]' = -0.0001 is outside its allowed range \[0, 1000\]"),
    ({"rotor_C": (2e-5, float("nan"), 2e-5)}, r"'rotor_C\[1\]' = nan is not finite"),
    ({"housing5": (1e-5, 1e-5, 5e-5)}, "triangle inequality"),
    ({"platform": (0.08, 0.09, 0.1, 0.2, 0, 0)}, "not positive definite"),
    ({"mounting": (0, 0, 0.5, 0.5)}, "not a unit quaternion"),
    ({"servo_limit": 0.0}, r"'servo_limit' = 0 is outside its allowed range \(0"),
    ({"latitude": 2.0}, "'latitude'"),
    ({"rotor_C": (3e-5, 2e-5, 2e-5)}, r"rotor_C\[0\].*2·rotor_A\[0\]"),
])
def test_bad_parameters_name_the_parameter(changes, match):
    with pytest.raises(ParameterError, match=match):
        NAV1.with_(**changes)


def test_from_dict_rejects_unknown_and_bad_types():
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) \['rotor_spin'\]"):
        PlatformParams.from_dict({"rotor_spin": 1})
    with pytest.raises(ParameterError, match="'servo_kp' must be a number"):
        PlatformParams.from_dict({"servo_kp": "fast"})
    p = PlatformParams.from_dict({"spring": 0.2, "latitude": math.radians(10)})
    assert p.spring == (0.2,) * 5


def test_options_validation():
    with pytest.raises(OptionsError, match="'fidelity'"):
        ModelOptions.make("carried", "exact")
    with pytest.raises(OptionsError, match="unknown effect"):
        ModelOptions.make("carried", "full", ["warp_drive"])
    with pytest.raises(OptionsError, match="need mode 'stabilised'"):
        ModelOptions.make("carried", "full", ["servo"])
