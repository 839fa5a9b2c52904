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

"""The standard benchmark scenes: vehicle motions sampled at 1 kHz (SI units, rad/s, m/s²)."""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..physics.options import DEFAULT_EFFECTS
from ..scenes.motions import CoordinatedTurn, RateSteps, Sine, Sinusoidal

__all__ = ["SAMPLE_RATE", "BenchScene", "ship_scene", "aircraft_scene"]

SAMPLE_RATE = 1000.0     # Hz, vehicle input


@dataclass
class BenchScene:
    """A vehicle motion: sample times ``t`` (s), body rates ``omega`` (N, 3; rad/s, FLU),
    specific force ``force`` (N, 3; m/s²) and the effects switched on."""

    name: str
    description: str
    t: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    effects: frozenset


def ship_scene(duration: float = 600.0) -> BenchScene:
    """Ship rolling and pitching, 10° at 0.1 Hz (pitch 5° at 0.1 Hz, quarter period later)."""
    m = Sinusoidal(roll=Sine(math.radians(10.0), 0.1, 0.0), pitch=Sine(math.radians(5.0), 0.1, math.pi / 2))
    t, w, f = m.arrays(duration, SAMPLE_RATE)
    eff = DEFAULT_EFFECTS["stabilised"] | {"mass_unbalance"}
    return BenchScene("ship", f"ship rolling 10° / pitching 5° at 0.1 Hz, stabilised, {duration:g} s", t, w, f, eff)


def aircraft_scene(duration: float = 120.0) -> BenchScene:
    """Aircraft: right coordinated turn (60 m/s, 30° bank), then yaw/roll rate steps."""
    half = duration / 2
    turn = CoordinatedTurn(speed=60.0, bank=math.radians(30.0), roll_time=3.0, start=2.0, hold=half - 10.0)
    t1, w1, f1 = turn.arrays(half, SAMPLE_RATE)
    steps = RateSteps(times=[0.0, 5.0, 10.0, 15.0, 25.0, 35.0, 45.0],
                      rates=[[0, 0, 0], [0.5, 0, 0], [0, 0, 0], [0, 0, 0.3], [0, 0, 0], [0, 0.2, 0], [0, 0, 0]])
    t2, w2, f2 = steps.arrays(half, SAMPLE_RATE)
    t = np.concatenate([t1, t2[1:] + t1[-1]])
    w = np.vstack([w1, w2[1:]])
    f = np.vstack([f1, f2[1:]])
    eff = DEFAULT_EFFECTS["stabilised"] | {"mass_unbalance"}
    return BenchScene("aircraft", f"aircraft: coordinated turn then rate steps, stabilised, {duration:g} s",
                      t, w, f, eff)
