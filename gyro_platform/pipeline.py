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

import copy
from dataclasses import dataclass, field, fields, replace
import math
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from .engine.inputs import RateSample
# ---- the chunked path's pieces, from their rooms (one place to see them)
from .engine.outputs import OutputBlock  # noqa: F401
from .errors import InputError, SimulationError
from .io import messages as msgs
from .io.bag_reader import InputBag
from .io.bag_writer import OutputBag
from .io.blocks import take_rows
from .io.decode import decode_rates
from .io.gate import Action, ALL_REASONS, Decision, DROP, NS, plain_decision, reading_of, RESET, TimeGate
from .io.messages import Mounting, Rejected
from .physics.jit import abandon_compiles_when

offer_block = TimeGate.offer_block
rotate_block = Mounting.rotate_block
bag_chunks = InputBag.chunks
write_many = OutputBag.write_many
copy_chunk = OutputBag.copy_chunk


def prefetched(items: Iterator[Any], work: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
    """``(item, work(item))`` for each of ``items`` in order, the next one taken and worked on by
    a reader thread while the caller handles this one: what releases the GIL there (file reads,
    SQLite, the compiled decoder) runs beside the caller's work; at most one item ahead. An
    exception of ``items`` or ``work`` is raised here, after the items before it. Closing the
    generator (``contextlib.closing``; also on an exception in the caller) stops the thread."""
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=1)
    stop = threading.Event()

    def put(entry: tuple) -> bool:
        while not stop.is_set():
            try:
                q.put(entry, timeout=0.05)
                return True
            except queue.Full:
                pass
        return False

    def produce() -> None:
        try:
            with abandon_compiles_when(stop):      # a stop does not wait for a kernel compiling here
                for item in items:
                    if not put((item, work(item), None)):
                        return
        except BaseException as e:                  # raised in the caller, in order
            put((None, None, e))
            return
        put((None, None, StopIteration))

    thread = threading.Thread(target=produce, name="gyro-bag-reader", daemon=True)
    thread.start()
    try:
        while True:
            item, res, err = q.get()
            if err is StopIteration:
                return
            if err is not None:
                raise err
            yield item, res
    finally:
        stop.set()
        thread.join()


def push_block(sim: Any, t: Any, omega: Any, force: Any, out_idx: Any) -> Any:
    """Push one block into the simulator: ``Simulator.push_block`` with these arguments."""
    return sim.push_block(t, omega, force, out_idx)


#: outcomes of :func:`apply_decision` after which the simulator holds a new instant
ADVANCED = ("pushed", "reset", "restarted")


# the members as plain globals: an Enum attribute lookup costs ~60 ns, several per message
_ACT_DROP, _ACT_RESET = Action.DROP, Action.RESET


class ChunkPacer:
    """Rows in the next chunk, so that a chunk takes about ``target`` s of wall time whatever a
    row costs (signals are taken and outputs committed between chunks; a slow model — full tree,
    micro-steps — must not hold a Ctrl-C or the output for many seconds). Starts at
    ``START_ROWS``, grows at most 4× a chunk, never above ``max_rows`` or below ``START_ROWS``.
    Call it for the size; ``observe(rows, seconds)`` after each chunk."""

    START_ROWS = 64

    def __init__(self, max_rows: int, target: float = 0.25) -> None:
        self.max_rows, self.target = int(max_rows), float(target)
        self.min_rows = self.rows = min(self.START_ROWS, self.max_rows)

    def __call__(self) -> int:
        return self.rows

    def observe(self, rows: int, seconds: float) -> None:
        """The chunk just done had ``rows`` rows and took ``seconds`` s."""
        fit = self.target * rows / seconds if seconds > 0 else float("inf")
        self.rows = int(max(self.min_rows, min(self.max_rows, 4 * self.rows, fit)))


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
    action = decision.action
    if action is _ACT_DROP or decision.sample is None:
        return "dropped"
    if action is _ACT_RESET:
        sim.reset()
    try:
        sim.push(decision.sample)
    except InputError:
        return "rejected"
    except SimulationError:
        return restart_at(sim, decision.sample)
    return "reset" if action is _ACT_RESET else "pushed"


def restart_at(sim: Any, sample: RateSample) -> str:
    """After a failed integration: reset the simulator and start it again at ``sample``.
    Returns ``"restarted"``, or ``"rejected"`` when even that fails."""
    sim.reset()
    try:
        sim.push(sample)
    except SimulationError:
        return "rejected"
    return "restarted"


#: Hz: the highest output (and diagnostics) grid rate. Above it the slot numbers of a long run
#: would leave int64 (1e20 Hz: slot ~1e20 after a second); any rate above the input's gives an
#: output after every sample, which rate 0 asks for directly
MAX_GRID_RATE = 1e6


def check_grid_rate(rate: float | None, name: str, zero_ok: bool = True) -> None:
    """ValueError (one line naming ``name``) unless ``rate`` is None, 0 (``zero_ok``) or a
    finite rate in (0, ``MAX_GRID_RATE``] Hz."""
    if rate is None or (zero_ok and rate == 0):
        return
    if not (math.isfinite(rate) and 0 < rate <= MAX_GRID_RATE):
        every = " (0 = every sample)" if zero_ok else ""
        raise ValueError(f"{name} {rate!r}: must be a finite rate in (0, {MAX_GRID_RATE:g}] Hz{every}")


def grid_index(t_ns: int, origin_ns: int, rate: float) -> int:
    """Index of the output slot of ``t_ns``: floor((t − origin)·rate) (times in ns, rate in Hz)."""
    return math.floor((t_ns - origin_ns) * 1e-9 * rate + 1e-9)


#: why a drop reason took every sample, and the fix
DROP_HINTS = {
    "zero_stamp": "every header stamp is 0; time by receive time instead (--time-source receive or auto)",
    "unknown_frame": "the input frame has no mounting; give --mount FRAME=... or --unknown-frame identity",
    "over_rate": "every rate exceeds --max-rate; raise it if the rates are real",
    "over_specific_force": "every specific force exceeds --max-specific-force; raise it if the accelerations are real",
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


# ---- the chunked path: blocks of rows through gate, simulator and output grid ------------------
#: per-row outcome codes of a block; the names are the keys of ``Pipeline.outcomes``
OUTCOMES = ("dropped", "pushed", "reset", "rejected", "restarted")
O_DROPPED, O_PUSHED, O_RESET, O_REJECTED, O_RESTARTED = range(len(OUTCOMES))
_NO_SLOT = np.iinfo(np.int64).min
MAX_ERRORS = 100                    # simulator error messages kept by a Pipeline


def grid_indices(t_ns: np.ndarray, origin_ns: int, rate: float) -> np.ndarray:
    """:func:`grid_index` of every stamp (int64; the same float operations, so the same slots)."""
    d = (np.asarray(t_ns, dtype=np.int64) - np.int64(origin_ns)).astype(np.float64)
    return np.floor(d * 1e-9 * rate + 1e-9).astype(np.int64)


def new_slots(slots: np.ndarray, last: int | None) -> np.ndarray:
    """Rows whose slot is beyond every slot before them (and ``last``, None = none): where a
    grid on these slots emits (bool (N,))."""
    run = np.maximum.accumulate(np.concatenate([[_NO_SLOT if last is None else last], slots]))
    return slots > run[:-1]


def rate_rows(rb: Any, a: int, b: int) -> Any:
    """Rows ``a:b`` of a RateBlock (the contract's fields; ``detail`` renumbered)."""
    if a == 0 and b == len(rb.stamp_ns):
        return rb
    cut = lambda v: None if v is None else v[a:b]  # noqa: E731
    return replace(rb, stamp_ns=rb.stamp_ns[a:b], has_header=rb.has_header[a:b], frame_id=rb.frame_id[a:b],
                   omega=rb.omega[a:b], force=rb.force[a:b], has_force=rb.has_force[a:b], reject=rb.reject[a:b],
                   detail={r - a: d for r, d in rb.detail.items() if a <= r < b}, identity=cut(rb.identity))


@dataclass
class RunOutputs:
    """Outputs of one run of a block: ``rows`` (K,) indices into the block's rows, ``block``
    (K outputs), ``new_segment``: the first of them is the first output after a reset."""

    rows: np.ndarray
    block: Any
    new_segment: bool


@dataclass
class BlockResult:
    """What :meth:`Pipeline.run_block` did with N rows: the gate's decisions, the simulator's
    outcome per row (index into :data:`OUTCOMES`), the outputs taken (in row order) and the
    rows whose outputs failed (counted as ``output_failed``)."""

    gate: Any
    outcome: np.ndarray
    outputs: list[RunOutputs]
    output_failed: list[int]
    #: row → (gate snapshot, ``outcomes``) after that row, for the ``snap_rows`` of run_block
    snapshots: dict = field(default_factory=dict)

    @property
    def n_outputs(self) -> int:
        return sum(len(r.rows) for r in self.outputs)


class _Refused(Exception):
    """The simulator refused row ``row`` of a block (the gate must be told)."""

    def __init__(self, row: int):
        self.row = row


def _concat_results(parts: list[tuple[int, BlockResult]]) -> BlockResult:
    """One BlockResult of consecutive parts ``(first row, result)``."""
    gbs = [r.gate for _, r in parts]
    return BlockResult(_concat_gate(gbs), np.concatenate([r.outcome for _, r in parts]),
                       [replace(o, rows=o.rows + a) for a, r in parts for o in r.outputs],
                       [i + a for a, r in parts for i in r.output_failed])


def _concat_gate(gbs: list[Any]) -> Any:
    """One GateBlock of consecutive ones."""
    if len(gbs) == 1:
        return gbs[0]
    return replace(gbs[0], **{f.name: np.concatenate([getattr(g, f.name) for g in gbs]) for f in fields(gbs[0])
                              if isinstance(getattr(gbs[0], f.name), np.ndarray)})


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


class Pipeline:
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
        """A reading (or ``Rejected``) from :mod:`gyro_platform.io.messages`. A plain reading
        (``TimeGate.offer_plain``) goes to ``Simulator.push_plain`` with no decision or sample
        object made; the same decisions, outcomes and state as :meth:`apply` of ``gate.offer``."""
        gate = self.gate
        plain = gate.offer_plain(reading, receive_ns)
        if plain is None:
            return self.apply(gate.offer(reading, receive_ns))
        try:
            self.sim.push_plain(plain[0], plain[1], plain[2])
        except InputError:
            outcome = "rejected"
        except SimulationError:
            outcome = restart_at(self.sim, gate.last.sample)
        else:
            return self._settle(None, "pushed", plain)
        return self._settle(gate.last, outcome)

    def apply(self, decision: Decision) -> Step:
        """A gate decision: simulator, outcome count, output grid (restarted on a reset)."""
        return self._settle(decision, apply_decision(self.sim, decision))

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

    def decode(self, bag: InputBag, chunk: Any) -> Iterator[tuple[np.ndarray, Any]]:
        """The input rows of a RowChunk (``bag``'s input topic), decoded and rotated into base_link:
        ``(rows into the chunk, RateBlock)`` per run of rows of one connection."""
        conns = {c.id: c for c in bag.connections if bag.is_input(c)}
        rows = np.flatnonzero(np.isin(chunk.conn_id, np.fromiter(conns, np.int64, len(conns))))
        if rows.size == 0:
            return
        ids = chunk.conn_id[rows]
        cuts = np.flatnonzero(ids[1:] != ids[:-1]) + 1
        for part in np.split(rows, cuts):
            conn = conns[int(chunk.conn_id[part[0]])]
            a, b = int(part[0]), int(part[-1]) + 1
            raws = chunk.raws[a:b] if b - a == len(part) else take_rows(chunk.raws, part)
            rb = decode_rates(conn.msgtype, raws, bag.store_for(conn))
            yield part, rotate_block(self.mounting, rb)

    def run_chunk(self, bag: InputBag, chunk: Any) -> Iterator[tuple[np.ndarray, Any, BlockResult]]:
        """A RowChunk's input rows through gate and simulator: ``(rows into the chunk, RateBlock,
        BlockResult)`` per :meth:`decode` part (the receive times are the chunk's record times)."""
        for rows, rb in self.decode(bag, chunk):
            yield rows, rb, self.run_block(rb, chunk.ts[rows])

    def run_block(self, rb: Any, receive_ns: np.ndarray, snap_rows: Any = ()) -> BlockResult:
        """N decoded rows (a rotated RateBlock) received at ``receive_ns`` (int64 ns): one
        ``offer_block``, then one ``push_block`` per run of accepted rows (a RESET starts a run:
        new time base, new output grid segment) with the output indices of the grid; the same
        decisions, outcomes and outputs as :meth:`feed` on each message (the reference).
        ``snap_rows`` (increasing): rows after which the gate snapshot and ``outcomes`` are kept
        in ``snapshots`` (what they are after a ``run_block`` ending at that row: the gate is
        cut there, the simulator is not).

        A sample the simulator refuses (``rejected``) is handed back to the gate when it can
        take it back (``TimeGate.refuse``): the gate is rewound to before the block, judges the
        rows up to that one again, is told, and the rows after it are judged anew."""
        rx = np.asarray(receive_ns, dtype=np.int64)
        refuse = getattr(self.gate, "refuse", None)
        parts: list[tuple[int, BlockResult]] = []
        snaps = np.asarray(snap_rows, np.int64)
        gate_snaps: dict[int, dict] = {}
        a, n = 0, len(rx)
        while a < n or not parts:
            part = rate_rows(rb, a, n)
            saved = copy.deepcopy(self.gate) if refuse is not None else None
            res = BlockResult(self._offer(part, rx[a:], snaps - a, gate_snaps, a),
                              np.full(n - a, O_DROPPED, np.int8), [], [])
            try:
                self._simulate(res, part, refuse is not None)
            except _Refused as r:
                j = r.row
                # rewind, judge rows 0..j again (row j by the scalar offer, which refuse undoes)
                vars(self.gate).update(vars(copy.deepcopy(saved)))
                res.gate = offer_block(self.gate, rate_rows(part, 0, j + 1), rx[a:a + j + 1])
                vars(self.gate).update(vars(saved))
                self._offer(rate_rows(part, 0, j), rx[a:a + j], snaps - a, gate_snaps, a)
                self.gate.offer(reading_of(part, j), int(rx[a + j]))
                refuse("the simulator refused the sample")
                if a + j in gate_snaps:
                    gate_snaps[a + j] = self.gate.snapshot()
                res.gate.action[j] = DROP
                if "refused" in ALL_REASONS:
                    res.gate.reason[j] = ALL_REASONS.index("refused")
                res.outcome = res.outcome[:j + 1]
                parts.append((a, res))
                a += j + 1
                continue
            parts.append((a, res))
            break
        res = parts[0][1] if len(parts) == 1 else _concat_results(parts)
        rows = snaps.tolist()
        for r, counted in zip(rows, self._counts_after(res, rows)):
            res.snapshots[r] = (gate_snaps[r], counted)
        self._count(res)
        return res

    def _offer(self, rb: Any, rx: np.ndarray, snaps: np.ndarray, into: dict[int, dict], at: int) -> Any:
        """``offer_block`` of ``rb``, the gate's snapshot after each row of ``snaps`` inside it
        kept in ``into`` (keyed by row + ``at``)."""
        n = len(rx)
        cuts = snaps[(snaps >= 0) & (snaps < n)]
        if not len(cuts):
            return offer_block(self.gate, rb, rx)
        got: dict[int, dict] = {}
        gb = offer_block(self.gate, rb, rx, cuts.tolist(), got)
        for r, snap in got.items():
            into[r + at] = snap
        return gb

    def _simulate(self, res: BlockResult, rb: Any, refusable: bool) -> None:
        """The accepted rows of a gated block through the simulator, run by run."""
        gb = res.gate
        acc = np.flatnonzero(gb.action != DROP)
        if self.duration is not None and acc.size:
            if self.t_first is None:
                self.t_first = float(gb.t[acc[0]])
            over = np.flatnonzero(gb.t[acc] > self.t_first + self.duration + 1e-9)
            if over.size:                           # the rest is neither simulated nor counted
                self.stopped = True
                res.outcome[acc[over[0]]:] = -1
                acc = acc[:over[0]]
        self._refusable = refusable
        if acc.size:
            starts = np.flatnonzero(gb.action[acc] == RESET)
            bounds = np.unique(np.concatenate([[0], starts, [acc.size]]))
            for a, b in zip(bounds[:-1], bounds[1:]):
                self._run(acc[a:b], rb, res)

    def _emits(self, stamps: np.ndarray, last: int | None) -> tuple[np.ndarray, np.ndarray | None]:
        """(emit (N,), grid slot after each row or None without a rate) for pushed rows."""
        rate = self.output_rate
        if rate is None or rate <= 0:
            return np.ones(len(stamps), bool), None
        s = grid_indices(stamps, self.gate.origin_ns or 0, rate)
        emit = new_slots(s, last)
        return emit, np.maximum.accumulate(np.concatenate([[_NO_SLOT if last is None else last], s]))[1:]

    def _run(self, rows: np.ndarray, rb: Any, res: BlockResult) -> None:
        """One run of accepted rows (only ``rows[0]`` may be a RESET) through ``push_block``;
        a failing sample goes the per-message way (:func:`apply_decision`: reset, push again)."""
        gb = res.gate
        has_f = rb.has_force[rows]
        if has_f.any() and not has_f.all():             # a force on some rows only: rare, per message
            return self._scalar(rows, rb, res)
        with_f = bool(has_f.all())
        start = 0
        while start < len(rows):
            r = rows[start:]
            first_reset = start == 0 and gb.action[r[0]] == RESET
            if first_reset:
                self.sim.reset()
            emit, slots = self._emits(gb.stamp_ns[r], None if first_reset else self.slot)
            out_idx = np.flatnonzero(emit)
            try:
                block = push_block(self.sim, gb.t[r], rb.omega[r], rb.force[r] if with_f else None, out_idx)
                n_done, failed = len(r), None
            except InputError:                          # refused before touching the state
                return self._scalar(r, rb, res)
            except SimulationError as e:
                block, n_done, failed = e.block, e.n_done, e
            if n_done:
                res.outcome[r[:n_done]] = O_PUSHED
                if first_reset:
                    res.outcome[r[0]] = O_RESET
                    self.slot, self.new_segment = None, True
                if slots is not None:
                    self.slot = int(slots[n_done - 1])
            if len(block):
                res.outputs.append(RunOutputs(r[out_idx[:len(block)]], block, self.new_segment))
                self.new_segment = False
            if failed is None:
                return
            if failed.output_failed is not None:
                self._outputs_after(failed, r[out_idx], gb, res)
            if n_done == len(r):                        # only outputs failed
                return
            self._scalar(r[n_done:n_done + 1], rb, res)   # the integration to r[n_done] failed
            start += n_done + 1

    def _outputs_after(self, failed: SimulationError, rows: np.ndarray, gb: Any, res: BlockResult) -> None:
        """The recorded instants of a ``push_block`` from its first failed output on
        (``failed.output_failed``; ``rows``: their rows): each failing instant counted as
        ``output_failed``, the outputs of the others kept — as on the per-message path, where
        a failed output stops neither the simulation nor the outputs after it."""
        snaps, k, err = failed.snapshots, failed.output_failed, failed.output_error
        while k is not None:
            i = int(rows[k])
            res.output_failed.append(i)
            self._error(f"t={int(gb.stamp_ns[i])}: outputs failed: {err}")
            if k + 1 == len(snaps):
                return
            try:
                block, nxt = self.sim.outputs_at(snaps.take(slice(k + 1, None))), None
            except SimulationError as e:
                block, err = e.block, e
                nxt = k + 1 + len(block)
            if len(block):
                res.outputs.append(RunOutputs(rows[k + 1:k + 1 + len(block)], block, self.new_segment))
                self.new_segment = False
            k = nxt

    def _scalar(self, rows: np.ndarray, rb: Any, res: BlockResult) -> None:
        """Rows one by one as the per-message path does (apply_decision, due, outputs())."""
        gb = res.gate
        for i in rows:
            i = int(i)
            stamp = int(gb.stamp_ns[i])
            action = Action.RESET if gb.action[i] == RESET else Action.ACCEPT
            sample = RateSample(float(gb.t[i]), rb.omega[i].copy(), rb.force[i].copy() if rb.has_force[i] else None)
            outcome = apply_decision(self.sim, Decision(action, ALL_REASONS[gb.reason[i]], sample, stamp))
            res.outcome[i] = OUTCOMES.index(outcome)
            if outcome == "rejected" and self._refusable:
                raise _Refused(i)
            if outcome in ("reset", "restarted"):
                self.slot, self.new_segment = None, True
            if outcome == "restarted":
                self._error(f"t={stamp}: integration failed, simulator restarted")
            if outcome in ADVANCED and self.due(stamp):
                try:
                    o = self.sim.outputs()
                except SimulationError as e:
                    res.output_failed.append(i)
                    self._error(f"t={stamp}: outputs failed: {e}")
                    continue
                res.outputs.append(RunOutputs(np.array([i]), OutputBlock.stack([o]), self.new_segment))
                self.new_segment = False

    def _count(self, res: BlockResult) -> None:
        """Add a block's outcomes to ``outcomes`` (new keys in the order the per-message path
        would have added them)."""
        if len(res.outcome):
            self._counts_after(res, [len(res.outcome) - 1], into=self.outcomes)

    def _counts_after(self, res: BlockResult, rows: list[int], into: dict | None = None) -> list[dict]:
        """The outcome counts after each ``r`` of ``rows`` (increasing): ``outcomes`` plus the
        block's rows up to ``r``, new keys in the order the per-message path would have added
        them; each a new dict, or (one row) added to ``into``. From running counts made once
        (a count per snapshot row over the whole prefix grew with the block times its snapshots)."""
        if not rows:
            return []
        outcome = res.outcome
        codes = [(int(np.argmax(outcome == c)), c) for c in np.flatnonzero(
            np.bincount(outcome[outcome >= 0], minlength=len(OUTCOMES))).tolist()]
        running = {c: np.cumsum(outcome == c) for _, c in codes}
        failed = np.sort(np.asarray(res.output_failed, np.int64))
        n_failed = np.searchsorted(failed, rows, side="right").tolist() if failed.size else [0] * len(rows)
        out = []
        for r, nf in zip(rows, n_failed):
            events = [(float(first), OUTCOMES[c], int(running[c][r])) for first, c in codes if first <= r]
            if nf:
                events.append((int(failed[0]) + 0.5, "output_failed", nf))
            counted = dict(self.outcomes) if into is None else into
            for _, key, n in sorted(events):
                counted[key] = counted.get(key, 0) + n
            out.append(counted)
        return out

    def _error(self, text: str) -> None:
        if len(self.errors) < MAX_ERRORS:
            self.errors.append(text)
