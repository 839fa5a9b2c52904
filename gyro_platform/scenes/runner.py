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

"""Running a scene: its motion (synthetic, or a bag through the pipeline's gate) into the
simulator in chunks (one ``push_block`` per chunk, outputs at the instants of the output grid),
expectations evaluated; ``outputs.csv`` written as the run goes (whole rows, flushed per chunk),
``summary.json`` and ``plot.png`` at the end, on request.

Output grid: slot ``floor((t − t_first)·rate + 1e-9)`` of the scene's output rate; an output
at the first sample of each new slot and always at the last sample. A bag motion goes through
:class:`~gyro_platform.pipeline.Pipeline` exactly like ``replay``: its grid restarts after a
reset (a gap, a looped bag jumping back). A signal (SIGINT/SIGTERM) stops at the next chunk:
the CSV ends on a whole row and ``KeyboardInterrupt`` is raised (``run`` exits 130).
"""
from __future__ import annotations

from contextlib import nullcontext
from pathlib import Path
import threading
import time
from typing import Any, Iterator

import numpy as np

from .schema import Check, load_scene, MotionError, ScenarioError, Scene, scene_info
from ..bags.reader import InputBag
from ..engine.conditioning import check_tolerance, compare, lock_margin, LockCheck, LockMargin
from ..errors import BagReadError, RunStopped, SimulationError
from ..physics.jit import abandon_compiles_when
from ..pipeline.chunked import push_block
from ..pipeline.gate import TimeGate
from ..pipeline.grid import new_slots
from ..pipeline.outcomes import ADVANCED, no_sample_hint, OUTCOMES
from ..pipeline.pacing import ChunkPacer
from ..pipeline.stream import Pipeline
from ..reports.plot_process import draw
from ..reports.recording import CsvWriter, Recorder
from ..signals import deferred_signals

__all__ = ["run_scene", "evaluate", "load_scene", "synthetic_samples"]   # load_scene: for callers that load and run

CHUNK = 4096                    # samples per push_block / rows per bag chunk


class _Feed:
    """What a motion gave so far: samples simulated, the outcome counts (bag), the last
    simulated sample's ``extra`` if it was not recorded, a read error after usable samples,
    the bag reader's warnings (``InputBag.warnings``)."""

    def __init__(self) -> None:
        self.n_in = 0
        self.counts: dict[str, int] = {}
        self.pending: dict[str, np.ndarray] | None = None
        self.error: str | None = None
        self.gate: TimeGate | None = None
        self.bag_warnings: list[str] = []


def synthetic_samples(scene: Scene) -> tuple[np.ndarray, ...]:
    """A synthetic motion's samples ``(t, omega, specific_force, quaternion)`` (s, rad/s, m/s²,
    vehicle attitude x, y, z, w) at the scene's sample rate. ``MotionError`` (one line) when
    they cannot be made or are not finite: numbers beyond floating point (a rate of 1e200 rad/s,
    an RMS of 1e300°) are refused here, before anything is written."""
    gen = scene.motion.generator
    where = f"scene '{scene.name}': motion '{scene.motion.type}'"
    try:
        with np.errstate(all="ignore"):
            t, w, f = gen.arrays(scene.duration, scene.sample_rate)
            for name, a in (("rates", w), ("specific force", f)):
                bad = int(np.count_nonzero(~np.isfinite(a).all(axis=-1)))
                if bad:
                    raise MotionError(f"{where}: its {name} are not finite at {bad} of {len(a)} samples: "
                                      "its numbers are beyond floating point")
            quat = gen.quaternion(t) if t.size else np.empty((0, 4))
    except (ValueError, ArithmeticError) as e:
        if isinstance(e, MotionError):
            raise
        raise MotionError(f"{where}: cannot be generated ({type(e).__name__}: {str(e).splitlines()[0]}): "
                          "are its numbers beyond floating point?") from e
    if not np.isfinite(quat).all():
        raise MotionError(f"{where}: its attitude is not finite: its numbers are beyond floating point")
    return t, w, f, quat


def _synthetic_blocks(scene: Scene, samples: tuple[np.ndarray, ...], sim: Any,
                      feed: _Feed) -> Iterator[tuple[Any, dict]]:
    """``(OutputBlock, extra)`` per chunk of a synthetic motion's ``samples`` (:func:`synthetic_samples`)."""
    t, w, f, quat = samples
    n = t.size
    if n == 0:
        return
    emit = new_slots(np.floor((t - t[0]) / (1.0 / scene.output_rate) + 1e-9).astype(np.int64), None)
    emit[-1] = True                         # always record the last instant
    pace = ChunkPacer(CHUNK)
    a = 0
    while a < n:
        b = min(a + pace(), n)
        t0 = time.perf_counter()
        idx = np.flatnonzero(emit[a:b])
        try:
            block = push_block(sim, t[a:b], w[a:b], f[a:b], idx)
        except SimulationError as e:        # the outputs before it are recorded, then it goes up
            done = getattr(e, "block", None)    # (an InputError refuses the chunk before any sample)
            feed.n_in += getattr(e, "n_done", 0)
            if done is not None and len(done):
                yield done, {"vehicle_omega": w[a:b][idx[:len(done)]],
                             "vehicle_attitude": quat[a:b][idx[:len(done)]]}
            raise
        feed.n_in += b - a
        pace.observe(b - a, time.perf_counter() - t0)
        yield block, {"vehicle_omega": w[a:b][idx], "vehicle_attitude": quat[a:b][idx]}
        a = b


def _bag_blocks(scene: Scene, sim: Any, feed: _Feed) -> Iterator[tuple[Any, dict]]:
    """``(OutputBlock, extra)`` per run of a bag motion through :class:`Pipeline` (gate, resets,
    the grid restarting after each reset), up to the scene's duration."""
    feed.gate = gate = TimeGate()
    pipe = Pipeline(sim, gate, scene.output_rate)
    pipe.duration = scene.duration
    kw = {} if scene.motion.topic is None else {"topic": scene.motion.topic}
    with InputBag(scene.motion.path, **kw) as bag:
        feed.bag_warnings = list(bag.warnings)
        pace = ChunkPacer(CHUNK)
        chunks = bag.chunks(CHUNK, input_only=True, pace=pace)
        while not pipe.stopped:
            try:
                chunk = next(chunks)
            except StopIteration:
                break
            except BagReadError as e:
                if feed.n_in == 0:
                    raise
                feed.error = str(e)
                break
            t0 = time.perf_counter()
            for _, rb, res in pipe.run_chunk(bag, chunk):
                advanced = np.isin(res.outcome, [OUTCOMES.index(k) for k in ADVANCED])
                feed.n_in += int(np.count_nonzero(advanced))
                last = int(np.flatnonzero(advanced)[-1]) if advanced.any() else None
                emitted = set()
                for run in res.outputs:
                    emitted.update(run.rows.tolist()[-1:])
                    yield run.block, {"vehicle_omega": rb.omega[run.rows]}
                if last is not None:
                    feed.pending = None if last in emitted else {"vehicle_omega": rb.omega[last].copy()}
            pace.observe(len(chunk.ts), time.perf_counter() - t0)
    feed.counts = dict(pipe.outcomes.items())


def run_scene(scene: Scene, out_dir=None, stop: threading.Event | None = None):
    """Run ``scene`` with the real simulator.

    Returns ``(recorder, summary, results)`` where ``results`` is a list of
    ``(check, passed, detail)``. With ``out_dir`` it writes ``outputs.csv`` (as the run goes),
    ``summary.json`` and ``plot.png`` there. A bag goes through :class:`Pipeline` (gate
    decisions, drops, resets: counts in ``summary['bag']``). ``stop``: once set, the run ends
    at the next chunk (~0.25 s of work) with :class:`~gyro_platform.errors.RunStopped`, or a
    wait for a kernel compile ends at once with ``CompileAbandoned``
    (``physics.jit.abandon_compiles_when``).
    """
    from ..engine.remote import OutputsAside
    from ..engine.simulator import Simulator

    wall0 = time.perf_counter()
    samples = None if scene.motion.is_bag else synthetic_samples(scene)    # MotionError: nothing written
    with (nullcontext() if stop is None else abandon_compiles_when(stop)), \
            OutputsAside(scene.params, scene.options):     # a cold cache: the output kernel compiles beside
        return _run(scene, out_dir, Simulator(params=scene.params, options=scene.options), samples, wall0, stop)


def _run(scene: Scene, out_dir, sim, samples, wall0: float, stop: threading.Event | None = None):
    """:func:`run_scene` with its simulator made."""
    rec = Recorder()
    feed = _Feed()
    out = None if out_dir is None else Path(out_dir)
    csv = None if out is None else CsvWriter(out / "outputs.csv")
    blocks = (_bag_blocks(scene, sim, feed) if samples is None
              else _synthetic_blocks(scene, samples, sim, feed))
    try:
        while True:
            if stop is not None and stop.is_set():
                raise RunStopped(f"scene '{scene.name}': stopped by its caller after {feed.n_in} samples")
            with deferred_signals():             # a signal stops between blocks: whole CSV rows
                item = next(blocks, None)
                if item is None:
                    break
                block, extra = item
                rec.extend(block, **extra)
                if csv is not None:
                    csv.write(rec.rows(csv.rows_written))
        with deferred_signals():
            if feed.n_in and feed.pending is not None:   # always record the last instant
                rec.append(sim.outputs(), **feed.pending)
                if csv is not None:
                    csv.write(rec.rows(csv.rows_written))
    finally:
        blocks.close()
        if csv is not None:
            csv.close()
    if feed.n_in == 0:
        hint = ""
        if scene.motion.is_bag:
            snap = feed.gate.snapshot()
            hint = ": " + no_sample_hint(snap["dropped_by_reason"], snap["received"])
        raise ScenarioError(f"scene '{scene.name}': the motion gave no usable samples{hint}")
    lock = lock_margin(rec.t, rec.gimbal_angles)
    check = _lock_check(scene, samples, rec, lock, stop) if samples is not None and lock and lock.near else None
    wall = time.perf_counter() - wall0
    return rec, *_finish(scene, sim, rec, feed, out, wall, lock, check)


def _lock_check(scene: Scene, samples: tuple[np.ndarray, ...], rec: Recorder, lock: LockMargin,
                stop: threading.Event | None) -> LockCheck:
    """The run came near gimbal lock: the same samples again at a tolerance ``CHECK_TIGHTER``
    times tighter, its gimbal angles at the same instants against the run's
    (``engine.conditioning``). A check run that stops early (refused) is compared as far as it got."""
    from ..engine.simulator import Simulator

    rtol, atol = check_tolerance(scene.options.rtol, scene.options.atol)
    sim = Simulator(params=scene.params, options=scene.options.with_(rtol=rtol, atol=atol))
    blocks = _synthetic_blocks(scene, samples, sim, _Feed())
    angles = []
    try:
        for block, _ in blocks:
            if stop is not None and stop.is_set():
                raise RunStopped(f"scene '{scene.name}': stopped by its caller during its gimbal-lock check")
            angles.append(np.array(block.gimbal_angles))
    except SimulationError:     # refused: _synthetic_blocks yielded its outputs before the failure
        pass
    finally:
        blocks.close()
    got = np.concatenate(angles) if angles else np.zeros((0, 5))
    return compare(lock, rec.t, rec.gimbal_angles, got, scene.options.rtol, scene.options.atol)


def _finish(scene: Scene, sim: Any, rec: Recorder, feed: _Feed, out: Path | None, wall: float,
            lock: LockMargin | None = None, check: LockCheck | None = None):
    """Summary, expectations and the files after the CSV: ``(summary, results)``. ``lock``,
    ``check``: the run's closest approach to gimbal lock and its check run (None: not near)."""
    error = feed.error
    summary = rec.summary(fit_start=scene.fit_start, mounting=scene.params.mounting)
    summary = {"scene": scene.name, **summary, "n_samples": feed.n_in,
               "sample_rate": scene.sample_rate, "output_rate": scene.output_rate, "wall_time": wall}
    stats = sim.stats      # what the integrator achieved against the asked rtol/atol
    summary.update(integrator=stats["integrator"], max_error_estimate=stats["max_error_estimate"],
                   max_error_norm=stats.get("max_error_norm"))
    summary["units"] = {**summary.get("units", {}), "sample_rate": "Hz", "output_rate": "Hz", "wall_time": "s",
                        "max_error_estimate": "state units (rad, rad/s)",
                        "max_error_norm": "1 = the asked tolerance"}
    warnings = list(summary.pop("notes", []))
    if scene.motion.is_bag:
        summary["bag"] = feed.counts
        warnings += feed.bag_warnings       # skipped channels, a write-ahead log left unread …
        covered = summary.get("duration", 0.0) + 1.5 / scene.output_rate
        if error is None and covered < scene.duration:
            warnings.append(f"the bag ends {summary.get('duration', 0.0):.6g} s after its first usable sample, "
                            f"before the scene's duration ({scene.duration:g} s)")
    if error is not None:
        warnings.append(f"bag damaged, results cover its readable part: {error}")
        summary["error"] = error
    if check is not None:
        summary["gimbal_lock_check"] = check.as_dict()
        warnings.append(check.sentence())
    elif lock is not None and lock.near:          # a bag scene: its input is not read twice
        warnings.append(f"{lock.phrase()}: a motion through it can amplify errors beyond the asked tolerance "
                        "(not checked: a bag scene is run once)")
    summary["warnings"] = warnings
    results = evaluate(scene, summary)
    if out is not None:
        rec.write_json(out / "summary.json", extra={
            "summary": summary,
            "scene": scene_info(scene),
            "expectations": [{"check": c.label, "why": c.why, "passed": p, "detail": det}
                             for c, p, det in results],
            "simulator": sim.stats,
        })
        draw(rec, out / "plot.png", title=f"{scene.name}: {scene.description}".rstrip(": "), summary=summary)
    return summary, results


def evaluate(scene: Scene, summary: dict) -> list[tuple[Check, bool | None, str]]:
    """``(check, passed, detail)`` per expectation; ``passed`` is None (not evaluable) when
    the run covers less than :attr:`Scene.expect_duration` (a short ``--duration``, a bag
    that ends early or is damaged): expectations are never judged on too little data."""
    covered = summary.get("duration", 0.0) + 1.5 / scene.output_rate
    if covered < scene.expect_duration or summary.get("error"):
        why = (f"the run covers {summary.get('duration', 0.0):.6g} s, the expectations need "
               f"{scene.expect_duration:g} s" if covered < scene.expect_duration else "the input is damaged")
        return [(c, None, f"{c.label}: not evaluable: {why}") for c in scene.expect]
    return [(c, *c.evaluate(summary)) for c in scene.expect]
