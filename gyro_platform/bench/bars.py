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

"""Issue 31's bars as data: what each headline figure is held to (:class:`Bar`: at least or at
most a bound), written once and read by the sections that print them (``consumer``,
``roughness``) and by the headline, which computes ✓/✗ with :meth:`Bar.met`. Reports name a
bar by its key in :data:`BARS`. Imports nothing of this package."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Bar", "BARS"]


@dataclass(frozen=True)
class Bar:
    """``value ≥ bound`` (``at_least``) or ``value ≤ bound``; ``unit``: ``"×"`` for a ratio or
    a real-time factor (written before the number), else written after it (``" µs"``)."""

    at_least: bool
    bound: float
    unit: str = "×"

    def met(self, value: float | None) -> bool | None:
        """Whether ``value`` holds the bar (None for no value or NaN)."""
        if value is None or value != value:
            return None
        return value >= self.bound if self.at_least else value <= self.bound

    def __str__(self) -> str:
        sign = "≥" if self.at_least else "≤"
        return f"{sign} ×{self.bound:g}" if self.unit == "×" else f"{sign} {self.bound:g}{self.unit}"


#: key → bar (issue 31)
BARS: dict[str, Bar] = {
    "cold_over_warm": Bar(False, 3.0),          # a command's whole time, empty kernel cache ÷ warm
    "replay_1khz": Bar(True, 500.0),            # real-time factor of a 1 kHz Imu replay
    "replay_over_floor": Bar(False, 2.0),       # replay wall ÷ its I/O floor's
    "replay_husky": Bar(True, 300.0),           # real-time factor of the husky replay
    "node_median": Bar(False, 10.0, " µs"),     # NodeCore.on_message per 1 kHz Imu message
    "node_p99": Bar(False, 50.0, " µs"),
    "roughness": Bar(False, 1.5),               # rhs per sample at equal accuracy, vibrating ÷ smooth 1 kHz IMU
    "peer": Bar(True, 10.0),                    # MuJoCo ÷ kernel CPU at equal accuracy
}
