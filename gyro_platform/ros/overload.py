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

"""Input overload: samples lost before the node took them (transport reports and stamp gaps)."""
from __future__ import annotations

from bisect import bisect_left, insort
from collections import deque

from ..io.gate import NS

__all__ = ["InputLoss"]


class InputLoss:
    """Input samples lost before the node took them: reported by the transport (rclpy QoS
    message-lost events, DDS queue overwrites) and inferred from gaps in the input stamps.

    Stamp gaps: the nominal input period is the mean of the single steps among the last
    ``WINDOW`` stamp steps of accepted samples, single = shorter than 1.5 × their lower quartile
    (robust while fewer than ~3/4 of the steps span a loss, and unbiased by jitter); a step of
    ``k`` nominal periods (``k`` ≥ 2, rounded) counts ``k − 1`` missing samples. Longer gaps than ``max_gap`` are the
    gate's (a pause, not an overload) and are not counted."""

    WINDOW = 64

    def __init__(self) -> None:
        self.transport = 0                 # samples the transport says it lost
        self.stamp_gaps = 0                # samples missing between consecutive stamps
        self.last_rx_ns: int | None = None  # receive time of the last loss (node clock)
        self._steps: deque[int] = deque()  # the last WINDOW steps (ns), oldest first
        self._sorted: list[int] = []       # the same steps, sorted
        self._last_stamp: int | None = None

    @property
    def total(self) -> int:
        return self.transport + self.stamp_gaps

    def on_transport_loss(self, count: int, rx_ns: int | None) -> None:
        if count > 0:
            self.transport += int(count)
            self.last_rx_ns = rx_ns

    def on_stamp(self, stamp_ns: int, rx_ns: int | None, max_gap_s: float) -> None:
        """One accepted sample's stamp (ns). Pure Python on a sorted window (no numpy per
        call): the quartile is numpy's default (linear) percentile, the mean is exact."""
        last, self._last_stamp = self._last_stamp, stamp_ns
        if last is None or stamp_ns <= last:
            return
        step = stamp_ns - last
        srt = self._sorted
        # a loss needs step ≥ 1.5 period ≥ 1.5 min(window): below that nothing to compute
        if len(srt) >= 8 and step <= max_gap_s * NS and step >= 1.5 * srt[0]:
            q = _quartile(srt)
            single = srt[:bisect_left(srt, 1.5 * q)]         # steps < 1.5 q (q > 0: never empty)
            period = sum(single) / len(single)              # mean of the single steps
            k = int(round(step / period)) if period > 0 else 1
            if k >= 2:
                self.stamp_gaps += k - 1
                self.last_rx_ns = rx_ns
        steps = self._steps
        if len(steps) == self.WINDOW:
            old = steps.popleft()
            if old != step:             # a steady input replaces a step by an equal one: srt stays
                del srt[bisect_left(srt, old)]
                insort(srt, step)
        else:
            insort(srt, step)
        steps.append(step)

    def restart(self) -> None:
        """A new time base (reset): stamp steps across it are not gaps."""
        self._steps.clear()
        self._sorted.clear()
        self._last_stamp = None


def _quartile(srt: list[int]) -> float:
    """25th percentile of sorted values, as ``numpy.percentile(..., 25)`` (linear interpolation)."""
    pos = 0.25 * (len(srt) - 1)
    lo = int(pos)
    frac = pos - lo
    if frac == 0.0:
        return float(srt[lo])
    a, b = srt[lo], srt[lo + 1]
    diff = b - a
    return b - diff * (1.0 - frac) if frac >= 0.5 else a + diff * frac
