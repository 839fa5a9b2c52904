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

from ..pipeline.gate_rules import NS

__all__ = ["InputLoss"]


class InputLoss:
    """Input samples lost before the node took them: reported by the transport (rclpy QoS
    message-lost events, DDS queue overwrites) and inferred from the header stamps of the
    accepted samples (a keep-last queue that overwrites samples raises no event on Cyclone DDS,
    and it gives no publication sequence numbers).

    Stamp gaps, by segment: a segment is a run of stamps at one nominal period ``P``; its loss
    is ``round((last stamp − first stamp) / P) − steps`` — the samples the span holds at the
    nominal rate minus those taken — recomputed at every step that is not a single (and when
    the period changes), so a period learnt late (a node
    that never saw two consecutive samples until its queue drained) counts the whole segment.
    ``P`` is the mean of the segment's *single* steps: shorter than 1.5 × the current ``P``
    (the cluster at the window's minimum: jitter averages out, multi-period steps stay out however
    many there are). A step shorter than ``P`` / 1.5 makes it the period at once (the segment is
    counted at it); once ``CONFIRM`` singles confirm it, the steps of the window before it tell
    why it appeared:

    * they are a regular rate (¾ of them within half a period of their minimum), neither its
      multiples nor spread multiples of any shorter period (exact stamps of a node that takes
      every 7th to 11th sample look regular, but their steps differ by whole periods): the
      publisher sped up — the segment closes where the new rate began, counted at the old
      period, and a new one starts there;
    * else the period was hidden by losses (its multiples, the spread steps of an overload, e.g.
      a node stalled at its start, or multiples of a period still hidden): the segment stays,
      counted at the new period from its first stamp (and again at each shorter period learnt
      later).

    Stamps whose every step spans losses (no single ever, no drain): every ``WINDOW`` steps, when
    the window's steps are spread, the largest period they are all multiples of (the smallest
    difference between their groups, divided by 1…4, refined as the least-squares period of the
    steps, shortest first: exact for exact stamps, within the jitter's mean for jittered ones)
    becomes ``P`` if shorter.

    A publisher that slows down: ``WINDOW`` steps in a row without a single, ¾ of them within
    half a period of the window's minimum (a regular rate, not the spread of an overload) — the
    segment closes where those steps began and they start a new one at their period. An exact
    integer slow-down (100 → 50 Hz) cannot be told from every other sample lost and counts as loss
    until the rest of the window spreads. A step longer than ``max_gap`` is a pause (the gate's,
    not counted; the segment closes, the period is kept) unless the receive times say the samples
    came without one (receive step ≤ ``max_gap``: a replay faster than its stamps loses them).
    Per sample: O(1) and an insertion into the sorted window of ``WINDOW`` steps."""

    WINDOW = 64
    SINGLE = 1.5
    CONFIRM = 8
    #: steps within this many periods of an integer multiple are "multiples" (jitter tolerance)
    MULTIPLE_TOL = 0.15

    def __init__(self) -> None:
        self.transport = 0                 # samples the transport says it lost
        self.closed = 0                    # stamp-gap losses of closed segments
        self.last_rx_ns: int | None = None  # receive time of the last loss (node clock)
        self._steps: deque[int] = deque()  # the last WINDOW steps (ns), oldest first
        self._sorted: list[int] = []       # the same steps, sorted
        self._last_stamp: int | None = None
        self._last_rx: int | None = None
        self._forget_period()
        self._seg_start: int | None = None
        self._seg_steps = 0
        self._current = 0                  # stamp-gap loss of the open segment

    def _forget_period(self) -> None:
        self._sum = 0                      # singles of the nominal period: sum (ns) and count
        self._n = 0
        self._ref: float | None = None     # the nominal period (ns) steps are classified against
        self._no_single = 0                # steps in a row without a single
        self._pending: tuple | None = None  # a shorter period not yet confirmed (see _decide)

    @property
    def period_ns(self) -> float | None:
        """The nominal input period (ns) of the open segment; None before a step."""
        return self._ref

    @property
    def stamp_gaps(self) -> int:
        return self.closed + self._current

    @property
    def total(self) -> int:
        return self.transport + self.stamp_gaps

    def on_transport_loss(self, count: int, rx_ns: int | None) -> None:
        if count > 0:
            self.transport += int(count)
            self.last_rx_ns = rx_ns

    def on_stamp(self, stamp_ns: int, rx_ns: int | None, max_gap_s: float, seen_ns: int | None = None) -> None:
        """One accepted sample's stamp (ns), its receive time (``rx_ns``, None when unknown)
        and the time that stands for it in the WARN's recency (``seen_ns``, default
        ``rx_ns``). Pure Python, no numpy."""
        last = self._last_stamp
        if last is not None and stamp_ns <= last:
            return                         # repeated or backward: no step (the gate's to judge)
        self._last_stamp = stamp_ns
        last_rx, self._last_rx = self._last_rx, rx_ns
        if last is None:
            self._open(stamp_ns)
            return
        step = stamp_ns - last
        gap = max_gap_s * NS
        if step > gap and (rx_ns is None or last_rx is None or not 0 <= rx_ns - last_rx <= gap):
            self._close()                  # a pause (the gate's): not lost samples
            self._open(stamp_ns)
            self._pending = None
            self._steps.clear()
            self._sorted.clear()
            self._no_single = 0
            return
        self._seg_steps += 1
        ref = self._ref
        single = ref is not None and step < self.SINGLE * ref and step * self.SINGLE >= ref and self._pending is None
        if single:
            self._sum += step              # a single step at a known period: the common case, inline
            self._n += 1
            self._ref = self._sum / self._n
            self._no_single = 0
        else:
            self._classify(step, last)
        steps, srt = self._steps, self._sorted          # the window, and sorted
        if len(steps) == self.WINDOW:
            old = steps.popleft()
            if old != step:             # a steady input replaces a step by an equal one: srt stays
                del srt[bisect_left(srt, old)]
                insort(srt, step)
        else:
            insort(srt, step)
        steps.append(step)
        if self._no_single >= self.WINDOW:
            self._slowed_down(stamp_ns)
        elif len(self._steps) == self.WINDOW and self._seg_steps % self.WINDOW == 0:
            self._hidden_period()
        elif single:
            return                         # no loss in this step: the count is redone at the next one
        cur = int(round((stamp_ns - self._seg_start) / self._ref)) - self._seg_steps
        if cur > self._current:
            self.last_rx_ns = rx_ns if rx_ns is not None else seen_ns
        self._current = cur if cur > 0 else 0

    # ---- segments -----------------------------------------------------------------------
    def _open(self, stamp_ns: int) -> None:
        self._seg_start, self._seg_steps, self._current = stamp_ns, 0, 0

    def _close(self) -> None:
        self.closed += self._current
        self._current = 0

    def _count(self, span: int, steps: int) -> int:
        p = self._ref
        return max(0, int(round(span / p)) - steps) if p else 0

    def _classify(self, step: int, last: int) -> None:
        ref = self._ref
        if ref is None:
            self._sum, self._n, self._ref, self._no_single = step, 1, float(step), 0
        elif step * self.SINGLE < ref:                  # shorter than the nominal period
            if self._n >= self.CONFIRM and self._pending is None:
                # sped up, or the period was hidden by losses: decided once the new one is
                # confirmed; meanwhile the segment is counted at the new period
                self._pending = (last, self._seg_steps - 1, self._current, list(self._sorted), ref)
            self._sum, self._n, self._ref, self._no_single = step, 1, float(step), 0
        elif step < self.SINGLE * ref:
            self._sum += step
            self._n += 1
            self._ref = self._sum / self._n
            self._no_single = 0
            if self._pending is not None and self._n >= self.CONFIRM:
                self._decide()
        else:
            self._no_single += 1

    def _decide(self) -> None:
        """The shorter period is confirmed: were the steps before it a regular slower rate that
        is neither its multiples nor spread multiples of a shorter period (the publisher sped
        up: the segment closes where the new rate began, with its count at the old period), or
        not (losses hid it: the segment stays, counted at it)?"""
        at, steps_before, count_before, window, old_ref = self._pending
        self._pending = None
        if (self._regular(window, old_ref) and not self._multiples(window, self._ref)
                and self._base_period(window) is None):
            self.closed += count_before
            self._seg_start, self._seg_steps = at, self._seg_steps - steps_before

    @staticmethod
    def _regular(srt: list[int], p: float) -> int:
        """The sorted steps ``srt`` a regular rate of period ≈ ``p``: ¾ of them within half a
        period of their minimum (not the spread steps of an overload)? The count of those
        near the minimum if so, else 0."""
        near = bisect_left(srt, srt[0] + 0.5 * p) if srt else 0
        return near if near * 4 >= 3 * len(srt) else 0

    def _multiples(self, srt: list[int], p: float) -> bool:
        """Are the sorted steps ``srt`` multiples of ``p`` that differ (losses hid ``p``)?"""
        if not srt or srt[-1] - srt[0] < (1.0 - self.MULTIPLE_TOL) * p:
            return False
        tol = self.MULTIPLE_TOL
        return all(abs(s / p - round(s / p)) <= tol for s in srt)

    def _hidden_period(self) -> None:
        """Every ``WINDOW`` steps: are the window's steps spread multiples of a period shorter
        than the nominal one (exact stamps, every step spanning losses: no single ever seen)?
        That period (:meth:`_base_period`) becomes the nominal one."""
        p = self._base_period(self._sorted)
        if p is not None and p * self.SINGLE < self._ref:
            self._sum, self._n, self._ref, self._no_single = p, 1, p, 0
            self._pending = None

    def _base_period(self, srt: list[int]) -> float | None:
        """The period the sorted steps ``srt`` are spread multiples of, None if they are not
        (jittered stamps, or a tight cluster: a regular rate). The steps grouped (within 2 %),
        the smallest difference between groups divided by 1…4 is tried (refined by
        :func:`_fitted_period`); the largest that every step is a multiple of (the simplest
        account)."""
        if not srt or srt[-1] - srt[0] < 0.3 * srt[0]:
            return None
        groups = [srt[0]]
        for x in srt:
            if x - groups[-1] > 0.02 * srt[0]:
                groups.append(x)
        if len(groups) < 2:
            return None
        d = min(b - a for a, b in zip(groups, groups[1:]))
        for j in (1, 2, 3, 4):
            p = _fitted_period(srt, d / j)
            if p is not None and self._multiples(srt, p):
                return p
        return None

    def _slowed_down(self, stamp_ns: int) -> None:
        """``WINDOW`` steps without a single: a regular slower rate starts a new segment there."""
        srt = self._sorted
        near = self._regular(srt, self._ref)
        if not near:
            self._no_single = 0            # spread: an overload, not a slower publisher
            return
        span = sum(self._steps)
        self._current = self._count(stamp_ns - span - self._seg_start, self._seg_steps - len(self._steps))
        self._close()
        self._seg_start, self._seg_steps = stamp_ns - span, len(self._steps)
        p0 = sum(srt[:near]) / near
        singles = srt[:bisect_left(srt, self.SINGLE * p0)]      # the cluster's jitter in full
        self._sum, self._n, self._no_single = sum(singles), len(singles), 0
        self._ref = self._sum / self._n
        self._pending = None

    def restart(self) -> None:
        """A new time base (reset): stamp steps across it are not gaps; the period is learnt
        again."""
        self._close()
        self._steps.clear()
        self._sorted.clear()
        self._last_stamp = None
        self._last_rx = None
        self._seg_start, self._seg_steps = None, 0
        self._forget_period()


def _fitted_period(srt: list[int], p: float) -> float | None:
    """The period ``p`` (ns) refined over the sorted steps ``srt``, shortest first: each step's
    multiple taken at the estimate so far, the estimate the least-squares period of
    step = multiple × period (Σ steps / Σ multiples). With jittered stamps the smallest
    difference between groups of steps is off by the jitter, and a long step's multiple taken at
    it can be off by one (77 periods read as 78 at 0.7 % short); refined on the short steps
    first it is not. None if a step is shorter than half the period."""
    ss = sm = 0
    for s in srt:
        m = round(s / p)
        if m < 1:
            return None
        ss += s
        sm += m
        p = ss / sm
    return p
