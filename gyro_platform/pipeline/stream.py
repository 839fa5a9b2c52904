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

"""Input messages → time gate → simulator → output instants: the one pipeline that the replay,
the scene runs and the node core share.

* :func:`judge` decodes one bag message, maps it to base_link (sensor mounting) and lets the
  :class:`~gyro_platform.pipeline.gate.TimeGate` decide; :func:`read_samples` streams a bag's input
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

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from .chunked import ChunkedRuns
from .gate import TimeGate
from .gate_rules import Decision, NS, plain_decision
from .grid import check_grid_rate, grid_index
from .outcomes import ADVANCED, apply_decision, refusal, restart_at
from .. import messages as msgs
from ..bags.reader import InputBag
from ..engine.inputs import RateSample
from ..errors import InputError, SimulationError
from ..messages import Mounting, Rejected


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


class Step:
    """What one input did: the gate's ``decision``, the simulator's ``outcome`` (see
    :func:`apply_decision`) and ``emit``: the sample starts a new output slot, take the outputs.
    ``plain``: a plain sample's tuple (``TimeGate.last_plain``) from which the decision is
    made when asked (``stamp_ns``, ``source`` without making it)."""

    __slots__ = ("_decision", "_plain", "outcome", "emit")

    def __init__(self, decision: Decision | None, outcome: str, emit: bool, plain: tuple | None = None):
        self._decision, self._plain, self.outcome, self.emit = decision, plain, outcome, emit

    @property
    def decision(self) -> Decision:
        """Return the gate's decision, made from the plain tuple on the first call."""
        if self._decision is None:
            self._decision = plain_decision(self._plain)
        return self._decision

    @property
    def stamp_ns(self) -> int | None:
        """The decision's ``stamp_ns``."""
        return self._plain[3] if self._decision is None else self._decision.stamp_ns

    @property
    def source(self) -> str | None:
        """The decision's ``source``."""
        return self._plain[4] if self._decision is None else self._decision.source

    def __repr__(self) -> str:
        return f"Step({self.decision!r}, {self.outcome!r}, {self.emit!r})"


class Pipeline(ChunkedRuns):
    """One input stream through the gate into a simulator, on an output grid.

    ``sim``: a ``Simulator``; ``gate``: its ``TimeGate`` (its origin anchors the grid);
    ``output_rate``: Hz, None or ≤ 0 = every accepted sample; ``mounting``: sensor frames for
    :meth:`feed`. ``outcomes`` counts the :func:`apply_decision` results (callers may add
    their own keys, e.g. ``output_failed``).
    """

    def __init__(self, sim: Any, gate: TimeGate, output_rate: float | None,
                 mounting: Mounting | None = None):
        check_grid_rate(output_rate if output_rate is None or output_rate > 0 else None, "output rate")
        self.sim, self.gate, self.output_rate = sim, gate, output_rate
        self.mounting = mounting or Mounting()
        self.outcomes: dict[str, int] = {}
        self.slot: int | None = None        # output grid slot of the last output
        self.new_segment = True             # no output since the last (re)start
        self.errors: list[str] = []         # simulator failures (at most MAX_ERRORS)
        self.duration: float | None = None  # s: stop at the first sample this long after the first one
        self.t_first: float | None = None   # s: sample time of the first accepted sample
        self.stopped = False                # the duration was reached (run_block only)
        self._refusable = False             # a refused row ends the block part (gate.refuse)

    def feed(self, msg: Any, receive_ns: int | None) -> Step:
        """A decoded input message (Imu/Twist/TwistStamped) received at ``receive_ns``."""
        return self.offer(msgs.reading_from_msg(msg, self.mounting), receive_ns)

    def offer(self, reading: Any, receive_ns: int | None) -> Step:
        """A reading (or ``Rejected``) from :mod:`gyro_platform.messages`. A plain reading
        (``TimeGate.offer_plain``) goes to ``Simulator.push_plain`` with no decision or sample
        object made; the same decisions, outcomes and state as :meth:`apply` of ``gate.offer``."""
        gate = self.gate
        plain = gate.offer_plain(reading, receive_ns)
        if plain is None:
            return self.apply(gate.offer(reading, receive_ns))
        try:
            self.sim.push_plain(plain[0], plain[1], plain[2])
        except InputError as e:
            outcome = "rejected"
            self.record_error(refusal(e))
        except SimulationError:
            outcome = restart_at(self.sim, gate.last.sample)
        else:
            return self._settle(None, "pushed", plain)
        return self._settle(gate.last, outcome)

    def apply(self, decision: Decision) -> Step:
        """A gate decision: simulator, outcome count, output grid (restarted on a reset)."""
        return self._settle(decision, apply_decision(self.sim, decision, self.record_error))

    def _settle(self, decision: Decision | None, outcome: str, plain: tuple | None = None) -> Step:
        """Count the simulator's ``outcome`` of ``decision`` (None: a pushed ``plain`` reading,
        ``TimeGate.offer_plain``); gate roll-back, output grid."""
        outcomes = self.outcomes
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
        if outcome == "pushed":
            return Step(decision, outcome, self.due(plain[3] if decision is None else decision.stamp_ns), plain)
        if outcome == "rejected":       # the gate must not keep a time the simulator refused
            self.gate.refuse("the simulator refused the sample")
        if outcome in ("reset", "restarted"):
            self.slot, self.new_segment = None, True
        return Step(decision, outcome, outcome in ADVANCED and self.due(decision.stamp_ns))

    def due(self, stamp_ns: int) -> bool:
        """True when ``stamp_ns`` starts a new slot of the output grid (always without a rate)."""
        rate = self.output_rate
        if rate is None or rate <= 0:
            return True
        slot = grid_index(stamp_ns, self.gate.origin_ns or 0, rate)
        last = self.slot
        if last is None or slot > last:
            self.slot = slot
            return True
        return False

    def run(self, stream: Iterable[tuple[Any, int | None]]) -> Iterator[Step]:
        """:meth:`feed` every ``(message, receive_ns)`` of ``stream``, one step per message."""
        for msg, receive_ns in stream:
            yield self.feed(msg, receive_ns)

    # ---- the chunked path ------------------------------------------------------------------
