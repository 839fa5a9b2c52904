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

"""Scene files: a YAML description of one simulation run, validated into a typed ``Scene``.

A scene names the model (mode, fidelity, effects, parameter overrides, integrator), the vehicle
motion that drives it, how long and how finely to sample it, and a list of expectations that the
run must meet. ``gyro-platform run SCENE`` (a path or a shipped scene's name, see
``find_scene``) runs it, prints a summary table and the expectation results, and writes
``outputs.csv``, ``summary.json`` and ``plot.png`` into the output folder (default
``results/<scene name>/``); the exit status is 1 if an expectation fails or cannot be evaluated
(a run shorter than ``test_duration``), 2 for a bad scene or bag path, 3 for a damaged bag.

Schema (every key is checked; unknown keys are rejected; errors name the key path, e.g.
``scene 'x.yaml': motion.bank_deg: expected a number``)::

    name: str                 # default: the file name without .yaml
    description: str          # free text
    mode: stabilised          # carried | stabilised                        (default stabilised)
    fidelity: linear          # full | linear | precession   (default: linear when stabilised, full when carried)
    effects: [defaults, bias_torque]
                              # names of options.EFFECTS; the entry `defaults` stands for the
                              # mode's default effects; omitted = the mode's defaults
    params: {bias_torque: [0, 0, 0, 0, 1.0e-7]}
                              # overrides of PlatformParams fields (SI units, angles in rad)
    integrator: auto          # integrator name (see integrators), default auto
    max_step: 1.0e-3          # s, largest internal step                     (default 1e-3)
    rtol: 1.0e-6              # local error tolerance every integrator is held to (default 1e-6)
    atol: 1.0e-9              # absolute part, state units rad, rad/s (default 1e-9)
    duration: 60              # s simulated (required, > 0; see "Run size" below)
    test_duration: 20         # s; the shortest run for which the expectations still hold —
                              # the test suite runs the scene this long    (optional, ≤ duration)
    sample_rate: 100          # Hz of the input samples (default 100; not allowed with bag)
    output_rate: 10           # Hz of the recorded outputs (default 10, ≤ sample_rate)
    fit_start: 0              # s after the start where the least-squares drift fits begin (≤ duration − 1/output_rate)
    motion: {type: ..., ...}  # the vehicle motion, see below (required)
    expect: [...]             # checks on the run's summary, see below (default none)

Run size: a synthetic scene is refused before it starts when its estimate exceeds
``MAX_MEMORY_BYTES`` (8 GiB: ``BYTES_PER_SAMPLE`` per input sample, ``BYTES_PER_OUTPUT`` per
recorded output) or ``MAX_STEPS`` (1e9 internal steps: at least ``duration / max_step`` and one
per sample, ~``SECONDS_PER_STEP`` each); the error names the key (``duration``, ``sample_rate``
or ``max_step``) and gives the estimate (:func:`run_budget`). Parameter overrides are numbers or
flat lists of numbers (``true``, nested lists and strings that are no number are refused);
``rtol`` ≥ 1e-13 (below, float64 rounding cannot meet it).

Motions (angles in degrees where the key says ``_deg``, else SI; body axes FLU, navigation
axes ENU; see ``motions`` for the exact kinematics)::

    {type: constant, omega: [x, y, z] rad/s, initial_rpy_deg: [r, p, y]}
    {type: earth_fixed, latitude_deg: 45, heading_deg: 0}
        # at rest on the rotating Earth; latitude defaults to params.latitude, the rate is
        # params.earth_rate; heading is the ENU yaw of the body x axis (0 = East, body = N)
    {type: coordinated_turn, speed: m/s, bank_deg: deg (+ = right), roll_time: s (2),
     start: s (0), hold: s (null = until the end), heading_deg: 0}
    {type: sinusoidal, heading_deg: 0,
     roll:  {amplitude_deg, frequency_hz, phase_deg},   # each of roll/pitch/yaw optional
     pitch: {...}, yaw: {...},
     heave: {amplitude_m, frequency_hz, phase_deg}}
    {type: coning, half_angle_deg, frequency_hz, axis: x|y|z (x), phase_deg: 0,
     initial_rpy_deg: [0, 0, 0]}
    {type: rate_steps, steps: [{t: s, omega: [x, y, z] rad/s}, ...], rise_time: s (0),
     initial_rpy_deg: [0, 0, 0]}            # rate is zero before the first step
    {type: random, seed: int, angle_rms_deg: number or [roll, pitch, yaw],
     band_hz: [lo, hi] ([0.05, 2]), components: int (16, ≤ 256), accel_rms: m/s² (0), heading_deg: 0}
    {type: bag, path: str, topic: str}      # rosbag2 input via gyro_platform.pipeline;
        # a relative path is tried against the scene file's folder, then the repository root
        # (the folder above the scene with setup.py / package.xml), then the working folder

Expectations (each a mapping)::

    {quantity: NAME, <selector>: KEY, value: v, rtol: r, atol: a}   # |x − v| ≤ atol + rtol·|v|
    {quantity: NAME, <selector>: KEY, max: hi, min: lo}             # lo ≤ x ≤ hi (either or both)
    why: str                                                        # where the number comes from

Quantities (``QUANTITIES``; selector and unit):

    max_abs_gimbal_angle, final_gimbal_angle      joint: alpha4|beta5|beta7|alpha9|beta10   rad
    gimbal_angle_slope (least-squares slope)      joint                                     rad/s
    max_abs_bearing_torque (max of the norm)      bearing: support|gimbal4|…|rotor11         N m
    max_abs_motor_torque                          rotor: rotor6|rotor8|rotor11               N m
    max_abs_servo_torque                          axis: x|y|z|norm                          N m
    final_drift_angle, max_abs_drift_angle        axis                                      rad
    drift_rate, drift_rate_deg_per_h (LSQ slope)  axis                                      rad/s, °/h
    platform_vs_vehicle_rate_deg_per_h            axis (synthetic, steady vehicle rate)     °/h
    mean_vehicle_rate (time average), max_abs_…   axis                                      rad/s
    duration                                      —                                         s

``load_scene(path) -> Scene`` (here: the schema, loading and lookup by name; the checks of single
values and ``ScenarioError`` are :mod:`gyro_platform.scenes.validation`);
running is :func:`gyro_platform.scenes.runner.run_scene`, the command
:mod:`gyro_platform.scenes.command`.
"""
from __future__ import annotations

from dataclasses import dataclass
from dataclasses import fields as dc_fields
from dataclasses import replace
import math
from pathlib import Path
import re
import sys
from typing import Any

import numpy as np

from . import motions as mo
from .budget import MAX_MEMORY_BYTES, MAX_STEPS, MIN_RTOL, oversize, run_budget, RunBudget
from .scene_yaml import load_yaml, SceneYAMLError
from .validation import join_path, param_value, ScenarioError, type_name, Validator
from ..physics.options import DEFAULT_EFFECTS, DEFAULT_FIDELITY, EFFECTS, FIDELITIES, ModelOptions, MODES, OptionsError
from ..physics.params import ParameterError, PlatformParams
from ..pipeline.grid import MAX_GRID_RATE
from ..reports.summary import ENTRY_NAMES, SUMMARY_FIGURES

#: quantities an expectation may check -> (selector key or None, allowed selector values, unit): the
#: summary's figures (``reports.summary.SUMMARY_FIGURES``: entries and units)
QUANTITIES: dict[str, tuple[str | None, tuple[str, ...], str]] = {
    q: (SUMMARY_FIGURES[q][1], ENTRY_NAMES.get(SUMMARY_FIGURES[q][1] or "", ()), SUMMARY_FIGURES[q][0])
    for q in ("max_abs_gimbal_angle", "final_gimbal_angle", "gimbal_angle_slope", "max_abs_bearing_torque",
              "max_abs_motor_torque", "max_abs_servo_torque", "final_drift_angle", "max_abs_drift_angle",
              "drift_rate", "drift_rate_deg_per_h", "platform_vs_vehicle_rate_deg_per_h", "mean_vehicle_rate",
              "max_abs_vehicle_rate", "duration")}
SELECTORS = tuple(ENTRY_NAMES)         # joint, bearing, rotor, axis
MOTION_TYPES = ("constant", "earth_fixed", "coordinated_turn", "sinusoidal", "coning", "rate_steps",
                "random", "bag")
TOP_KEYS = ("name", "description", "mode", "fidelity", "effects", "params", "integrator", "max_step",
            "rtol", "atol", "duration", "test_duration", "sample_rate", "output_rate", "fit_start",
            "motion", "expect")


class MotionError(ScenarioError):
    """A synthetic motion whose numbers cannot be generated (beyond floating point): found when
    its samples are made, before the run writes anything (``runner.synthetic_samples``)."""


def check_budget(source: str, duration: float, sample_rate: float | None, output_rate: float, max_step: float,
                 keys: dict[str, str] | None = None) -> None:
    """ScenarioError naming the key that makes a synthetic run too big (:func:`budget.oversize`);
    ``keys`` renames them for flags (``{"duration": "--duration"}``). A bag's length bounds its run."""
    if sample_rate is None:
        return
    problem = oversize(duration, sample_rate, output_rate, max_step)
    if problem is not None:
        key, text = problem
        raise ScenarioError(f"scene '{source}': {(keys or {}).get(key, key)}: {text}")


# ---- typed scene --------------------------------------------------------------------------
@dataclass(frozen=True)
class Check:
    """One expectation: ``quantity`` (``QUANTITIES``) at ``selector`` compared with ``value``
    (± ``atol`` + ``rtol``·|value|) and/or the bounds ``min``/``max``."""

    quantity: str
    selector: str | None = None
    value: float | None = None
    rtol: float = 0.0
    atol: float = 0.0
    min: float | None = None
    max: float | None = None
    why: str = ""

    @property
    def label(self) -> str:
        return self.quantity + (f"[{self.selector}]" if self.selector else "")

    def measured(self, summary: dict) -> float | None:
        v = summary.get(self.quantity)
        if self.selector is not None:
            v = v.get(self.selector) if isinstance(v, dict) else None
        return None if v is None else float(v)

    def evaluate(self, summary: dict) -> tuple[bool, str]:
        """(passed, detail): detail gives the measured value and the criterion."""
        unit = QUANTITIES[self.quantity][2]
        x = self.measured(summary)
        if x is None:
            return False, f"{self.label}: not available in this run"
        ok = math.isfinite(x)
        crit = []
        if self.value is not None:
            tol = self.atol + self.rtol * abs(self.value)
            ok = ok and abs(x - self.value) <= tol
            tol_s = []
            if self.rtol:
                tol_s.append(f"{self.rtol * 100:g} %")
            if self.atol:
                tol_s.append(f"{self.atol:.3g}")
            crit.append(f"expected {self.value:.6g} ± {' + '.join(tol_s)} (dev {x - self.value:+.3g})")
        if self.min is not None:
            ok = ok and x >= self.min
            crit.append(f"≥ {self.min:.4g}")
        if self.max is not None:
            ok = ok and x <= self.max
            crit.append(f"≤ {self.max:.4g}")
        return bool(ok), f"{self.label} = {x:.6g} {unit}; {', '.join(crit)}"


@dataclass(frozen=True)
class MotionSpec:
    """The validated ``motion`` block: ``type``, ``settings`` (as written, validated) and either
    a synthetic ``generator`` (``motions.Motion``) or a bag ``path`` + ``topic``."""

    type: str
    settings: dict
    generator: mo.Motion | None = None
    path: Path | None = None
    topic: str | None = None

    @property
    def is_bag(self) -> bool:
        return self.type == "bag"


@dataclass(frozen=True)
class Scene:
    """A validated scene. ``params``/``options`` are ready for ``Simulator``; durations in s,
    rates in Hz."""

    name: str
    description: str
    mode: str
    fidelity: str
    effects: tuple[str, ...]
    param_overrides: dict
    params: PlatformParams
    options: ModelOptions
    integrator: str
    max_step: float
    duration: float
    test_duration: float | None
    sample_rate: float | None
    output_rate: float
    fit_start: float
    motion: MotionSpec
    expect: tuple[Check, ...] = ()
    source: Path | None = None

    @property
    def expect_duration(self) -> float:
        """Shortest run (s) on which the expectations can be evaluated: ``test_duration``, else
        the scene's ``duration``."""
        return self.test_duration if self.test_duration is not None else self.duration

    def with_duration(self, duration: float) -> "Scene":
        """Copy with another simulated duration (s); the expectations still need
        :attr:`expect_duration` of the original (a shorter run leaves them not evaluable)."""
        if not (duration > 0 and math.isfinite(duration)):
            raise ScenarioError(f"scene '{self.name}': --duration must be a finite number > 0, got {duration}")
        if fit_window_too_short(self.fit_start, duration, self.output_rate):
            raise ScenarioError(f"scene '{self.name}': --duration {duration:g} s must exceed fit_start "
                                f"({self.fit_start:g} s) by one output period ({1 / self.output_rate:g} s): "
                                "the drift fits need two outputs")
        check_budget(self.name, duration, self.sample_rate, self.output_rate, self.max_step,
                     {"duration": "--duration"})
        return replace(self, duration=float(duration), test_duration=self.expect_duration)

    def with_integrator(self, integrator: str | None = None, max_step: float | None = None) -> "Scene":
        """Copy with another integrator and/or internal step bound (s)."""
        from ..engine.integrators import INTEGRATOR_CHOICES

        name = self.integrator if integrator is None else integrator
        step = self.max_step if max_step is None else float(max_step)
        if name not in INTEGRATOR_CHOICES:
            raise ScenarioError(f"scene '{self.name}': integrator: expected one of "
                                f"{', '.join(INTEGRATOR_CHOICES)}, got {name!r}")
        try:
            opts = self.options.with_(integrator=name, max_step=step)
        except OptionsError as e:
            raise ScenarioError(f"scene '{self.name}': {e}") from None
        check_budget(self.name, self.duration, self.sample_rate, self.output_rate, step, {"max_step": "--max-step"})
        return replace(self, integrator=name, max_step=step, options=opts)


# ---- finding and loading ----------------------------------------------------------------------
SCENE_SUFFIXES = (".yaml", ".yml")


def scene_dirs() -> list[Path]:
    """Folders searched for a scene given by name, first match wins: the source tree's
    ``config/scenes``; the installed share folder ``<prefix>/share/gyro_platform/config/scenes``
    of the prefix this package is installed under (pip, ``--prefix``, ``--user``, colcon) and
    of ``sys.prefix``; the ament index's share folder when ``ament_index_python`` is there."""
    here = Path(__file__).resolve().parents[1]        # the gyro_platform package folder
    dirs = [here.parent / "config" / "scenes"]
    share = Path("share") / "gyro_platform" / "config" / "scenes"
    # <prefix>/lib/pythonX.Y/site-packages/gyro_platform -> <prefix>
    if len(here.parents) >= 4:
        dirs.append(here.parents[3] / share)
    dirs.append(Path(sys.prefix) / share)
    try:
        from ament_index_python.packages import get_package_share_directory

        dirs.append(Path(get_package_share_directory("gyro_platform")) / "config" / "scenes")
    except Exception:  # not a ROS install: no ament index to ask
        pass
    unique: list[Path] = []
    for d in dirs:
        if d not in unique:
            unique.append(d)
    return unique


def scene_names() -> list[str]:
    """Names of the scenes found in :func:`scene_dirs`."""
    names: set[str] = set()
    for d in scene_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.iterdir() if p.suffix in SCENE_SUFFIXES)
    return sorted(names)


def find_scene(name) -> Path:
    """Path of a scene given as a path (absolute or relative to the working folder) or as a
    name in :func:`scene_dirs` (``coning`` or ``coning.yaml``). ScenarioError if none exists."""
    p = Path(name).expanduser()
    cands = [p]
    if not p.is_absolute() and len(p.parts) == 1:
        names = [p.name] if p.suffix in SCENE_SUFFIXES else [p.name + ".yaml", p.name + ".yml"]
        cands += [d / n for d in scene_dirs() for n in names]
    for c in cands:
        if c.is_file():
            return c
    if p.is_dir():
        raise ScenarioError(f"scene '{name}': is a folder, not a scene file")
    known = scene_names()
    raise ScenarioError(f"scene file '{name}' not found: no such file or scene name"
                        + (f" (scenes: {', '.join(known)})" if known else ""))


def load_scene(path) -> Scene:
    """Read and validate a scene given by file path or by name (see :func:`find_scene`; the
    module docs give the schema)."""
    path = find_scene(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ScenarioError(f"scene '{path}': cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"scene '{path}': not a text file (a scene is YAML)") from None
    try:
        data = load_yaml(text)                        # one-line errors; a repeated key is refused
    except SceneYAMLError as e:
        raise ScenarioError(f"scene '{path.name}': not valid YAML: {e}") from None
    return scene_from_dict(data, source=path.name, base_dir=path.resolve().parent,
                           default_name=path.stem, path=path)


def repo_root(start: Path) -> Path | None:
    """The nearest folder at or above ``start`` holding ``setup.py`` or ``package.xml``."""
    for d in [start, *start.parents]:
        if (d / "setup.py").is_file() or (d / "package.xml").is_file():
            return d
    return None


def top_frequency(motion: MotionSpec) -> float | None:
    """Highest frequency (Hz) of a periodic or band-limited synthetic motion (sinusoidal,
    coning, random), None for the others (their input is not a sum of oscillations)."""
    m = motion.settings
    if motion.type == "sinusoidal":
        return max((float(m[ax]["frequency_hz"]) for ax in ("roll", "pitch", "yaw", "heave") if ax in m),
                   default=None)
    if motion.type == "coning":
        return float(m["frequency_hz"])
    if motion.type == "random":
        return float(m.get("band_hz", [0.05, 2.0])[1])
    return None


def fit_window_too_short(fit_start: float, duration: float, output_rate: float) -> bool:
    """The drift fits' window [fit_start, duration] holds fewer than two outputs of the grid
    (outputs every 1/output_rate s and at the end: it must span one output period)."""
    return fit_start > duration - 1.0 / output_rate


def scene_from_dict(data: Any, source: str = "<dict>", base_dir: Path | None = None,
                    default_name: str = "scene", path: Path | None = None) -> Scene:
    """Validate a parsed scene mapping (``source`` names it in error messages)."""
    v = Validator(source)
    d = v.mapping(data, "", TOP_KEYS, required=("duration", "motion"))
    name = v.string(d.get("name", default_name), "name")
    if not re.fullmatch(r"[A-Za-z0-9_.\-]+", name) or not name.strip("."):
        v.fail("name", f"use letters, digits, '_', '-', '.' only, not dots alone (it names the output folder "
                       f"results/NAME), got {name!r}")
    description = v.string(d.get("description", ""), "description")
    mode = v.choice(d.get("mode", "stabilised"), "mode", MODES)
    fidelity = v.choice(d.get("fidelity", DEFAULT_FIDELITY[mode]), "fidelity", FIDELITIES)

    # effects
    if "effects" in d:
        raw = d["effects"]
        if not isinstance(raw, list):
            v.fail("effects", f"expected a list of effect names, got {type_name(raw)}")
        eff: list[str] = []
        for i, e in enumerate(raw):
            e = v.choice(e, f"effects[{i}]", ("defaults", *EFFECTS))
            for name_ in (sorted(DEFAULT_EFFECTS[mode]) if e == "defaults" else [e]):
                if name_ not in eff:
                    eff.append(name_)
        effects = tuple(eff)
    else:
        effects = tuple(sorted(DEFAULT_EFFECTS[mode]))

    # params
    overrides = d.get("params", {}) or {}
    known = tuple(f.name for f in dc_fields(PlatformParams))
    v.mapping(overrides, "params", known)
    overrides = {k: param_value(v, val, f"params.{k}") for k, val in overrides.items()}
    try:
        params = PlatformParams.from_dict(overrides)
    except ParameterError as e:
        m = re.search(r"parameter '([A-Za-z_0-9]+)", str(e))
        v.fail(f"params.{m.group(1)}" if m else "params", str(e))

    from ..engine.integrators import INTEGRATOR_CHOICES

    integrator = v.choice(d.get("integrator", "auto"), "integrator", INTEGRATOR_CHOICES)
    max_step = v.number(d.get("max_step", 1e-3), "max_step", lo=0.0, hi=1.0, lo_open=True)
    kw: dict[str, Any] = {"integrator": integrator, "max_step": max_step}
    for k in ("rtol", "atol"):
        if k in d:
            kw[k] = v.number(d[k], k, lo=0.0, hi=1.0, lo_open=True)
    if kw.get("rtol", MIN_RTOL) < MIN_RTOL:
        v.fail("rtol", f"must be ≥ {MIN_RTOL:g} (float64 rounding cannot meet less), got {kw['rtol']:g}")
    try:
        options = ModelOptions.make(mode, fidelity, effects, **kw)
    except OptionsError as e:
        m = re.search(r"option '(\w+)'", str(e))
        v.fail(m.group(1) if m else "effects", str(e))

    duration = v.number(d["duration"], "duration", lo=0.0, lo_open=True)
    test_duration = None
    if d.get("test_duration") is not None:
        test_duration = v.number(d["test_duration"], "test_duration", lo=0.0, hi=duration, lo_open=True)
    output_rate = v.number(d.get("output_rate", 10.0), "output_rate", lo=0.0, hi=MAX_GRID_RATE, lo_open=True)
    fit_start = v.number(d.get("fit_start", 0.0), "fit_start", lo=0.0)
    if fit_window_too_short(0.0, duration, output_rate):
        v.fail("duration", f"must span one output period (1/output_rate = {1 / output_rate:g} s) so that the "
                           f"drift fits have two outputs, got {duration:g} s")
    if fit_window_too_short(fit_start, duration, output_rate):
        v.fail("fit_start", f"must leave the drift fits two outputs: ≤ duration − 1/output_rate "
                            f"({duration - 1 / output_rate:g} s), got {fit_start:g}")

    motion = _motion(v, d["motion"], params, base_dir, path)
    if motion.is_bag:
        if "sample_rate" in d:
            v.fail("sample_rate", "not used with motion type 'bag' (the bag's own stamps are used); remove it")
        sample_rate = None
    else:
        sample_rate = v.number(d.get("sample_rate", 100.0), "sample_rate", lo=0.0, lo_open=True)
        if output_rate > sample_rate * (1 + 1e-12):
            v.fail("output_rate", f"must be ≤ sample_rate ({sample_rate:g} Hz), got {output_rate:g}")
        if sample_rate * duration < 1.0:
            v.fail("sample_rate", f"gives fewer than 2 samples over {duration:g} s")
        top = top_frequency(motion)
        if top is not None and top >= sample_rate / 2:
            v.fail("sample_rate", f"{sample_rate:g} Hz cannot carry the motion's {top:g} Hz (at or above half the "
                                  f"sample rate its samples are a different, aliased motion); give more than "
                                  f"{2 * top:g} Hz")
    check_budget(source, duration, sample_rate, output_rate, max_step)

    raw_expect = d.get("expect", []) or []
    if not isinstance(raw_expect, list):
        v.fail("expect", f"expected a list of checks, got {type_name(raw_expect)}")
    checks = tuple(_check(v, c, f"expect[{i}]") for i, c in enumerate(raw_expect))
    return Scene(name=name, description=description, mode=mode, fidelity=fidelity, effects=effects,
                 param_overrides=dict(overrides), params=params, options=options, integrator=integrator,
                 max_step=max_step, duration=duration, test_duration=test_duration,
                 sample_rate=sample_rate, output_rate=output_rate, fit_start=fit_start, motion=motion,
                 expect=checks, source=path)


_SINE_KEYS = ("amplitude_deg", "frequency_hz", "phase_deg")
_MOTION_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # type: (allowed keys besides 'type', required)
    "constant": (("omega", "initial_rpy_deg"), ("omega",)),
    "earth_fixed": (("latitude_deg", "heading_deg"), ()),
    "coordinated_turn": (("speed", "bank_deg", "roll_time", "start", "hold", "heading_deg"), ("speed", "bank_deg")),
    "sinusoidal": (("roll", "pitch", "yaw", "heave", "heading_deg"), ()),
    "coning": (("half_angle_deg", "frequency_hz", "axis", "phase_deg", "initial_rpy_deg"),
               ("half_angle_deg", "frequency_hz")),
    "rate_steps": (("steps", "rise_time", "initial_rpy_deg"), ("steps",)),
    "random": (("seed", "angle_rms_deg", "band_hz", "components", "accel_rms", "heading_deg"),
               ("seed", "angle_rms_deg")),
    "bag": (("path", "topic"), ("path",)),
}


def _initial(v: Validator, m: dict, path: str):
    from scipy.spatial.transform import Rotation

    if "initial_rpy_deg" not in m:
        return None
    r, p, y = np.radians(v.vector(m["initial_rpy_deg"], join_path(path, "initial_rpy_deg")))
    return Rotation.from_euler("ZYX", [y, p, r])


def _motion(v: Validator, raw: Any, params: PlatformParams, base_dir: Path | None, path: Path | None) -> MotionSpec:
    P = "motion"
    if not isinstance(raw, dict):
        v.fail(P, f"expected a mapping with a 'type' key, got {type_name(raw)}")
    if "type" not in raw:
        v.fail(join_path(P, "type"), f"required key is missing (one of {', '.join(MOTION_TYPES)})")
    typ = v.choice(raw["type"], join_path(P, "type"), MOTION_TYPES)
    allowed, required = _MOTION_KEYS[typ]
    m = v.mapping(raw, P, ("type", *allowed), required)
    J = lambda k: join_path(P, k)  # noqa: E731
    num = lambda k, default=None, **kw: (v.number(m[k], J(k), **kw) if k in m and m[k] is not None  # noqa: E731
                                         else default)
    deg = lambda k, default=0.0, **kw: math.radians(num(k, default, **kw))  # noqa: E731
    try:
        if typ == "constant":
            gen: mo.Motion | None = mo.ConstantRate(v.vector(m["omega"], J("omega")), _initial(v, m, P))
        elif typ == "earth_fixed":
            lat = (math.radians(num("latitude_deg", lo=-90, hi=90)) if "latitude_deg" in m
                   else params.latitude)
            gen = mo.EarthFixed(lat, deg("heading_deg"), params.earth_rate)
        elif typ == "coordinated_turn":
            gen = mo.CoordinatedTurn(
                speed=num("speed", lo=0.0, lo_open=True),
                bank=math.radians(num("bank_deg", lo=-80.0, hi=80.0)),
                roll_time=num("roll_time", 2.0, lo=0.0, lo_open=True),
                start=num("start", 0.0, lo=0.0), hold=num("hold", None, lo=0.0),
                heading=deg("heading_deg"))
        elif typ == "sinusoidal":
            sines = {}
            for ax in ("roll", "pitch", "yaw", "heave"):
                if ax not in m:
                    continue
                keys = ("amplitude_m", "frequency_hz", "phase_deg") if ax == "heave" else _SINE_KEYS
                s = v.mapping(m[ax], J(ax), keys, required=keys[:2])
                amp = v.number(s[keys[0]], f"{J(ax)}.{keys[0]}", lo=0.0)
                sines[ax] = mo.Sine(amplitude=amp if ax == "heave" else math.radians(amp),
                                    frequency=v.number(s["frequency_hz"], f"{J(ax)}.frequency_hz", lo=0.0),
                                    phase=math.radians(v.number(s.get("phase_deg", 0.0), f"{J(ax)}.phase_deg")))
            gen = mo.Sinusoidal(heading=deg("heading_deg"), **sines)
        elif typ == "coning":
            axis = v.choice(m.get("axis", "x"), J("axis"), ("x", "y", "z"))
            gen = mo.Coning(half_angle=math.radians(num("half_angle_deg", lo=0.0, hi=90.0)),
                            frequency=2 * math.pi * num("frequency_hz", lo=0.0),
                            axis="xyz".index(axis), phase=deg("phase_deg"), initial=_initial(v, m, P))
        elif typ == "rate_steps":
            steps = m["steps"]
            if not isinstance(steps, list) or not steps:
                v.fail(J("steps"), f"expected a non-empty list of {{t, omega}} mappings, got {type_name(steps)}")
            times, rates = [], []
            for i, st in enumerate(steps):
                sp = f"{J('steps')}[{i}]"
                st = v.mapping(st, sp, ("t", "omega"), ("t", "omega"))
                times.append(v.number(st["t"], sp + ".t", lo=0.0))
                rates.append(v.vector(st["omega"], sp + ".omega"))
                if i and times[-1] <= times[-2]:
                    v.fail(sp + ".t", f"step times must increase, got {times[-1]:g} after {times[-2]:g}")
            gen = mo.RateSteps(times, rates, rise_time=num("rise_time", 0.0, lo=0.0),
                               initial=_initial(v, m, P))
        elif typ == "random":
            band = v.vector(m.get("band_hz", [0.05, 2.0]), J("band_hz"), 2)
            if not (0 < band[0] < band[1]):
                v.fail(J("band_hz"), f"need 0 < lo < hi, got {band.tolist()}")
            gen = mo.RandomMotion(
                seed=v.integer(m["seed"], J("seed"), lo=0),
                angle_rms=np.radians(v.scalar_or_vector(m["angle_rms_deg"], J("angle_rms_deg"), lo=0.0)),
                band=tuple(band), components=v.integer(m.get("components", 16), J("components"), lo=1,
                                                       hi=mo.RandomMotion.MAX_COMPONENTS),
                accel_rms=v.scalar_or_vector(m.get("accel_rms", 0.0), J("accel_rms"), lo=0.0),
                heading=deg("heading_deg"))
        else:  # bag
            p = v.string(m["path"], J("path"))
            topic = v.string(m["topic"], J("topic")) if m.get("topic") is not None else None
            return MotionSpec("bag", dict(m), None, _resolve_bag(v, p, base_dir), topic)
    except ValueError as e:
        if isinstance(e, ScenarioError):
            raise
        v.fail(P, str(e))
    return MotionSpec(typ, dict(m), gen)


def _resolve_bag(v: Validator, p: str, base_dir: Path | None) -> Path:
    cand: list[Path] = []
    pp = Path(p).expanduser()
    if pp.is_absolute():
        cand.append(pp)
    else:
        if base_dir is not None:
            cand.append(base_dir / pp)
            root = repo_root(base_dir)
            if root is not None:
                cand.append(root / pp)
        cand.append(Path.cwd() / pp)
    for c in cand:
        if c.exists():
            return c.resolve()
    v.fail("motion.path", "bag not found; tried " + ", ".join(str(c) for c in cand))
    raise AssertionError  # unreachable


def _check(v: Validator, raw: Any, path: str) -> Check:
    keys = ("quantity", *SELECTORS, "value", "rtol", "atol", "min", "max", "why")
    c = v.mapping(raw, path, keys, required=("quantity",))
    q = v.choice(c["quantity"], join_path(path, "quantity"), QUANTITIES)
    sel_key, sel_allowed, _ = QUANTITIES[q]
    for s in SELECTORS:
        if s in c and s != sel_key:
            v.fail(join_path(path, s), f"not a selector of '{q}'"
                   + (f" (it takes '{sel_key}')" if sel_key else " (it takes none)"))
    selector = None
    if sel_key is not None:
        if sel_key not in c:
            v.fail(join_path(path, sel_key), f"required for '{q}' (one of {', '.join(sel_allowed)})")
        selector = v.choice(c[sel_key], join_path(path, sel_key), sel_allowed)
    vals = {k: (v.number(c[k], join_path(path, k)) if c.get(k) is not None else None)
            for k in ("value", "rtol", "atol", "min", "max")}
    for k in ("rtol", "atol"):
        if vals[k] is not None and vals[k] < 0:
            v.fail(join_path(path, k), f"must be ≥ 0, got {vals[k]:g}")
    if vals["value"] is not None:
        if vals["rtol"] is None and vals["atol"] is None:
            v.fail(join_path(path, "value"), "needs a tolerance: 'rtol' and/or 'atol'")
    elif vals["rtol"] is not None or vals["atol"] is not None:
        v.fail(join_path(path, "rtol" if vals["rtol"] is not None else "atol"), "only used with 'value'")
    if vals["value"] is None and vals["min"] is None and vals["max"] is None:
        v.fail(path, "give 'value' (with 'rtol' and/or 'atol') or a bound 'min'/'max'")
    if vals["min"] is not None and vals["max"] is not None and vals["min"] > vals["max"]:
        v.fail(join_path(path, "min"), f"min ({vals['min']:g}) > max ({vals['max']:g})")
    why = v.string(c.get("why", ""), join_path(path, "why"))
    return Check(quantity=q, selector=selector, value=vals["value"], rtol=vals["rtol"] or 0.0,
                 atol=vals["atol"] or 0.0, min=vals["min"], max=vals["max"], why=why)


def scene_info(scene: Scene) -> dict:
    """The scene's settings as plain data (for JSON)."""
    return {
        "name": scene.name, "description": scene.description, "source": str(scene.source or ""),
        "mode": scene.mode, "fidelity": scene.fidelity, "effects": list(scene.effects),
        "params": scene.param_overrides, "integrator": scene.integrator, "max_step": scene.max_step,
        "duration": scene.duration, "sample_rate": scene.sample_rate, "output_rate": scene.output_rate,
        "fit_start": scene.fit_start, "motion": {"type": scene.motion.type, **{
            k: (str(v) if isinstance(v, Path) else v) for k, v in scene.motion.settings.items()}},
        "motion_description": scene.motion.generator.describe() if scene.motion.generator else
        f"bag {scene.motion.path} topic {scene.motion.topic}",
    }


__all__ = ["Scene", "MotionSpec", "Check", "ScenarioError", "MotionError", "QUANTITIES", "load_scene", "find_scene",
           "scene_dirs", "scene_names", "scene_from_dict", "scene_info", "RunBudget", "run_budget", "check_budget",
           "MAX_MEMORY_BYTES", "MAX_STEPS", "fit_window_too_short"]
