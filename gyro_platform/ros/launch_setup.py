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

"""What ``launch/platform.launch.py`` starts, computed from its argument values (ROS-free, tested).

The launch file only declares the arguments (:data:`ARGUMENTS`) and turns :func:`plan` into
``launch_ros`` ``Node`` actions; everything that can go wrong is decided here:

* the node's parameters: the params file, then only the overrides that were given
  (``scene``, ``input_type``, ``input_topic`` → ``imu_topic`` and ``twist_topic``,
  ``output_rate``, ``frame_prefix``, ``use_sim_time``);
* ``frame_prefix``: explicit when given (``frame_prefix:=robot1/``; ``frame_prefix:=/`` =
  none), else derived from the namespace (``namespace:=robot1`` → ``robot1/``, as
  ``robot_state_publisher``'s own ``frame_prefix`` convention and REP-105 multi-robot setups),
  else none; the same prefix goes to the node (its output frame ids) and to
  robot_state_publisher (TF), so outputs and TF agree;
* robot_state_publisher: ``robot_description`` = the URDF of :mod:`gyro_platform.ros.urdf` for the
  same parameters (so it never disagrees with the node's model), ``joint_states`` remapped to
  the node's ``gimbal/joint_states``; it publishes ``/robot_description`` (transient local),
  ``/tf_static`` (fixed joints) and ``/tf`` (every moving joint, from the JointState).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Mapping

from .config import load_params_file, NodeConfig
from .parameters import ConfigError, NODE_NAME, SPECS
from .urdf import config_urdf

#: (name, default, description); the launch file declares exactly these
ARGUMENTS: tuple[tuple[str, str, str], ...] = (
    ("params_file", "", "parameters file of the node; empty: the package's config/platform.yaml"),
    ("scene", "", "scene file or name in config/scenes (coning, default …) giving the model defaults; "
                  "empty: the params file's"),
    ("input_topic", "", "input topic (Imu or Twist/TwistStamped); empty: the params file's"),
    ("input_type", "", "imu, twist or twist_stamped; empty: the params file's"),
    ("output_rate", "", "rate of the output topics in Hz (0 = after every sample); empty: the params file's"),
    ("use_sim_time", "false", "use /clock (true when replaying a bag with 'ros2 bag play --clock')"),
    ("namespace", "", "namespace of the node, robot_state_publisher and their topics"),
    ("frame_prefix", "", "prefix of every frame id (outputs and TF); empty: '<namespace>/' with a namespace, "
                         "else none; '/' forces none"),
    ("log_level", "info", "log level of both nodes: debug, info, warn, error or fatal"),
    ("robot_state_publisher", "true", "start robot_state_publisher (TF and /robot_description of the URDF)"),
)
LOG_LEVELS = ("debug", "info", "warn", "error", "fatal")
TRUE, FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


class LaunchArgumentError(ValueError):
    """A launch argument has a value the node would refuse; the message names it."""


@dataclass
class LaunchPlan:
    """The two nodes to start: parameters (a list as launch_ros takes them), ROS arguments."""

    namespace: str | None
    frame_prefix: str
    node_parameters: list[Any]
    ros_arguments: list[str]
    rsp_parameters: dict[str, Any] | None = None
    rsp_remappings: list[tuple[str, str]] = field(default_factory=list)


def _flag(name: str, value: str) -> bool:
    v = value.strip().lower()
    if v in TRUE:
        return True
    if v in FALSE:
        return False
    raise LaunchArgumentError(f"{name}:={value}: expected true or false")


def frame_prefix_for(explicit: str, namespace: str) -> str:
    """The frame prefix: ``explicit`` (``/`` = none; a missing trailing ``/`` is added), else
    ``<namespace>/`` (leading/trailing slashes dropped), else ``""``."""
    explicit = explicit.strip()
    if explicit == "/":
        return ""
    if explicit:
        return explicit if explicit.endswith("/") else explicit + "/"
    ns = namespace.strip().strip("/")
    return f"{ns}/" if ns else ""


def urdf_from_params_file(params_file: str | None, scene: str = "", node_name: str | None = None,
                          overrides: Mapping[str, object] | None = None) -> str:
    """URDF for a ROS params file (+ scene and other overrides), as the node would configure
    itself from them — used by the launch file to hand ``robot_state_publisher`` the same
    model. Raises ``ConfigError`` on a bad parameter."""
    params = dict(load_params_file(params_file, node_name or NODE_NAME)) if params_file else {}
    if scene:
        params["scene"] = scene
    params.update(overrides or {})
    return config_urdf(NodeConfig.from_ros_params(params))


def plan(values: Mapping[str, str], default_params_file: str) -> LaunchPlan:
    """The launch plan for argument ``values`` (name → string, as LaunchConfiguration gives
    them). Raises :class:`LaunchArgumentError` (one line naming the argument) on a bad value,
    and ``ConfigError`` when the parameters do not give a valid model."""
    cfg = {name: str(values.get(name, default)) for name, default, _ in ARGUMENTS}
    params_file = cfg["params_file"] or default_params_file
    sim_time = _flag("use_sim_time", cfg["use_sim_time"])
    level = cfg["log_level"].strip().lower()
    if level not in LOG_LEVELS:
        raise LaunchArgumentError(f"log_level:={cfg['log_level']}: expected one of {', '.join(LOG_LEVELS)}")
    overrides: dict[str, Any] = {"use_sim_time": sim_time}
    if cfg["scene"]:
        overrides["scene"] = cfg["scene"]
    if cfg["input_type"]:
        overrides["input_type"] = cfg["input_type"]
    if cfg["input_topic"]:
        overrides["imu_topic"] = overrides["twist_topic"] = cfg["input_topic"]
    if cfg["output_rate"]:
        try:
            rate = float(cfg["output_rate"])
        except ValueError:
            raise LaunchArgumentError(f"output_rate:={cfg['output_rate']}: expected a number in Hz") from None
        if not math.isfinite(rate):
            raise LaunchArgumentError(f"output_rate:={cfg['output_rate']}: expected a finite number in Hz")
        try:
            overrides["output_rate"] = SPECS["output_rate"].coerce(rate)
        except ConfigError as e:
            raise LaunchArgumentError(f"output_rate:={cfg['output_rate']}: {e}") from None
    prefix = frame_prefix_for(cfg["frame_prefix"], cfg["namespace"])
    overrides["frame_prefix"] = prefix
    for name in ("input_type",):
        if name in overrides:
            try:
                SPECS[name].coerce(overrides[name])
            except ConfigError as e:
                raise LaunchArgumentError(f"{name}:={overrides[name]}: {e}") from None
    ros_args = ["--log-level", level]
    res = LaunchPlan(namespace=cfg["namespace"].strip() or None, frame_prefix=prefix,
                     node_parameters=[params_file, overrides], ros_arguments=ros_args)
    if _flag("robot_state_publisher", cfg["robot_state_publisher"]):
        model_overrides = {k: v for k, v in overrides.items() if k in ("scene",)}
        urdf = urdf_from_params_file(params_file, node_name=NODE_NAME, overrides=model_overrides)
        res.rsp_parameters = {"robot_description": urdf, "frame_prefix": prefix, "use_sim_time": sim_time}
        res.rsp_remappings = [("joint_states", "gimbal/joint_states")]
    return res
