"""Input gate between messages and the simulator: timing and sanity of every rate sample.

:meth:`TimeGate.offer` takes what :func:`gyro_platform.io.messages.reading_from_msg` made of one
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
| `zero_stamp` | drop | header mode and stamp 0 |
| `no_time` | drop | receive mode and no receive time given |
| `repeated_stamp` | drop | t = previous accepted t |
| `backward_stamp` | drop | t < previous accepted t by at most `reset_on_jump_back` |
| `jump_back` | reset | t < previous accepted t by more than `reset_on_jump_back` (looped bag) |
| `gap` | reset | t − previous > `max_gap` and `on_gap="reset"` (default) |
| `ok` | accept | otherwise (first sample: `start`) |

Notes counted beside the decisions: ``receive_time`` (time taken from the receive clock),
``gap_integrated`` (a gap integrated across with ``on_gap="integrate"``), ``identity_frame``
(unknown frame taken as base_link).

Default ``on_gap="reset"``: across a gap the simulator would interpolate the rate linearly and
so invent the vehicle's motion; restarting is honest, and the outputs before the gap are kept.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from ..engine.inputs import RateSample
from .messages import Reading, Rejected

NS = 1_000_000_000


class Action(str, Enum):
    """What the caller does with a sample."""

    ACCEPT = "accept"
    DROP = "drop"
    RESET = "reset"   # reset the simulator, then push the sample


DROP_REASONS = ("no_rate", "unknown_frame", "bad_message", "non_finite", "over_rate", "zero_stamp",
                "no_time", "repeated_stamp", "backward_stamp")
RESET_REASONS = ("jump_back", "gap")
ACCEPT_REASONS = ("start", "ok")
NOTES = ("receive_time", "gap_integrated", "identity_frame")


@dataclass(frozen=True, slots=True)
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


@dataclass(frozen=True)
class GateConfig:
    """Gate settings. ``max_gap`` s; ``on_gap``: ``reset`` | ``integrate``;
    ``reset_on_jump_back`` s; ``max_rate`` rad/s; ``time_source``: ``auto`` | ``header`` |
    ``receive``; ``rate_smoothing``: weight of a new interval in the rate estimates."""

    max_gap: float = 1.0
    on_gap: str = "reset"
    reset_on_jump_back: float = 1.0
    max_rate: float = 35.0
    time_source: str = "auto"
    rate_smoothing: float = 0.05

    def __post_init__(self) -> None:
        if not (self.max_gap > 0 and math.isfinite(self.max_gap)):
            raise ValueError(f"max_gap = {self.max_gap} s; must be > 0")
        if self.on_gap not in ("reset", "integrate"):
            raise ValueError(f"on_gap = {self.on_gap!r}; allowed: reset, integrate")
        if not self.reset_on_jump_back >= 0:
            raise ValueError(f"reset_on_jump_back = {self.reset_on_jump_back} s; must be >= 0")
        if not self.max_rate > 0:
            raise ValueError(f"max_rate = {self.max_rate} rad/s; must be > 0")
        if self.time_source not in ("auto", "header", "receive"):
            raise ValueError(f"time_source = {self.time_source!r}; allowed: auto, header, receive")
        if not 0 < self.rate_smoothing <= 1:
            raise ValueError(f"rate_smoothing = {self.rate_smoothing}; allowed (0, 1]")


@dataclass
class _State:
    source: str | None = None          # locked time source
    origin_ns: int | None = None       # time zero of sample.t
    last_ns: int | None = None         # last accepted time
    dt_ema: float | None = None        # s, smoothed interval of accepted samples
    rx_last: int | None = None         # last receive time, ns
    rx_dt_ema: float | None = None     # s, smoothed interval of arriving messages


class TimeGate:
    """Decides for each message: accept, drop (with reason) or reset-then-accept. Never raises
    on input data; counts every decision; :meth:`snapshot` gives the diagnostics."""

    def __init__(self, config: GateConfig | None = None):
        self.config = config or GateConfig()
        self._s = _State()
        self.counts: Counter[str] = Counter()     # decision reason -> count
        self.notes: Counter[str] = Counter()      # note -> count
        self.received = 0
        self.last: Decision | None = None
        self.last_drop: Decision | None = None

    # ---- properties -----------------------------------------------------------------
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

    # ---- the decision ---------------------------------------------------------------
    def offer(self, reading: Reading | Rejected, receive_ns: int | None = None) -> Decision:
        """Decide about one message; ``receive_ns`` is its receive time (ns) if known."""
        self.received += 1
        self._arrival(receive_ns)
        try:
            d = self._decide(reading, receive_ns)
        except Exception as e:  # defensive: the gate never raises on data
            d = Decision(Action.DROP, "bad_message", detail=f"gate could not judge the input: {e}")
        self.counts[d.reason] += 1
        self.last = d
        if d.action is Action.DROP:
            self.last_drop = d
        return d

    def _arrival(self, receive_ns: int | None) -> None:
        s = self._s
        if receive_ns is None:
            return
        if s.rx_last is not None and 0 < receive_ns - s.rx_last <= self.config.max_gap * NS:
            dt = (receive_ns - s.rx_last) / NS
            a = self.config.rate_smoothing
            s.rx_dt_ema = dt if s.rx_dt_ema is None else s.rx_dt_ema + a * (dt - s.rx_dt_ema)
        s.rx_last = int(receive_ns)

    def _drop(self, reason: str, detail: str, stamp_ns: int | None = None, source: str | None = None) -> Decision:
        return Decision(Action.DROP, reason, None, stamp_ns, source, detail)

    def _decide(self, r: Reading | Rejected, receive_ns: int | None) -> Decision:
        cfg, s = self.config, self._s
        if isinstance(r, Rejected):
            return self._drop(r.reason, r.detail, r.stamp_ns)
        if not isinstance(r, Reading):
            return self._drop("bad_message", f"not a Reading: {type(r).__name__}")
        omega = np.asarray(r.omega, dtype=float)
        force = None if r.specific_force is None else np.asarray(r.specific_force, dtype=float)
        if omega.shape != (3,) or (force is not None and force.shape != (3,)):
            return self._drop("bad_message", "rate or specific force is not a 3-vector")
        if not np.all(np.isfinite(omega)) or (force is not None and not np.all(np.isfinite(force))):
            return self._drop("non_finite", f"non-finite value: omega={omega.tolist()}, "
                                            f"specific_force={None if force is None else force.tolist()}")
        rate = float(np.linalg.norm(omega))
        if rate > cfg.max_rate:
            return self._drop("over_rate", f"|omega| = {rate:.6g} rad/s > max_rate {cfg.max_rate:g} rad/s")

        # -- choose the time
        stamp_valid = r.stamp_ns is not None and r.stamp_ns != 0
        source = s.source
        if source is None:
            source = cfg.time_source
            if source == "auto":
                source = "header" if stamp_valid else "receive"
        if source == "header":
            if not stamp_valid:
                what = "no header" if r.stamp_ns is None else "header stamp is 0"
                return self._drop("zero_stamp", f"{what} while timing by header stamps")
            t_ns = int(r.stamp_ns)
        else:
            if receive_ns is None:
                return self._drop("no_time", "timing by receive time but no receive time given")
            t_ns = int(receive_ns)

        # -- order, gaps, jumps
        action, reason, detail = Action.ACCEPT, "ok", ""
        note: list[str] = []
        if s.last_ns is None:
            reason = "start"
        else:
            dt_ns = t_ns - s.last_ns
            if dt_ns == 0:
                return self._drop("repeated_stamp", f"t = previous t ({t_ns} ns)", t_ns, source)
            if dt_ns < 0:
                if -dt_ns > cfg.reset_on_jump_back * NS:
                    action, reason = Action.RESET, "jump_back"
                    detail = f"time jumped back {-dt_ns / NS:.6g} s (> {cfg.reset_on_jump_back:g} s)"
                else:
                    return self._drop("backward_stamp", f"t is {-dt_ns / NS:.6g} s before the previous t",
                                      t_ns, source)
            elif dt_ns > cfg.max_gap * NS:
                detail = f"gap of {dt_ns / NS:.6g} s (> max_gap {cfg.max_gap:g} s)"
                if cfg.on_gap == "reset":
                    action, reason = Action.RESET, "gap"
                else:
                    note.append("gap_integrated")
            else:
                dt = dt_ns / NS
                s.dt_ema = dt if s.dt_ema is None else s.dt_ema + cfg.rate_smoothing * (dt - s.dt_ema)

        # -- commit
        s.source = source
        if s.origin_ns is None:
            s.origin_ns = t_ns
        s.last_ns = t_ns
        if source == "receive":
            note.append("receive_time")
        if r.identity_assumed:
            note.append("identity_frame")
        for n in note:
            self.notes[n] += 1
        sample = RateSample((t_ns - s.origin_ns) / NS, omega, force)
        return Decision(action, reason, sample, t_ns, source, detail)

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
