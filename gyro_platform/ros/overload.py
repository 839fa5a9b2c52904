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

    ``total`` counts each lost sample once: both sources see the same overwrites (the DDS
    transport reports its queue's, and the stamps show their gaps), so per run of one time base
    (between :meth:`restart` calls) the total is the larger of the transport's count and the
    stamp gaps', summed over the runs. The transport alone counts what the stamps cannot see
    (unstamped input, a loss before a run's first stamp), the stamps alone what the transport
    cannot (Cyclone's keep-last overwrites); when both see some of each, the larger is a lower
    bound of their union (never more than the samples lost).

    Stamp gaps, by segment: a segment is a run of stamps at one nominal period ``P``; its loss
    is ``round((last stamp − first stamp) / P) − steps`` — the samples the span holds at the
    nominal rate minus those taken — recomputed at every step that is not a single (and when
    the period changes), so a period learnt late (a node
    that never saw two consecutive samples until its queue drained) counts the whole segment.
    ``P`` is the mean of the segment's *single* steps: shorter than 1.5 × the current ``P``
    (the cluster at the window's minimum: jitter averages out, multi-period steps stay out however
    many there are). A step shorter than ``P`` / 1.5 is the period hidden by losses only when
    supported (a single short step, or a jittered pair summing to a regular one, is no period:
    a 10 ms publisher's exact stamps are multiples of any 0.1 ms catch-up step): at once when
    the window's steps are multiples of it spread over ``SPREAD`` or more multiples, at most half
    of them at one; or after ``DRAIN`` such steps in a row, near each other (a keep-last queue
    drained), when the steps before are no regular rate or the period has not had ``CONFIRM``
    singles yet. ``CONFIRM`` of them in a row after a regular rate are a publisher that sped up
    (the segment closes where they began, counted at the old period). Other short steps are
    jitter or a burst after a stall: no single, the count stays at ``P``. A period taken at
    once (the segment is counted at it) is checked once ``CONFIRM`` singles confirm it: the
    steps of the window before it tell why it appeared:

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
    becomes ``P`` if shorter and the steps spread over its multiples as above.

    A publisher that slows down: ``WINDOW`` steps in a row without a single, ¾ of them within
    half a period of the window's minimum (a regular rate, not the spread of an overload) — the
    segment closes where those steps began and they start a new one at their period (a period
    that never had ``CONFIRM`` singles is abandoned instead: the segment is recounted at the
    slower one, no count made at it is kept; the count of a segment is never more than its
    span at ``P`` minus the samples taken). A slower rate whose steps are whole multiples of
    ``P`` (100 → 50 Hz) cannot be told from a node that takes every m-th sample at a steady pace
    (its callbacks cost the same each time): it counts as loss (:meth:`_steady_overload`). A
    step longer than ``max_gap`` is a pause (the gate's, not counted; the segment closes, the
    period is kept) unless the receive times say the samples came without one (receive step
    ≤ ``max_gap``: a replay faster than its stamps loses them). Per sample: O(1) and an
    insertion into the sorted window of ``WINDOW`` steps."""

    WINDOW = 64
    SINGLE = 1.5
    CONFIRM = 8
    #: steps within this many periods of an integer multiple are "multiples" (jitter tolerance)
    MULTIPLE_TOL = 0.15
    #: distinct multiples the steps must spread over for a period hidden by losses
    SPREAD = 3
    #: short steps in a row after spread steps that make a period hidden by losses (a drain)
    DRAIN = 3

    def __init__(self) -> None:
        self.transport = 0                 # samples the transport says it lost
        self.closed = 0                    # stamp-gap losses of closed segments
        self._union_closed = 0             # total of the runs (time bases) before this one
        self._run_transport = 0            # transport and stamp-gap counts when this run began
        self._run_stamp = 0
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
        self._fast: tuple | None = None    # short steps not (yet) a period (see _short_step)

    @property
    def period_ns(self) -> float | None:
        """The nominal input period (ns) of the open segment; None before a step."""
        return self._ref

    @property
    def stamp_gaps(self) -> int:
        """Samples lost by the gaps in the header stamps (all runs)."""
        return self.closed + self._current

    @property
    def total(self) -> int:
        """Samples lost, each counted once: per run, the larger of the transport's count and the
        stamp gaps' (both see the same overwrites; the transport alone sees unstamped input)."""
        return self._union_closed + max(self.transport - self._run_transport, self.stamp_gaps - self._run_stamp)

    def on_transport_loss(self, count: int, rx_ns: int | None) -> None:
        """``count`` samples the transport reports lost, at receive time ``rx_ns``."""
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
            self._pending = self._fast = None
            self._steps.clear()
            self._sorted.clear()
            self._no_single = 0
            return
        self._seg_steps += 1
        ref = self._ref
        if self._fast is not None and (ref is None or step * self.SINGLE >= ref):
            self._fast = None              # short steps that stopped: jitter or a burst, not a period
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
            run = self._short_step(step, last)
            if run is None:
                return                     # not (yet) a period: no single, no count at it
            at, before, total, n = run
            if self._n >= self.CONFIRM and self._pending is None:
                # sped up, or the period was hidden by losses: decided once the new one is
                # confirmed; meanwhile the segment is counted at the new period
                self._pending = (at, before, self._count(at - self._seg_start, before),
                                 sorted(list(self._steps)[:before - self._seg_steps + len(self._steps) + 1]), ref)
            self._sum, self._n, self._ref, self._no_single = total, n, total / n, 0
        elif step < self.SINGLE * ref:
            self._sum += step
            self._n += 1
            self._ref = self._sum / self._n
            self._no_single = 0
            if self._pending is not None and self._n >= self.CONFIRM:
                self._decide()
        else:
            self._no_single += 1

    def _short_step(self, step: int, last: int) -> tuple | None:
        """A step shorter than the period: does it become the period (losses hid it)? At once
        when the window's steps are multiples of it (refined by :func:`_fitted_period`) spread
        over several multiples (:meth:`_spread_multiples`); else once ``DRAIN`` such steps come
        in a row, near each other, after steps that are no regular rate, or before the period
        is established by ``CONFIRM`` singles (a node behind a keep-last queue takes its last
        samples one by one when the input stops). Else it is
        jitter, a catch-up burst after a stall (after regular steps), or a publisher that sped
        up: that takes ``CONFIRM`` such steps in a row (:meth:`_sped_up`; before the period is
        established by ``CONFIRM`` singles they become it, the segment kept). Until then the
        step is no single and the count stays at the period. The run that becomes the period:
        (stamp before it, the segment's steps before it, sum of its steps, their count); None
        if none."""
        fast = self._fast
        if fast is not None and step < self.SINGLE * fast[2] / fast[3] and step * self.SINGLE >= fast[2] / fast[3]:
            self._fast = fast = (fast[0], fast[1], fast[2] + step, fast[3] + 1)
            if fast[3] >= self.CONFIRM:
                if self._n >= self.CONFIRM:
                    self._sped_up()
                    return None
            elif fast[3] < self.DRAIN or (self._n >= self.CONFIRM
                                          and self._regular(self._before(fast[3] - 1), self._ref)):
                return None
            self._fast = None
            return fast
        srt = self._sorted
        p = _fitted_period(srt, step) if srt else None
        self._fast = (last, self._seg_steps - 1, step, 1)
        if p is not None and p * self.SINGLE < self._ref and self._spread_multiples(srt, p):
            self._fast = None
            return last, self._seg_steps - 1, step, 1
        return None

    def _before(self, k: int) -> list[int]:
        """The window's steps but its last ``k``, sorted."""
        steps = list(self._steps)
        return sorted(steps[:len(steps) - k])

    def _sped_up(self) -> None:
        """``CONFIRM`` short steps in a row: the publisher sped up. The segment closes where the
        new rate began, counted at the old period; a new one starts there at the new period."""
        at, steps_before, total, n = self._fast
        self._fast = None
        self.closed += self._count(at - self._seg_start, steps_before)
        self._current = 0
        self._seg_start, self._seg_steps = at, self._seg_steps - steps_before
        self._sum, self._n, self._ref, self._no_single = total, n, total / n, 0
        self._pending = None

    def _spread_multiples(self, srt: list[int], p: float) -> bool:
        """Are the sorted steps ``srt`` multiples of ``p`` spread over several multiples (losses
        hid ``p``), not mostly one multiple (a regular rate with one jittered or late step, or
        a burst: exact stamps of a 100 Hz publisher are multiples of any 1 ms step)? At most
        half of the steps at one multiple, at least ``SPREAD`` multiples."""
        if not self._multiples(srt, p):
            return False
        counts: dict[int, int] = {}
        for s in srt:
            m = round(s / p)
            counts[m] = counts.get(m, 0) + 1
        return len(counts) >= self.SPREAD and 2 * max(counts.values()) <= len(srt)

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
        if p is not None and p * self.SINGLE < self._ref and self._spread_multiples(self._sorted, p):
            self._sum, self._n, self._ref, self._no_single = p, 1, p, 0
            self._pending = self._fast = None

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
        """``WINDOW`` steps without a single: a regular slower rate starts a new segment there —
        unless the period it replaces never had ``CONFIRM`` singles (a short step taken for the
        period too early, e.g. a burst after a stall at the start): that period is abandoned,
        the segment stays and is recounted at the slower one, not kept at the count made at
        it."""
        srt, ref = self._sorted, self._ref
        if self._n < self.CONFIRM:         # the steps at their own scale, if not multiples of it
            srt = srt[bisect_left(srt, self.SINGLE * ref):]
            tol = self.MULTIPLE_TOL
            if srt and any(abs(s / ref - round(s / ref)) > tol for s in srt):
                ref = srt[0]
        near = self._regular(srt, ref)
        if not near or self._steady_overload(srt[:near]):
            self._no_single = 0            # spread, or whole periods: an overload, not a slower publisher
            return
        if self._n >= self.CONFIRM:
            span = sum(self._steps)
            self._current = self._count(stamp_ns - span - self._seg_start, self._seg_steps - len(self._steps))
            self._close()
            self._seg_start, self._seg_steps = stamp_ns - span, len(self._steps)
        p0 = sum(srt[:near]) / near
        singles = srt[:bisect_left(srt, self.SINGLE * p0)]      # the cluster's jitter in full
        self._sum, self._n, self._no_single = sum(singles), len(singles), 0
        self._ref = self._sum / self._n
        self._pending = self._fast = None

    def _steady_overload(self, cluster: list[int]) -> bool:
        """Are the sorted steps of a regular slower rate (``cluster``: the window's steps near its
        minimum) whole multiples (two or more) of the period, each within ``MULTIPLE_TOL``: a
        node that takes every m-th sample at a steady pace (its callbacks cost the same each
        time), not a slower publisher? The two look alike in the stamps; the loss is counted (a
        publisher that slows to an exact fraction of its rate without a pause reads as loss,
        rather than a real loss as none)."""
        ref, tol = self._ref, self.MULTIPLE_TOL
        if not cluster or cluster[0] < (2 - tol) * ref:
            return False
        return all(abs(s / ref - round(s / ref)) <= tol for s in cluster)

    def restart(self) -> None:
        """A new time base (reset): stamp steps across it are not gaps; the period is learnt
        again."""
        self._close()
        self._union_closed = self.total
        self._run_transport, self._run_stamp = self.transport, self.stamp_gaps
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
