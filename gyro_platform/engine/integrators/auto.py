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

"""``auto``: a cheap primary method with a robust fallback for the intervals it refuses."""
from __future__ import annotations

from .base import Controlled, Integrator
from ...errors import ToleranceError

__all__ = ["Auto", "AUTO_STICKY"]


class Auto(Integrator):
    """``auto``: a cheap primary method (compiled batch path); an interval it cannot bring within
    the tolerance within the budget is done by the fallback (exprb, re-linearised at every
    step), and so are the next ``AUTO_STICKY`` intervals (the hard stretch usually lasts), then
    the primary is tried again. Both honour rtol/atol."""

    def __init__(self, primary: "Controlled", fallback: Integrator) -> None:
        super().__init__(fallback.max_step, fallback.rtol, fallback.atol, fallback.max_substeps)
        self.primary, self.fallback = primary, fallback
        self.name = f"auto:{primary.name}+{fallback.name}"
        self.order = primary.order
        self.uses_linear_part = primary.uses_linear_part
        self.n_fallback = 0
        self.sticky = 0

    def _advance(self, system, t0, y, t1):
        if self.sticky == 0:
            try:
                return self.primary.advance(system, t0, y, t1)
            except ToleranceError:
                self.sticky = AUTO_STICKY
        self.sticky -= 1
        self.n_fallback += 1
        return self.fallback.advance(system, t0, y, t1)

    def reset(self) -> None:
        self.primary.reset()
        self.fallback.reset()
        self.n_fallback = 0
        self.sticky = 0


#: intervals auto gives to its fallback after the primary refused one
AUTO_STICKY = 100
