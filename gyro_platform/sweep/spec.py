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

"""The sweep file: one scene plus parameter distributions (Monte Carlo), or one scene and many bags.

Schema (every key is checked; errors name the key)::

    scene: default            # scene name (config/scenes) or path to a scene YAML (required)
    duration: 60              # s; optional override of the scene's duration
    seed: 1                   # base seed (default 0); run i draws from SeedSequence(seed, spawn_key=(i,))
    runs: 200                 # Monte Carlo: number of runs (required with 'vary')
    vary:                     # Monte Carlo: parameter -> distribution
      bias_torque[4]: {dist: normal, mean: 0.0, std: 1.0e-7}     # N m on beta10 (element 4)
      unbalance: {dist: uniform, low: 0.0, high: 5.0e-8}          # m
      support_coulomb: {dist: list, values: [1.0e-3, 5.0e-3]}     # run i takes values[i % n]
      rotor_speed[2]: {dist: fixed, value: 2513.0}                # rad/s
      motion.roll.amplitude_deg: {dist: uniform, low: 5, high: 15}
    bags: [bags/a.mcap, fleet/]  # fleet replay instead of 'vary': one run per bag; a folder
                                 # stands for every bag below it (rosbag2 folders, .mcap, .db3)

A parameter key is a field of ``PlatformParams`` (SI units, as in a scene's ``params``), or a
dotted path into the scene mapping (``motion.roll.amplitude_deg``); ``[i]`` picks one element of
a vector. Draws depend only on ``seed`` and the run index, never on the worker that runs them,
so a sweep is reproducible on any number of workers and can be extended (larger ``runs``) into
the same output folder.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, fields
import hashlib
import json
import math
from pathlib import Path
import re
from typing import Any

import numpy as np

from .runs import RunTask
from ..physics.options import PARAM_EFFECTS
from ..physics.params import PlatformParams
from ..scenes.scene_yaml import as_float, load_yaml, SceneYAMLError
from ..scenes.schema import find_scene, fit_window_too_short, ScenarioError, scene_from_dict

DISTRIBUTIONS: dict[str, tuple[str, ...]] = {
    "normal": ("mean", "std"),
    "uniform": ("low", "high"),
    "list": ("values",),
    "fixed": ("value",),
}
TOP_KEYS = ("scene", "duration", "seed", "runs", "vary", "bags")
BAG_SUFFIXES = (".mcap", ".db3")
_KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*)(?:\[(\d+)\])?$")


class SweepSpecError(ValueError):
    """A sweep file that cannot run; the message names the file and the key."""


@dataclass(frozen=True)
class Variation:
    """One varied parameter: ``path`` into the scene mapping, optional vector ``index``."""

    key: str
    path: tuple[str, ...]
    index: int | None
    dist: str
    args: dict[str, Any]

    def draw(self, rng: np.random.Generator, run: int) -> float:
        """The value of run ``run`` (the generator is that run's own)."""
        a = self.args
        if self.dist == "normal":
            return float(rng.normal(a["mean"], a["std"]))
        if self.dist == "uniform":
            return float(rng.uniform(a["low"], a["high"]))
        if self.dist == "list":
            return float(a["values"][run % len(a["values"])])
        return float(a["value"])

    def centre(self) -> float:
        """A representative value (for checking the spec before any run)."""
        a = self.args
        return float({"normal": lambda: a["mean"], "uniform": lambda: 0.5 * (a["low"] + a["high"]),
                      "list": lambda: a["values"][0], "fixed": lambda: a["value"]}[self.dist]())


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the scene mapping, and either variations with ``runs`` or ``bags``."""

    source: Path
    scene_path: Path
    scene: dict
    seed: int
    runs: int
    vary: tuple[Variation, ...]
    bags: tuple[Path, ...]
    warnings: tuple[str, ...] = ()      # varied parameters the scene's effects leave unused

    @property
    def kind(self) -> str:
        return "fleet" if self.bags else "monte_carlo"

    @property
    def n_runs(self) -> int:
        return len(self.bags) if self.bags else self.runs

    def fingerprint(self) -> str:
        """Identity of the sweep's runs, independent of ``runs`` (so a sweep can be extended)."""
        doc = {"scene": self.scene, "seed": self.seed, "kind": self.kind,
               "vary": [[v.key, v.dist, v.args] for v in self.vary], "bags": [str(b) for b in self.bags]}
        return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]

    def task(self, run: int) -> RunTask:
        """The self-contained task of run ``run`` (what a Dask worker receives)."""
        scene = copy.deepcopy(self.scene)
        values: dict[str, float] = {}
        bag = None
        if self.bags:
            bag = str(self.bags[run])
            scene["motion"] = {**scene["motion"], "path": bag}
        else:
            rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(run,)))
            for v in self.vary:
                values[v.key] = v.draw(rng, run)
                apply_value(scene, v, values[v.key])
        return RunTask(run=run, scene=scene, source=f"{self.scene_path.name} run {run}",
                       base_dir=str(self.scene_path.resolve().parent), values=values, bag=bag)

    def tasks(self, skip: set[int] = frozenset()) -> list[RunTask]:
        return [self.task(i) for i in range(self.n_runs) if i not in skip]


def _param_default(name: str) -> Any:
    return next(f.default for f in fields(PlatformParams) if f.name == name)


def apply_value(scene: dict, v: Variation, value: float) -> None:
    """Set ``value`` at the variation's place in the scene mapping (in place)."""
    parent = scene
    for k in v.path[:-1]:
        parent = parent.setdefault(k, {})
        if not isinstance(parent, dict):
            raise SweepSpecError(f"vary.{v.key}: '{k}' is not a mapping in the scene")
    last = v.path[-1]
    if v.index is None:
        parent[last] = value
        return
    current = parent.get(last)
    if current is None and v.path[0] == "params":
        current = _param_default(last)
    if not isinstance(current, (list, tuple)):
        raise SweepSpecError(f"vary.{v.key}: [{v.index}] needs a vector, the scene has {current!r}")
    if v.index >= len(current):
        raise SweepSpecError(f"vary.{v.key}: index {v.index} out of range (length {len(current)})")
    vec = list(current)
    vec[v.index] = value
    parent[last] = vec


def _number(x: Any, where: str) -> float:
    """A finite number, written as scene files take them (``3e-8`` too: :func:`as_float`)."""
    v = as_float(x)
    if v is None or not math.isfinite(v):
        raise SweepSpecError(f"{where}: expected a finite number, got {x!r}")
    return v


def _variation(key: Any, raw: Any, where: str) -> Variation:
    m = _KEY.match(str(key))
    if not isinstance(key, str) or not m:
        raise SweepSpecError(f"{where}: bad parameter key {key!r} (e.g. 'unbalance', 'bias_torque[4]', "
                             "'motion.roll.amplitude_deg')")
    dotted, idx = m.group(1), m.group(2)
    path = tuple(dotted.split("."))
    params = {f.name for f in fields(PlatformParams)}
    if len(path) == 1:
        if path[0] not in params:
            raise SweepSpecError(f"{where}: '{path[0]}' is not a platform parameter "
                                 f"(known: {', '.join(sorted(params))}) nor a dotted scene path")
        path = ("params", path[0])
    elif path[0] == "params" and (len(path) != 2 or path[1] not in params):
        raise SweepSpecError(f"{where}: unknown platform parameter '{'.'.join(path[1:])}'")
    if not isinstance(raw, dict) or "dist" not in raw:
        raise SweepSpecError(f"{where}: expected {{dist: {'|'.join(DISTRIBUTIONS)}, ...}}, got {raw!r}")
    dist = raw["dist"]
    if dist not in DISTRIBUTIONS:
        raise SweepSpecError(f"{where}.dist: {dist!r}; allowed: {', '.join(DISTRIBUTIONS)}")
    need = DISTRIBUTIONS[dist]
    extra = sorted(set(raw) - {"dist", *need})
    missing = [k for k in need if k not in raw]
    if extra or missing:
        raise SweepSpecError(f"{where}: distribution '{dist}' takes {', '.join(need)}"
                             + (f"; unknown {extra}" if extra else "") + (f"; missing {missing}" if missing else ""))
    args: dict[str, Any] = {}
    if dist == "list":
        vals = raw["values"]
        if not isinstance(vals, list) or not vals:
            raise SweepSpecError(f"{where}.values: expected a non-empty list of numbers")
        args["values"] = [_number(x, f"{where}.values[{i}]") for i, x in enumerate(vals)]
    else:
        for k in need:
            args[k] = _number(raw[k], f"{where}.{k}")
    if dist == "normal" and args["std"] < 0:
        raise SweepSpecError(f"{where}.std: must be ≥ 0, got {args['std']:g}")
    if dist == "uniform" and args["low"] > args["high"]:
        raise SweepSpecError(f"{where}: low ({args['low']:g}) > high ({args['high']:g})")
    return Variation(key=str(key), path=path, index=None if idx is None else int(idx), dist=dist, args=args)


def _find_bags(entries: list, base: Path, where: str) -> tuple[Path, ...]:
    out: list[Path] = []
    for i, e in enumerate(entries):
        if not isinstance(e, str) or not e:
            raise SweepSpecError(f"{where}[{i}]: expected a path, got {e!r}")
        p = Path(e).expanduser()
        p = p if p.is_absolute() else (base / p)
        if p.is_file() and p.suffix in BAG_SUFFIXES:
            out.append(p.resolve())
        elif p.is_dir() and (p / "metadata.yaml").is_file():
            out.append(p.resolve())
        elif p.is_dir():
            folders = {q.parent for q in p.rglob("metadata.yaml")}
            files = {q for q in p.rglob("*") if q.suffix in BAG_SUFFIXES and q.is_file()
                     and not any(f in q.parents for f in folders)}
            found = sorted(folders | files)
            if not found:
                raise SweepSpecError(f"{where}[{i}]: no bag below {p}")
            out.extend(q.resolve() for q in found)
        else:
            raise SweepSpecError(f"{where}[{i}]: not a bag (rosbag2 folder, .mcap or .db3): {p}")
    if not out:
        raise SweepSpecError(f"{where}: no bags")
    return tuple(dict.fromkeys(out))


def _scene_path(name: str, base: Path) -> Path:
    """A scene path relative to the sweep file's folder, else a path or name as ``run`` takes it."""
    p = Path(name).expanduser()
    if not p.is_absolute() and (base / p).is_file():
        return base / p
    return find_scene(name)


def load_sweep(path) -> SweepSpec:
    """Read and validate a sweep file; the scene is checked with the distributions' centres."""
    path = Path(path)
    try:
        raw = load_yaml(path.read_text())        # a repeated key is refused, as in scene files
    except OSError as e:
        raise SweepSpecError(f"sweep '{path}': cannot read: {e.strerror or e}") from None
    except SceneYAMLError as e:
        raise SweepSpecError(f"sweep '{path.name}': not valid YAML: {e}") from None
    src = f"sweep '{path.name}'"
    if not isinstance(raw, dict):
        raise SweepSpecError(f"{src}: expected a mapping with keys {', '.join(TOP_KEYS)}")
    unknown = sorted(set(raw) - set(TOP_KEYS))
    if unknown:
        raise SweepSpecError(f"{src}: unknown key(s) {unknown}; allowed: {', '.join(TOP_KEYS)}")
    if "scene" not in raw:
        raise SweepSpecError(f"{src}: 'scene' is required")
    if ("vary" in raw) == ("bags" in raw):
        raise SweepSpecError(f"{src}: give either 'vary' (Monte Carlo) or 'bags' (fleet replay)")
    try:
        scene_path = _scene_path(str(raw["scene"]), path.resolve().parent)
        scene = load_yaml(scene_path.read_text())     # a repeated key is refused, as by load_scene
    except (ScenarioError, OSError) as e:
        raise SweepSpecError(f"{src}: scene: {e}") from None
    except SceneYAMLError as e:
        raise SweepSpecError(f"{src}: scene {raw['scene']}: not valid YAML: {e}") from None
    if not isinstance(scene, dict):
        raise SweepSpecError(f"{src}: scene {scene_path} is not a mapping")
    if "duration" in raw:
        scene["duration"] = _number(raw["duration"], f"{src}: duration")
        if scene.get("test_duration") is not None and scene["test_duration"] > scene["duration"]:
            scene["test_duration"] = scene["duration"]
        rate = as_float(scene.get("output_rate", 10.0))
        if rate and rate > 0 and fit_window_too_short(as_float(scene.get("fit_start", 0.0)) or 0.0,
                                                      scene["duration"], rate):
            scene["fit_start"] = 0.0                   # the fits over the whole (shorter) run
    seed = raw.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SweepSpecError(f"{src}: seed: expected an integer ≥ 0, got {seed!r}")
    vary: tuple[Variation, ...] = ()
    bags: tuple[Path, ...] = ()
    runs = 0
    if "vary" in raw:
        if not isinstance(raw["vary"], dict) or not raw["vary"]:
            raise SweepSpecError(f"{src}: vary: expected a mapping parameter -> distribution")
        vary = tuple(_variation(k, v, f"{src}: vary.{k}") for k, v in raw["vary"].items())
        runs = raw.get("runs")
        if isinstance(runs, bool) or not isinstance(runs, int) or not 1 <= runs <= 1_000_000:
            raise SweepSpecError(f"{src}: runs: expected an integer in [1, 1000000], got {runs!r}")
        trial = copy.deepcopy(scene)
        try:
            for v in vary:
                apply_value(trial, v, v.centre())
        except SweepSpecError as e:
            raise SweepSpecError(f"{src}: {e}") from None
    else:
        if not isinstance(raw["bags"], list):
            raise SweepSpecError(f"{src}: bags: expected a list of bag paths or folders")
        if (scene.get("motion") or {}).get("type") != "bag":
            raise SweepSpecError(f"{src}: bags need a scene whose motion type is 'bag' (e.g. husky_replay)")
        if "runs" in raw:
            raise SweepSpecError(f"{src}: runs: not used with 'bags' (one run per bag)")
        bags = _find_bags(raw["bags"], path.resolve().parent, f"{src}: bags")
        trial = copy.deepcopy(scene)
        trial["motion"] = {**trial["motion"], "path": str(bags[0])}
    try:  # the scene must accept the sweep's values (each run is still checked on its own)
        checked = scene_from_dict(trial, source=f"{scene_path.name} in {path.name}",
                                  base_dir=scene_path.resolve().parent, default_name=scene_path.stem)
    except ScenarioError as e:
        raise SweepSpecError(f"{src}: {e}") from None
    scene.setdefault("name", scene_path.stem)
    return SweepSpec(source=path, scene_path=scene_path, scene=scene, seed=seed, runs=runs, vary=vary, bags=bags,
                     warnings=unused_variations(vary, checked.options.effects, src))


def unused_variations(vary: tuple[Variation, ...], effects: frozenset[str], src: str) -> tuple[str, ...]:
    """One line per varied platform parameter that no effect of the scene evaluates
    (``physics.options.PARAM_EFFECTS``): its draws would change nothing and still fill the table."""
    out = []
    for v in vary:
        need = PARAM_EFFECTS.get(v.path[-1]) if v.path[0] == "params" else None
        if need and not need & effects:
            out.append(f"{src}: vary.{v.key}: the scene's effects leave it unused ({' or '.join(sorted(need))} "
                       "is off): its draws change nothing")
    return tuple(out)


__all__ = ["SweepSpec", "SweepSpecError", "Variation", "load_sweep", "apply_value", "unused_variations",
           "DISTRIBUTIONS"]
