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

"""The integrator contract: ``Integrator``, ``StepStats``, the error norm and the step controller.

All methods integrate ``dy/dt = system.rhs(t, y)`` (``OdeSystem``) from ``t0`` to exactly
``t1`` (s) and return the new state and a ``StepStats``. The simulator calls ``advance`` once
per input-sample interval (1–10 ms).

**Accuracy is an input.** Every method is given ``rtol``/``atol`` and estimates its local error
at every (sub)step; the weighted norm ``‖err‖ = RMS(err_i / (atol + rtol·max(|y0_i|, |y1_i|)))``
must be ≤ 1 for a step to be accepted (the scipy convention). ``max_step`` (s) is always an
upper bound of the step. The budget is ``max_substeps``: no step shorter than
``max_step / max_substeps``. A method that cannot meet the tolerance within the budget raises
``ToleranceError`` (a ``SimulationError``) naming the time, the method, the estimate and the
tolerance; ``y0`` is untouched (the caller keeps its state).

The fixed-grid methods (rk4, etd*, exprb, implicit_midpoint) derive from :class:`Controlled`,
one step-size controller: the interval is cut into ``nsub = ceil(dt/max_step − STEP_SLACK)`` equal chunks
and each chunk into ``level_substeps(level)`` equal substeps (1, 2, 3, 4, 6, 8, 12, …); a chunk
with a rejected substep is redone at the coarsest finer level whose predicted error
``‖err‖·(n/n')^(q+1)`` is ≤ 1 (n, n' the levels' substeps, q the estimator's order), and the
next chunk goes as many levels coarser as keep that prediction ≤ ``COARSEN``. So
a brief hard stretch (a friction reversal inside a 33 ms interval) costs fine substeps only
in its own chunk, not over the whole interval; at one chunk per interval (samples at
≤ max_step) chunk and interval coincide. A method may plan its chunks itself (``_plan``: the
exponential ones cut whole steps of a grid and end the interval with a short last step
``_tail``, controlled alike from level 0). A method that ``locates_switches`` (rk4) also ends a
chunk's piece at the next kink the system predicts (``switch_time``: the support friction's
regime change, :mod:`gyro_platform.physics.switching`) and goes on from there with the rest of the
chunk; once per piece, a kink it finds looking back from the piece's end (``switch_passed``)
shortens the piece to end just before it (:func:`shortened_piece`; redone: one rejection). A
piece to a predicted kink ends a little short of it and a micro step lands on it
(:func:`aimed_switch`). The pieces of a chunk cut at a kink do not coarsen the level below the
chunk's, nor does its end up to ``HOLD_KINKS`` pieces (:func:`held_level`). A piece takes
substeps no longer than its chunk's level's (:func:`piece_substeps`), not the level's whole number
of its own, and a rejected one goes to the level that gives it more (:func:`next_piece_level`);
RK4 tries a one-substep attempt shorter than ``MICRO_STEP``·max_step as an Euler step first
(:func:`is_micro_step`).
A step across a kink is only first-order accurate, so a vibrating input otherwise costs 3–8× the
substeps of a smooth one. The compiled batch loop (:mod:`gyro_platform.engine.batch`) runs the
same controller: it calls :func:`next_level`, :func:`coarser_level`, :func:`held_level`,
:func:`level_substeps`, :func:`piece_substeps`, :func:`next_piece_level`, :func:`aimed_switch` and
:func:`is_micro_step`, the rules this controller calls.

Non-finite results are never returned: ``SimulationError``.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
import math
from typing import Any, Callable, Hashable, Protocol

import numpy as np

from ...errors import SimulationError, ToleranceError
from ...physics.jit import njit, plain

__all__ = ["OdeSystem", "StepStats", "Integrator", "Controlled", "error_norm", "next_level", "coarser_level",
           "level_substeps", "finest_level",
           "is_rejected", "piece_substeps", "MAX_SUBSTEPS", "COARSEN", "MAX_JUMP", "STEP_SLACK", "SWITCH_MIN",
           "MAX_SWITCHES", "SWITCH_EDGE", "SWITCH_AIM", "aimed_switch", "MICRO_STEP", "is_micro_step", "HOLD_KINKS",
           "held_level", "LOOKBACK_AIM", "next_piece_level", "MAX_PIECE_JUMP",
           "shortened_piece"]

_CACHE_SIZE = 64          # (key, h) entries kept per integrator; h takes few values per run
#: default budget: no step shorter than max_step / MAX_SUBSTEPS (0.24 µs at 1 ms)
MAX_SUBSTEPS = 4096
#: controller: after a chunk, the next one goes as many levels coarser as keep its predicted worst
#: error ‖err‖·(n/n')^(q+1) ≤ COARSEN (n, n': substeps of the levels); a rejection jumps at most
#: MAX_JUMP levels (×16 the substeps)
COARSEN = 0.5
MAX_JUMP = 8


def error_norm(err: np.ndarray, y0: np.ndarray, y1: np.ndarray, rtol: float, atol: float) -> float:
    """Weighted RMS norm of a local error estimate (≤ 1: within tolerance; scipy's convention)."""
    sc = atol + rtol * np.maximum(np.abs(y0), np.abs(y1))
    return float(np.sqrt(np.mean((err / sc) ** 2)))


@njit(cache=True, inline="always")
def level_substeps(level: int) -> int:
    """Substeps of a whole chunk at ``level``: 1, 2, 3, 4, 6, 8, 12, 16, … (×1.5 and ×4/3 in turn
    from 2 on). Finer than powers of two: a chunk that needs a little more than 2 substeps takes
    3, not 4 (at rtol 1e-8 the vibrating 1 kHz input's right-hand sides −19 %, the smooth one's −9 %).
    This and the two level rules are inlined into the compiled kernel: called there, the
    coarsening's call cost 7–15 % a sample at rtol 1e-6 (session 36)."""
    if level <= 0:
        return 1
    if level & 1:
        return 1 << ((level + 1) >> 1)
    return 3 << ((level >> 1) - 1)


@njit(cache=True, inline="always")
def _step_up(level: int, q1: int) -> float:
    """``(n/n')^q1`` for the substeps n of ``level`` ≥ 1 and n' of the level below (2^q1, then
    (3/2)^q1 and (4/3)^q1 in turn), as a quotient of integer powers: exact in both controllers."""
    if level == 1:
        return 2.0 ** q1
    if level & 1:
        return 4.0 ** q1 / 3.0 ** q1
    return 3.0 ** q1 / 2.0 ** q1


@njit(cache=True, inline="always")
def next_level(level: int, norm: float, q1: int) -> int:
    """Level after a rejected chunk with worst normalised error ``norm`` (q1 = q + 1): the
    coarsest finer level whose predicted error ``norm·(n/n')^q1`` is ≤ 1, at most ``MAX_JUMP``
    finer (non-finite ``norm``: ``MAX_JUMP`` finer)."""
    if not norm < math.inf:                     # nan or inf: non-finite, Newton failure
        return level + MAX_JUMP
    new = level + 1
    norm /= _step_up(new, q1)
    while norm > 1.0 and new < level + MAX_JUMP:
        new += 1
        norm /= _step_up(new, q1)
    return new


@njit(cache=True, inline="always")
def coarser_level(level: int, norm: float, q1: int) -> int:
    """Level for the next chunk after an accepted one whose worst normalised error was
    ``norm``: as many levels coarser as keep the predicted error ``norm·(n/n')^q1`` ≤ COARSEN."""
    while level > 0:
        up = norm * _step_up(level, q1)
        if up > COARSEN:
            break
        norm = up
        level -= 1
    return level


def finest_level(max_substeps: int) -> int:
    """The finest level whose chunk takes at most ``max_substeps`` substeps (interpreted: an
    integrator is made before any kernel is loaded, and a cold node must not compile for it)."""
    substeps = plain(level_substeps)
    level = 0
    while substeps(level + 1) <= max_substeps:
        level += 1
    return level


#: how much longer than ``max_step`` a chunk of the equal-step methods (rk4, exprb,
#: implicit_midpoint) may be: an input interval up to 1.1·max_step is one chunk, not two.
#: A 1 kHz driver's header stamps jitter by a few percent, so with ``max_step`` = 1 ms half its
#: intervals would be cut in two; the error control still holds every step to the tolerance
#: (measured on a 1 kHz bag with ±5 % stamp jitter: 19 % fewer RK4 steps, the same largest
#: error estimate). The exponential methods keep their grid (``_ETD._plan``).
STEP_SLACK = 0.1
#: switch location (``Controlled.locates_switches``): a predicted kink closer than
#: ``SWITCH_MIN``·max_step (1e-14 s at 1 ms) to either end of a chunk piece is not split off, and at
#: most ``MAX_SWITCHES`` pieces of one chunk end at kinks (a rate hovering at ±ε: the substeps take
#: over). A step that starts or ends δ from a kink it does not end at is off by ~(h/6)·δ·(the jump
#: of the friction's slope × rel̇)/J, linear in δ and in the step: δ = 0.18 ns left a 1 ms chunk
#: 35× the tolerance off at rtol 1e-8 with an estimate of 0.45 (session 41; SWITCH_MIN was 1e-6,
#: and the vibrating 1 kHz IMU delivered 4.3e-12 rad where the smooth one delivered 2.3e-13; now
#: 1.7e-13). A kink is ended at by two pieces (:func:`aimed_switch`), so a chunk holds 16 kinks; a
#: parked vehicle's noisy rates cross the friction's zone up to ~10 times a 1 ms interval, and
#: capped at 16 pieces the rest of a chunk stepped over its kinks (9.1e-10 rad over 10 s at rtol 1e-6,
#: 3.7e-12 with 32)
SWITCH_MIN = 1e-11
MAX_SWITCHES = 32
#: a kink found looking back from a step's end within this fraction of the step from its start
#: is the one the step starts at (the backward look is linear: not exact that far back)
SWITCH_EDGE = 1e-3
#: a kink found looking back from a piece's end was judged from a state that passed it, and a
#: step that ends past a kink by δ is off by ~(h/6)·δ·(the friction's slope × rel̇)/J, linear in δ
#: *and* in the step (the last stage samples the other side: 26 ns past it, a 0.93 ms step was 26×
#: the tolerance off while its estimate read 4.8). So the redone piece aims LOOKBACK_AIM·d before
#: the end (before the kink by a quarter of the distance found, :func:`shortened_piece`; 1.1 left
#: 1.7e-11 rad where 1.25 and 1.5 leave 1.4e-11 on the vibrating 1 kHz IMU at rtol 1e-6)
LOOKBACK_AIM = 1.25
#: a piece to a predicted kink more than MICRO_STEP·max_step away ends SWITCH_AIM of the way short
#: of it (:func:`aimed_switch`), and the next piece, a micro step, lands on it: the first-order
#: prediction is late by up to ~1e-4 of its reach (0.1 µs over 0.99 ms), and a piece that ends
#: past the kink costs a look-back and a redo
SWITCH_AIM = 1e-4
#: the most levels a rejected piece goes finer at once (:func:`next_piece_level`; 32 levels: 2^16
#: substeps more); the budget's own limit applies after it
MAX_PIECE_JUMP = 32
#: a piece up to (1 + PIECE_SLACK) level substeps long takes that many (rounding of its ends)
PIECE_SLACK = 1e-6
#: the end of a chunk cut into up to HOLD_KINKS pieces at kinks (two a kink, :func:`aimed_switch`)
#: keeps the level the chunk began at (:func:`held_level`)
HOLD_KINKS = 8
#: a one-substep attempt shorter than MICRO_STEP·max_step is first tried as an Euler step
#: (:func:`is_micro_step`)
MICRO_STEP = 1e-4


class OdeSystem(Protocol):
    """What an integrator needs from the model.

    Required: ``rhs(t, y) -> dy/dt`` (shape (n,); t in s). Optional, found with ``getattr``:

    - ``linear_part() -> (A, key)``: ``f(t, y) = A y + g(t, y)`` with ``g`` slow/mild; ``key``
      (hashable) identifies ``A`` so that expm/φ/LU results can be cached. Needed by etd2/etd4;
      used as the Newton matrix by implicit_midpoint and as the Jacobian by radau.
    - ``jacobian(t, y) -> ∂f/∂y`` (n×n): exact Jacobian, preferred over ``linear_part``.
    - ``switch_time(t, y, yd, t_end, h_min) -> float``: the next time in ``(t + h_min, t_end −
      h_min)`` at which ``rhs`` has a kink, predicted from ``yd`` = f(t, y); ``t_end`` if none;
      with ``switch_passed(t, y, yd, lo, hi) -> float``: how long before t a kink was passed
      (the largest in (lo, hi)), 0.0 if none. Used by the methods that ``locates_switches``.
    """

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray: ...


@dataclass
class StepStats:
    """Work and quality of one ``advance`` call.

    ``n_steps``: accepted (sub)steps; ``n_rhs``: calls of ``system.rhs`` (including
    finite-difference Jacobians); ``error_estimate``: largest local error estimate (max-norm,
    state units: rad, rad/s, …) of the accepted steps; ``error_norm``: largest weighted norm of
    those estimates (≤ 1 = within rtol/atol); ``n_rejected``: rejected (redone) steps or
    intervals; ``level``: substep level used (substeps = ceil(dt/max_step)·level_substeps(level)).
    """

    n_steps: int
    n_rhs: int
    error_estimate: float
    error_norm: float = math.nan
    n_rejected: int = 0
    level: int = 0


class Integrator(ABC):
    """Base class. Subclasses set ``name``, ``order`` and ``adaptive`` and implement ``_advance``.

    ``max_step`` (s): upper bound of every step; ``rtol``, ``atol``: tolerances (state units);
    ``max_substeps``: budget, the shortest step allowed is ``max_step / max_substeps``."""

    name: str = ""
    #: the method consults ``system.linear_part()`` (so the system keeps it current per step)
    uses_linear_part: bool = False
    order: int = 0
    #: every method adapts its step to the tolerance; kept for the scipy family's warm start
    adaptive: bool = True

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        self.max_step = float(max_step)
        self.rtol, self.atol = float(rtol), float(atol)
        self.max_substeps = int(max_substeps)
        self.max_level = finest_level(self.max_substeps)

    def advance(self, system: OdeSystem, t0: float, y0: np.ndarray, t1: float
                ) -> tuple[np.ndarray, StepStats]:
        """Integrate from ``t0`` to exactly ``t1`` (s, ``t1 > t0``); ``y0`` is not modified.

        Returns ``(y1, stats)``. Raises ``ValueError`` for a bad interval or state shape and
        ``SimulationError`` if the state becomes non-finite or the tolerance cannot be met.
        """
        t0 = float(t0)
        t1 = float(t1)
        if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
            raise ValueError(f"{self.name}: need finite t1 > t0, got t0={t0!r}, t1={t1!r}")
        y = np.array(y0, dtype=float)          # always a copy
        if y.ndim != 1:
            raise ValueError(f"{self.name}: y0 must be 1-D, got shape {y.shape}")
        y, stats = self._advance(system, t0, y, t1)
        if not np.isfinite(y).all():
            raise SimulationError(f"non-finite state after {self.name} step at t={t1!r}")
        return y, stats

    @abstractmethod
    def _advance(self, system: OdeSystem, t0: float, y: np.ndarray, t1: float
                 ) -> tuple[np.ndarray, StepStats]:
        """Integrate in place of the owned copy ``y``; interval already checked."""

    def reset(self) -> None:
        """Forget warm-start data and caches."""

    def refuse(self, t: float, estimate: float, norm: float, h: float, why: str = "") -> ToleranceError:
        """The error raised when the tolerance cannot be met within the budget (t: the
        integration time of the failing step, s)."""
        if not norm < math.inf:     # a stage or the state went non-finite: no estimate to quote
            return ToleranceError(
                f"{self.name} cannot meet the tolerance at t={t!r} s: the state or a stage is non-finite "
                f"even with steps of {h:.3g} s (budget: max_step/{self.max_substeps}){why}; "
                f"state kept at the interval start")
        return ToleranceError(
            f"{self.name} cannot meet the tolerance at t={t!r} s: error estimate {estimate:.3g} "
            f"({norm:.3g}× the tolerance rtol={self.rtol:g}, atol={self.atol:g}) even with steps of "
            f"{h:.3g} s (budget: max_step/{self.max_substeps}){why}; state kept at the interval start")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} order={self.order}>"


# --------------------------------------------------------------------------- controlled (fixed grid)


class Controlled(Integrator):
    """Methods on a grid of ``nsub·level_substeps(level)`` equal substeps per interval (see module doc).

    Subclasses implement ``_substeps(system, t0, y0, nsub, h)`` returning ``(y1, norm, est,
    n_rhs, t_bad)``: the worst normalised error and max-norm estimate over the substeps, and
    the start of the first rejected substep (the run stops there; ``norm`` > 1 or nan)."""

    #: order + 1 of the local error the estimator measures (err ∝ h^q1)
    q1: int = 2
    #: the method substeps on a grid; the step level is carried between calls
    level: int = 0
    #: chunks end at the kinks the system predicts (``OdeSystem.switch_time``)
    locates_switches: bool = False

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        super().__init__(max_step, rtol, atol, max_substeps)
        self._n = -1
        self._cache: dict[tuple[Hashable, float], Any] = {}
        self.level = 0

    cache_size = _CACHE_SIZE

    def _base(self, t0: float, t1: float) -> tuple[int, float]:
        """(nsub, h): ``ceil((t1 − t0)/max_step − STEP_SLACK)`` equal steps: an interval up to
        ``(1 + STEP_SLACK)·max_step`` long is one step (see :data:`STEP_SLACK`)."""
        nsub = max(1, math.ceil((t1 - t0) / self.max_step - STEP_SLACK))
        return nsub, (t1 - t0) / nsub

    def _cached(self, key: Hashable, h: float, make: Callable[[], Any]) -> Any:
        """LRU cache of matrices by (key, h); ``h`` is compared exactly."""
        k = (key, h)
        val = self._cache.pop(k, None)
        if val is None:
            val = make()
            if len(self._cache) >= self.cache_size:
                del self._cache[next(iter(self._cache))]
        self._cache[k] = val
        return val

    def reset(self) -> None:
        self._cache.clear()
        self._n = -1
        self.level = 0

    def _prepare(self, system, t0: float, y0: np.ndarray) -> int:
        """Per-call setup (Jacobians, linear part); returns the rhs calls it made."""
        return 0

    def _norm(self, err, y0, y1) -> float:
        return error_norm(err, y0, y1, self.rtol, self.atol)

    def _judge(self, err, y0, y1, est: float, worst: float) -> tuple[float, float, float]:
        """One substep's error estimate ``err`` (state units) from ``y0`` to ``y1``: (its
        weighted norm, the largest max-norm estimate so far, the worst norm so far)."""
        nrm = self._norm(err, y0, y1)
        return nrm, max(est, float(np.abs(err).max())), max(worst, nrm)

    def _plan(self, t0: float, t1: float):
        """The interval's chunks ``[(start, length)]`` (s) and ``(start, length)`` of a last
        short step that ends it exactly at t1 (``_tail``; None: none): here ``_base``'s equal
        chunks and no tail."""
        nsub, h0 = self._base(t0, t1)
        return [(t0 + c * h0, h0) for c in range(nsub)], None

    def _chunk(self, system, tc, y, hc, level, q1, step, passed=None, hg=None):
        """One chunk of ``hc`` s from (tc, y) by ``step`` (``_substeps`` or ``_tail``) at
        ``level_substeps(level)`` substeps (a piece of a chunk ``hg`` s long: :func:`piece_substeps`), redone
        finer until accepted: (y1, norm, est, n_rhs, level, rejected, hc, nsub). Raises the
        refusal beyond the budget. ``passed`` (switch location):
        the system's ``switch_passed``; once per chunk, a kink it finds inside the chunk (judged
        from the end of its last substep) shortens the chunk to end just before it
        (:func:`shortened_piece`), redone at the same level (one rejection)."""
        nrhs = rejected = 0
        while True:
            nsub = level_substeps(level) if hg is None else piece_substeps(hc, hg, level)
            h = hc / nsub
            y1, norm, est, n, t_bad = step(system, tc, y, nsub, h)
            nrhs += n
            if passed is not None and norm < math.inf and (norm <= 1.0 or t_bad == tc + (nsub - 1) * h):
                d = passed(tc + hc, y1, system.rhs(tc + hc, y1), SWITCH_MIN * self.max_step,
                           hc - max(SWITCH_EDGE * hc, 4 * SWITCH_MIN * self.max_step))
                nrhs += 1
                if d > 0.0:
                    hc = shortened_piece(hc, d)
                    passed = None
                    rejected += 1
                    continue
            if norm <= 1.0:
                return y1, norm, est, nrhs, level, rejected, hc, nsub
            rejected += 1
            new = next_level(level, norm, q1) if hg is None else next_piece_level(level, norm, q1, hc, hg, nsub)
            if new > self.max_level:
                if level < self.max_level:
                    new = self.max_level               # try the budget's own limit once
                else:
                    raise self.refuse(t_bad, est, norm, h)
            level = new

    def _advance(self, system, t0, y, t1):
        chunks, tail = self._plan(t0, t1)
        nrhs = self._prepare(system, t0, y)
        level, rejected = self.level, 0
        steps, est_all, worst, top = 0, 0.0, 0.0, level
        switch = getattr(system, "switch_time", None) if self.locates_switches else None
        h_min = SWITCH_MIN * self.max_step
        for tg, hg in chunks:
            tc, hc, end, n_sw = tg, hg, tg + hg, 0
            chunk_level = level
            while True:
                # the piece ends at the next predicted kink (the rest of the chunk follows), or
                # is the whole (rest of the) chunk
                ts = end
                passed = None
                if switch is not None and n_sw < MAX_SWITCHES:
                    ts = switch(tc, y, system.rhs(tc, y), end, h_min)
                    if ts < end:
                        ts = aimed_switch(tc, ts, self.max_step)
                    nrhs += 1
                    passed = system.switch_passed
                hp = hc if ts >= end else ts - tc
                y, norm, est, n, level, rej, hq, ns = self._chunk(system, tc, y, hp, level, self.q1,
                                                                  self._substeps, passed, hg if passed else None)
                if hq != hp:                # shortened to a kink found inside
                    ts = tc + hq
                nrhs += n
                rejected += rej
                steps += ns
                est_all = max(est_all, est)
                worst = max(worst, norm)
                top = max(top, level)
                level = _held_level(coarser_level(level, norm, self.q1), chunk_level, ts < end, n_sw)
                if ts >= end:
                    break
                tc, hc, n_sw = ts, end - ts, n_sw + 1
        if tail is not None:     # its own level from 0; the chunks' controller level is not touched
            y, norm, est, n, lv, rej, _, ns = self._chunk(system, tail[0], y, tail[1], 0, self.q1, self._tail)
            nrhs += n
            rejected += rej
            steps += ns
            est_all = max(est_all, est)
            worst = max(worst, norm)
        self.level = level
        return y, StepStats(steps, nrhs, est_all, worst, rejected, top)

    def _tail(self, system, t0: float, y0: np.ndarray, nsub: int, h: float):
        """The last short step(s) of ``_plan`` (same contract as ``_substeps``)."""
        raise NotImplementedError

    @abstractmethod
    def _substeps(self, system, t0: float, y0: np.ndarray, nsub: int, h: float):
        ...


@njit(cache=True)
def piece_substeps(hp: float, hg: float, level: int) -> int:
    """Substeps of a piece ``hp`` s long of a chunk ``hg`` s long at ``level``: as many as keep
    them no longer than the level's (``hg / level_substeps(level)``), all of them for the whole chunk. Pieces
    end at the mount friction's kinks; a short one takes a few substeps, not the chunk's number.
    (One rule for the Python controller and the compiled one, :mod:`gyro_platform.engine.batch`.)"""
    return max(1, math.ceil(hp / hg * level_substeps(level) - PIECE_SLACK))


@njit(cache=True, inline="always")
def next_piece_level(level: int, norm: float, q1: int, hp: float, hg: float, nsub: int) -> int:
    """:func:`next_level` for a rejected piece ``hp`` s long of a chunk ``hg`` s long that took
    ``nsub`` substeps: on from there to the first level at which the piece's own substeps
    (:func:`piece_substeps`) make the predicted error ``norm·(nsub/n')^q1`` ≤ 1. A piece shorter
    than its level's substeps takes one at several levels: a 50 µs piece of a parked vehicle's
    1 ms chunk rejected at norm 2.8 was redone at one substep 7–9 times, a level each time, before
    level 8 gave it two (rtol 1e-8: 5.3 rejections a sample). (Both controllers.)"""
    new = next_level(level, norm, q1)
    if not norm < math.inf:
        return new
    while new < level + MAX_PIECE_JUMP and norm * (nsub / piece_substeps(hp, hg, new)) ** q1 > 1.0:
        new += 1
    return new


@njit(cache=True, inline="always")
def held_level(level: int, chunk_level: int, cut: bool, n_cut: int) -> int:
    """The level after a piece of a chunk that began at ``chunk_level``, ``level`` being what
    :func:`coarser_level` made of the piece's error: not below ``chunk_level`` where the piece
    ended at a kink (``cut``) or ended a chunk cut into 1 … ``HOLD_KINKS`` pieces (``n_cut``). A
    piece's error does not speak for its level: a piece is shorter than its level's substeps,
    and the motion changes at the kink. At rtol 1e-8 the vibrating 1 kHz input's piece after a
    friction reversal went on at the level a short piece before it had coarsened to, and was
    rejected there: 0.20 rejections a sample → 0.07, right-hand sides a sample −4 % (the smooth
    input's −0.4 %). A chunk cut more often (a vibration faster than the samples) ends as
    coarsened: held there, a level a rejection raised would stay up from chunk to chunk. (One rule
    for both controllers.)"""
    if level < chunk_level and (cut or 0 < n_cut <= HOLD_KINKS):
        return chunk_level
    return level


@njit(cache=True, inline="always")
def is_micro_step(nsub: int, h: float, max_step: float) -> bool:
    """A one-substep attempt of ``h`` s shorter than ``MICRO_STEP``·max_step (s): RK4 tries it as
    an Euler step first, ``y1 = y + h f(t, y)`` with the estimate ``h/2 (f(t+h, y1) − f(t, y))``
    (its local error ½h²ÿ to leading order), and takes the RK4 step only if that exceeds the
    tolerance. Such attempts are the nanosecond to microsecond pieces between a kink the
    first-order prediction ended a piece short of and the kink itself, and the crossings of the
    mount friction's linear zone: 0.19 a sample of the vibrating 1 kHz input at rtol 1e-6 and
    1e-8, each 1 right-hand side instead of 4 (the Euler step's f(t+h, y1) is the next step's
    first stage), with the same delivered error. (One rule for both controllers.)"""
    return nsub == 1 and h < MICRO_STEP * max_step


@njit(cache=True, inline="always")
def shortened_piece(hc: float, d: float) -> float:
    """The new length (s) of a piece ``hc`` s long that passed a kink ``d`` s before its end
    (``switch_passed``): it ends before the kink by (LOOKBACK_AIM − 1)·d, and by no more than half
    the way from its start to the kink (the Python controller and the compiled kernel alike)."""
    s = hc - d
    return s - min((LOOKBACK_AIM - 1.0) * d, 0.5 * s)


@njit(cache=True, inline="always")
def aimed_switch(tc: float, ts: float, max_step: float) -> float:
    """Where a piece from ``tc`` to a kink predicted at ``ts`` (s) ends: SWITCH_AIM·(ts − tc) short
    of it when it is more than MICRO_STEP·max_step away, so that a late prediction does not end
    it past the kink; the next prediction, from there, lands on it. (Both controllers.)"""
    reach = ts - tc
    if reach > MICRO_STEP * max_step:
        return ts - SWITCH_AIM * reach
    return ts


def is_rejected(norm: float) -> bool:
    """True when a (sub)step with weighted error norm ``norm`` is rejected (> 1, or nan)."""
    return not norm <= 1.0


_held_level = plain(held_level)        # the Python controller's (interpreted: nothing to compile)
