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

"""Input gate between messages and the simulator: timing and sanity of every rate sample.

:meth:`TimeGate.offer` takes what :func:`gyro_platform.messages.reading_from_msg` made of one
message (a ``Reading`` or a ``Rejected``) and the message's receive time, and returns an explicit
:class:`Decision`. The gate never touches the physics; the caller applies the decision:

* ``accept``: ``sim.push(decision.sample)``;
* ``reset``: ``sim.reset()`` then ``sim.push(decision.sample)`` (outputs already emitted stay);
* ``drop``: nothing.

Sample time. ``time_source="auto"`` (default) locks on the first message: the header stamp if
it is set (non-zero), else the receive time (bag record time / node clock) — one real
recording has every header stamp at 0. Once locked, the source does not change (mixing two
clocks would make jumps); a zero stamp in header mode is dropped (``zero_stamp``). Times are
kept as integer ns (``Decision.stamp_ns``, the input's time base); ``sample.t`` is seconds since
``origin_ns``, the first accepted sample, so that it keeps full float precision.

Decisions and their reasons (checked in this order; every decision is counted by reason):

| reason | action | when |
| --- | --- | --- |
| `no_rate` | drop | Imu `angular_velocity_covariance[0] == -1` |
| `unknown_frame` | drop | frame_id without mounting and `unknown_frame="reject"` |
| `bad_message` | drop | undecodable or unsupported message |
| `non_finite` | drop | NaN/Inf in rate or specific force |
| `over_rate` | drop | ‖ω‖ > `max_rate` (rad/s; default 35 ≈ 2000 °/s, a gyro's full scale) |
| `over_specific_force` | drop | ‖f‖ > `max_specific_force` (m/s²; default 2000 ≈ 200 g, beyond an IMU's full scale) |
| `no_specific_force` | drop | the model needs the specific force (`require_specific_force`) and the message carries none |
| `zero_stamp` | drop | header mode and stamp 0 |
| `no_time` | drop | receive mode and no receive time given |
| `repeated_stamp` | drop | t = previous accepted t |
| `backward_stamp` | drop | t < previous accepted t by at most `reset_on_jump_back` |
| `jump_back` | reset | t < previous accepted t by more than `reset_on_jump_back` (looped bag) |
| `gap` | reset | t − previous > `max_gap` and `on_gap="reset"` (default) |
| `ok` | accept | otherwise (first sample: `start`) |
| `refused` | drop | the simulator refused a sample the gate had accepted (:meth:`TimeGate.refuse` rolls the gate back) |

Notes counted beside the decisions: ``receive_time`` (time taken from the receive clock),
``gap_integrated`` (a gap integrated across with ``on_gap="integrate"``), ``identity_frame``
(unknown frame taken as base_link).

Blocks: :meth:`TimeGate.offer_block` decides a whole :class:`~gyro_platform.messages.blocks.RateBlock`
at once (:class:`GateBlock`): plain runs (usable, finite, in range, increasing, no gap) are
vectorised, every other row goes through :meth:`TimeGate.offer`; counters, notes, the last
decision and the rate estimates end as after one ``offer`` per row.

Default ``on_gap="reset"``: across a gap the simulator would interpolate the rate linearly and
so invent the vehicle's motion; restarting is honest, and the outputs before the gap are kept.

This module holds :class:`TimeGate`. The vocabulary (:class:`Action`, :class:`Decision`, the
reason tables, :class:`GateConfig`, :class:`GateBlock`) and the one rule for a row's values
(:func:`~gyro_platform.pipeline.gate_rules.row_verdict`: `non_finite`, `over_rate`,
`over_specific_force`, `no_specific_force`; every path calls it) are in
:mod:`~gyro_platform.pipeline.gate_rules`, the compiled block passes in
:mod:`~gyro_platform.pipeline.gate_kernels`.
"""  # noqa: E501 (the reason table: one row a line)
from __future__ import annotations

from collections import Counter
import copy
from dataclasses import dataclass
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from .gate_kernels import accept_rows, arrival_ema, ema, ema_add, EXACT_NS, ns_floor, reading_of, usable_rows
from .gate_rules import (ACCEPT, ACCEPT_REASONS, Action, ACTION_CODE, Decision, DROP, DROP_REASONS, GateBlock,
                         GateConfig, NS, plain_decision, REASON_INDEX, RESET_REASONS, ROW_NO_SPECIFIC_FORCE,
                         ROW_NON_FINITE, ROW_OK, ROW_OVER_RATE, ROW_REASONS, row_verdict)
from ..engine.inputs import RateSample
from ..messages import Reading, Rejected
from ..physics.jit import plain

if TYPE_CHECKING:
    from ..messages.blocks import RateBlock

__all__ = ["TimeGate"]

# the members as plain globals: an Enum attribute lookup costs ~60 ns, several per message
_A_ACCEPT, _A_DROP, _A_RESET = Action.ACCEPT, Action.DROP, Action.RESET
#: the row rule's own source, run by Python: a per-message call of the compiled dispatcher costs more
#: (~0.3 µs) than the rule; the block pass runs the compiled ``row_verdict`` (one source, two runners)
_verdict = plain(row_verdict)


@dataclass
class _State:
    source: str | None = None          # locked time source
    origin_ns: int | None = None       # time zero of sample.t
    last_ns: int | None = None         # last accepted time
    dt_ema: float | None = None        # s, smoothed interval of accepted samples
    rx_last: int | None = None         # last receive time, ns
    rx_dt_ema: float | None = None     # s, smoothed interval of arriving messages


def _row_detail(verdict: int, w: tuple, f: tuple | None, cfg: GateConfig) -> str:
    """The detail of a drop for a row's values (:func:`row_verdict` code ``verdict``)."""
    if verdict == ROW_NON_FINITE:
        return f"non-finite value: omega={list(w)}, specific_force={None if f is None else list(f)}"
    if verdict == ROW_OVER_RATE:
        rate = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        return f"|omega| = {rate:.6g} rad/s > max_rate {cfg.max_rate:g} rad/s"
    if verdict == ROW_NO_SPECIFIC_FORCE:
        return "the model's effects need the specific force; this message carries none"
    force = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])      # (or it overflows)
    return f"|specific force| = {force:.6g} m/s² > max_specific_force {cfg.max_specific_force:g} m/s²"


class TimeGate:
    """Decides for each message: accept, drop (with reason) or reset-then-accept. Never raises
    on input data; counts every decision; :meth:`snapshot` gives the diagnostics."""

    def __init__(self, config: GateConfig | None = None):
        self.config = config or GateConfig()
        self._s = _State()
        self.counts: Counter[str] = Counter()     # decision reason -> count
        self.notes: Counter[str] = Counter()      # note -> count
        self.received = 0
        self._last: Decision | None = None
        self._plain: tuple | None = None          # the last decision, when offer_plain made it
        self.last_drop: Decision | None = None
        self._undo: tuple | None = None           # time base before the last accepted sample

    def __deepcopy__(self, memo: dict) -> "TimeGate":
        """A copy whose state is independent of this gate's (what ``Pipeline.run_block`` keeps
        to rewind it): the time base and counters copied; the config and the decisions are
        shared (never changed once made)."""
        new = object.__new__(type(self))
        memo[id(self)] = new
        for k, v in vars(self).items():
            if k in ("config", "_last", "_plain", "last_drop", "_undo"):
                new.__dict__[k] = v
            elif k == "_s":
                new.__dict__[k] = copy.copy(v)
            elif type(v) is Counter:
                new.__dict__[k] = v.copy()
            else:
                new.__dict__[k] = copy.deepcopy(v, memo)
        return new

    # ---- properties -----------------------------------------------------------------
    @property
    def last(self) -> Decision | None:
        """The last decision (None before the first)."""
        p = self._plain
        if p is not None:           # made by offer_plain: build it now, once
            self._last, self._plain = plain_decision(p), None
        return self._last

    @last.setter
    def last(self, d: Decision | None) -> None:
        self._last, self._plain = d, None

    @property
    def origin_ns(self) -> int | None:
        """Input-time-base ns of ``sample.t == 0`` (the first accepted sample)."""
        return self._s.origin_ns

    @property
    def time_source(self) -> str | None:
        """``header`` or ``receive`` once locked, else None."""
        return self._s.source

    @property
    def last_stamp_ns(self) -> int | None:
        return self._s.last_ns

    def restart(self) -> None:
        """Forget the time base (source lock, origin, last time); counters are kept."""
        self._s = _State()
        self._undo = None

    # ---- the decision ---------------------------------------------------------------
    def offer(self, reading: Reading | Rejected, receive_ns: int | None = None) -> Decision:
        """Decide about one message; ``receive_ns`` is its receive time (ns) if known."""
        if receive_ns is not None:
            self._arrival(receive_ns)
        return self._offer(reading, receive_ns)

    def _arrival(self, receive_ns: int) -> None:
        """The arrival-rate update (every message, dropped ones too)."""
        s = self._s
        last = s.rx_last
        if last is not None and 0 < receive_ns - last <= self.config.max_gap * NS:
            s.rx_dt_ema = ema_add(s.rx_dt_ema, (receive_ns - last) / NS, self.config.rate_smoothing)
        s.rx_last = int(receive_ns)

    def offer_plain(self, r: Reading | Rejected, receive_ns: int | None = None) -> tuple | None:
        """:meth:`offer` for a plain reading — what :meth:`offer_block` vectorises: a
        ``Reading`` of finite 3-vectors, ‖ω‖ ≤ ``max_rate``, ‖f‖ ≤ ``max_specific_force``, a specific
        force if one is required, its time (source locked) within (0, ``max_gap``] after the last — with the
        same counters, notes, rate estimates and undo, but no ``Decision`` made: returns
        ``(t, omega, specific_force, stamp_ns, source)`` (t s since the origin, the vectors as
        float 3-tuples; :func:`plain_decision` makes the decision, :attr:`last` when asked).
        None for any other reading, nothing changed: then call :meth:`offer`. The node's
        per-message path (µs counted)."""
        s, cfg = self._s, self.config
        source, last_ns = s.source, s.last_ns
        if r.__class__ is not Reading or source is None or last_ns is None:
            return None
        try:
            if source == "header":
                t_ns = r.stamp_ns
                if t_ns is None or t_ns == 0:
                    return None
                t_ns = int(t_ns)
            elif receive_ns is None:
                return None
            else:
                t_ns = int(receive_ns)
            dt_ns = t_ns - last_ns
            if not 0 < dt_ns <= cfg.max_gap * NS:
                return None
            wx, wy, wz = r.omega
            wx, wy, wz = float(wx), float(wy), float(wz)
            f = r.specific_force
            if f is None:
                fx = fy = fz = 0.0
            else:
                fx, fy, fz = f
                fx, fy, fz = float(fx), float(fy), float(fz)
                f = (fx, fy, fz)
            if _verdict(wx, wy, wz, fx, fy, fz, f is not None, cfg.max_rate, cfg.max_specific_force,
                        cfg.require_specific_force) != ROW_OK:
                return None
        except (TypeError, ValueError, OverflowError):
            return None                         # offer says what is wrong with it
        # -- commit (as offer: accepted "ok")
        if receive_ns is not None:
            self._arrival(receive_ns)
        self.received += 1
        self.counts["ok"] += 1
        note: tuple[str, ...] = ()
        if source == "receive" or r.identity_assumed:
            note = ("receive_time",) if source == "receive" else ()
            if r.identity_assumed:
                note += ("identity_frame",)
            for n in note:
                self.notes[n] += 1
        e, origin = s.dt_ema, s.origin_ns
        self._undo = (source, origin, last_ns, e, note)
        s.dt_ema = ema_add(e, dt_ns / NS, cfg.rate_smoothing)
        s.last_ns = t_ns
        self._last = None
        self._plain = p = ((t_ns - origin) / NS, (wx, wy, wz), f, t_ns, source)
        return p

    @property
    def last_plain(self) -> tuple | None:
        """``(t, omega, specific_force, stamp_ns, source)`` of the last decision when
        :meth:`offer_plain` made it and nobody has asked for :attr:`last` since, else None."""
        return self._plain

    def _offer(self, reading: Reading | Rejected, receive_ns: int | None) -> Decision:
        self.received += 1
        self._undo = None
        try:
            d = self._decide(reading, receive_ns)
        except Exception as e:  # defensive: the gate never raises on data
            d = Decision(Action.DROP, "bad_message", detail=f"gate could not judge the input: {e}")
        self.counts[d.reason] += 1
        self.last = d
        if d.action is _A_DROP:
            self.last_drop = d
        return d

    def refuse(self, detail: str) -> None:
        """The simulator refused the sample of the last (accepting) decision: undo its effect
        on the time base (source lock, origin, last time, rate estimate, notes) and count it as
        dropped ``refused`` instead, so the next sample is judged as if it had never come.
        Does nothing unless the last decision accepted a sample."""
        undo, last = self._undo, self.last
        if undo is None or last is None or last.action is Action.DROP:
            return
        s = self._s
        s.source, s.origin_ns, s.last_ns, s.dt_ema, notes = undo
        for n in notes:
            self.notes[n] -= 1
        self.counts[last.reason] -= 1
        self.counts["refused"] += 1
        self.last = self.last_drop = Decision(Action.DROP, "refused", None, last.stamp_ns, last.source, detail)
        self._undo = None

    def _drop(self, reason: str, detail: str, stamp_ns: int | None = None, source: str | None = None) -> Decision:
        return Decision(Action.DROP, reason, None, stamp_ns, source, detail)

    def _decide(self, r: Reading | Rejected, receive_ns: int | None) -> Decision:
        cfg, s = self.config, self._s
        if r.__class__ is not Reading:
            if isinstance(r, Rejected):
                return self._drop(r.reason, r.detail, r.stamp_ns)
            if not isinstance(r, Reading):
                return self._drop("bad_message", f"not a Reading: {type(r).__name__}")
        w, f = r.omega, r.specific_force
        if len(w) != 3 or (f is not None and len(f) != 3):
            return self._drop("bad_message", "rate or specific force is not a 3-vector")
        wx, wy, wz = float(w[0]), float(w[1]), float(w[2])
        if f is None:
            fx = fy = fz = 0.0
        else:
            fx, fy, fz = float(f[0]), float(f[1]), float(f[2])
        verdict = _verdict(wx, wy, wz, fx, fy, fz, f is not None, cfg.max_rate, cfg.max_specific_force,
                           cfg.require_specific_force)
        if verdict != ROW_OK:
            f = None if f is None else (fx, fy, fz)
            return self._drop(ROW_REASONS[verdict], _row_detail(verdict, (wx, wy, wz), f, cfg))

        # -- choose the time
        stamp = r.stamp_ns
        stamp_valid = stamp is not None and stamp != 0
        source = s.source
        if source is None:
            source = cfg.time_source
            if source == "auto":
                source = "header" if stamp_valid else "receive"
        if source == "header":
            if not stamp_valid:
                what = "no header" if stamp is None else "header stamp is 0"
                return self._drop("zero_stamp", f"{what} while timing by header stamps")
            t_ns = int(stamp)
        else:
            if receive_ns is None:
                return self._drop("no_time", "timing by receive time but no receive time given")
            t_ns = int(receive_ns)

        # -- order, gaps, jumps
        action, reason, detail = _A_ACCEPT, "ok", ""
        note: tuple[str, ...] = ()
        last_ns, dt_ema = s.last_ns, s.dt_ema
        if last_ns is None:
            reason = "start"
        else:
            dt_ns = t_ns - last_ns
            if dt_ns == 0:
                return self._drop("repeated_stamp", f"t = previous t ({t_ns} ns)", t_ns, source)
            if dt_ns < 0:
                if -dt_ns > cfg.reset_on_jump_back * NS:
                    action, reason = _A_RESET, "jump_back"
                    detail = f"time jumped back {-dt_ns / NS:.6g} s (> {cfg.reset_on_jump_back:g} s)"
                else:
                    return self._drop("backward_stamp", f"t is {-dt_ns / NS:.6g} s before the previous t",
                                      t_ns, source)
            elif dt_ns > cfg.max_gap * NS:
                detail = f"gap of {dt_ns / NS:.6g} s (> max_gap {cfg.max_gap:g} s)"
                if cfg.on_gap == "reset":
                    action, reason = _A_RESET, "gap"
                else:
                    note = ("gap_integrated",)
            else:
                dt_ema = ema_add(dt_ema, dt_ns / NS, cfg.rate_smoothing)

        if action is _A_RESET and cfg.rebase_on_reset and cfg.time_source == "auto" and stamp_valid:
            source, t_ns = "header", int(stamp)     # a fresh start chooses its time source again (restart())
        # -- commit
        if source == "receive":
            note += ("receive_time",)
        if r.identity_assumed:
            note += ("identity_frame",)
        origin = s.origin_ns
        self._undo = (s.source, origin, last_ns, s.dt_ema, note)
        s.source = source
        if origin is None or (action is _A_RESET and cfg.rebase_on_reset):
            s.origin_ns = origin = t_ns
        s.last_ns = t_ns
        s.dt_ema = dt_ema
        if note:
            for n in note:
                self.notes[n] += 1
        sample = RateSample((t_ns - origin) / NS, np.array((wx, wy, wz)),
                            None if f is None else np.array((fx, fy, fz)))
        return Decision(action, reason, sample, t_ns, source, detail)

    # ---- blocks -----------------------------------------------------------------------
    def offer_block(self, rb: "RateBlock", receive_ns: np.ndarray | None = None, snap_rows: Any = (),
                    snapshots: dict[int, dict] | None = None) -> GateBlock:
        """Decide about every row of ``rb`` (rows in base_link: :meth:`Mounting.rotate_block`),
        ``receive_ns`` int64 (N,) their receive times (None: unknown). Same decisions, counters,
        notes, last decision and rate estimates as one :meth:`offer` per row; runs of plain rows
        (usable, finite, within ``max_rate``, time valid, increasing, no gap, source locked) are
        decided with array operations, every other row by :meth:`offer`. ``snapshots`` (a dict):
        the :meth:`snapshot` after each row of ``snap_rows`` is stored there under its row (what
        it would be after ``offer_block`` of the rows up to it)."""
        n = len(rb)
        action = np.full(n, DROP, np.int8)
        reason = np.zeros(n, np.int16)
        t = np.full(n, np.nan)
        stamp = np.full(n, -1, np.int64)
        if n == 0:
            return GateBlock(action, reason, t, stamp)
        cfg, s = self.config, self._s
        rx = None if receive_ns is None else np.asarray(receive_ns, np.int64)
        rx_list = None if rx is None else rx.tolist()
        snaps = sorted({int(r) for r in snap_rows if 0 <= r < n}) if snapshots is not None else []
        ks = 0                                  # the next snapshot row: snaps[ks]
        arrived = 0                             # arrivals counted up to this row (exclusive)
        if rx_list is not None and not snaps:
            self._arrivals(rx, rx_list)
            arrived = n

        usable = usable_rows(rb.omega, rb.force, rb.has_force, rb.reject, float(cfg.max_rate),
                             float(cfg.max_specific_force), bool(cfg.require_specific_force))
        gap_ns = ns_floor(cfg.max_gap)

        tn = plain_next = intrinsic = stops = tn_source = None
        i = 0
        while i < n:
            if s.source is not None and s.source != tn_source:    # (a reset may choose the source again)
                tn_source = s.source
                if s.source == "header":
                    tn, valid = rb.stamp_ns, rb.has_header & (rb.stamp_ns != 0)
                elif rx is not None:
                    tn, valid = rx, np.ones(n, bool)
                else:
                    tn, valid = np.zeros(n, np.int64), np.zeros(n, bool)
                if np.abs(tn).max() > 2**62:           # int64 differences could wrap: no vectorising
                    valid = np.zeros(n, bool)
                d = np.diff(tn)
                intrinsic = usable & valid
                plain_next = intrinsic.copy()
                plain_next[1:] &= (d > 0) & (d <= gap_ns)
                stops = np.flatnonzero(~plain_next)
            if tn is not None and intrinsic[i] and 0 < int(tn[i]) - s.last_ns <= gap_ns:
                k = int(np.searchsorted(stops, i + 1))
                j = int(stops[k]) if k < len(stops) else n
                if ks < len(snaps) and snaps[ks] < j:       # the run cut after a snapshot row
                    j = snaps[ks] + 1
                self._accept_run(rb, tn, i, j, action, reason, t, stamp)
                i = j
            else:
                d1 = self._offer(reading_of(rb, i), None if rx_list is None else rx_list[i])
                action[i] = ACTION_CODE[d1.action]
                reason[i] = REASON_INDEX[d1.reason]
                if d1.sample is not None:
                    t[i] = d1.sample.t
                if d1.stamp_ns is not None:
                    stamp[i] = d1.stamp_ns
                i += 1
            if ks < len(snaps) and snaps[ks] == i - 1:
                if rx_list is not None:                     # the arrivals up to that row
                    self._arrivals(rx[arrived:i], rx_list[arrived:i])
                    arrived = i
                snapshots[i - 1] = self.snapshot()
                ks += 1
        if rx_list is not None and arrived < n:
            self._arrivals(rx[arrived:], rx_list[arrived:])
        return GateBlock(action, reason, t, stamp)

    def _arrivals(self, rx: np.ndarray, rx_list: list[int]) -> None:
        """The arrival-rate update of :meth:`offer` for every receive time of a block (same float operations)."""
        s = self._s
        first = s.rx_last
        gap_ns = ns_floor(self.config.max_gap)
        lo, hi = min(rx_list), max(rx_list)
        if first is not None:
            lo, hi = min(lo, first), max(hi, first)
        if gap_ns < EXACT_NS and -2**62 < lo and hi < 2**62:
            e, unset = arrival_ema(rx, 0 if first is None else first, first is not None, gap_ns,
                                   np.nan if s.rx_dt_ema is None else s.rx_dt_ema, s.rx_dt_ema is None,
                                   self.config.rate_smoothing)
            s.rx_dt_ema = None if unset else float(e)
        else:                                   # int64 differences could wrap or lose digits
            prev = np.empty(len(rx), np.int64)
            prev[1:] = rx[:-1]
            prev[0] = 0 if first is None else first
            d = rx - prev
            ok = (d > 0) & (d <= gap_ns)
            if first is None:
                ok[0] = False
            s.rx_dt_ema = ema(s.rx_dt_ema, d[ok], self.config.rate_smoothing)
        s.rx_last = int(rx_list[-1])

    def _accept_run(self, rb: "RateBlock", tn: np.ndarray, i: int, j: int, action: np.ndarray,
                    reason: np.ndarray, t: np.ndarray, stamp: np.ndarray) -> None:
        """Accept rows i..j-1 (a plain run: each within (0, max_gap] after the previous one)."""
        s, m = self._s, j - i
        origin = s.origin_ns
        if ns_floor(self.config.max_gap) < EXACT_NS and -2**62 <= origin <= 2**62:
            # (the run's times are within 2**62: offer_block vectorises no others)
            s.dt_ema = float(accept_rows(tn, i, j, s.last_ns, origin,
                                         np.nan if s.dt_ema is None else s.dt_ema, s.dt_ema is None,
                                         self.config.rate_smoothing, t, stamp))
        else:                                   # intervals beyond 2**53 ns: exact Python division
            run = tn[i:j]
            prev = np.empty(m, np.int64)
            prev[0] = s.last_ns
            prev[1:] = run[:-1]
            s.dt_ema = ema(s.dt_ema, run - prev, self.config.rate_smoothing)
            t[i:j] = (run - origin) / NS
            stamp[i:j] = run
        s.last_ns = last_ns = int(tn[j - 1])
        action[i:j] = ACCEPT
        reason[i:j] = REASON_INDEX["ok"]
        self.received += m
        self.counts["ok"] += m
        if s.source == "receive":
            self.notes["receive_time"] += m
        n_id = int(np.count_nonzero(rb.identity[i:j]))
        if n_id:
            self.notes["identity_frame"] += n_id
        k = j - 1
        force = rb.force[k].copy() if rb.has_force[k] else None
        sample = RateSample((last_ns - origin) / NS, rb.omega[k].copy(), force)
        self.last = Decision(Action.ACCEPT, "ok", sample, last_ns, s.source, "")
        self._undo = None

    # ---- diagnostics ----------------------------------------------------------------
    @property
    def input_rate_hz(self) -> float | None:
        """Smoothed arrival rate of messages by receive time (Hz; all messages, dropped ones
        too), None until two receive times within ``max_gap`` were seen."""
        dt = self._s.rx_dt_ema
        return None if not dt else 1.0 / dt

    @property
    def accepted_rate_hz(self) -> float | None:
        """Smoothed rate of accepted samples by sample time (Hz), None before two in a row."""
        dt = self._s.dt_ema
        return None if not dt else 1.0 / dt

    def snapshot(self) -> dict[str, Any]:
        """Counts by reason, totals, last decision, input rate (Hz), time source, origin."""
        dropped = {k: v for k, v in self.counts.items() if k in DROP_REASONS and v}
        resets = {k: v for k, v in self.counts.items() if k in RESET_REASONS and v}
        accepted = sum(v for k, v in self.counts.items() if k in ACCEPT_REASONS) + sum(resets.values())
        last = self.last
        return {
            "received": self.received,
            "accepted": accepted,
            "dropped": sum(dropped.values()),
            "resets": sum(resets.values()),
            "dropped_by_reason": dropped,
            "resets_by_reason": resets,
            "notes": {k: v for k, v in self.notes.items() if v},
            "last_action": None if last is None else last.action.value,
            "last_reason": None if last is None else last.reason,
            "last_detail": None if last is None else last.detail,
            "last_drop_reason": None if self.last_drop is None else self.last_drop.reason,
            "input_rate_hz": self.input_rate_hz,
            "accepted_rate_hz": self.accepted_rate_hz,
            "time_source": self._s.source,
            "origin_ns": self._s.origin_ns,
            "last_stamp_ns": self._s.last_ns,
        }
