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
"""  # noqa: E501 (the reason table: one row a line)
from __future__ import annotations

from collections import Counter
import copy
from dataclasses import dataclass
from enum import Enum
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from ..engine.inputs import RateSample
from ..errors import check_number
from ..messages import Reading, Rejected
from ..messages.blocks import REJECT_REASONS
from ..physics.jit import njit

if TYPE_CHECKING:
    from ..messages.blocks import RateBlock

NS = 1_000_000_000


class Action(str, Enum):
    """What the caller does with a sample."""

    ACCEPT = "accept"
    DROP = "drop"
    RESET = "reset"   # reset the simulator, then push the sample


DROP_REASONS = ("no_rate", "unknown_frame", "bad_message", "non_finite", "over_rate", "over_specific_force",
                "no_specific_force", "zero_stamp", "no_time", "repeated_stamp", "backward_stamp", "refused")
RESET_REASONS = ("jump_back", "gap")
ACCEPT_REASONS = ("start", "ok")
#: every decision reason; ``GateBlock.reason`` indexes this tuple
REASONS = DROP_REASONS + RESET_REASONS + ACCEPT_REASONS
ALL_REASONS = REASONS
REASON_INDEX = {r: i for i, r in enumerate(REASONS)}
NOTES = ("receive_time", "gap_integrated", "identity_frame")
#: ``GateBlock.action`` codes
ACCEPT, DROP, RESET = 0, 1, 2
ACTION_CODE = {}  # filled below (Action → code)


ACTION_CODE.update({Action.ACCEPT: ACCEPT, Action.DROP: DROP, Action.RESET: RESET})
# the members as plain globals: an Enum attribute lookup costs ~60 ns, several per message
_A_ACCEPT, _A_DROP, _A_RESET = Action.ACCEPT, Action.DROP, Action.RESET


@dataclass(slots=True)
class Decision:
    """The gate's verdict on one message.

    ``sample`` (ACCEPT/RESET only): time ``t`` s since ``origin_ns``, omega rad/s and specific
    force m/s² in base_link. ``stamp_ns``: the chosen time in the input's time base (ns), None if
    none could be chosen. ``source``: ``"header"`` or ``"receive"``.
    """

    action: Action
    reason: str
    sample: RateSample | None = None
    stamp_ns: int | None = None
    source: str | None = None
    detail: str = ""

    @property
    def accepted(self) -> bool:
        """True for ACCEPT and RESET (the sample goes to the simulator)."""
        return self.action is not Action.DROP


def plain_decision(p: tuple) -> Decision:
    """The ``Decision`` of a plain reading from :attr:`TimeGate.last_plain`'s tuple ``(t,
    omega, specific_force, stamp_ns, source)``: what :meth:`TimeGate.offer` returns for it."""
    t, w, f, t_ns, source = p
    return Decision(_A_ACCEPT, "ok", RateSample(t, np.array(w), None if f is None else np.array(f)), t_ns, source, "")


@dataclass(frozen=True)
class GateConfig:
    """Gate settings. ``max_gap`` s; ``on_gap``: ``reset`` | ``integrate``;
    ``reset_on_jump_back`` s; ``max_rate`` rad/s; ``max_specific_force`` m/s²; ``time_source``: ``auto`` | ``header`` |
    ``receive``; ``rate_smoothing``: weight of a new interval in the rate estimates;
    ``require_specific_force``: drop samples without specific force (``no_specific_force``),
    set when the model's effects need it (the simulator would refuse them);
    ``rebase_on_reset``: a reset (gap, jump back) also moves the origin to the reset sample
    (its ``sample.t`` is 0, as for a fresh gate: a reset is a fresh start; the node uses this);
    default False: one origin for the whole stream."""

    max_gap: float = 1.0
    on_gap: str = "reset"
    reset_on_jump_back: float = 1.0
    max_rate: float = 35.0
    max_specific_force: float = 2000.0
    time_source: str = "auto"
    rate_smoothing: float = 0.05
    require_specific_force: bool = False
    rebase_on_reset: bool = False

    def __post_init__(self) -> None:       # numbers: errors.check_number, the rule of every flag (finite)
        check_number("max_gap", self.max_gap, "s", gt=0)
        check_number("reset_on_jump_back", self.reset_on_jump_back, "s", ge=0)
        check_number("max_rate", self.max_rate, "rad/s", gt=0)
        check_number("max_specific_force", self.max_specific_force, "m/s²", gt=0)
        check_number("rate_smoothing", self.rate_smoothing, gt=0, le=1)
        if self.on_gap not in ("reset", "integrate"):
            raise ValueError(f"on_gap = {self.on_gap!r}; allowed: reset, integrate")
        if self.time_source not in ("auto", "header", "receive"):
            raise ValueError(f"time_source = {self.time_source!r}; allowed: auto, header, receive")


@dataclass
class _State:
    source: str | None = None          # locked time source
    origin_ns: int | None = None       # time zero of sample.t
    last_ns: int | None = None         # last accepted time
    dt_ema: float | None = None        # s, smoothed interval of accepted samples
    rx_last: int | None = None         # last receive time, ns
    rx_dt_ema: float | None = None     # s, smoothed interval of arriving messages


@dataclass(slots=True)
class GateBlock:
    """The gate's decisions on the N rows of a RateBlock (:meth:`TimeGate.offer_block`).

    ``action`` int8 (N,): ``ACCEPT`` 0, ``DROP`` 1, ``RESET`` 2; ``reason`` int16 (N,): index
    into :data:`REASONS`; ``t`` float64 (N,): sample time s since the gate's origin as valid
    after that row's decision (NaN if dropped); ``stamp_ns`` int64 (N,): the chosen time in
    the input's time base (-1 if none)."""

    action: np.ndarray
    reason: np.ndarray
    t: np.ndarray
    stamp_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.action)

    @property
    def accepted(self) -> np.ndarray:
        """bool (N,): the sample goes to the simulator (ACCEPT or RESET)."""
        return self.action != DROP

    def reason_name(self, i: int) -> str:
        return REASONS[int(self.reason[i])]


#: intervals (ns) at most this long convert to float exactly: ``d / NS`` is then the same
#: correctly rounded quotient in Python (int true division) and in compiled code
_EXACT_NS = 2 ** 53


def _ema_add(e: float | None, dt: float, a: float) -> float:
    """One interval ``dt`` (s) into the average ``e``: ``dt`` if none yet, else ``e + a·(dt − e)``
    (the scalar gate's update; the compiled passes' is ``_ema_step``)."""
    return dt if e is None else e + a * (dt - e)


def _ema(e: float | None, d_ns: np.ndarray, a: float) -> float | None:
    """``e`` after ``e = dt if e is None else e + a·(dt − e)`` for every interval ``dt = d/NS``
    of ``d_ns`` (int64 ns) in order: the same float operations as the scalar gate's."""
    if not len(d_ns):
        return e
    if np.abs(d_ns).max() >= _EXACT_NS:
        for dn in d_ns.tolist():
            e = _ema_add(e, dn / NS, a)
        return e
    return float(_ema_kernel(np.nan if e is None else e, e is None, d_ns, a))


@njit(cache=True, inline="always")
def _ema_step(e, unset, d, a):  # pragma: no cover - compiled
    """One interval of ``d`` ns into the average: ``dt`` if none yet (``unset``), else
    ``e + a·(dt − e)``; the one update of every compiled pass below."""
    dt = d / 1_000_000_000
    return dt if unset else e + a * (dt - e)


@njit(cache=True)
def _ema_kernel(e, unset, d_ns, a):  # pragma: no cover - compiled
    for k in range(d_ns.shape[0]):
        e = _ema_step(e, unset, d_ns[k], a)
        unset = False
    return e


@njit(cache=True)
def _usable_rows(w, f, has_force, reject, max_rate, max_force, require_f):  # pragma: no cover - compiled
    """Rows whose values the gate can take as they are: not rejected by the decoder, rate finite
    and within ``max_rate`` (|ω| by the same float operations as the scalar gate), specific
    force finite and within ``max_force`` where present (and present if ``require_f``)."""
    n = w.shape[0]
    out = np.zeros(n, np.bool_)
    for k in range(n):
        w0, w1, w2 = w[k, 0], w[k, 1], w[k, 2]
        ok = reject[k] == 0 and np.isfinite(w0) and np.isfinite(w1) and np.isfinite(w2)
        ok = ok and np.sqrt(w0 * w0 + w1 * w1 + w2 * w2) <= max_rate
        if has_force[k]:
            f0, f1, f2 = f[k, 0], f[k, 1], f[k, 2]
            fin = np.isfinite(f0) and np.isfinite(f1) and np.isfinite(f2)
            ok = ok and fin and np.sqrt(f0 * f0 + f1 * f1 + f2 * f2) <= max_force
        elif require_f:
            ok = False
        out[k] = ok
    return out


@njit(cache=True)
def _accept_rows(tn, i, j, last_ns, origin, e, unset, a, t, stamp):  # pragma: no cover - compiled
    """Rows i..j−1 of a plain run: ``t`` (s after ``origin``) and ``stamp`` (ns) filled, the
    interval EMA ``e`` (``unset``: none yet) advanced over each row's interval after the one
    before (``last_ns`` before row i); returns it. The float operations of :func:`_ema`."""
    prev = last_ns
    for k in range(i, j):
        x = tn[k]
        e = _ema_step(e, unset, x - prev, a)
        unset = False
        prev = x
        t[k] = (x - origin) / 1_000_000_000
        stamp[k] = x
    return e


@njit(cache=True)
def _arrival_ema(rx, first, has_first, gap_ns, e, unset, a):  # pragma: no cover - compiled
    """The arrival-interval EMA over receive times ``rx`` (int64 ns; ``first``: the one before,
    if ``has_first``), intervals outside (0, gap_ns] skipped; returns (e, unset)."""
    prev = first
    for k in range(rx.shape[0]):
        d = rx[k] - prev
        if (k > 0 or has_first) and 0 < d <= gap_ns:
            e = _ema_step(e, unset, d, a)
            unset = False
        prev = rx[k]
    return e, unset


def _ns_floor(seconds: float) -> int:
    """Largest integer ns ≤ ``seconds``·1e9, so that ``d > seconds*NS`` ⟺ ``d > _ns_floor`` for int d."""
    x = seconds * NS
    return 2**62 if x >= 2**62 else math.floor(x)       # (1e300 s: x is inf, which floor refuses)


def reading_of(rb: "RateBlock", i: int) -> Reading | Rejected:
    """Row ``i`` of a block as the scalar gate's input (what reading_from_msg gives)."""
    stamp = int(rb.stamp_ns[i]) if rb.has_header[i] else None
    rj = int(rb.reject[i])
    if rj:
        return Rejected(REJECT_REASONS[rj - 1], rb.detail.get(i, ""), stamp, rb.frame_id[i])
    w = rb.omega[i].tolist()
    f = tuple(rb.force[i].tolist()) if rb.has_force[i] else None
    return Reading((w[0], w[1], w[2]), f, stamp, rb.frame_id[i], bool(rb.identity[i]))


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
            s.rx_dt_ema = _ema_add(s.rx_dt_ema, (receive_ns - last) / NS, self.config.rate_smoothing)
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
            # NaN and ±Inf fail this test too (and a finite ω whose norm overflows)
            if not math.sqrt(wx * wx + wy * wy + wz * wz) <= cfg.max_rate:
                return None
            f = r.specific_force
            if f is not None:
                fx, fy, fz = f
                f = (float(fx), float(fy), float(fz))
                # NaN and ±Inf fail this test too (and a finite force whose norm overflows)
                if not math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) <= cfg.max_specific_force:
                    return None
            elif cfg.require_specific_force:
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
        s.dt_ema = _ema_add(e, dt_ns / NS, cfg.rate_smoothing)
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
        # x - x is 0.0 (false) for a finite x, NaN (true) for NaN or ±Inf
        bad = (wx - wx) or (wy - wy) or (wz - wz)
        if f is not None:
            fx, fy, fz = float(f[0]), float(f[1]), float(f[2])
            bad = bad or (fx - fx) or (fy - fy) or (fz - fz)
        if bad:
            return self._drop("non_finite", f"non-finite value: omega={[wx, wy, wz]}, specific_force="
                                            f"{None if f is None else [fx, fy, fz]}")
        rate = math.sqrt(wx * wx + wy * wy + wz * wz)
        if rate > cfg.max_rate:
            return self._drop("over_rate", f"|omega| = {rate:.6g} rad/s > max_rate {cfg.max_rate:g} rad/s")
        if f is not None and not (force := math.sqrt(fx * fx + fy * fy + fz * fz)) <= cfg.max_specific_force:
            return self._drop("over_specific_force", f"|specific force| = {force:.6g} m/s² > "     # (or overflows)
                                                     f"max_specific_force {cfg.max_specific_force:g} m/s²")
        if f is None and cfg.require_specific_force:
            return self._drop("no_specific_force", "the model's effects need the specific force; "
                                                   "this message carries none")

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
                dt_ema = _ema_add(dt_ema, dt_ns / NS, cfg.rate_smoothing)

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

        usable = _usable_rows(rb.omega, rb.force, rb.has_force, rb.reject, float(cfg.max_rate),
                              float(cfg.max_specific_force), bool(cfg.require_specific_force))
        gap_ns = _ns_floor(cfg.max_gap)

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
        gap_ns = _ns_floor(self.config.max_gap)
        lo, hi = min(rx_list), max(rx_list)
        if first is not None:
            lo, hi = min(lo, first), max(hi, first)
        if gap_ns < _EXACT_NS and -2**62 < lo and hi < 2**62:
            e, unset = _arrival_ema(rx, 0 if first is None else first, first is not None, gap_ns,
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
            s.rx_dt_ema = _ema(s.rx_dt_ema, d[ok], self.config.rate_smoothing)
        s.rx_last = int(rx_list[-1])

    def _accept_run(self, rb: "RateBlock", tn: np.ndarray, i: int, j: int, action: np.ndarray,
                    reason: np.ndarray, t: np.ndarray, stamp: np.ndarray) -> None:
        """Accept rows i..j-1 (a plain run: each within (0, max_gap] after the previous one)."""
        s, m = self._s, j - i
        origin = s.origin_ns
        if _ns_floor(self.config.max_gap) < _EXACT_NS and -2**62 <= origin <= 2**62:
            # (the run's times are within 2**62: offer_block vectorises no others)
            s.dt_ema = float(_accept_rows(tn, i, j, s.last_ns, origin,
                                          np.nan if s.dt_ema is None else s.dt_ema, s.dt_ema is None,
                                          self.config.rate_smoothing, t, stamp))
        else:                                   # intervals beyond 2**53 ns: exact Python division
            run = tn[i:j]
            prev = np.empty(m, np.int64)
            prev[0] = s.last_ns
            prev[1:] = run[:-1]
            s.dt_ema = _ema(s.dt_ema, run - prev, self.config.rate_smoothing)
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
