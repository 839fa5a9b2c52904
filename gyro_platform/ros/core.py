"""Transport-independent core of the platform node (ROS-free).

The rclpy node (:mod:`gyro_platform.ros.node`) and a plain-DDS adapter are thin shells around
:class:`NodeCore`: they hand it every input message with its receive time and publish what it
returns. The core owns the input gate (:class:`~gyro_platform.io.gate.TimeGate`), the
:class:`~gyro_platform.engine.simulator.Simulator`, the output-rate grid, the callback timing and the
counters; it never raises on input data (every bad sample is counted in the diagnostics).

* :data:`PARAMETERS` — every node parameter (name, type, default, unit, range or choices,
  description, read-only/live): the single source of the rclpy parameter descriptors, of the
  default params file and of the README table (:func:`parameters_markdown`).
* :class:`NodeConfig` — validated parameter values; :meth:`NodeConfig.from_ros_params` takes the
  ``ros__parameters`` mapping of a params file, :meth:`NodeConfig.from_yaml` a whole params file.
* ``scene`` — a scene file (``config/scenes/*.yaml``) supplies the *defaults* of the model
  parameters (``mode``, ``fidelity``, ``effects``, ``integrator``, ``max_step``,
  ``output_rate``, ``physics.*``); values set explicitly (params file, ``-p``) override them.
  The scene's motion is not used: the vehicle motion is the input topic.

Topic names returned by :meth:`NodeCore.on_message` are relative to the node namespace
(``gimbal/joint_states`` …), as in the topic table of :mod:`gyro_platform.io.messages`; rclpy
resolves them itself, other transports with ``messages.resolve(name, namespace)``. Output
messages are stamped with the sample time (the input header stamp, or the receive time when the
stamps are not set); diagnostics with the ``now_ns`` the caller passes.
"""
from __future__ import annotations

import difflib
import math
import time
from collections import Counter, deque
from dataclasses import dataclass, field, fields as dc_fields
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..io import messages as msgs
from ..io.messages import IMU, TWIST, TWIST_STAMPED, MessageTypes, Mounting
from ..physics.options import DEFAULT_EFFECTS, DEFAULT_FIDELITY, EFFECTS, FIDELITIES, MODES, NEEDS_SPECIFIC_FORCE, ModelOptions, OptionsError
from ..physics.params import NAV1, ParameterError, PlatformParams
from ..pipeline import apply_decision, grid_index
from ..io.gate import NS, GateConfig, TimeGate

NODE_NAME = "gyro_platform_node"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: input_type parameter value -> ROS message type
INPUT_TYPES: dict[str, str] = {"imu": IMU, "twist": TWIST, "twist_stamped": TWIST_STAMPED}
#: parameters every rclpy node (or a library it uses) declares itself; accepted and ignored here
ROS_STANDARD_PARAMETERS = ("use_sim_time", "start_type_description_service", "diagnostic_updater.period")
ROS_STANDARD_PREFIXES = ("qos_overrides.",)
#: gimbal-lock proximity: WARN when min |cos| of the inner gimbal angles falls below this
GIMBAL_LOCK_WARN = 0.1
#: real-time margin (1 − callback time / input period) below which diagnostics WARN
MARGIN_WARN = 0.2
#: how long (s of the caller's clock) a rejected sample or an internal error keeps the status raised
RECENT_S = 10.0


class ConfigError(ValueError):
    """A parameter value is invalid; ``parameter`` names it, the message says what is allowed."""

    def __init__(self, parameter: str, message: str):
        super().__init__(f"parameter '{parameter}': {message}")
        self.parameter = parameter


# =========================================================================================
# parameters
# =========================================================================================
@dataclass(frozen=True)
class ParamSpec:
    """One node parameter. ``type``: ``bool``, ``double``, ``string``, ``double[]`` or
    ``string[]`` (the ROS parameter type); ``range``: inclusive (lo, hi) of a double;
    ``choices``: allowed strings (each element of a ``string[]``); ``length``: of a ``double[]``;
    ``read_only``: fixed after start (structure), else live (applied without restart)."""

    name: str
    type: str
    default: Any
    description: str
    unit: str = ""
    range: tuple[float, float] | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None
    read_only: bool = False

    @property
    def live(self) -> bool:
        """True when a change is applied at once, without restarting the node."""
        return not self.read_only

    def constraints(self) -> str:
        """Human-readable range / choices / length (for descriptors and the README)."""
        if self.choices:
            return "one of: " + ", ".join(self.choices)
        if self.range:
            return f"[{_num(self.range[0])}, {_num(self.range[1])}]"
        if self.length:
            return f"{self.length} values"
        return ""

    def coerce(self, value: Any) -> Any:
        """Validated value (tuples for arrays) or ConfigError naming the parameter. Types are
        strict, as in rclpy: a double must be written ``10.0``, not ``10``."""
        t, v = self.type, value
        if t == "bool":
            if not isinstance(v, bool):
                self._fail(f"expected true or false, got {v!r}")
            return v
        if t == "double":
            x = self._double(v, "a double")
            if self.range and not (self.range[0] <= x <= self.range[1]):
                self._fail(f"{_num(x)}{' ' + self.unit if self.unit else ''} is outside the allowed range "
                           f"[{_num(self.range[0])}, {_num(self.range[1])}]")
            return x
        if t == "string":
            if not isinstance(v, str):
                self._fail(f"expected a string, got {v!r}")
            if self.choices and v not in self.choices:
                self._fail(f"{v!r} is not allowed; allowed: {', '.join(self.choices)}")
            return v
        if t == "double[]":
            if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
                self._fail(f"expected a list of {self.length or ''} doubles, got {v!r}".replace("  ", " "))
            out = tuple(self._double(x, "doubles (write 0.0, not 0)") for x in v)
            if self.length is not None and len(out) != self.length:
                self._fail(f"expected {self.length} values, got {len(out)}")
            return out
        if t == "string[]":
            if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
                self._fail(f"expected a list of strings, got {v!r}")
            out = tuple(v)
            for x in out:
                if not isinstance(x, str):
                    self._fail(f"expected a list of strings, got element {x!r}")
                if self.choices and x not in self.choices:
                    self._fail(f"{x!r} is not allowed; allowed: {', '.join(self.choices)}")
            return out
        raise AssertionError(f"unknown parameter type {t}")

    def _double(self, v: Any, what: str) -> float:
        if isinstance(v, bool) or not isinstance(v, float):
            if isinstance(v, int) and not isinstance(v, bool):
                self._fail(f"expected {what}, got the integer {v} (write {v}.0)")
            self._fail(f"expected {what}, got {type(v).__name__} {v!r}")
        x = float(v)
        if not math.isfinite(x):
            self._fail(f"expected a finite number, got {x}")
        return x

    def _fail(self, message: str):
        raise ConfigError(self.name, message)


def _num(x: float) -> str:
    return f"{x:g}"


#: PlatformParams field -> (unit, description); physics.<field> parameters
PHYSICS_DOCS: dict[str, tuple[str, str]] = {
    "rotor_C": ("kg m²", "axial moments of inertia C of rotors 6, 8, 11"),
    "rotor_A": ("kg m²", "equatorial moments of inertia A of rotors 6, 8, 11"),
    "rotor_speed": ("rad/s", "spin speeds of rotors 6, 8, 11 relative to their housings"),
    "housing5": ("kg m²", "principal moments (x, y, z) of housing 5 without its rotor"),
    "housing7": ("kg m²", "principal moments (x, y, z) of housing 7 without its rotor"),
    "housing10": ("kg m²", "principal moments (x, y, z) of housing 10 without its rotor"),
    "frame4": ("kg m²", "principal moments (x, y, z) of gimbal frame 4"),
    "frame9": ("kg m²", "principal moments (x, y, z) of gimbal frame 9"),
    "platform": ("kg m²", "platform inertia tensor P11, P22, P33, P12, P13, P23 (P12 = −∫xy dm)"),
    "spring": ("N m/rad", "restraint springs on alpha4, beta5, beta7, alpha9, beta10 (effect gimbal_springs)"),
    "damper": ("N m s/rad", "viscous dampers per gimbal (effect gimbal_dampers)"),
    "gimbal_coulomb": ("N m", "Coulomb friction per gimbal (effect gimbal_friction)"),
    "gimbal_viscous_friction": ("N m s/rad", "viscous friction per gimbal (effect gimbal_friction)"),
    "bias_torque": ("N m", "constant gimbal torques per gimbal (effect bias_torque)"),
    "friction_rate_eps": ("rad/s", "rate that regularises sign() in the gimbal Coulomb friction"),
    "support_rate_eps": ("rad/s", "rate that regularises sign() in the support Coulomb friction"),
    "servo_kp": ("N m/rad", "platform servo proportional gain (effect servo)"),
    "servo_kd": ("N m s/rad", "platform servo derivative gain (effect servo)"),
    "servo_ki": ("N m/(rad s)", "platform servo integral gain (effect servo)"),
    "servo_limit": ("N m", "platform servo torque saturation (effect servo)"),
    "support_viscous": ("N m s/rad", "platform mount viscous friction (effect support_friction)"),
    "support_coulomb": ("N m", "platform mount Coulomb friction (effect support_friction)"),
    "gyro_mass": ("kg", "mass of each housing + rotor assembly (g-sensitive effects)"),
    "unbalance": ("m", "CG offset along the spin axis (effect mass_unbalance)"),
    "anisoelastic": ("m/N", "compliance along minus across the spin axis (effect anisoelastic)"),
    "latitude": ("rad", "latitude (effect earth_rate)"),
    "earth_rate": ("rad/s", "Earth rotation rate (effect earth_rate)"),
    "mounting": ("", "vehicle → platform rotation, quaternion x, y, z, w (carried mode, mount zero)"),
}
#: physics parameters applied live (servo gains); every other physics.* is read-only
LIVE_PHYSICS = {"servo_kp": (0.0, 1e9), "servo_kd": (0.0, 1e9), "servo_ki": (0.0, 1e9),
                "servo_limit": (1e-9, 1e6)}
#: ranges (inclusive) of the other scalar physics parameters: those ``params.validate`` enforces
#: (an open bound 0 becomes 1e-12), so ``ros2 param describe`` shows them as FloatingPointRange
PHYSICS_RANGES = {"friction_rate_eps": (1e-12, 1.0), "support_rate_eps": (1e-12, 1.0),
                  "support_viscous": (0.0, 1e9), "support_coulomb": (0.0, 1e9), "gyro_mass": (0.0, 1e9),
                  "unbalance": (-1.0, 1e9), "anisoelastic": (0.0, 1e9),
                  "latitude": (-math.pi / 2, math.pi / 2), "earth_rate": (0.0, 1e-2)}
PHYSICS_PREFIX = "physics."


def _integrators() -> tuple[str, ...]:
    from ..engine.integrators import INTEGRATORS

    return ("auto", *INTEGRATORS)


def _physics_specs() -> list[ParamSpec]:
    specs = []
    for f in dc_fields(PlatformParams):
        unit, doc = PHYSICS_DOCS.get(f.name, ("", f"PlatformParams.{f.name}"))
        default = getattr(NAV1, f.name)
        if isinstance(default, tuple):
            specs.append(ParamSpec(PHYSICS_PREFIX + f.name, "double[]", tuple(float(x) for x in default), doc,
                                   unit, length=len(default), read_only=True))
        else:
            live = f.name in LIVE_PHYSICS
            specs.append(ParamSpec(PHYSICS_PREFIX + f.name, "double", float(default), doc, unit,
                                   range=LIVE_PHYSICS.get(f.name) or PHYSICS_RANGES.get(f.name), read_only=not live))
    return specs


PARAMETERS: list[ParamSpec] = [
    # -- input
    ParamSpec("input_type", "string", "imu",
              "input message: sensor_msgs/Imu on imu_topic, geometry_msgs/Twist or TwistStamped on twist_topic",
              choices=tuple(INPUT_TYPES), read_only=True),
    ParamSpec("imu_topic", "string", "imu", "Imu input topic (relative to the node namespace)", read_only=True),
    ParamSpec("twist_topic", "string", "twist", "Twist / TwistStamped input topic", read_only=True),
    ParamSpec("vehicle_frame", "string", msgs.VEHICLE_FRAME,
              "vehicle body frame (FLU); input frames are rotated into it", read_only=True),
    ParamSpec("sensor_mountings", "string[]", (),
              "sensor frames in vehicle_frame: 'FRAME=qx,qy,qz,qw' or 'FRAME=roll,pitch,yaw' (rad, URDF rpy)"),
    ParamSpec("unknown_frame", "string", "identity",
              "input frame_id without mounting: take it as vehicle_frame (counted) or drop the sample",
              choices=Mounting.UNKNOWN_POLICIES),
    # -- time base / gate
    ParamSpec("gate.time_source", "string", "auto",
              "sample time: header stamp, receive time (node clock), or auto (header unless the first stamp is 0)",
              choices=("auto", "header", "receive"), read_only=True),
    ParamSpec("gate.max_gap", "double", GateConfig.max_gap, "longest input gap before on_gap applies", "s",
              range=(1e-3, 3600.0)),
    ParamSpec("gate.on_gap", "string", GateConfig.on_gap,
              "after a longer gap: restart the simulation or integrate across it", choices=("reset", "integrate")),
    ParamSpec("gate.reset_on_jump_back", "double", GateConfig.reset_on_jump_back,
              "stamps jumping back by more than this restart the simulation; smaller steps back are dropped", "s",
              range=(0.0, 3600.0)),
    ParamSpec("gate.max_rate", "double", GateConfig.max_rate, "samples with a rate norm ‖ω‖ above this are dropped",
              "rad/s", range=(1e-3, 1e4)),
    ParamSpec("reset_on_clock_jump", "bool", True,
              "reset when the node clock jumps back (looped 'ros2 bag play --clock --loop')"),
    # -- outputs
    ParamSpec("output_rate", "double", 10.0,
              "rate of the output topics on the sample-time grid; 0 = after every accepted sample", "Hz",
              range=(0.0, 1e4)),
    ParamSpec("diagnostics_rate", "double", 1.0, "rate of /diagnostics (node clock)", "Hz",
              range=(0.01, 100.0), read_only=True),
    ParamSpec("frame_prefix", "string", "",
              "prefix of the output frame ids (e.g. 'robot1/' gives 'robot1/platform')", read_only=True),
    # -- model
    ParamSpec("scene", "string", "",
              "scene file (path or name in config/scenes) supplying the model defaults; its motion is not used",
              read_only=True),
    ParamSpec("mode", "string", "stabilised", "platform mode", choices=MODES, read_only=True),
    ParamSpec("fidelity", "string", "auto", "model fidelity; auto: the mode's default ("
              + ", ".join(f"{f} when {m}" for m, f in DEFAULT_FIDELITY.items()) + ")",
              choices=("auto", *FIDELITIES), read_only=True),
    ParamSpec("effects", "string[]", ("defaults",),
              "effects switched on; 'defaults' = the mode's default set, 'none' alone = no effect",
              choices=("defaults", "none", *EFFECTS)),
    ParamSpec("integrator", "string", "auto", "integrator (auto: by mode and fidelity)", choices=_integrators(),
              read_only=True),
    ParamSpec("max_step", "double", 1e-3, "largest internal step of the fixed-step integrators", "s",
              range=(1e-6, 1.0), read_only=True),
    *_physics_specs(),
]
SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}
#: model parameters whose defaults a scene supplies
SCENE_KEYS = ("mode", "fidelity", "effects", "integrator", "max_step", "output_rate",
              *(p.name for p in PARAMETERS if p.name.startswith(PHYSICS_PREFIX)))


def parameters_markdown() -> str:
    """The parameter table of the README (generated from :data:`PARAMETERS`)."""
    rows = ["| parameter | type | default | unit | range / choices | live | description |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    for p in PARAMETERS:
        rows.append(f"| `{p.name}` | {p.type} | `{_fmt_default(p.default)}` | {p.unit or '-'} | "
                    f"{p.constraints() or '-'} | {'yes' if p.live else 'no (read-only)'} | {p.description} |")
    return "\n".join(rows) + "\n"


def topics_markdown() -> str:
    """The topic table of the README: name, direction, type, units, frame, QoS (from
    ``messages.TOPICS``; input names are the defaults of ``imu_topic`` / ``twist_topic``)."""
    rows = ["| topic | dir | type | units | frame | QoS |", "| --- | --- | --- | --- | --- | --- |"]
    for t in msgs.TOPICS:
        if t.direction == "in":
            typ = ("`sensor_msgs/msg/Imu`" if t.type == IMU
                   else "`geometry_msgs/msg/Twist` or `geometry_msgs/msg/TwistStamped` (input_type)")
            name = f"`{t.name}` (param `{'imu_topic' if t.type == IMU else 'twist_topic'}`)"
            qos = "sensor data: best effort, keep last 5, volatile"
        else:
            typ, name = f"`{t.type}`", f"`{t.name}`"
            qos = "reliable, keep last 10, volatile"
        rows.append(f"| {name} | {t.direction} | {typ} | {t.units} | {t.frame or '-'} | {qos} |")
    rows += [  # robot_state_publisher's under rclpy (launch file), the node's own on DDS
        "| `robot_description` | out | `std_msgs/msg/String` | URDF (gyro_platform.io.urdf) | - | reliable, keep last 1, "
        "transient local |",
        "| `/tf` | out | `tf2_msgs/msg/TFMessage` | m, quaternion | every moving joint: parent → child link | "
        "reliable, keep last 100, volatile |",
        "| `/tf_static` | out | `tf2_msgs/msg/TFMessage` | m, quaternion | fixed joints | reliable, keep last 1, "
        "transient local |",
    ]
    return "\n".join(rows) + "\n"


def _fmt_default(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        s = f"{v:.6g}"
        return s if any(c in s for c in ".ein") else s + ".0"
    if isinstance(v, tuple):
        return "[" + ", ".join(_fmt_default(x) if not isinstance(x, str) else x for x in v) + "]"
    return str(v) if v != "" else '""'


def _yaml_value(v: Any) -> str:
    """A value as a YAML literal that rcl's parser and PyYAML read back with the same type."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        r = repr(v)
        if "e" in r:
            mant, exp = r.split("e")
            r = (mant if "." in mant else mant + ".0") + "e" + (exp if exp[0] in "+-" else "+" + exp)
        return r
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_yaml_value(x) for x in v) + "]"
    return '""' if v == "" else (f'"{v}"' if any(c in v for c in ":#{}[],&*!|>'%@`") else v)


def params_yaml(node_key: str = "/**") -> str:
    """A params file with every parameter and its documentation (``config/platform.yaml`` was
    made with it; dotted names are written nested, ``gate: {max_gap: …}``). Model parameters a
    scene supplies are written commented out, so that a ``scene`` given at launch is not
    overridden by this file."""
    lines = [
        "# gyro_platform node parameters (generated by gyro_platform.ros.core.params_yaml; see README.md, ROS 2 node).",
        "# Types are strict (ROS 2): write doubles with a decimal point (10.0, 1.0e-07).",
        "# 'live' parameters can be changed while running (ros2 param set); read-only ones need a restart.",
        "# Lines commented out are model parameters whose default comes from the `scene` when one is",
        "# set (else the value shown); uncomment a line (and its group line, e.g. 'physics:') to",
        "# override the scene.",
        f"{node_key}:",
        "  ros__parameters:",
    ]
    group = None
    for p in PARAMETERS:
        prefix, _, key = p.name.rpartition(".")
        off = p.name in SCENE_KEYS or (p.type == "string[]" and not p.default)
        if prefix != group:
            group = prefix
            if prefix:
                lines.append(f"    {'# ' if off else ''}{prefix}:")
        ind = "      " if prefix else "    "
        unit = f" [{p.unit}]" if p.unit else ""
        cons = p.constraints()
        lines.append(f"{ind}# {p.description}{unit}" + (f"; {cons}" if cons else "")
                     + ("; live" if p.live else "; read-only"))
        if p.type == "string[]" and not p.default:
            lines.append(f'{ind}# {key}: ["imu_link=0.0,0.0,0.0,1.0"]   # empty by default: omit it rather than []')
        else:
            value = _yaml_value(list(p.default) if isinstance(p.default, tuple) else p.default)
            lines.append(f"{ind}{'# ' if off else ''}{key}: {value}")
    return "\n".join(lines) + "\n"


# =========================================================================================
# scenes
# =========================================================================================
def scene_dirs() -> list[Path]:
    """Folders searched for a scene given by name (see ``scene.scene_dirs``)."""
    from ..scenes.schema import scene_dirs as dirs

    return dirs()


def resolve_scene(name: str) -> Path:
    """Path of a scene given as a path or by name (``scene.find_scene``); ConfigError if none."""
    from ..scenes.schema import ScenarioError, find_scene

    try:
        return find_scene(name)
    except ScenarioError as e:
        raise ConfigError("scene", str(e)) from None


def load_node_scene(name: str):
    """Load a scene for the node: as ``scene.load_scene`` but a ``bag`` motion (whose bag the
    node does not need) is replaced by a zero rate, so a missing bag does not stop the node."""
    import yaml

    from ..scenes.schema import ScenarioError, scene_from_dict

    path = resolve_scene(name)
    try:
        data = yaml.safe_load(path.read_text())
        if isinstance(data, dict) and isinstance(data.get("motion"), dict) and data["motion"].get("type") == "bag":
            data = {**data, "motion": {"type": "constant", "omega": [0.0, 0.0, 0.0]}}
        return scene_from_dict(data, source=path.name, base_dir=path.resolve().parent, default_name=path.stem,
                               path=path)
    except (OSError, yaml.YAMLError, ScenarioError) as e:
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
def _flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _is_ros_standard(name: str) -> bool:
    return name in ROS_STANDARD_PARAMETERS or name.startswith(ROS_STANDARD_PREFIXES)


def load_params_file(path: str | Path, node_name: str = NODE_NAME) -> dict[str, Any]:
    """Flattened ``ros__parameters`` of a params file for one node: the ``/**`` section first,
    then the sections whose last name is ``node_name`` (``gyro_platform_node``,
    ``/ns/gyro_platform_node``), later ones overriding — as rcl merges them."""
    import yaml

    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError("params_file", f"{path}: {e}") from None
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
        merged.update(_flatten(sec["ros__parameters"] or {}))
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
        flat = _flatten(d or {})
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
        """Config from a params file (sections selected by ``load_params_file``)."""
        return NodeConfig.from_ros_params(load_params_file(path, node_name))

    @staticmethod
    def _build(values: dict[str, Any], scene: Any) -> "NodeConfig":
        cfg = NodeConfig(dict(values), scene)
        cfg._built.update(gate=cfg._gate_config(), mounting=cfg._mounting(), params=cfg._platform_params())
        cfg._built["options"] = cfg._model_options()
        return cfg

    def with_changes(self, changes: Mapping[str, Any]) -> "NodeConfig":
        """Copy with ``changes`` (validated; ConfigError names the first bad parameter)."""
        values = dict(self.values)
        for k, v in changes.items():
            if k not in SPECS:
                raise ConfigError(k, "unknown parameter")
            values[k] = SPECS[k].coerce(v)
        return NodeConfig._build(values, self.scene)

    def as_ros_params(self) -> dict[str, Any]:
        """Plain ``name -> value`` (lists for arrays), as a params file would hold them."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.values.items()}

    # ---- derived objects ------------------------------------------------------------
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

    def _gate_config(self) -> GateConfig:
        kw = {k: self[f"gate.{k}"] for k in ("max_gap", "on_gap", "reset_on_jump_back", "max_rate", "time_source")}
        try:
            return GateConfig(**kw)
        except ValueError as e:
            name = str(e).split(" ", 1)[0]
            raise ConfigError(f"gate.{name}" if f"gate.{name}" in SPECS else "gate", str(e)) from None

    def _mounting(self) -> Mounting:
        try:
            frames = dict(Mounting.parse_spec(s) for s in self["sensor_mountings"])
            return Mounting(frames, vehicle_frame=self["vehicle_frame"], unknown_frame=self["unknown_frame"])
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
        need = sorted(opts.effects & NEEDS_SPECIFIC_FORCE)
        if need and self["input_type"] != "imu":
            raise ConfigError("effects", f"{need} need the specific force, which input_type "
                                         f"'{self['input_type']}' does not carry (use input_type imu)")
        return opts


# =========================================================================================
# the core
# =========================================================================================
@dataclass
class _Timing:
    """Per-message processing time (ns, the core's clock) against the input period."""

    ema_ns: float | None = None
    max_ns: int = 0
    last_ns: int = 0
    n: int = 0

    def add(self, dt: int, a: float = 0.05) -> None:
        self.n += 1
        self.last_ns = dt
        self.max_ns = max(self.max_ns, dt)
        self.ema_ns = float(dt) if self.ema_ns is None else self.ema_ns + a * (dt - self.ema_ns)


class InputLoss:
    """Input samples lost before the node took them: reported by the transport (rclpy QoS
    message-lost events, DDS queue overwrites) and inferred from gaps in the input stamps.

    Stamp gaps: the nominal input period is the mean of the single steps among the last
    ``WINDOW`` stamp steps of accepted samples, single = shorter than 1.5 × their lower quartile
    (robust while fewer than ~3/4 of the steps span a loss, and unbiased by jitter); a step of
    ``k`` nominal periods (``k`` ≥ 2, rounded) counts ``k − 1`` missing samples. Longer gaps than ``max_gap`` are the
    gate's (a pause, not an overload) and are not counted."""

    WINDOW = 64

    def __init__(self) -> None:
        self.transport = 0                 # samples the transport says it lost
        self.stamp_gaps = 0                # samples missing between consecutive stamps
        self.last_rx_ns: int | None = None  # receive time of the last loss (node clock)
        self._steps: deque[int] = deque(maxlen=self.WINDOW)
        self._last_stamp: int | None = None

    @property
    def total(self) -> int:
        return self.transport + self.stamp_gaps

    def on_transport_loss(self, count: int, rx_ns: int | None) -> None:
        if count > 0:
            self.transport += int(count)
            self.last_rx_ns = rx_ns

    def on_stamp(self, stamp_ns: int, rx_ns: int | None, max_gap_s: float) -> None:
        last, self._last_stamp = self._last_stamp, stamp_ns
        if last is None or stamp_ns <= last:
            return
        step = stamp_ns - last
        if len(self._steps) >= 8 and step <= max_gap_s * NS:
            steps = np.fromiter(self._steps, float)
            q = float(np.percentile(steps, 25))
            period = float(np.mean(steps[steps < 1.5 * q]))      # mean of the single steps
            k = int(round(step / period)) if period > 0 else 1
            if k >= 2:
                self.stamp_gaps += k - 1
                self.last_rx_ns = rx_ns
        self._steps.append(step)

    def restart(self) -> None:
        """A new time base (reset): stamp steps across it are not gaps."""
        self._steps.clear()
        self._last_stamp = None


class NodeCore:
    """Input message → gate → simulator → output messages, with diagnostics and parameters.

    ``types``: the binding's message classes (``MessageTypes.rosbags()`` or ``.rclpy()``);
    ``clock_ns``: the wall clock used to time callbacks (default ``time.perf_counter_ns``).
    """

    def __init__(self, config: NodeConfig, types: MessageTypes, *,
                 clock_ns: Callable[[], int] = time.perf_counter_ns):
        from ..engine.simulator import Simulator

        self._Simulator = Simulator
        self.config = config
        self.types = types
        self._clock_ns = clock_ns
        self.gate = TimeGate(config.gate)
        self.sim = Simulator(config.params, config.options)
        self.timing = _Timing()
        self.outcomes: Counter[str] = Counter()     # apply_decision results + output_failed
        self.resets: Counter[str] = Counter()       # reset reason -> count (core resets and gate resets)
        self.clock_jumps: Counter[str] = Counter()  # "back" / "forward"
        self.received = 0
        self.published = 0                          # output instants published
        self.internal_errors = 0
        self.identity_frames: set[str] = set()      # input frames without mounting, taken as base_link
        self.notices: list[str] = []                # one-time INFO lines for the transport to log
        self.parameter_changes = 0
        self.last_error: str | None = None
        self.last_reset_reason: str | None = None
        self.last_out = None
        self._slot: int | None = None
        self._last_rx_ns: int | None = None
        self._last_rejected_rx: int | None = None
        self._last_error_rx: int | None = None
        self.loss = InputLoss()

    # ---- topics ---------------------------------------------------------------------
    @property
    def input_topic(self) -> str:
        return self.config.input_topic

    @property
    def input_type(self) -> str:
        """ROS type name of the input topic."""
        return self.config.input_type_name

    def input_topics(self) -> dict[str, str]:
        """Input topic (relative to the node namespace) → ROS type: the one subscription."""
        return {self.input_topic: self.input_type}

    @staticmethod
    def output_topics(with_diagnostics: bool = False) -> dict[str, str]:
        """Output topic → ROS type, names relative to the node namespace as :meth:`on_message`
        returns them (``gimbal/joint_states`` …); ``/diagnostics`` (absolute) only if asked."""
        return {(t if t == DIAGNOSTICS_TOPIC else t.lstrip("/")): typ for t, typ in msgs.output_topics("").items()
                if with_diagnostics or t != DIAGNOSTICS_TOPIC}

    # ---- input ----------------------------------------------------------------------
    def on_message(self, msg: Any, receive_ns: int | None) -> list[tuple[str, Any]]:
        """Process one input message received at ``receive_ns`` (node clock, ns; None or ≤ 0 =
        unknown). Returns the ``(topic, message)`` pairs to publish now: the outputs when the
        sample starts a new slot of the output grid, else nothing. Never raises."""
        t0 = self._clock_ns()
        self.received += 1
        rx = int(receive_ns) if receive_ns is not None and receive_ns > 0 else None
        if rx is not None:
            self._last_rx_ns = rx
        result: list[tuple[str, Any]] = []
        try:
            with np.errstate(all="ignore"):           # NaN/Inf input: the gate counts it, no warning spam
                reading = msgs.reading_from_msg(msg, self.config.mounting)
            if getattr(reading, "identity_assumed", False) and reading.frame_id not in self.identity_frames:
                self.identity_frames.add(reading.frame_id)
                self.notices.append(f"input frame '{reading.frame_id}' has no sensor mounting: taken as "
                                    "base_link (identity); counted as identity_frame in /diagnostics")
            decision = self.gate.offer(reading, rx)
            outcome = apply_decision(self.sim, decision)
            self.outcomes[outcome] += 1
            if outcome == "pushed" and self.gate.time_source == "header":   # receive times say nothing
                self.loss.on_stamp(decision.stamp_ns, rx if rx is not None else self._last_rx_ns,
                                   self.config["gate.max_gap"])
            if outcome in ("reset", "restarted"):
                self.loss.restart()
                self._slot = None
                reason = decision.reason if outcome == "reset" else "integration_failed"
                self.resets[reason] += 1
                self.last_reset_reason = reason
            if outcome in ("rejected", "restarted"):
                self._last_rejected_rx = rx if rx is not None else self._last_rx_ns
            if outcome in ("pushed", "reset", "restarted") and self._due(decision.stamp_ns):
                result = self._emit(decision.stamp_ns)
        except Exception as e:  # defensive: a message must never take the node down
            self.internal_errors += 1
            self.last_error = f"{type(e).__name__}: {e}"
            self._last_error_rx = rx if rx is not None else self._last_rx_ns
            result = []
        finally:
            self.timing.add(self._clock_ns() - t0)
        return result

    def take_notices(self) -> list[str]:
        """The one-time INFO lines gathered since the last call (the transport logs them)."""
        out, self.notices = self.notices, []
        return out

    def _due(self, stamp_ns: int) -> bool:
        if self.config["output_rate"] <= 0:
            return True
        slot = self._grid(stamp_ns)
        if self._slot is None or slot > self._slot:
            self._slot = slot
            return True
        return False

    def _grid(self, stamp_ns: int) -> int:
        return grid_index(stamp_ns, self.gate.origin_ns or 0, self.config["output_rate"])

    def _emit(self, stamp_ns: int) -> list[tuple[str, Any]]:
        from ..errors import SimulationError

        try:
            out = self.sim.outputs()
        except SimulationError as e:
            self.outcomes["output_failed"] += 1
            self.last_error = f"outputs failed: {e}"
            return []
        pairs = [(t.lstrip("/"), m) for t, m in msgs.output_messages(out, self.types, stamp_ns, "")]
        prefix = self.config["frame_prefix"]
        if prefix:
            for _, m in pairs:
                h = getattr(m, "header", None)
                if h is not None and h.frame_id:
                    h.frame_id = prefix + h.frame_id
        self.last_out = out
        self.published += 1
        return pairs

    # ---- control --------------------------------------------------------------------
    def reset(self, reason: str) -> None:
        """Restart the simulation and the time base (``~/reset`` service, clock jump back …);
        counters are kept, the reset is counted under ``reason``."""
        self.sim.reset()
        self.gate.restart()
        self.loss.restart()
        self._slot = None
        self.resets[reason] += 1
        self.last_reset_reason = reason

    def on_clock_jump(self, backward: bool, delta_ns: int | None = None) -> None:
        """The node clock jumped (``delta_ns`` if known). Backward: reset (reason
        ``clock_jump_back``) when ``reset_on_clock_jump`` is true."""
        self.clock_jumps["back" if backward else "forward"] += 1
        if backward and self.config["reset_on_clock_jump"]:
            self.reset("clock_jump_back")

    def set_parameters(self, changes: Mapping[str, Any]) -> tuple[bool, str]:
        """Validate and apply ``changes`` (name → value) atomically. Returns ``(True, "")`` or
        ``(False, reason)`` naming the parameter; read-only parameters are refused unless the
        value is unchanged. Live changes: gate limits, output rate, mountings, effects and
        servo gains (the simulator is rebuilt with the state carried over)."""
        try:
            for k, v in changes.items():
                spec = SPECS.get(k)
                if spec is None:
                    raise ConfigError(k, "unknown parameter")
                if spec.read_only and spec.coerce(v) != self.config[k]:
                    raise ConfigError(k, "is read-only (it fixes the structure of the node or model); "
                                         "restart the node to change it")
            new = self.config.with_changes(changes)
        except ConfigError as e:
            return False, str(e)
        old = self.config
        if new.params != old.params or new.options != old.options:
            try:
                sim = self._Simulator(new.params, new.options)
            except Exception as e:  # e.g. precession model invalid for these values
                return False, f"cannot rebuild the model: {e}"
            _carry_state(self.sim, sim)
            self.sim = sim
        if new.gate != old.gate:
            self.gate.config = new.gate
        self.config = new
        if new["output_rate"] != old["output_rate"]:
            last = self.gate.last_stamp_ns
            self._slot = self._grid(last) if (last is not None and new["output_rate"] > 0) else None
        self.parameter_changes += 1
        return True, ""

    # ---- diagnostics ----------------------------------------------------------------
    def real_time_margin(self) -> float | None:
        """1 − (mean callback time / input period): 0.8 = 20 % of each period used; < 0 = the
        node falls behind. None before the input period is known."""
        rate = self.gate.input_rate_hz or self.gate.accepted_rate_hz
        if not rate or self.timing.ema_ns is None:
            return None
        return 1.0 - self.timing.ema_ns * 1e-9 * rate

    def snapshot(self, now_ns: int | None = None) -> dict[str, Any]:
        """Counters and health figures (the content of the ``node`` diagnostics status)."""
        g = self.gate.snapshot()
        rate = self.gate.input_rate_hz or self.gate.accepted_rate_hz
        stats = self.sim.stats
        stamp_anomalies = {k: v for k, v in {**g["dropped_by_reason"], **g["resets_by_reason"]}.items()
                           if k in ("zero_stamp", "repeated_stamp", "backward_stamp", "jump_back", "gap", "no_time")}
        lock = None if self.last_out is None else self.last_out.status.get("gimbal_lock_margin")
        return {
            "input_topic": self.input_topic,
            "input_type": self.input_type,
            "messages": self.received,
            "accepted": g["accepted"],
            "dropped": g["dropped"],
            "dropped_by_reason": g["dropped_by_reason"],
            "stamp_anomalies": stamp_anomalies,
            "input_lost": self.loss.total,
            "input_lost_transport": self.loss.transport,
            "input_lost_stamp_gaps": self.loss.stamp_gaps,
            "simulator": dict(self.outcomes),
            "outputs_published": self.published,
            "output_rate_hz": self.config["output_rate"],
            "resets": sum(self.resets.values()),
            "resets_by_reason": dict(self.resets),
            "last_reset_reason": self.last_reset_reason,
            "clock_jumps": dict(self.clock_jumps),
            "integrator": stats["integrator"],
            "integrator_steps": stats["n_steps"],
            "integrator_error_estimate_max": stats["max_error_estimate"],
            "input_rate_hz": rate,
            "input_period_ms": None if not rate else 1e3 / rate,
            "callback_time_mean_ms": None if self.timing.ema_ns is None else self.timing.ema_ns * 1e-6,
            "callback_time_max_ms": self.timing.max_ns * 1e-6,
            "real_time_margin": self.real_time_margin(),
            "gimbal_lock_margin": lock,
            "since_last_input_s": (None if now_ns is None or self._last_rx_ns is None
                                   else (now_ns - self._last_rx_ns) / NS),
            "parameter_changes": self.parameter_changes,
            "internal_errors": self.internal_errors,
            "last_error": self.last_error,
        }

    def diagnostics(self, now_ns: int) -> Any:
        """``diagnostic_msgs/DiagnosticArray`` stamped ``now_ns`` (node clock) with statuses
        ``gyro_platform: input`` (gate counters by reason, input rate), ``gyro_platform:
        platform`` (outputs' status, integrator figures) and ``gyro_platform: node`` (see
        :meth:`snapshot`; ERROR when falling behind real time or after an internal error,
        WARN near gimbal lock, on a thin real-time margin or after a rejected sample, STALE
        before the first input or when none came for max_gap). No side effects."""
        stats = self.sim.stats
        extra = {"integrator": stats["integrator"], "n_samples": stats["n_samples"],
                 "integrator_steps": stats["n_steps"], "max_error_estimate": stats["max_error_estimate"],
                 "outputs_published": self.published}
        arr = msgs.diagnostic_array(self.gate.snapshot(), self.last_out, self.types, now_ns, extra)
        snap = self.snapshot(now_ns)
        level, message = self._node_level(snap, now_ns)
        cls = self.types["diagnostic_msgs/msg/DiagnosticStatus"]
        lvl = {0: cls.OK, 1: cls.WARN, 2: cls.ERROR, 3: cls.STALE}[level]
        items = [(k, "n/a" if v is None else v) for k, v in msgs._flatten(snap)]
        arr.status.append(cls(level=lvl, name=f"{msgs.HARDWARE_ID}: node", message=message,
                              hardware_id=msgs.HARDWARE_ID, values=msgs._key_values(self.types, items)))
        return arr

    def _node_level(self, snap: dict[str, Any], now_ns: int) -> tuple[int, str]:
        def recent(rx: int | None) -> bool:
            return rx is not None and (now_ns - rx) <= RECENT_S * NS

        if self.received == 0:
            return 3, "no input yet"
        since = snap["since_last_input_s"]
        if since is not None and since > self.config["gate.max_gap"]:
            return 3, f"no input for {since:.3g} s"
        margin = snap["real_time_margin"]
        if self.internal_errors and recent(self._last_error_rx):
            return 2, f"internal error: {self.last_error}"
        if margin is not None and margin < 0:
            return 2, f"falling behind real time (margin {margin:.2f})"
        lock = snap["gimbal_lock_margin"]
        if lock is not None and lock < GIMBAL_LOCK_WARN:
            return 1, f"near gimbal lock (min |cos| of inner gimbals {lock:.3g})"
        if recent(self.loss.last_rx_ns):
            return 1, (f"input overload: samples lost (transport {self.loss.transport}, stamp gaps "
                       f"{self.loss.stamp_gaps}); the node or its transport is slower than the input")
        if recent(self._last_rejected_rx):
            return 1, "simulator rejected or restarted a sample recently"
        if margin is not None and margin < MARGIN_WARN:
            return 1, f"thin real-time margin ({margin:.2f})"
        return 0, "ok"


def _carry_state(old: Any, new: Any) -> None:
    """Move the integration state of ``old`` into ``new`` (same mode and fidelity, hence the
    same state layout): used when live parameters rebuild the simulator."""
    if old.t_start is None or old.layout.n != new.layout.n:
        return
    new.y = old.y.copy()
    new.t_start = old.t_start
    new.t_rel = old.t_rel
    new._last = old._last
    new.n_samples = old.n_samples
    new.n_steps = old.n_steps
    new.max_error_estimate = old.max_error_estimate


__all__ = ["ConfigError", "ParamSpec", "PARAMETERS", "SPECS", "NodeConfig", "NodeCore", "parameters_markdown",
           "parameter_defaults", "resolve_scene", "load_node_scene", "scene_defaults", "INPUT_TYPES",
           "NODE_NAME", "DIAGNOSTICS_TOPIC", "ROS_STANDARD_PARAMETERS", "params_yaml", "topics_markdown"]
