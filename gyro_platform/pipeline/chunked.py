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

"""The chunked path of a :class:`~gyro_platform.pipeline.stream.Pipeline`: blocks of rows through
the gate (``TimeGate.offer_block``), the simulator (``push_block``) and the output grid, with the
same decisions, outcomes and outputs as one message at a time (:class:`ChunkedRuns`, mixed into
``Pipeline``). Times ns on the input's time base."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields, replace
from typing import Any, Iterator

import numpy as np

from .gate_kernels import reading_of
from .gate_rules import Action, ALL_REASONS, Decision, DROP, RESET
from .grid import grid_indices, new_slots, NO_SLOT
from .outcomes import ADVANCED, apply_decision, MAX_ERRORS, O_DROPPED, O_PUSHED, O_RESET, OUTCOMES
from ..bags.reader import InputBag
from ..engine.inputs import RateSample
from ..engine.outputs import OutputBlock
from ..errors import InputError, SimulationError
from ..messages.blocks import take_rows
from ..messages.decode import decode_rates


def push_block(sim: Any, t: Any, omega: Any, force: Any, out_idx: Any) -> Any:
    """Push one block into the simulator: ``Simulator.push_block`` with these arguments."""
    return sim.push_block(t, omega, force, out_idx)


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


class ChunkedRuns:
    """The chunked methods of :class:`~gyro_platform.pipeline.stream.Pipeline` (its ``sim``, ``gate``,
    ``mounting``, ``output_rate``, ``outcomes``, ``slot`` and ``errors``)."""

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
            yield part, self.mounting.rotate_block(rb)

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
                res.gate = self.gate.offer_block(rate_rows(part, 0, j + 1), rx[a:a + j + 1])
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
            return self.gate.offer_block(rb, rx)
        got: dict[int, dict] = {}
        gb = self.gate.offer_block(rb, rx, cuts.tolist(), got)
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
            starts = np.flatnonzero(gb.action[acc] == RESET)      # increasing, in [0, acc.size)
            bounds = np.concatenate([[0], starts[starts > 0], [acc.size]])
            for a, b in zip(bounds[:-1], bounds[1:]):
                self._run(acc[a:b], rb, res)

    def _emits(self, stamps: np.ndarray, last: int | None) -> tuple[np.ndarray, np.ndarray | None]:
        """(emit (N,), grid slot after each row or None without a rate) for pushed rows."""
        rate = self.output_rate
        if rate is None or rate <= 0:
            return np.ones(len(stamps), bool), None
        s = grid_indices(stamps, self.gate.origin_ns or 0, rate)
        emit = new_slots(s, last)
        return emit, np.maximum.accumulate(np.concatenate([[NO_SLOT if last is None else last], s]))[1:]

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
            self.record_error(f"t={int(gb.stamp_ns[i])}: outputs failed: {err}")
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
            outcome = apply_decision(self.sim, Decision(action, ALL_REASONS[gb.reason[i]], sample, stamp),
                                     self.record_error)
            res.outcome[i] = OUTCOMES.index(outcome)
            if outcome == "rejected" and self._refusable:
                raise _Refused(i)
            if outcome in ("reset", "restarted"):
                self.slot, self.new_segment = None, True
            if outcome == "restarted":
                self.record_error(f"t={stamp}: integration failed, simulator restarted")
            if outcome in ADVANCED and self.due(stamp):
                try:
                    o = self.sim.outputs()
                except SimulationError as e:
                    res.output_failed.append(i)
                    self.record_error(f"t={stamp}: outputs failed: {e}")
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

    def record_error(self, text: str) -> None:
        """Keep ``text`` among ``errors`` (simulator failures; the first ``MAX_ERRORS`` only)."""
        if len(self.errors) < MAX_ERRORS:
            self.errors.append(text)
