"""Running a scene: its motion (synthetic, or a bag through the pipeline's gate) into the
simulator, outputs recorded on the scene's output grid, expectations evaluated; ``outputs.csv``,
``summary.json`` and ``plot.png`` written on request."""
from __future__ import annotations

import math
import time
from pathlib import Path

from ..errors import BagReadError
from ..io.recording import Recorder
from ..engine.inputs import RateSample
from ..io.gate import TimeGate
from ..pipeline import ADVANCED, apply_decision, no_sample_hint, read_samples
from .schema import Check, ScenarioError, Scene, load_scene, scene_info

__all__ = ["run_scene", "evaluate", "load_scene"]   # load_scene: for callers that load and run


def _synthetic_stream(scene: Scene):
    """(t, omega, f, quaternion) per sample of a synthetic motion."""
    gen = scene.motion.generator
    t, w, f = gen.arrays(scene.duration, scene.sample_rate)
    quat = gen.quaternion(t)
    for i in range(t.size):
        yield RateSample(float(t[i]), w[i], f[i]), quat[i]


def run_scene(scene: Scene, out_dir=None):
    """Run ``scene`` with the real simulator.

    Returns ``(recorder, summary, results)`` where ``results`` is a list of
    ``(check, passed, detail)``. With ``out_dir`` it writes ``outputs.csv``, ``summary.json``
    and ``plot.png`` there. A bag is streamed through ``pipeline.read_samples`` and its gate
    decisions (drops, resets) are applied with ``pipeline.apply_decision``; their counts are in
    ``summary['bag']``.
    """
    from ..engine.simulator import Simulator

    sim = Simulator(params=scene.params, options=scene.options)
    rec = Recorder()
    dt_out = 1.0 / scene.output_rate
    t_first: float | None = None
    next_out = 0.0
    n_in = 0
    bag_counts: dict[str, int] = {}
    pending = None          # extras of the last pushed sample if it was not recorded
    wall0 = time.perf_counter()

    error = None            # a bag damaged after some readable samples
    read_errors: type[Exception] | tuple = ()   # nothing to catch for a synthetic motion
    if scene.motion.is_bag:
        kw = {} if scene.motion.topic is None else {"topic": scene.motion.topic}
        gate = TimeGate()
        source = read_samples(scene.motion.path, gate=gate, **kw)
        read_errors = BagReadError
    else:
        source = _synthetic_stream(scene)
    try:
        for item in _until_damage(source, read_errors, lambda: n_in):
            if scene.motion.is_bag:
                d = item.decision
                if d.sample is not None and t_first is not None and d.sample.t > t_first + scene.duration + 1e-9:
                    break
                status = apply_decision(sim, d)
                bag_counts[status] = bag_counts.get(status, 0) + 1
                if status not in ADVANCED:
                    continue
                sample, quat = d.sample, None
            else:
                sample, quat = item
                sim.push(sample)
            if t_first is None:
                t_first, next_out = sample.t, sample.t
            n_in += 1
            extra = {"vehicle_omega": sample.omega}
            if quat is not None:
                extra["vehicle_attitude"] = quat
            if sample.t >= next_out - 1e-9 * dt_out:
                rec.append(sim.outputs(), **extra)
                pending = None
                next_out = t_first + (math.floor((sample.t - t_first) / dt_out + 1e-9) + 1) * dt_out
            else:
                pending = extra
    except _Damaged as e:
        error = e.message
    finally:
        close = getattr(source, "close", None)
        if close is not None:
            close()
    if n_in == 0:
        hint = ""
        if scene.motion.is_bag:
            snap = gate.snapshot()
            hint = ": " + no_sample_hint(snap["dropped_by_reason"], snap["received"])
        raise ScenarioError(f"scene '{scene.name}': the motion gave no usable samples{hint}")
    if pending is not None:  # always record the last instant
        rec.append(sim.outputs(), **pending)
    wall = time.perf_counter() - wall0

    summary = rec.summary(fit_start=scene.fit_start, mounting=scene.params.mounting)
    summary = {"scene": scene.name, **summary, "n_samples": n_in,
               "sample_rate": scene.sample_rate, "output_rate": scene.output_rate, "wall_time": wall}
    stats = sim.stats      # what the integrator achieved against the asked rtol/atol
    summary.update(integrator=stats["integrator"], max_error_estimate=stats["max_error_estimate"],
                   max_error_norm=stats.get("max_error_norm"))
    summary["units"] = {**summary.get("units", {}), "sample_rate": "Hz", "output_rate": "Hz", "wall_time": "s",
                        "max_error_estimate": "state units (rad, rad/s)",
                        "max_error_norm": "1 = the asked tolerance"}
    warnings = list(summary.pop("notes", []))
    if scene.motion.is_bag:
        summary["bag"] = bag_counts
        covered = summary.get("duration", 0.0) + 1.5 / scene.output_rate
        if error is None and covered < scene.duration:
            warnings.append(f"the bag ends {summary.get('duration', 0.0):.6g} s after its first usable sample, "
                            f"before the scene's duration ({scene.duration:g} s)")
    if error is not None:
        warnings.append(f"bag damaged, results cover its readable part: {error}")
        summary["error"] = error
    summary["warnings"] = warnings
    results = evaluate(scene, summary)
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        rec.write_csv(out / "outputs.csv")
        rec.write_json(out / "summary.json", extra={
            "summary": summary,
            "scene": scene_info(scene),
            "expectations": [{"check": c.label, "why": c.why, "passed": p, "detail": det}
                             for c, p, det in results],
            "simulator": sim.stats,
        })
        rec.plot(out / "plot.png", title=f"{scene.name}: {scene.description}".rstrip(": "), summary=summary)
    return rec, summary, results


class _Damaged(Exception):
    def __init__(self, message: str):
        self.message = message


def _until_damage(source, errors, n_done):
    """Iterate ``source``; a read error (``errors``) after ``n_done() > 0`` usable samples ends
    the iteration as ``_Damaged`` (the readable part is kept); before any, it propagates."""
    it = iter(source)
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except errors as e:
            if n_done() == 0:
                raise
            raise _Damaged(str(e)) from None
        yield item


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
