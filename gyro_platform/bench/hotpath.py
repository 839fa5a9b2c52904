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

"""Per-sample cost: the hot path and the cost of each effect (``gyro-platform bench hotpath|effects``).

``hotpath``: µs per sample of ``Simulator.push`` (what the ROS node does per message) and of
the compiled ``push_many``. ``effects``: CPU µs per sample with each effect on versus off: what
is off costs nothing. Timing is CPU time (``time.process_time``), medians of repeats.
"""
from __future__ import annotations

from pathlib import Path
import time

import numpy as np

from .bench_scenes import ship_scene
from ..engine.inputs import RateSample
from ..engine.simulator import Simulator
from ..physics.options import DEFAULT_EFFECTS, EFFECTS, ModelOptions
from ..physics.params import NAV1
from ..reports.jsonio import write_json

__all__ = ["hotpath", "effects_cost"]


def _check_repeats(repeats: int) -> None:
    """A median needs at least one timing (0 repeats would quote NaN)."""
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")


def effects_cost(out_dir: Path, repeats: int = 5) -> list[dict]:
    """CPU µs per sample (compiled batch, 1 kHz, 20 s ship motion) with each effect on alone
    on top of the minimum (rotor gyroscopic + servo), per fidelity."""
    _check_repeats(repeats)
    sc = ship_scene(20.0)
    rows = []
    base = {"rotor_gyroscopic", "servo"}
    for fid in ("full", "linear"):
        for extra in [None] + sorted(set(EFFECTS) - base - {"vehicle_angular_acceleration"}):
            eff = frozenset(base | ({extra} if extra else set()))
            opt = ModelOptions.make("stabilised", fid, eff, integrator="rk4", max_step=1e-3)
            ts = []
            for _ in range(repeats):
                sim = Simulator(NAV1, opt)
                sim.push_many(sc.t[:2], sc.omega[:2], sc.force[:2])
                t0 = time.process_time()
                sim.push_many(sc.t[2:], sc.omega[2:], sc.force[2:])
                ts.append((time.process_time() - t0) / (len(sc.t) - 2) * 1e6)
            rows.append({"fidelity": fid, "effect": extra or "(minimum)", "us_per_sample": float(np.median(ts))})
            print(f"{fid:7s} {extra or '(minimum)':30s} {np.median(ts):6.2f} µs/sample", flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "effects.json", rows, indent=1)
    return rows


def hotpath(repeats: int = 5) -> dict:
    """µs per sample: Python ``push`` (what the ROS node does per message) and compiled
    ``push_many``, stabilised default effects, 1 kHz."""
    _check_repeats(repeats)
    sc = ship_scene(10.0)
    res = {}
    for fid, integ in (("full", "etd2"), ("linear", "etd2"), ("linear", "rk4"), ("full", "rk4")):
        opt = ModelOptions.make("stabilised", fid, DEFAULT_EFFECTS["stabilised"], integrator=integ, max_step=1e-3)
        tp, tb = [], []
        for _ in range(repeats):
            sim = Simulator(NAV1, opt)
            sim.push_many(sc.t[:3], sc.omega[:3])
            t0 = time.process_time()
            for i in range(3, 2003):
                sim.push(RateSample(float(sc.t[i]), sc.omega[i]))
            tp.append((time.process_time() - t0) / 2000 * 1e6)
            sim = Simulator(NAV1, opt)
            sim.push_many(sc.t[:3], sc.omega[:3])
            t0 = time.process_time()
            sim.push_many(sc.t[3:], sc.omega[3:])
            tb.append((time.process_time() - t0) / (len(sc.t) - 3) * 1e6)
        res[f"{fid}+{integ}"] = {"push_us": float(np.median(tp)), "batch_us": float(np.median(tb))}
        print(f"{fid:7s} {integ:5s}  push {np.median(tp):7.2f} µs/sample   batch {np.median(tb):6.2f} µs/sample "
              f"(real time ×{1e3 / np.median(tb):.0f} at 1 kHz)", flush=True)
    return res
