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

"""Vehicle input samples: what drives the platform.

A sample is the vehicle's inertial angular rate ``omega`` (rad/s, vehicle body axes, FLU per
REP-103) and optionally its specific force ``specific_force`` (m/s², vehicle axes, what an
accelerometer measures: +9.81 up at rest, REP-145) at time ``t`` (s). Between two samples the
simulator interpolates linearly (so the angular acceleration is constant over the interval).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True, init=False)
class RateSample:
    """One timed vehicle sample. ``omega`` rad/s and ``specific_force`` m/s², vehicle axes."""

    t: float
    omega: np.ndarray
    specific_force: np.ndarray | None = None

    def __init__(self, t: float, omega: np.ndarray, specific_force: np.ndarray | None = None):
        # the generated frozen __init__ (object.__setattr__ per field) costs twice as much, and a
        # sample is made per input message: set the slots through their descriptors
        _SET_T(self, t)
        _SET_OMEGA(self, omega)
        _SET_FORCE(self, specific_force)

    @staticmethod
    def of(t: float, omega, specific_force=None) -> "RateSample":
        """Build a sample from any 3-sequences (copies into float arrays)."""
        f = None if specific_force is None else np.asarray(specific_force, dtype=float).reshape(3)
        return RateSample(float(t), np.asarray(omega, dtype=float).reshape(3), f)

    def is_finite(self) -> bool:
        ok = np.isfinite(self.t) and bool(np.all(np.isfinite(self.omega)))
        if self.specific_force is not None:
            ok = ok and bool(np.all(np.isfinite(self.specific_force)))
        return bool(ok)


_SET_T, _SET_OMEGA, _SET_FORCE = (getattr(RateSample, n).__set__ for n in ("t", "omega", "specific_force"))
