"""Input messages → time gate → simulator → output instants: the one pipeline that the replay,
the scene runs and the node core share.

* :func:`judge` decodes one bag message, maps it to base_link (sensor mounting) and lets the
  :class:`~gyro_platform.io.gate.TimeGate` decide; :func:`read_samples` streams a bag's input
  topic as those decisions (scenes of motion type ``bag``).
* :func:`apply_decision` applies one gate decision to a ``Simulator``.
* :func:`grid_index` is the output grid: an output is taken when a sample's stamp starts a new
  slot ``floor((t − t_origin)·rate)``.
* :class:`Pipeline` holds these together for one stream: ``feed(message, receive_ns)`` (a decoded
  message) or ``offer``/``apply`` (a reading / a decision) → :class:`Step` (the decision, the
  simulator's outcome, whether to take the outputs now); ``run(stream)`` feeds a whole stream.
  One object per stream, so that a batched (compiled) path can later replace the per-sample
  loop inside ``run`` without touching its callers.

Times: ns (int) on the input's time base; rates in Hz.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from .engine.inputs import RateSample
from .errors import InputError, SimulationError
from .io import messages as msgs
from .io.bag_reader import InputBag
from .io.gate import NS, Action, Decision, TimeGate
from .io.messages import Mounting, Rejected

#: outcomes of :func:`apply_decision` after which the simulator holds a new instant
ADVANCED = ("pushed", "reset", "restarted")


@dataclass(frozen=True, slots=True)
class BagSample:
    """One input-topic message with the gate's decision. ``receive_ns``: bag record time (ns);
    ``msg``: the decoded message (None if it could not be decoded)."""

    decision: Decision
    receive_ns: int
    msg: Any
    connection: Any
    rawdata: bytes

    @property
    def sample(self) -> RateSample | None:
        return self.decision.sample

    @property
    def receive_time(self) -> float:
        """Receive time, s since the epoch (for display; use ``receive_ns`` for arithmetic)."""
        return self.receive_ns / NS


def judge(bag: InputBag, conn: Any, raw: bytes, receive_ns: int, mounting: Mounting,
          gate: TimeGate) -> tuple[Decision, Any]:
    """Decode one input message, map it to base_link and let the gate decide (never raises)."""
    try:
        msg = bag.deserialize(conn, raw)
    except Exception as e:
        return gate.offer(Rejected("bad_message", f"cannot decode {conn.msgtype}: {e}"), receive_ns), None
    return gate.offer(msgs.reading_from_msg(msg, mounting), receive_ns), msg


def read_samples(bag_path: str | Path, topic: str | None = None, *, mounting: Mounting | None = None,
                 gate: TimeGate | None = None) -> Iterator[BagSample]:
    """Stream the input topic of a bag as gate decisions (a generator: one message at a time).

    ``topic``: default the first Imu/Twist/TwistStamped topic; ``mounting``: sensor frames
    (default: base_link only, unknown frames taken as identity); ``gate``: default
    ``TimeGate()``. Raises BagReadError (naming the file) when the bag cannot be read,
    ReplayError when it has no usable topic.
    """
    mounting = mounting or Mounting()
    gate = gate or TimeGate()
    with InputBag(bag_path, topic) as bag:
        for conn, ts, raw in bag.messages(input_only=True):
            decision, msg = judge(bag, conn, raw, ts, mounting, gate)
            yield BagSample(decision, ts, msg, conn, raw)


def apply_decision(sim: Any, decision: Decision) -> str:
    """Apply a gate decision to a ``Simulator``. Returns ``"pushed"``, ``"reset"`` (reset, then
    pushed), ``"dropped"``, ``"rejected"`` (the simulator refused the sample: InputError, state
    unchanged) or ``"restarted"`` (the integration failed: SimulationError; the simulator is
    reset and restarted at this sample). Outputs already taken are never touched."""
    if decision.action is Action.DROP or decision.sample is None:
        return "dropped"
    if decision.action is Action.RESET:
        sim.reset()
    try:
        sim.push(decision.sample)
    except InputError:
        return "rejected"
    except SimulationError:
        sim.reset()
        try:
            sim.push(decision.sample)
        except SimulationError:
            return "rejected"
        return "restarted"
    return "reset" if decision.action is Action.RESET else "pushed"



def grid_index(t_ns: int, origin_ns: int, rate: float) -> int:
    """Index of the output slot of ``t_ns``: floor((t − origin)·rate) (times in ns, rate in Hz)."""
    return math.floor((t_ns - origin_ns) * 1e-9 * rate + 1e-9)


#: why a drop reason took every sample, and the fix
DROP_HINTS = {
    "zero_stamp": "every header stamp is 0; time by receive time instead (--time-source receive or auto)",
    "unknown_frame": "the input frame has no mounting; give --mount FRAME=... or --unknown-frame identity",
    "over_rate": "every rate exceeds --max-rate; raise it if the rates are real",
    "no_rate": "the messages carry no angular rate",
    "non_finite": "every rate is NaN or infinite",
    "bad_message": "no message could be decoded",
}


def no_sample_hint(dropped_by_reason: dict[str, int], n_in: int) -> str:
    """One line: no sample of ``n_in`` was accepted, the main drop reason and its fix."""
    if not dropped_by_reason:
        return f"none of the {n_in} input messages was accepted: no outputs"
    reason, count = max(dropped_by_reason.items(), key=lambda kv: kv[1])
    hint = DROP_HINTS.get(reason, "see dropped_by_reason in the summary")
    return f"none of the {n_in} input messages was accepted ({count} dropped as {reason}): {hint}"



@dataclass(slots=True)
class Step:
    """What one input did: the gate's ``decision``, the simulator's ``outcome`` (see
    :func:`apply_decision`) and ``emit``: the sample starts a new output slot, take the outputs."""

    decision: Decision
    outcome: str
    emit: bool


class Pipeline:
    """One input stream through the gate into a simulator, on an output grid.

    ``sim``: a ``Simulator``; ``gate``: its ``TimeGate`` (its origin anchors the grid);
    ``output_rate``: Hz, None or ≤ 0 = every accepted sample; ``mounting``: sensor frames for
    :meth:`feed`. ``outcomes`` counts the :func:`apply_decision` results (callers may add
    their own keys, e.g. ``output_failed``).
    """

    def __init__(self, sim: Any, gate: TimeGate, output_rate: float | None,
                 mounting: Mounting | None = None):
        self.sim, self.gate, self.output_rate = sim, gate, output_rate
        self.mounting = mounting or Mounting()
        self.outcomes: dict[str, int] = {}
        self.slot: int | None = None        # output grid slot of the last output

    def feed(self, msg: Any, receive_ns: int | None) -> Step:
        """A decoded input message (Imu/Twist/TwistStamped) received at ``receive_ns``."""
        return self.offer(msgs.reading_from_msg(msg, self.mounting), receive_ns)

    def offer(self, reading: Any, receive_ns: int | None) -> Step:
        """A reading (or ``Rejected``) from :mod:`gyro_platform.io.messages`."""
        return self.apply(self.gate.offer(reading, receive_ns))

    def apply(self, decision: Decision) -> Step:
        """A gate decision: simulator, outcome count, output grid (restarted on a reset)."""
        outcome = apply_decision(self.sim, decision)
        self.outcomes[outcome] = self.outcomes.get(outcome, 0) + 1
        if outcome == "rejected":       # the gate must not keep a time the simulator refused
            self.gate.refuse("the simulator refused the sample")
        if outcome in ("reset", "restarted"):
            self.slot = None
        return Step(decision, outcome, outcome in ADVANCED and self.due(decision.stamp_ns))

    def due(self, stamp_ns: int) -> bool:
        """True when ``stamp_ns`` starts a new slot of the output grid (always without a rate)."""
        rate = self.output_rate
        if rate is None or rate <= 0:
            return True
        slot = grid_index(stamp_ns, self.gate.origin_ns or 0, rate)
        if self.slot is None or slot > self.slot:
            self.slot = slot
            return True
        return False

    def run(self, stream: Iterable[tuple[Any, int | None]]) -> Iterator[Step]:
        """:meth:`feed` every ``(message, receive_ns)`` of ``stream``, one step per message."""
        for msg, receive_ns in stream:
            yield self.feed(msg, receive_ns)
