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

"""Explicit Runge–Kutta methods on the controlled grid of :class:`~.base.Controlled`.

``rk4``: classic RK4 with an embedded third-order estimate (the FSAL stage f(t+h, y1):
``err = h/6 (k4 − k5)``). Explicit: at h·ω > 2.8 it must substep; it damps nutation by
≈ (hω)⁶/72 per step, which the tolerance bounds. It ends its steps at the kinks the system
predicts (``locates_switches``: the support friction's regime changes); a one-substep attempt
shorter than ``MICRO_STEP``·max_step is tried as an Euler step first (``base.is_micro_step``).
(DOP853 and RK45 are scipy's: :mod:`.scipy_methods`.)
"""
from __future__ import annotations

import math

import numpy as np

from .base import Controlled, is_micro_step, is_rejected
from ...physics.jit import plain

_is_micro_step = plain(is_micro_step)

__all__ = ["RK4"]


class RK4(Controlled):
    """Classic explicit RK4; embedded third-order estimate ``h/6 (k4 − k5)``, k5 = f(t+h, y1)
    (first same as last: k5 is the next substep's k1)."""

    name, order, q1 = "rk4", 4, 4
    locates_switches = True

    def _substeps(self, system, t0, y0, nsub, h):
        rhs = system.rhs
        hh, h6 = 0.5 * h, h / 6.0
        y = y0.copy()
        k1 = np.array(rhs(t0, y), dtype=float)
        nrhs, worst, est = 1, 0.0, 0.0
        if _is_micro_step(nsub, h, self.max_step):        # Euler first (see is_micro_step)
            y1 = y + h * k1
            k5 = np.array(rhs(t0 + h, y1), dtype=float)
            nrhs += 1
            err = h / 6.0 * ((4.0 * k5 - 3.0 * k1) - k5)      # h/2 (k5 − k1), as the kernel forms it
            nrm, est_e, _ = self._judge(err, y, y1, 0.0, 0.0)
            if nrm <= 1.0:
                return y1, nrm, est_e, nrhs, t0
        for i in range(nsub):
            t = t0 + i * h
            k2 = rhs(t + hh, y + hh * k1)
            k3 = rhs(t + hh, y + hh * k2)
            k4 = rhs(t + h, y + h * k3)
            y1 = y + h6 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            k5 = np.array(rhs(t + h, y1), dtype=float)
            nrhs += 4
            err = h6 * (k4 - k5)
            nrm, est, worst = self._judge(err, y, y1, est, worst)
            if is_rejected(nrm):
                return y1, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y, k1 = y1, k5
        return y, worst, est, nrhs, t0
