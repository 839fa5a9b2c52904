"""The replay run: a rosbag2 bag through the pipeline into an output bag, a JSON summary and a plot.

Every input message is copied to the output bag (same record time); the input topic goes
through :class:`~gyro_platform.pipeline.Pipeline` (gate → simulator → output grid) and the
outputs are written with the receive time of the message that produced them; ``/diagnostics``
runs on the receive clock. One message in memory at a time. Progress: ``tqdm`` on stderr, shown
only on a terminal.
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BagReadError, ReplayError, SimulationError, deferred_signals, stop_reason
from ..io import messages as msgs
from ..io.bag_reader import InputBag
from ..io.bag_writer import OutputBag
from ..io.gate import GateConfig, TimeGate
from ..io.messages import MessageTypes, Mounting
from ..pipeline import NS, Pipeline, grid_index, judge, no_sample_hint
from .stats import PlotSeries, Stats

DEFAULT_OUTPUT_RATE = 10.0      # Hz
DEFAULT_DIAGNOSTICS_RATE = 1.0  # Hz


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
    from ..engine.simulator import Simulator

    cfg = config or ReplayConfig()
    in_bag, out_bag = Path(in_bag), Path(out_bag)
    if out_bag.exists():
        raise ReplayError(f"{out_bag}: exists already; choose another --out (nothing is overwritten)")
    summary_path, plot_path = sidecar_paths(out_bag)
    wall0 = time.perf_counter()
    bag = InputBag(in_bag, cfg.topic)
    bag.open()
    try:
        if bag.salvaged:
            print(f"gyro-platform replay: warning: {in_bag}: {bag.damage}; salvaging the readable messages",
                  file=sys.stderr)
        out_topics = msgs.output_topics(cfg.namespace)
        # /diagnostics is shared by every node (status names tell them apart): no clash there
        clash = sorted({c.topic for c in bag.connections
                        if c.topic in out_topics and not (c.topic == "/diagnostics" and c.msgtype == out_topics[c.topic])})
        if clash:
            raise ReplayError(f"{in_bag}: has output topic(s) {clash} already; use --namespace to separate them")
        kwargs = {}
        if cfg.params is not None:
            kwargs["params"] = cfg.params
        if cfg.options is not None:
            kwargs["options"] = cfg.options
        sim = Simulator(**kwargs)
        out = OutputBag(out_bag, cfg.storage or bag.storage)
        try:
            for conn in bag.connections:
                out.copy_connection(conn, bag.store_for(conn))
            for topic, typ in out_topics.items():
                out.add_output(topic, typ)
            run = _Run(bag, out, sim, cfg)
            run.loop()
        finally:
            with deferred_signals():   # a signal now would cut the metadata: held until closed
                out.close()       # index + metadata written: the bag is readable whatever happened
    finally:
        bag.close()
    summary = run.summary(in_bag, out_bag, time.perf_counter() - wall0)
    if out.skipped:
        summary["output"]["skipped_topics"] = out.skipped
    summary["files"] = {"bag": str(out_bag), "summary": str(summary_path), "plot": None}
    if cfg.plot:
        summary["files"]["plot"], summary["recorder"] = run.plot(plot_path)
    summary_path.write_text(json.dumps(summary, indent=2, default=json_default) + "\n")
    return summary




def json_default(o: Any) -> Any:
    """JSON for numpy scalars and arrays (and ``str`` of anything else)."""
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


class _Run:
    """State of one replay loop (kept out of ``replay`` to keep that readable)."""

    def __init__(self, bag: InputBag, out: OutputBag, sim: Any, cfg: ReplayConfig):
        self.bag, self.out, self.sim, self.cfg = bag, out, sim, cfg
        self.types = MessageTypes.rosbags()
        self.gate = TimeGate(cfg.gate)
        self.pipeline = Pipeline(sim, self.gate, cfg.output_rate, cfg.mounting)
        self.stats = Stats()
        self.series = PlotSeries()
        self.outcomes = self.pipeline.outcomes      # apply_decision results + output_failed
        self.n_msgs = 0
        self.n_in = 0
        self.n_out = 0
        self.diag_slot: int | None = None
        self.first_rx: int | None = None
        self.first_ts: int | None = None
        self.last_ts: int | None = None
        self.last_out = None
        self.new_segment = True
        self.error: str | None = None
        self.interrupted = False
        self.sim_errors: list[str] = []
        self.identity_frames: list[str] = []
        self.diag_topic = msgs.resolve("/diagnostics")

    def loop(self) -> None:
        from tqdm import tqdm

        progress = tqdm(total=self.bag.message_count, desc="replay", unit="msg", file=sys.stderr,
                        disable=not (self.cfg.progress and sys.stderr.isatty()))
        try:
            for conn, ts, raw in self.bag.messages():
                self.n_msgs += 1
                if self.first_ts is None:
                    self.first_ts = ts
                self.last_ts = ts
                copy = self.out.copy_connection(conn, self.bag.store_for(conn))
                if copy is not None:
                    self.out.write_raw(copy, ts, raw)
                if self.bag.is_input(conn):
                    self._input(conn, ts, raw)
                progress.update()
        except BagReadError as e:
            self.error = str(e)
        except KeyboardInterrupt as e:     # Ctrl-C, or SIGTERM (errors.Terminated)
            self.interrupted = True
            self.error = stop_reason(e)
        finally:
            progress.close()

    def _input(self, conn: Any, ts: int, raw: bytes) -> None:
        self.n_in += 1
        n_identity = self.gate.notes["identity_frame"]
        decision, msg = judge(self.bag, conn, raw, ts, self.cfg.mounting, self.gate)
        if self.gate.notes["identity_frame"] > n_identity:
            frame = str(msg.header.frame_id)
            if frame not in self.identity_frames:
                self.identity_frames.append(frame)
                print(f"gyro-platform replay: info: frame_id {frame!r} has no --mount; taken as "
                      f"base_link, counted in the summary (--unknown-frame reject drops such samples)",
                      file=sys.stderr)
        step = self.pipeline.apply(decision)
        if step.outcome in ("reset", "restarted"):
            self.new_segment = True
        if step.outcome == "restarted" and len(self.sim_errors) < 100:
            self.sim_errors.append(f"t={decision.stamp_ns}: integration failed, simulator restarted")
        if step.emit:
            self._emit(decision.stamp_ns, ts)
        # diagnostics on the receive clock, like a node's timer
        if self.first_rx is None:
            self.first_rx = ts
        dslot = grid_index(ts, self.first_rx, self.cfg.diagnostics_rate)
        if self.diag_slot is None or dslot > self.diag_slot:
            self.diag_slot = dslot
            self.out.write_msg(self.diag_topic, ts, msgs.diagnostic_array(
                self.gate.snapshot(), self.last_out, self.types, ts, self._sim_figures()))

    def _emit(self, stamp: int, ts: int) -> None:
        try:
            o = self.sim.outputs()
        except SimulationError as e:
            self.outcomes["output_failed"] = self.outcomes.get("output_failed", 0) + 1
            if len(self.sim_errors) < 100:
                self.sim_errors.append(f"t={stamp}: outputs failed: {e}")
            return
        for topic, m in msgs.output_messages(o, self.types, stamp, self.cfg.namespace):
            self.out.write_msg(topic, ts, m)
        self.n_out += 1
        self.stats.add(o, self.new_segment)
        self.new_segment = False
        self.series.add(o)
        self.last_out = o

    def _sim_figures(self) -> dict[str, Any]:
        return {"outputs": self.n_out, **{f"sim_{k}": v for k, v in self.outcomes.items()}}

    # ---- results --------------------------------------------------------------------------
    def summary(self, in_bag: Path, out_bag: Path, wall: float) -> dict[str, Any]:
        snap = self.gate.snapshot()
        duration = 0.0 if self.first_ts is None else (self.last_ts - self.first_ts) / NS
        opts = self.sim.options
        return {
            "input": {"bag": str(in_bag), "storage": self.bag.storage, "topic": self.bag.topic,
                      "type": self.bag.msgtype, "messages": self.n_msgs, "topic_messages": self.n_in,
                      "salvaged": self.bag.salvaged, "damage": self.bag.damage,
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
            "real_time_factor": duration / wall if wall > 0 else None,
            "messages_per_s": self.n_msgs / wall if wall > 0 else None,
            "ranges": self.stats.ranges(),
            "non_finite_outputs": self.stats.non_finite,
            "drift": self.stats.drift(),
            "simulator": {"mode": opts.mode, "fidelity": opts.fidelity, "effects": sorted(opts.effects),
                          "stats": self.sim.stats, "errors": self.sim_errors[:20]},
            "config": {"gate": vars(self.cfg.gate), "mounting": self.cfg.mounting.frames(),
                       "unknown_frame": self.cfg.mounting.unknown_frame,
                       "frames_taken_as_base_link": self.identity_frames},
            "warnings": self.warnings(snap),
            "error": self.error,
        }

    def warnings(self, snap: dict[str, Any]) -> list[str]:
        """What a user must know about this replay's results (also printed)."""
        res = []
        if self.n_in and not snap["accepted"]:
            res.append(no_sample_hint(snap["dropped_by_reason"], self.n_in))
        elif self.n_in == 0 and self.error is None:
            res.append(f"topic {self.bag.topic} has no messages: no outputs")
        return res

    def plot(self, path: Path) -> tuple[str | None, Any]:
        """PNG and Recorder summary of the (thinned) output series, via ``recording.Recorder``."""
        if not self.series.items:
            return None, None
        try:
            from ..io.recording import Recorder
        except ImportError as e:
            print(f"gyro-platform replay: warning: no plot ({e})", file=sys.stderr)
            return None, {"unavailable": str(e)}
        rec = Recorder()
        for o in self.series.items:
            rec.append(o)
        try:
            rec.plot(path, title=f"replay of {self.bag.path.name}, topic {self.bag.topic} "
                                 f"({self.sim.options.mode}, {self.sim.options.fidelity})")
            return str(path), rec.summary()
        except Exception as e:  # a plot must not lose the replay
            print(f"gyro-platform replay: warning: plot failed: {e}", file=sys.stderr)
            return None, {"error": str(e)}

