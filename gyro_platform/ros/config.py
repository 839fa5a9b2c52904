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

"""Validated node configuration: :class:`NodeConfig`, params files and scene defaults.

* :class:`NodeConfig` — validated values of every parameter of
  :data:`~gyro_platform.ros.parameters.PARAMETERS`; :meth:`NodeConfig.from_ros_params` takes the
  ``ros__parameters`` mapping of a params file, :meth:`NodeConfig.from_yaml` a whole params
  file (:func:`load_params_file` selects its sections as rcl does). It builds the gate
  configuration, sensor mountings, platform parameters and model options the core runs on.
* ``scene`` — a scene file (``config/scenes/*.yaml``) supplies the *defaults* of the model
  parameters (``mode``, ``fidelity``, ``effects``, ``integrator``, ``max_step``,
  ``output_rate``, ``physics.*``); values set explicitly (params file, ``-p``) override them.
  The scene's motion is not used: the vehicle motion is the input topic.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from dataclasses import fields as dc_fields
import difflib
import functools
from pathlib import Path
import re
from typing import Any, Iterable, Mapping

from .dds_names import expand_topic_name, NameError_
from .parameters import ConfigError, INPUT_TYPES, NODE_NAME, PARAMETERS, PHYSICS_PREFIX, SPECS
from ..messages import flatten, Mounting, output_topics
from ..physics.options import DEFAULT_EFFECTS, ModelOptions, NEEDS_SPECIFIC_FORCE, OptionsError
from ..physics.params import ParameterError, PlatformParams
from ..pipeline.gate_rules import GateConfig

#: parameters every rclpy node (or a library it uses) declares itself; accepted and ignored here
ROS_STANDARD_PARAMETERS = ("use_sim_time", "start_type_description_service", "diagnostic_updater.period")
ROS_STANDARD_PREFIXES = ("qos_overrides.",)


# =========================================================================================
# scenes
# =========================================================================================
def resolve_scene(name: str) -> Path:
    """Path of a scene given as a path or by name (``scene.find_scene``); ConfigError if none."""
    from ..scenes.schema import find_scene, ScenarioError

    try:
        return find_scene(name)
    except ScenarioError as e:
        raise ConfigError("scene", str(e)) from None


def load_node_scene(name: str):
    """Load a scene for the node: as ``scene.load_scene`` but a ``bag`` motion (whose bag the
    node does not need) is replaced by a zero rate, so a missing bag does not stop the node."""
    from ..scenes.scene_yaml import load_yaml, SceneYAMLError
    from ..scenes.schema import ScenarioError, scene_from_dict

    path = resolve_scene(name)
    try:
        data = load_yaml(path.read_text())
        if isinstance(data, dict) and isinstance(data.get("motion"), dict) and data["motion"].get("type") == "bag":
            data = {**data, "motion": {"type": "constant", "omega": [0.0, 0.0, 0.0]}}
        return scene_from_dict(data, source=path.name, base_dir=path.resolve().parent, default_name=path.stem,
                               path=path)
    except SceneYAMLError as e:
        raise ConfigError("scene", f"scene '{path.name}': not valid YAML: {e}") from None
    except (OSError, UnicodeDecodeError, ScenarioError) as e:
        raise ConfigError("scene", str(e)) from None


def scene_defaults(scene: Any) -> dict[str, Any]:
    """Parameter defaults a loaded scene supplies (``SCENE_KEYS``)."""
    d: dict[str, Any] = {
        "mode": scene.mode, "fidelity": scene.fidelity, "effects": tuple(scene.effects) or ("none",),
        "integrator": scene.integrator, "max_step": float(scene.max_step), "output_rate": float(scene.output_rate),
    }
    for f in dc_fields(PlatformParams):
        v = getattr(scene.params, f.name)
        d[PHYSICS_PREFIX + f.name] = tuple(float(x) for x in v) if isinstance(v, tuple) else float(v)
    return d


def parameter_defaults(scene: str = "") -> dict[str, Any]:
    """Default of every parameter, with the model defaults of ``scene`` when given."""
    d = {p.name: p.default for p in PARAMETERS}
    if scene:
        d["scene"] = scene
        d.update(scene_defaults(load_node_scene(scene)))
    return d


# =========================================================================================
# configuration
# =========================================================================================
def _is_ros_standard(name: str) -> bool:
    return name in ROS_STANDARD_PARAMETERS or name.startswith(ROS_STANDARD_PREFIXES)


def unknown_parameter_lines(names: Iterable[str]) -> list[str]:
    """One line for each of ``names`` (parameters set for this node by a params file or ``-p``)
    that is neither the node's nor ROS's own: rclpy ignores them silently, so a misspelt or
    misplaced one (``input_topic`` is the launch argument; the parameter is ``imu_topic``)
    would change nothing unseen."""
    lines = []
    for k in sorted(set(names)):
        if k not in SPECS and not _is_ros_standard(k):
            close = difflib.get_close_matches(k, SPECS, n=1, cutoff=0.5)
            hint = {"input_topic": "imu_topic or twist_topic (input_topic is the launch argument)"}.get(
                k, f"'{close[0]}'" if close else "")
            lines.append(f"parameter '{k}' is not one of this node's: ignored" + (f"; did you mean {hint}?"
                                                                                  if hint else ""))
    return lines


#: plain scalars rcl's YAML parser reads as doubles (strtod on the whole scalar) and YAML 1.1
#: does not: ``1e2``, ``1.0e3``, ``-2.5E-3`` (YAML 1.2 core floats, with a point or an exponent)
RCL_FLOAT = (r"^(?:[-+]?(?:\.[0-9]+|[0-9]+\.[0-9]*)(?:[eE][-+]?[0-9]+)?|[-+]?[0-9]+[eE][-+]?[0-9]+"
             r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")


@functools.lru_cache(maxsize=None)
def params_loader() -> type:
    """PyYAML SafeLoader reading numbers as rcl does: a plain scalar is an int when YAML reads
    it so, else a float when it matches :data:`RCL_FLOAT`; quoted scalars stay strings."""
    import yaml

    class ParamsLoader(yaml.SafeLoader):
        pass

    float_tag = "tag:yaml.org,2002:float"
    ParamsLoader.yaml_implicit_resolvers = {
        ch: [(tag, rx) for tag, rx in rs if tag != float_tag]
        for ch, rs in yaml.SafeLoader.yaml_implicit_resolvers.items()}
    ParamsLoader.add_implicit_resolver(float_tag, re.compile(RCL_FLOAT), list("-+0123456789."))
    return ParamsLoader


def load_params_file(path: str | Path, node_name: str = NODE_NAME) -> dict[str, Any]:
    """Flattened ``ros__parameters`` of a params file for one node: the ``/**`` section first,
    then the sections whose last name is ``node_name`` (``gyro_platform_node``,
    ``/ns/gyro_platform_node``), later ones overriding — as rcl merges them. Numbers are read
    as rcl reads them (``1e2`` is a double: :func:`params_loader`)."""
    import yaml

    path = Path(path)
    try:
        doc = yaml.load(path.read_text(), Loader=params_loader())   # noqa: S506 - a SafeLoader
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise ConfigError("params_file", f"{path}: {' '.join(str(e).split())}") from None   # one line
    if not isinstance(doc, dict):
        raise ConfigError("params_file", f"{path}: expected a mapping of node names")
    keys = [k for k in doc if k == "/**"] + [k for k in doc if k != "/**" and
                                             str(k).rstrip("/").split("/")[-1] == node_name]
    if not keys:
        raise ConfigError("params_file", f"{path}: no section '/**' or '{node_name}'")
    merged: dict[str, Any] = {}
    for k in keys:
        sec = doc[k]
        if not isinstance(sec, dict) or "ros__parameters" not in sec:
            raise ConfigError("params_file", f"{path}: section {k!r} has no 'ros__parameters'")
        values = sec["ros__parameters"] or {}
        if not isinstance(values, Mapping):
            raise ConfigError("params_file", f"{path}: 'ros__parameters' of section {k!r} must be a mapping "
                                             f"of parameter names, got {type(values).__name__} {values!r}")
        merged.update(dict(flatten(values)))
    return merged


@dataclass(frozen=True)
class NodeConfig:
    """Validated values of every parameter of :data:`PARAMETERS` (``values[name]``), and the
    scene they were built on (None without ``scene``). Build with :meth:`from_ros_params`."""

    values: Mapping[str, Any]
    scene: Any = None
    _built: dict = field(default_factory=dict, repr=False, compare=False)

    def __getitem__(self, name: str) -> Any:
        return self.values[name]

    # ---- construction ---------------------------------------------------------------
    @staticmethod
    def from_ros_params(d: Mapping[str, Any] | None = None) -> "NodeConfig":
        """Config from a ``ros__parameters`` mapping (nested or dotted keys). Keys absent take
        their default (the scene's for model keys); unknown or bad keys raise ConfigError
        naming the key. ROS's own parameters (``use_sim_time`` …) are accepted and ignored."""
        flat = dict(flatten(d or {}))
        for k in flat:
            if k not in SPECS and not _is_ros_standard(k):
                close = difflib.get_close_matches(k, SPECS, n=1)
                raise ConfigError(k, "unknown parameter" + (f"; did you mean '{close[0]}'?" if close else ""))
        scene_name = SPECS["scene"].coerce(flat.get("scene", ""))
        values = {p.name: p.default for p in PARAMETERS}
        scene = load_node_scene(scene_name) if scene_name else None
        if scene is not None:
            values.update(scene_defaults(scene))
        for k, v in flat.items():
            if k in SPECS:
                values[k] = SPECS[k].coerce(v)
        return NodeConfig._build(values, scene)

    @staticmethod
    def from_yaml(path: str | Path, node_name: str = NODE_NAME) -> "NodeConfig":
        """Config from a params file (sections selected by ``load_params_file``); a bad value
        is a ConfigError naming the parameter and the file."""
        params = load_params_file(path, node_name)
        try:
            return NodeConfig.from_ros_params(params)
        except ConfigError as e:
            raise e.in_file(path) from None

    @staticmethod
    def _build(values: dict[str, Any], scene: Any) -> "NodeConfig":
        cfg = NodeConfig(dict(values), scene)
        cfg._check_input()
        cfg._built.update(mounting=cfg._mounting(), params=cfg._platform_params())
        cfg._built["options"] = opts = cfg._model_options()
        cfg._built["gate"] = cfg._gate_config(bool(opts.effects & NEEDS_SPECIFIC_FORCE))
        return cfg

    def with_changes(self, changes: Mapping[str, Any]) -> "NodeConfig":
        """Copy with ``changes`` (validated; ConfigError names the first bad parameter)."""
        values = dict(self.values)
        for k, v in changes.items():
            if k not in SPECS:
                raise ConfigError(k, "unknown parameter")
            values[k] = SPECS[k].coerce(v)
        return NodeConfig._build(values, self.scene)

    # ---- derived objects ------------------------------------------------------------
    def _check_input(self) -> None:
        """The input topic is a name rcl accepts and none of the node's own topics (a
        subscription on ``drift/angle`` would take the node's outputs as its input, with another
        type); a Twist, which has no header, cannot be timed by header stamps."""
        param = "imu_topic" if self["input_type"] == "imu" else "twist_topic"
        try:
            name = expand_topic_name(self[param], NODE_NAME)
        except NameError_ as e:
            raise ConfigError(param, str(e)) from None
        own = {*output_topics(""), "/tf", "/tf_static", "/robot_description"}
        if name in own:
            raise ConfigError(param, f"{name} is one of the node's own output topics; choose another input topic")
        if self["input_type"] == "twist" and self["gate.time_source"] == "header":
            raise ConfigError("gate.time_source", "'header' cannot time input_type 'twist' (geometry_msgs/Twist has "
                                                  "no header); use auto or receive, or input_type twist_stamped")

    @property
    def input_type_name(self) -> str:
        """ROS type of the input (``sensor_msgs/msg/Imu`` …)."""
        return INPUT_TYPES[self["input_type"]]

    @property
    def input_topic(self) -> str:
        return self["imu_topic"] if self["input_type"] == "imu" else self["twist_topic"]

    @property
    def gate(self) -> GateConfig:
        return self._built["gate"]

    @property
    def mounting(self) -> Mounting:
        return self._built["mounting"]

    @property
    def params(self) -> PlatformParams:
        return self._built["params"]

    @property
    def options(self) -> ModelOptions:
        return self._built["options"]

    def _gate_config(self, needs_force: bool) -> GateConfig:
        """The gate of the node: a sample without the specific force the model needs is dropped
        (``no_specific_force``) before it reaches the time base; a reset re-anchors the time
        origin (a reset is a fresh start of the core)."""
        kw = {k: self[f"gate.{k}"] for k in ("max_gap", "on_gap", "reset_on_jump_back", "max_rate",
                                             "max_specific_force", "time_source")}
        try:
            return GateConfig(**kw, require_specific_force=needs_force, rebase_on_reset=True)
        except ValueError as e:
            name = str(e).split(" ", 1)[0]
            raise ConfigError(f"gate.{name}" if f"gate.{name}" in SPECS else "gate", str(e)) from None

    def _mounting(self) -> Mounting:
        """The sensor mountings; with a ``frame_prefix`` (a namespaced robot: its drivers and
        robot_state_publisher stamp ``robot1/imu_link``) each mounted frame and the vehicle frame
        also under the prefixed name (they were taken as base_link: the rotation dropped)."""
        try:
            vehicle = self["vehicle_frame"]
            frames = Mounting.parse_specs(self["sensor_mountings"], vehicle)
            prefix = self["frame_prefix"].lstrip("/")
            if prefix:
                frames.update({prefix + f: r for f, r in frames.items()
                               if not f.startswith(prefix) and prefix + f not in frames})
            m = Mounting(frames, vehicle_frame=vehicle, unknown_frame=self["unknown_frame"])
            if prefix and not vehicle.startswith(prefix):
                m.add(prefix + vehicle, (0.0, 0.0, 0.0, 1.0))
            return m
        except ValueError as e:
            raise ConfigError("sensor_mountings", str(e)) from None

    def _platform_params(self) -> PlatformParams:
        kw = {k[len(PHYSICS_PREFIX):]: v for k, v in self.values.items() if k.startswith(PHYSICS_PREFIX)}
        try:
            return PlatformParams.from_dict(kw)
        except ParameterError as e:
            name = str(e).split("'")[1].split("[")[0] if "'" in str(e) else ""
            raise ConfigError(PHYSICS_PREFIX + name if PHYSICS_PREFIX + name in SPECS else "physics", str(e)) from None

    def _model_options(self) -> ModelOptions:
        mode = self["mode"]
        eff: list[str] = []
        names = self["effects"]
        if "none" in names and len(names) > 1:
            raise ConfigError("effects", "'none' must be the only entry")
        for e in names:
            for n in (sorted(DEFAULT_EFFECTS[mode]) if e == "defaults" else [] if e == "none" else [e]):
                if n not in eff:
                    eff.append(n)
        kw: dict[str, Any] = {"integrator": self["integrator"], "max_step": self["max_step"]}
        if self.scene is not None:
            kw.update(rtol=self.scene.options.rtol, atol=self.scene.options.atol)
        try:
            opts = ModelOptions.make(mode, None if self["fidelity"] == "auto" else self["fidelity"], eff, **kw)
        except OptionsError as e:
            name = str(e).split("'")[1] if "'" in str(e) else "effects"
            raise ConfigError(name if name in SPECS else "effects", str(e)) from None
        if opts.fidelity == "precession":          # the refusal a scene gives, before any simulator exists
            from ..errors import PrecessionInvalidError
            from ..physics.model import check_precession_valid

            try:
                check_precession_valid(self.params, opts)
            except PrecessionInvalidError as e:
                raise ConfigError("fidelity", str(e)) from None
        need = sorted(opts.effects & NEEDS_SPECIFIC_FORCE)
        if need and self["input_type"] != "imu":
            raise ConfigError("effects", f"{need} need the specific force, which input_type "
                                         f"'{self['input_type']}' does not carry (use input_type imu)")
        return opts


__all__ = ["NodeConfig", "load_params_file", "parameter_defaults", "resolve_scene", "load_node_scene",
           "scene_defaults", "ROS_STANDARD_PARAMETERS", "ROS_STANDARD_PREFIXES", "unknown_parameter_lines"]
