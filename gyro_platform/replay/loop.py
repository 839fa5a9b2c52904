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

"""The replay run: a rosbag2 bag through the pipeline into an output bag, a JSON summary and a plot.

Every input message is copied to the output bag (same record time); the input topic goes
through :class:`~gyro_platform.pipeline.Pipeline` (gate → simulator → output grid) and the
outputs are written with the receive time of the message that produced them; ``/diagnostics``
runs on the receive clock. ``engine="chunked"`` (default): chunks of rows, one gate block and
one ``push_block`` per run of accepted rows (``Pipeline.run_block``), three chunks in memory at
most: the next one read and decoded on a reader thread (``pipeline.prefetched``), this one gated
and simulated here, the one before copied, encoded and written on a writer thread;
``engine="per_message"``: the reference, one message at a time. Progress: ``tqdm`` on stderr,
shown only on a terminal. SIGINT/SIGTERM end the loop at a chunk boundary (what was simulated
is written before the bag is closed).
"""
from __future__ import annotations

from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
import sys
import time
from typing import Any

import numpy as np

from .stats import PlotSeries, Stats
from .. import messages as msgs
from ..bags.reader import InputBag
from ..bags.writer import OutputBag
from ..engine.outputs import OutputBlock
from ..errors import BagReadError, OutputError, ReplayError, SimulationError
from ..messages import MessageTypes, Mounting
from ..messages.encode import encode_outputs
from ..messages.typedefs import core_typestore
from ..pipeline.gate import TimeGate
from ..pipeline.gate_rules import DROP, GateConfig, NS
from ..pipeline.grid import grid_index, grid_indices, new_slots
from ..pipeline.outcomes import ADVANCED, no_sample_hint, nothing_integrated_hint
from ..pipeline.pacing import ChunkPacer, prefetched
from ..pipeline.stream import judge, Pipeline
from ..reports.jsonio import write_json
from ..signals import deferred_signals, stop_reason

DEFAULT_OUTPUT_RATE = 10.0      # Hz
DEFAULT_DIAGNOSTICS_RATE = 1.0  # Hz
ENGINES = ("chunked", "per_message")


@dataclass
class ReplayConfig:
    """How to replay. Rates in Hz (``output_rate`` 0 or None: every accepted sample)."""

    topic: str | None = None
    storage: str | None = None
    output_rate: float | None = DEFAULT_OUTPUT_RATE
    diagnostics_rate: float = DEFAULT_DIAGNOSTICS_RATE
    mounting: Mounting = field(default_factory=Mounting)
    gate: GateConfig = field(default_factory=GateConfig)
    namespace: str = ""
    params: Any = None
    options: Any = None
    plot: bool = True
    progress: bool = True
    engine: str = "chunked"          # or "per_message": the reference path, one message at a time
    chunk_rows: int = 32768          # rows per chunk of the chunked path (at most; ChunkPacer)

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise ValueError(f"engine = {self.engine!r}; allowed: {', '.join(ENGINES)}")
        if not (isinstance(self.chunk_rows, int) and self.chunk_rows >= 1):
            raise ValueError(f"chunk_rows = {self.chunk_rows!r}; must be an integer >= 1")


def sidecar_paths(out_bag: Path) -> tuple[Path, Path]:
    """(summary JSON, plot PNG) next to the output bag: ``OUT.summary.json``, ``OUT.png``."""
    out_bag = Path(out_bag)
    return out_bag.with_name(out_bag.name + ".summary.json"), out_bag.with_name(out_bag.name + ".png")


def replay(in_bag: str | Path, out_bag: str | Path, config: ReplayConfig | None = None) -> dict[str, Any]:
    """Replay ``in_bag`` into ``out_bag``; returns the summary (also written as JSON).

    Raises BagReadError / ReplayError if nothing could be started (no output is created then).
    A read error after the start ends the replay; the output bag is closed (readable) and the
    summary's ``error`` names it.
    """
    from ..engine.remote import OutputsAside
    from ..engine.simulator import Simulator

    cfg = config or ReplayConfig()
    in_bag, out_bag = Path(in_bag), Path(out_bag)
    if out_bag.exists():
        raise ReplayError(f"{out_bag}: exists already; choose another --out (nothing is overwritten)")
    summary_path = sidecar_paths(out_bag)[0]
    wall0, cpu0 = time.perf_counter(), time.process_time()
    bag = InputBag(in_bag, cfg.topic)
    bag.open()
    aside = None
    try:
        if bag.salvaged:
            print(f"gyro-platform replay: warning: {in_bag}: {bag.damage}; salvaging the readable messages",
                  file=sys.stderr)
        for w in getattr(bag, "warnings", []):      # skipped channels, foreign MCAP, other input types
            print(f"gyro-platform replay: warning: {w}", file=sys.stderr)
        out_topics = msgs.output_topics(cfg.namespace)
        # /diagnostics is shared by every node (status names tell them apart): no clash there
        clash = sorted(
            {
                c.topic
                for c in bag.connections
                if c.topic in out_topics and not (c.topic == "/diagnostics" and c.msgtype == out_topics[c.topic])
            }
        )
        if clash:
            raise ReplayError(f"{in_bag}: has output topic(s) {clash} already; use --namespace to separate them")
        kwargs = {}
        if cfg.params is not None:
            kwargs["params"] = cfg.params
        if cfg.options is not None:
            kwargs["options"] = cfg.options
        sim = Simulator(**kwargs)
        aside = OutputsAside(sim.params, sim.options)   # a cold cache: the output kernel compiles beside
        run = _Run(bag, None, sim, cfg)     # before any file exists: a signal until here leaves none
        out = None
        # a Ctrl-C/SIGTERM from here on stops the run in order: the bag is closed, the summary
        # and the plot of what was simulated are written, the summary's error says why
        try:
            try:
                with deferred_signals():    # the output bag is made whole before a signal stops the run
                    out = run.out = OutputBag(out_bag, cfg.storage or bag.storage)
                for conn in bag.connections:
                    out.copy_connection(conn, bag.store_for(conn))
                for line in skipped_warnings(out.skipped):
                    print(f"gyro-platform replay: warning: {line}", file=sys.stderr)
                for topic, typ in out_topics.items():
                    out.add_output(topic, typ)
                run.loop()
            except KeyboardInterrupt as e:  # setting up the output, or held while its last chunk was written
                run.stopped(e)
            except OutputError as e:        # the output bag failed mid-run (disk full): the bag is closed
                run.write_failed(e)         # with what it holds, the summary of what was simulated written
            finally:
                if out is not None:
                    with deferred_signals():   # a signal now would cut the index + metadata: held until closed
                        out.close()       # index + metadata written: the bag is readable whatever happened
        except KeyboardInterrupt as e:      # held while the bag was closed
            run.stopped(e)
    finally:
        bag.close()
        if aside is not None:
            aside.close()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    try:
        with deferred_signals():            # held until the summary and the plot are written
            summary = _results(run, in_bag, out_bag, wall, cpu, cfg.plot)
    except KeyboardInterrupt as e:          # it arrived while they were written: they are; say so
        run.stopped(e)
        summary["interrupted_by"], summary["error"] = run.interrupted, run.error
        write_json(summary_path, summary)
    return summary


def skipped_warnings(skipped: dict[str, str]) -> list[str]:
    """One line per input topic the output bag could not copy (``OutputBag.skipped``)."""
    return [f"input topic {t} is not in the output bag: {why}" for t, why in skipped.items()]


def _results(run: "_Run", in_bag: Path, out_bag: Path, wall: float, cpu: float, plot: bool) -> dict[str, Any]:
    """The run's summary, its plot when asked, both written next to ``out_bag`` (``wall``, ``cpu``:
    seconds of the replay, wall clock and this process's CPU)."""
    summary_path, plot_path = sidecar_paths(out_bag)
    summary = run.summary(in_bag, out_bag, wall, cpu)
    if run.out.skipped:
        summary["output"]["skipped_topics"] = run.out.skipped
        summary["warnings"] += skipped_warnings(run.out.skipped)
    summary["files"] = {"bag": str(out_bag), "summary": str(summary_path), "plot": None}
    if plot:
        try:
            summary["files"]["plot"], summary["recorder"] = run.plot(plot_path)
        except OSError:
            if run.write_error is None:
                raise                            # (after a failed bag: the same disk refused it)
    try:
        write_json(summary_path, summary)
    except OSError:
        if run.write_error is None:
            raise
        summary["files"]["summary"] = None
    return summary


class _NoBar:
    """The progress bar where none is shown (``--quiet``, stderr not a terminal): tqdm is not
    imported (~40 ms of a replay's clock, its lock included)."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _progress_bar(total: int) -> Any:
    """tqdm's bar on stderr over ``total`` messages."""
    from tqdm import tqdm

    return tqdm(total=total, desc="replay", unit="msg", file=sys.stderr)


class _Run:
    """State of one replay loop (kept out of ``replay`` to keep that readable)."""

    def __init__(self, bag: InputBag, out: OutputBag | None, sim: Any, cfg: ReplayConfig):
        self.bag, self.out, self.sim, self.cfg = bag, out, sim, cfg
        self.types = MessageTypes.rosbags(core_typestore())
        self.gate = TimeGate(cfg.gate)
        self.pipeline = Pipeline(sim, self.gate, cfg.output_rate, cfg.mounting)
        self.stats = Stats()
        self.series = PlotSeries()
        self.outcomes = self.pipeline.outcomes      # apply_decision results + output_failed
        self.sim_errors = self.pipeline.errors
        self.n_msgs = 0
        self.n_in = 0
        self.n_out = 0
        self.diag_slot: int | None = None
        self.first_rx: int | None = None
        self.first_ts: int | None = None
        self.last_ts: int | None = None
        self.last_out: tuple[Any, int] | None = None     # (OutputBlock, index) or (Outputs, -1)
        self.error: str | None = None
        self.write_error: str | None = None
        self.interrupted: str | None = None             # "SIGINT" / "SIGTERM"
        self.identity_frames: list[str] = []
        self.identity_more = False
        self.diag_topic = msgs.resolve("/diagnostics")
        self._queue: list[tuple] | None = None          # a chunk's outputs and diagnostics to write
        self._writer: Any = None                        # the writer thread of the chunked path
        self._inflight: Any = None                      # its chunk in flight (a Future), at most one

    def loop(self) -> None:
        """All messages of the bag, chunk by chunk (``engine="chunked"``) or one by one
        (``"per_message"``, the reference). A signal stops at the next chunk/message boundary."""
        progress = _progress_bar(self.bag.message_count) if self.cfg.progress and sys.stderr.isatty() else _NoBar()
        try:
            if self.cfg.engine == "per_message":
                for conn, ts, raw in self.bag.messages():
                    with deferred_signals():        # a signal stops between messages
                        self._message(conn, ts, raw)
                    progress.update()
            else:
                # ~0.25 s a chunk however slow the model; into MCAP smaller towards the bag's end
                # (into SQLite, whose writing the replay waits for anyway, each chunk more is one
                # transaction more: 2-3 % slower on the 120 s 1 kHz bag, where MCAP gains 2-6 %)
                taper = self.bag.message_count if self.out.storage == "mcap" else None
                pace = ChunkPacer(self.cfg.chunk_rows, total=taper)
                chunks = self.bag.chunks(self.cfg.chunk_rows, pace=pace)

                def decoded(chunk: Any) -> list:
                    pace.took(len(chunk.ts))
                    return list(self.pipeline.decode(self.bag, chunk))

                # the next chunk read and decoded on a reader thread while this one is simulated,
                # the one before written on the writer thread (_handoff)
                with closing(prefetched(chunks, decoded)) as feed:
                    for chunk, parts in feed:
                        t0 = time.perf_counter()
                        with deferred_signals():    # a signal stops between chunks: what is
                            self._chunk(chunk, parts)   # counted is what was simulated
                        pace.observe(len(chunk.ts), time.perf_counter() - t0)
                        progress.update(len(chunk.ts))
        except BagReadError as e:
            self.error = str(e)
        except KeyboardInterrupt as e:              # Ctrl-C, or SIGTERM (errors.Terminated)
            self.stopped(e)
        finally:
            progress.close()
            try:
                with deferred_signals():            # what was simulated is written, whatever happened
                    self._written()
            finally:
                if self._writer is not None:
                    self._writer.shutdown()

    def write_failed(self, e: OutputError) -> None:
        """The output bag could not be written (disk full, file size limit): the run ends here;
        the summary's ``error`` and ``write_error`` say why (``replay`` exits 4)."""
        self.write_error = str(e)
        self.error = f"cannot write the output: {e}"

    def stopped(self, e: KeyboardInterrupt) -> None:
        """A Ctrl-C (KeyboardInterrupt) or SIGTERM (``errors.Terminated``) stopped the run: the
        summary says so (``interrupted_by``, ``error``; the first signal counts)."""
        if self.interrupted is None:
            self.interrupted = "SIGTERM" if stop_reason(e) == "terminated" else "SIGINT"
            self.error = stop_reason(e)

    # ---- chunked path -----------------------------------------------------------------------
    def _chunk(self, chunk: Any, parts: list[tuple[np.ndarray, Any]]) -> None:
        """A RowChunk and its decoded input rows (``Pipeline.decode``) through gate and simulator
        here; copied and written on the writer thread (:meth:`_handoff`)."""
        lo, hi = int(chunk.ts.min()), int(chunk.ts.max())      # (a salvaged bag may be out of order)
        self.first_ts = lo if self.first_ts is None else min(self.first_ts, lo)
        self.last_ts = hi if self.last_ts is None else max(self.last_ts, hi)
        self.n_msgs += len(chunk.ts)
        done: list[tuple] = []
        try:
            for rows, rb in parts:
                done.append(self._simulate_block(rb, chunk.ts[rows]))
        finally:
            self._handoff(chunk, done)

    def _handoff(self, chunk: Any, done: list[tuple]) -> None:
        """The chunk's copies, outputs and diagnostics to the writer thread (one chunk in
        flight: the one before is waited for first, and its error raised here)."""
        self._written()
        if self._writer is None:
            from concurrent.futures import ThreadPoolExecutor
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="gyro-replay-writer")
        self._inflight = self._writer.submit(self._write_chunk, chunk, done)

    def _written(self) -> None:
        """Wait for the chunk in flight on the writer thread; its error is raised here."""
        f, self._inflight = self._inflight, None
        if f is not None:
            f.result()

    def _write_chunk(self, chunk: Any, done: list[tuple]) -> None:
        """(writer thread) The chunk's copies, then its outputs and diagnostics, as one write."""
        with self.out.batched():
            self.out.copy_chunk(chunk, self.bag)
            self._queue = []
            try:
                for item in done:
                    self._output_block(*item)
            finally:
                queue, self._queue = self._queue, None
                self._write_queue(queue)

    def _simulate_block(self, rb: Any, rx: np.ndarray) -> tuple:
        """Input rows received at ``rx``, one block, through gate and simulator, cut for the
        snapshots of the diagnostics instants (1 Hz of receive time) among them."""
        self.n_in += len(rx)
        if self.first_rx is None:
            self.first_rx = int(rx[0])
        dslot = grid_indices(rx, self.first_rx, self.cfg.diagnostics_rate)
        diag = new_slots(dslot, self.diag_slot)
        if diag.any():
            self.diag_slot = int(dslot[diag][-1])
        snaps = np.flatnonzero(diag)
        return rb, rx, snaps, self.pipeline.run_block(rb, rx, snaps)

    def _output_block(self, rb: Any, rx: np.ndarray, snaps: np.ndarray, res: Any) -> None:
        """(writer thread) A simulated block's outputs queued run by run; at each diagnostics
        instant the gate snapshot and outcomes after that row (``run_block``'s snapshots), the
        number of outputs and the last output up to it."""
        self._identity(rb, res.gate)
        n0, last0 = self.n_out, self.last_out
        runs = []                               # (run, outputs before it)
        for run in res.outputs:
            runs.append((run, self.n_out))
            self._write_block(run, res.gate, rx)
        for r in snaps.tolist():
            n_out, last = n0, last0             # the outputs up to row r (runs in row order)
            for run, before in runs:
                k = int(np.searchsorted(run.rows, r, side="right"))
                if k == 0:
                    break
                n_out, last = before + k, (run.block, k - 1)
            gate, outcomes = res.snapshots[r]
            self._diagnostics(int(rx[r]), gate, outcomes, n_out, last)

    def _identity(self, rb: Any, gb: Any) -> None:
        if rb.identity is None or not rb.identity.any():
            return
        hit = np.flatnonzero(rb.identity & (gb.action != DROP))
        for frame in dict.fromkeys(rb.frame_id[i] for i in hit):
            self._identity_frame(frame)

    def _write_block(self, run: Any, gb: Any, rx: np.ndarray) -> None:
        block = run.block
        self._queue.append(("out", block, rx[run.rows], gb.stamp_ns[run.rows]))
        self.n_out += len(block)
        self.stats.add_block(block, run.new_segment)
        self.series.add_block(block)
        self.last_out = (block, len(block) - 1)

    def _write_queue(self, queue: list[tuple]) -> None:
        """A chunk's outputs, then its diagnostics: the outputs encoded and written together,
        topic by topic (readers order a bag by record time, and an output and the diagnostics
        of the same row keep that order). If the encoding fails, each queued item is written
        in its order and the error is raised where it was."""
        outs = [q for q in queue if q[0] == "out"]
        enc = None
        if outs:
            try:
                enc = encode_outputs(OutputBlock.concat([q[1] for q in outs]) if len(outs) > 1 else outs[0][1],
                                     np.concatenate([q[3] for q in outs]), self.cfg.namespace, arrays=True)
            except ValueError:
                enc = None
        if enc is not None or not outs:
            if outs:
                self.out.write_topics(np.concatenate([q[2] for q in outs]), enc)
            for _, a, ts, b in (q for q in queue if q[0] == "msg"):
                self.out.write_msg(a, ts, b)
            return
        for kind, a, ts, b in queue:
            if kind == "msg":
                self.out.write_msg(a, ts, b)
            else:
                self.out.write_topics(ts, encode_outputs(a, b, self.cfg.namespace, arrays=True))

    # ---- per-message path (the reference) -----------------------------------------------------
    def _message(self, conn: Any, ts: int, raw: bytes) -> None:
        self.n_msgs += 1
        self.first_ts = ts if self.first_ts is None else min(self.first_ts, ts)
        self.last_ts = ts if self.last_ts is None else max(self.last_ts, ts)
        copy = self.out.copy_connection(conn, self.bag.store_for(conn))
        if copy is not None:
            self.out.write_raw(copy, ts, raw)
        if self.bag.is_input(conn):
            self._input(conn, ts, raw)

    def _input(self, conn: Any, ts: int, raw: bytes) -> None:
        self.n_in += 1
        n_identity = self.gate.notes["identity_frame"]
        decision, msg = judge(self.bag, conn, raw, ts, self.cfg.mounting, self.gate)
        if self.gate.notes["identity_frame"] > n_identity:
            self._identity_frame(str(msg.header.frame_id))
        step = self.pipeline.apply(decision)
        if step.outcome == "restarted":
            self.pipeline.record_error(f"t={decision.stamp_ns}: integration failed, simulator restarted")
        if step.emit:
            self._emit(decision.stamp_ns, ts)
        # diagnostics on the receive clock, like a node's timer
        if self.first_rx is None:
            self.first_rx = ts
        dslot = grid_index(ts, self.first_rx, self.cfg.diagnostics_rate)
        if self.diag_slot is None or dslot > self.diag_slot:
            self.diag_slot = dslot
            self._diagnostics(ts)

    def _emit(self, stamp: int, ts: int) -> None:
        try:
            o = self.sim.outputs()
        except SimulationError as e:
            self.outcomes["output_failed"] = self.outcomes.get("output_failed", 0) + 1
            self.pipeline.record_error(f"t={stamp}: outputs failed: {e}")
            return
        for topic, m in msgs.output_messages(o, self.types, stamp, self.cfg.namespace):
            self.out.write_msg(topic, ts, m)
        self.n_out += 1
        self.stats.add(o, self.pipeline.new_segment)
        self.pipeline.new_segment = False
        self.series.add(o)
        self.last_out = (o, -1)

    # ---- shared -------------------------------------------------------------------------------
    def _identity_frame(self, frame: str) -> None:
        """One info line per frame_id without ``--mount`` (``messages.FRAMES_NAMED`` named, each
        cut by ``messages.frame_label``; then one line for the rest: a bag of many frames printed
        a line each)."""
        if frame in self.identity_frames or self.identity_more:
            return
        if len(self.identity_frames) >= msgs.FRAMES_NAMED:
            self.identity_more = True
            print(f"gyro-platform replay: info: more than {msgs.FRAMES_NAMED} frame_ids have no --mount; taken as "
                  "base_link, counted in the summary, not named further", file=sys.stderr)
            return
        self.identity_frames.append(frame)
        print(f"gyro-platform replay: info: frame_id {msgs.frame_label(frame)!r} has no --mount; taken as "
              f"base_link, counted in the summary (--unknown-frame reject drops such samples)",
              file=sys.stderr)

    def _diagnostics(self, ts: int, gate: dict | None = None, outcomes: dict | None = None,
                     n_out: int | None = None, last_out: tuple[Any, int] | None = None) -> None:
        """``/diagnostics`` at ``ts``: the gate snapshot, simulator outcomes, number of outputs
        and last output (``(OutputBlock, index)`` or ``(Outputs, -1)``) given (default: as they
        are now)."""
        last = None
        last_out = self.last_out if n_out is None else last_out
        if last_out is not None:
            obj, i = last_out
            last = obj if i < 0 else obj[i]
        figures = self._sim_figures(outcomes)
        if n_out is not None:
            figures["outputs"] = n_out
        msg = msgs.diagnostic_array(self.gate.snapshot() if gate is None else gate, last, self.types, ts, figures)
        if self._queue is not None:         # chunked path: after the outputs queued before it
            self._queue.append(("msg", self.diag_topic, ts, msg))
        else:
            self.out.write_msg(self.diag_topic, ts, msg)

    def _sim_figures(self, outcomes: dict | None = None) -> dict[str, Any]:
        return {"outputs": self.n_out,
                **{f"sim_{k}": v for k, v in (self.outcomes if outcomes is None else outcomes).items()}}

    # ---- results --------------------------------------------------------------------------
    @property
    def simulated(self) -> int:
        """Input samples the simulator integrated (pushed, after a reset, after a restart)."""
        return sum(self.outcomes.get(k, 0) for k in ADVANCED)

    def summary(self, in_bag: Path, out_bag: Path, wall: float, cpu: float) -> dict[str, Any]:
        snap = self.gate.snapshot()
        idle = nothing_integrated_hint(self.outcomes, snap["resets_by_reason"], snap["accepted"],
                                       self.cfg.gate.max_gap)
        duration = 0.0 if self.first_ts is None else (self.last_ts - self.first_ts) / NS
        opts = self.sim.options
        return {
            "input": {"bag": str(in_bag), "storage": self.bag.storage, "topic": self.bag.topic,
                      "type": self.bag.msgtype, "messages": self.n_msgs, "topic_messages": self.n_in,
                      "salvaged": self.bag.salvaged, "damage": self.bag.damage,
                      **{k: getattr(self.bag, k) for k in ("skipped_channels", "skipped_input", "foreign",
                                                           "damaged_files", "chunk_source", "warnings")
                         if hasattr(self.bag, k)},
                      "time_source": snap["time_source"]},
            "output": {"bag": str(out_bag), "storage": self.out.storage, "version": 9,
                       "messages": sum(self.out.counts.values()), "messages_by_topic": dict(self.out.counts),
                       "outputs": self.n_out, "output_rate_hz": self.cfg.output_rate or None,
                       "diagnostics_rate_hz": self.cfg.diagnostics_rate, "namespace": self.cfg.namespace},
            "counts": {"in": self.n_in, "accepted": snap["accepted"], "dropped": snap["dropped"],
                       "dropped_by_reason": snap["dropped_by_reason"], "resets": snap["resets"],
                       "resets_by_reason": snap["resets_by_reason"], "notes": snap["notes"],
                       "simulator": dict(self.outcomes), "out": self.n_out},
            "gate": snap,
            "duration_s": duration,
            "wall_time_s": wall,
            "cpu_time_s": cpu,
            "real_time_factor": duration / wall if wall > 0 else None,
            "messages_per_s": self.n_msgs / wall if wall > 0 else None,
            "simulated": self.simulated,
            "no_usable_input": bool(self.n_in) and (self.simulated == 0 or idle is not None),
            "engine": self.cfg.engine,
            "interrupted_by": self.interrupted,
            "ranges": self.stats.ranges(),
            "non_finite_outputs": self.stats.non_finite,
            "drift": self.stats.drift(),
            "simulator": {"mode": opts.mode, "fidelity": opts.fidelity, "effects": sorted(opts.effects),
                          "stats": self.sim.stats, "errors": self.sim_errors[:20]},
            "config": {"gate": vars(self.cfg.gate), "mounting": self.cfg.mounting.frames(),
                       "unknown_frame": self.cfg.mounting.unknown_frame,
                       "frames_taken_as_base_link": [*map(msgs.frame_label, self.identity_frames),
                                                     *(["…"] if self.identity_more else [])]},
            "warnings": self.warnings(snap, idle),
            "error": self.error,
            "write_error": self.write_error,
        }

    def warnings(self, snap: dict[str, Any], idle: str | None) -> list[str]:
        """What a user must know about this replay's results (also printed); ``idle``: the line
        saying no interval was integrated (``nothing_integrated_hint``), or None."""
        res = []
        if self.n_in and not snap["accepted"]:
            res.append(no_sample_hint(snap["dropped_by_reason"], self.n_in, self.sim_errors))
        elif idle is not None and self.n_out:
            res.append(idle)
        elif self.n_in and not self.simulated:
            res.append(f"none of the {snap['accepted']} accepted samples could be simulated "
                       f"(simulator: {dict(self.outcomes)}; errors: {self.sim_errors[:1]}): no outputs")
        elif self.n_in and not self.n_out and self.error is None:
            res.append(f"{self.simulated} samples simulated but no output could be computed "
                       f"(simulator: {dict(self.outcomes)}; errors: {self.sim_errors[:1]}): no outputs")
        elif self.n_in == 0 and self.error is None:
            res.append(f"topic {self.bag.topic} has no messages: no outputs")
        return res

    def plot(self, path: Path) -> tuple[str | None, Any]:
        """PNG of the outputs (``recording.save_plot`` of the plot series' minima and maxima) and
        the summary's ``recorder`` figures (``PlotSeries.summary``: over every output)."""
        if not self.series.n:
            return None, None
        summary = self.series.summary(self.stats.drift_fit())
        try:
            from ..reports.plot_process import draw
        except ImportError as e:
            print(f"gyro-platform replay: warning: no plot ({e})", file=sys.stderr)
            return None, {**summary, "unavailable": str(e)}
        try:
            title = (f"replay of {self.bag.path.name}, topic {self.bag.topic} "
                     f"({self.sim.options.mode}, {self.sim.options.fidelity})")
            if self.series.stride > 1:
                title += f"; each stroke: min to max of {self.series.stride} outputs"
            draw(self.series, path, title=title, summary=summary)
            return str(path), summary
        except Exception as e:  # a plot must not lose the replay
            print(f"gyro-platform replay: warning: plot failed: {e}", file=sys.stderr)
            return None, {**summary, "error": str(e)}
