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

"""State snapshots at output instants: what the stepping hands to the output code.

``Simulator.push_block`` integrates a chunk of samples in one compiled call and records, after
each sample listed in ``out_idx``, everything the outputs at that instant depend on; the output
code (``engine.outputs``) turns a ``Snapshots`` into an ``OutputBlock``. ``Simulator.outputs()``
is the K = 1 case: ``Simulator._snapshot()`` gives the current instant as a ``Snapshots``.

The input over the interval ending at the instant is the ``seg`` row in the layout of
``physics.model`` (``SEG_N`` = 14 floats, field offsets ``SEG_*``):
``[t0_rel, dt, w0(3), w1(3), f0(3), f1(3)]`` —
interval start (s, relative to the first sample), length (s, > 0), vehicle rate at its start and
end (rad/s, vehicle axes), specific force at its start and end (m/s², vehicle axes; zeros when
the samples carry none). The input at the instant itself is ``w1``/``f1``; the vehicle angular
acceleration is ``(w1 − w0)/dt``. At the first sample after a start or reset there is no
interval: ``w0 = w1``, ``f0 = f1``, ``t0_rel = 0``, ``dt = 1`` (input held constant, zero slope),
exactly what ``system.seg`` holds then (``set_input(0, 1, w, w, f, f)``), so that a reset is a
fresh start.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.system import SEG_N

__all__ = ["Snapshots", "SEG_N"]


@dataclass(frozen=True, slots=True)
class Snapshots:
    """K output instants of one simulator (arrays over the instants, C-contiguous float64).

    ``t`` (K,) s: sample time in the samples' time base (``t_start + t_rel``, what
    ``Outputs.t`` reports); ``t_rel`` (K,) s since the first sample (the integration time: the
    right-hand side and the reference frame use it); ``y`` (K, n): integration state after the
    sample (``layout`` of the simulator's system); ``seg`` (K, 14): the input segment ending at
    the sample (module doc); ``n_steps`` (K,) int64: accepted substeps since the start (or
    reset) up to the sample (``status['n_steps']``)."""

    t: np.ndarray
    t_rel: np.ndarray
    y: np.ndarray
    seg: np.ndarray
    n_steps: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @staticmethod
    def empty(n: int) -> "Snapshots":
        """No instant (state size ``n``)."""
        return Snapshots(np.zeros(0), np.zeros(0), np.zeros((0, n)), np.zeros((0, SEG_N)), np.zeros(0, np.int64))

    def take(self, k: slice | np.ndarray) -> "Snapshots":
        """The instants ``k`` (a slice or an index array)."""
        return Snapshots(self.t[k], self.t_rel[k], self.y[k], self.seg[k], self.n_steps[k])
