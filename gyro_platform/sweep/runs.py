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

"""One sweep run: a self-contained task in, one flat record of figures out (a pure function).

A run never raises: its ``status`` says how it ended —

* ``ok``: the scene ran; the figures are filled in;
* ``refused``: the model refused this configuration (a parameter out of range, a
  ``SimulationError`` such as a tolerance that cannot be met) — a verdict, not a failure;
* ``failed_input``: the input could not be read (a damaged or missing bag, a missing topic);
* ``failed``: anything else (a bug): the message names the exception.

Figures (SI units and °/h, named with their unit): the least-squares drift rate per platform axis
and its norm, the final drift angle per axis, the peak gimbal angle (over all five gimbals) and
per gimbal, the peak bearing torque per bearing (norm), the integrator's achieved local error
estimate, the CPU and wall time of the run.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import sys
import time
from typing import Any

from ..engine.outputs import BEARING_NAMES, GIMBAL_NAMES
from ..errors import BagReadError, ReplayError, SimulationError
from ..physics.jit import compile_notices
from ..reports.summary import UNSTEADY_VEHICLE_NOTE
from ..scenes.runner import run_scene
from ..scenes.schema import MotionError, ScenarioError, scene_from_dict

AXES = ("x", "y", "z")
FINISHED = ("ok", "refused", "failed_input")  # a re-run skips these; 'failed'/'lost' run again
STATUSES = (*FINISHED, "failed", "lost")


@dataclass(frozen=True)
class RunTask:
    """Everything one run needs (picklable: it travels to a Dask worker)."""

    run: int
    scene: dict                       # the scene mapping with this run's values applied
    source: str                       # names the run in error messages
    base_dir: str                     # the scene file's folder (relative bag paths)
    values: dict[str, float] = field(default_factory=dict)   # varied parameter -> value
    bag: str | None = None            # fleet replay: the bag of this run


def figure_columns() -> list[str]:
    """The figure columns of a run record, in table order."""
    cols = [f"drift_rate_{a}_deg_per_h" for a in AXES] + ["drift_rate_norm_deg_per_h"]
    cols += [f"final_drift_{a}_rad" for a in AXES] + ["peak_gimbal_angle_rad"]
    cols += [f"peak_{g}_rad" for g in GIMBAL_NAMES]
    cols += [f"peak_torque_{b}_N_m" for b in BEARING_NAMES]
    cols += ["error_estimate", "n_samples", "sim_duration_s", "expectations_failed", "cpu_s", "wall_s"]
    return cols


def _figures(summary: dict[str, Any], results: list) -> dict[str, Any]:
    nan = math.nan
    dr = summary.get("drift_rate_deg_per_h", {})
    fd = summary.get("final_drift_angle", {})
    mg = summary.get("max_abs_gimbal_angle", {})
    bt = summary.get("max_abs_bearing_torque", {})
    f: dict[str, Any] = {f"drift_rate_{a}_deg_per_h": dr.get(a, nan) for a in AXES}
    f["drift_rate_norm_deg_per_h"] = math.sqrt(sum(dr.get(a, nan) ** 2 for a in AXES))
    f.update({f"final_drift_{a}_rad": fd.get(a, nan) for a in AXES})
    f["peak_gimbal_angle_rad"] = max(mg.values()) if mg else nan
    f.update({f"peak_{g}_rad": mg.get(g, nan) for g in GIMBAL_NAMES})
    f.update({f"peak_torque_{b}_N_m": bt.get(b, nan) for b in BEARING_NAMES})
    f["error_estimate"] = summary.get("max_error_estimate", nan)
    f["n_samples"] = summary.get("n_samples", 0)
    f["sim_duration_s"] = summary.get("duration", nan)
    f["expectations_failed"] = sum(1 for r in results if not r[1])
    return f


def _verdict(summary: dict[str, Any]) -> dict[str, Any]:
    """A finished run's status and message from its summary: ``failed_input`` for a damaged bag
    (the figures cover its readable part), ``refused`` for a run through gimbal lock that its
    check run contradicts (``engine.conditioning``), else ``ok``; the run's warnings (a bag that
    ends before the duration, a near approach to lock …) as the message."""
    warnings = "; ".join(w for w in summary.get("warnings", []) if w != UNSTEADY_VEHICLE_NOTE)   # (a note)
    if summary.get("error"):
        return {"status": "failed_input", "message": f"bag damaged, the figures cover its readable part: "
                                                     f"{summary['error']}"}
    if summary.get("gimbal_lock_check", {}).get("ill_conditioned"):
        return {"status": "refused", "message": f"ill-conditioned: {warnings}"}
    return {"status": "ok", "message": warnings}


def in_dask_worker() -> bool:
    """This code runs in a Dask worker (``distributed`` imported and a worker found)."""
    if "distributed" not in sys.modules:
        return False
    try:
        from distributed import get_worker

        get_worker()
    except Exception:  # noqa: BLE001 - ValueError outside a worker
        return False
    return True


def execute_run(task: RunTask) -> dict[str, Any]:
    """Run one task; return its record (never raises). In a local cluster's worker, a kernel
    compile of the run is abandoned when the worker closes, and the run itself stops at its next
    chunk (:mod:`.worker_close`)."""
    closing = None
    if in_dask_worker():
        from .worker_close import CLOSING as closing

        compile_notices("gyro-platform sweep worker")   # a worker's first run compiles: said on its stderr
    rec: dict[str, Any] = {"run": task.run, "status": "ok", "message": "", "bag": task.bag or ""}
    rec.update({f"param:{k}": v for k, v in task.values.items()})
    cpu0, wall0 = time.process_time(), time.perf_counter()
    try:
        try:
            scene = scene_from_dict(task.scene, source=task.source, base_dir=Path(task.base_dir),
                                    default_name=str(task.scene.get("name", "sweep")))
        except ScenarioError as e:
            # a bag that cannot be found is bad input; any other rejection is the model refusing
            rec.update(status="failed_input" if task.bag and "motion.path" in str(e) else "refused",
                       message=str(e))
        else:
            try:
                _, summary, results = run_scene(scene, stop=closing)
                rec.update(_figures(summary, results), **_verdict(summary))
            except (SimulationError, MotionError) as e:     # the drawn configuration cannot run
                rec.update(status="refused", message=f"{type(e).__name__}: {e}")
            except (ScenarioError, BagReadError, ReplayError, OSError) as e:
                rec.update(status="failed_input", message=f"{type(e).__name__}: {e}")
    except Exception as e:  # noqa: BLE001 — a sweep records every failure and goes on
        rec.update(status="failed", message=f"{type(e).__name__}: {e}".splitlines()[0])
    rec["cpu_s"] = time.process_time() - cpu0
    rec["wall_s"] = time.perf_counter() - wall0
    return rec


def lost_record(task: RunTask, why: str) -> dict[str, Any]:
    """The record of a run whose worker died (the scheduler gave up on it)."""
    return {"run": task.run, "status": "lost", "message": why.splitlines()[0] if why else "worker lost",
            "bag": task.bag or "", **{f"param:{k}": v for k, v in task.values.items()}}
