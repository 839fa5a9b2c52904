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

"""The node's parameter schema: every parameter, its type, default, unit, range and description.

* :data:`PARAMETERS` — every node parameter (name, type, default, unit, range or choices,
  description, read-only/live) as a :class:`ParamSpec`: the single source of the rclpy parameter
  descriptors (:mod:`gyro_platform.ros.node`), of the validation in
  :class:`~gyro_platform.ros.config.NodeConfig`, of the default params file
  (:func:`params_yaml`, ``config/platform.yaml``) and of the README tables
  (:func:`parameters_markdown`, :func:`topics_markdown`).
* :class:`ConfigError` — a bad parameter value, naming the parameter.
"""
from __future__ import annotations

from dataclasses import dataclass
from dataclasses import fields as dc_fields
import math
from typing import Any

from .. import messages as msgs
from ..errors import not_finite
from ..messages import IMU, Mounting, TWIST, TWIST_STAMPED
from ..physics.options import DEFAULT_FIDELITY, EFFECTS, FIDELITIES, MODES, PARAM_EFFECTS
from ..physics.params import NAV1, PlatformParams
from ..pipeline.gate_rules import GateConfig

NODE_NAME = "gyro_platform_node"
#: input_type parameter value -> ROS message type
INPUT_TYPES: dict[str, str] = {"imu": IMU, "twist": TWIST, "twist_stamped": TWIST_STAMPED}


class ConfigError(ValueError):
    """A parameter value is invalid; ``parameter`` names it, the message says what is allowed."""

    def __init__(self, parameter: str, message: str):
        super().__init__(f"parameter '{parameter}': {message}")
        self.parameter = parameter
        self.message = message

    def in_file(self, path: Any) -> "ConfigError":
        """The same error naming the params file it came from (``params_file`` errors already do)."""
        if self.parameter == "params_file":
            return self
        return ConfigError(self.parameter, f"{self.message} (in {path})")


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
                self._fail(f"{_exact(x)}{' ' + self.unit if self.unit else ''} is outside the allowed range "
                           f"[{_exact(self.range[0])}, {_exact(self.range[1])}]")
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
        if not_finite(x):                   # the rule of every number (errors.not_finite)
            self._fail(not_finite(x))
        return x

    def _fail(self, message: str):
        raise ConfigError(self.name, message)


def _num(x: float) -> str:
    return f"{x:g}"


def _exact(x: float) -> str:
    """``x`` short where that is exact, else in full (a refusal of 1.5708 must not show a
    bound of 1.5708: it is π/2 = 1.5707963267948966)."""
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


#: PlatformParams field -> (unit, description); physics.<field> parameters (the effects that
#: read a field are added from ``physics.options.PARAM_EFFECTS``: :func:`physics_description`)
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
    "spring": ("N m/rad", "restraint springs on alpha4, beta5, beta7, alpha9, beta10"),
    "damper": ("N m s/rad", "viscous dampers per gimbal"),
    "gimbal_coulomb": ("N m", "Coulomb friction per gimbal"),
    "gimbal_viscous_friction": ("N m s/rad", "viscous friction per gimbal"),
    "bias_torque": ("N m", "constant gimbal torques per gimbal"),
    "friction_rate_eps": ("rad/s", "rate that regularises sign() in the gimbal Coulomb friction"),
    "support_rate_eps": ("rad/s", "rate that regularises sign() in the support Coulomb friction"),
    "servo_kp": ("N m/rad", "platform servo proportional gain"),
    "servo_kd": ("N m s/rad", "platform servo derivative gain"),
    "servo_ki": ("N m/(rad s)", "platform servo integral gain"),
    "servo_limit": ("N m", "platform servo torque saturation"),
    "support_viscous": ("N m s/rad", "platform mount viscous friction"),
    "support_coulomb": ("N m", "platform mount Coulomb friction"),
    "gyro_mass": ("kg", "mass of each housing + rotor assembly"),
    "unbalance": ("m", "CG offset along the spin axis"),
    "anisoelastic": ("m/N", "compliance along minus across the spin axis"),
    "latitude": ("rad", "latitude"),
    "earth_rate": ("rad/s", "Earth rotation rate"),
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
    from ..engine.integrators import INTEGRATOR_CHOICES

    return INTEGRATOR_CHOICES


def physics_description(name: str) -> str:
    """Description of ``physics.<name>``: its PHYSICS_DOCS text and the effects that read it."""
    doc = PHYSICS_DOCS.get(name, ("", f"PlatformParams.{name}"))[1]
    effects = sorted(PARAM_EFFECTS.get(name, ()))
    return doc + (f" (effect{'s' if len(effects) > 1 else ''} {', '.join(effects)})" if effects else "")


def _physics_specs() -> list[ParamSpec]:
    specs = []
    for f in dc_fields(PlatformParams):
        unit, doc = PHYSICS_DOCS.get(f.name, ("", ""))[0], physics_description(f.name)
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
    ParamSpec("gate.max_specific_force", "double", GateConfig.max_specific_force,
              "samples with a specific force norm ‖f‖ above this are dropped", "m/s²", range=(1.0, 1e6)),
    ParamSpec("reset_on_clock_jump", "bool", True,
              "reset when the node clock jumps back (looped 'ros2 bag play --clock --loop')"),
    # -- outputs
    ParamSpec("output_rate", "double", 10.0,
              "rate of the output topics on the sample-time grid; 0 = after every accepted sample", "Hz",
              range=(0.0, 1e4)),
    ParamSpec("diagnostics_rate", "double", 1.0,
              "rate of /diagnostics (steady clock: published with use_sim_time and no /clock too)", "Hz",
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
            qos = "sensor data: best effort, keep last 5 (overridable: `qos_overrides`), volatile"
        else:
            typ, name = f"`{t.type}`", f"`{t.name}`"
            qos = "reliable, keep last 10, volatile"
        rows.append(f"| {name} | {t.direction} | {typ} | {t.units} | {t.frame or '-'} | {qos} |")
    rows += [  # robot_state_publisher's under rclpy (launch file), the node's own on DDS
        "| `robot_description` | out | `std_msgs/msg/String` | URDF (gyro_platform.ros.urdf) | - "
        "| reliable, keep last 1, "
        "transient local |",
        "| `/tf` | out | `tf2_msgs/msg/TFMessage` | m, quaternion | every moving joint: parent → child link; "
        "`platform` → `platform_reference` (the node's, with the attitude) | reliable, keep last 100, volatile |",
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
        "# gyro_platform node parameters (generated by gyro_platform.ros.parameters.params_yaml; "
        "see README.md, ROS 2 node).",
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


__all__ = ["ConfigError", "ParamSpec", "PARAMETERS", "SPECS", "SCENE_KEYS", "INPUT_TYPES", "NODE_NAME",
           "PHYSICS_DOCS", "PHYSICS_PREFIX", "LIVE_PHYSICS", "PHYSICS_RANGES", "physics_description",
           "parameters_markdown",
           "topics_markdown", "params_yaml"]
