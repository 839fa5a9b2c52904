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

"""The launch file, checked without ROS: its syntax and arguments (ast: the PyPI 'launch'
package is not ROS's, so the file is not imported), and what it starts (launch_setup.plan)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from gyro_platform.ros import launch_setup as L
from gyro_platform.ros.config import load_params_file, NodeConfig
from gyro_platform.ros.urdf import config_urdf

ROOT = Path(__file__).resolve().parents[1]
LAUNCH = ROOT / "launch" / "platform.launch.py"
PARAMS = str(ROOT / "config" / "platform.yaml")


def test_launch_file_parses_and_declares_every_argument_of_the_plan():
    tree = ast.parse(LAUNCH.read_text(), str(LAUNCH))
    imports = {(n.module, a.name) for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
    assert ("gyro_platform.ros.launch_setup", "ARGUMENTS") in imports
    assert ("gyro_platform.ros.launch_setup", "plan") in imports
    # DeclareLaunchArgument(name, default_value=default, description=desc) for each entry of ARGUMENTS
    comps = [n for n in ast.walk(tree) if isinstance(n, ast.ListComp)
             and isinstance(n.elt, ast.Call) and getattr(n.elt.func, "id", "") == "DeclareLaunchArgument"]
    assert len(comps) == 1 and getattr(comps[0].generators[0].iter, "id", "") == "ARGUMENTS"
    kw = {k.arg for k in comps[0].elt.keywords}
    assert kw == {"default_value", "description"}
    names = [a[0] for a in L.ARGUMENTS]
    assert len(set(names)) == len(names)
    for required in ("params_file", "scene", "input_topic", "input_type", "use_sim_time", "namespace",
                     "log_level", "output_rate", "frame_prefix"):
        assert required in names
    starts = {k.value.value for n in ast.walk(tree) if isinstance(n, ast.Call)
              for k in n.keywords if k.arg == "package" and isinstance(k.value, ast.Constant)}
    assert starts == {"gyro_platform", "robot_state_publisher"}
    # executables exist: the console script of setup.py
    assert "platform_node = gyro_platform.cli:platform_node" in (ROOT / "setup.py").read_text()


def test_default_plan_starts_the_node_and_robot_state_publisher_with_the_same_model():
    p = L.plan({}, PARAMS)
    assert p.namespace is None and p.frame_prefix == ""
    assert p.node_parameters[0] == PARAMS
    assert p.node_parameters[1] == {"use_sim_time": False, "frame_prefix": ""}
    assert p.ros_arguments == ["--log-level", "info"]
    assert p.rsp_remappings == [("joint_states", "gimbal/joint_states")]
    assert p.rsp_parameters["robot_description"] == config_urdf(NodeConfig.from_ros_params(load_params_file(PARAMS)))


def test_namespace_derives_the_frame_prefix_and_explicit_values_win():
    p = L.plan({"namespace": "robot1"}, PARAMS)
    assert p.namespace == "robot1" and p.frame_prefix == "robot1/"
    assert p.node_parameters[1]["frame_prefix"] == "robot1/" == p.rsp_parameters["frame_prefix"]
    assert L.plan({"namespace": "/fleet/robot2/"}, PARAMS).frame_prefix == "fleet/robot2/"
    assert L.plan({"namespace": "robot1", "frame_prefix": "r1"}, PARAMS).frame_prefix == "r1/"
    assert L.plan({"namespace": "robot1", "frame_prefix": "/"}, PARAMS).frame_prefix == ""


def test_overrides_and_scene_reach_both_nodes():
    p = L.plan({"scene": "coning", "output_rate": "50", "input_topic": "/imu/data", "input_type": "imu",
                "use_sim_time": "true", "log_level": "DEBUG", "robot_state_publisher": "true"}, PARAMS)
    o = p.node_parameters[1]
    assert o["scene"] == "coning" and o["output_rate"] == 50.0 and o["use_sim_time"] is True
    assert o["imu_topic"] == o["twist_topic"] == "/imu/data"
    assert p.ros_arguments == ["--log-level", "debug"] and p.rsp_parameters["use_sim_time"] is True
    cfg = NodeConfig.from_ros_params({**load_params_file(PARAMS), "scene": "coning"})
    assert p.rsp_parameters["robot_description"] == config_urdf(cfg)
    assert L.plan({"robot_state_publisher": "false"}, PARAMS).rsp_parameters is None


@pytest.mark.parametrize("values, fragment", [
    ({"output_rate": "fast"}, "output_rate:=fast: expected a number in Hz"),
    ({"output_rate": "-5"}, "outside the allowed range"),
    ({"output_rate": "nan"}, "finite"),
    ({"log_level": "loud"}, "log_level:=loud: expected one of debug, info, warn, error, fatal"),
    ({"use_sim_time": "maybe"}, "use_sim_time:=maybe: expected true or false"),
    ({"input_type": "odometry"}, "input_type:=odometry"),
])
def test_bad_arguments_give_one_line_naming_the_argument(values, fragment):
    with pytest.raises(L.LaunchArgumentError) as e:
        L.plan(values, PARAMS)
    assert fragment in str(e.value) and "\n" not in str(e.value)
