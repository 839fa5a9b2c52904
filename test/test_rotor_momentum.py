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

"""A rotor without polar inertia (``rotor_C`` 0) is refused alike by every consumer.

Physics (spec 3.2, 4): a rotor's relative spin momentum is ``L_r = C_r φ̇_r``; without polar
inertia a rotor has none at any speed, so the platform is no gyro (no precession, no
stabilisation) and its URDF has no rotor cylinder (``ros.urdf.equivalent_cylinder`` divides by
C). ``physics.params.validate`` refuses it with one line naming the parameter and the reason;
the node config, ``run``, ``replay``, the URDF and sweep draws all go through it. Before, the
DDS node crashed (ZeroDivisionError) and ``run`` exited 0 without a word. A rotor at rest
(``rotor_speed`` 0, C > 0) stays allowed: a gyro switched off.
"""
from __future__ import annotations

import argparse
import json

import pytest

from gyro_platform import cli
from gyro_platform.physics.params import NAV1, NO_POLAR_INERTIA, ParameterError

REASON = "a rotor without polar inertia has no spin momentum"
ZERO_SCENE = ("name: zero_c\nmode: stabilised\nduration: 1.0\nsample_rate: 50.0\n"
              "params:\n  rotor_C: {C}\nmotion: {{type: constant, omega: [0.0, 0.0, 0.01]}}\n")


def test_the_reason_is_one_line_naming_the_parameter():
    assert REASON in NO_POLAR_INERTIA and "\n" not in NO_POLAR_INERTIA
    for C in ((0.0, 0.0, 0.0), (2.0e-5, 0.0, 2.0e-5), (2.0e-5, 2.0e-5, -0.0)):
        with pytest.raises(ParameterError) as e:
            NAV1.with_(rotor_C=C)
        assert "'rotor_C[" in str(e.value) and REASON in str(e.value) and "\n" not in str(e.value)
    # the other degenerate case stays what it was: a gimbal without inertia is named as such
    with pytest.raises(ParameterError, match="gimbal inertia"):
        NAV1.with_(rotor_C=(0.0,) * 3, rotor_A=(0.0,) * 3, housing5=(0.0,) * 3, housing7=(0.0,) * 3,
                   frame4=(0.0,) * 3)
    assert NAV1.with_(rotor_speed=(0.0, 0.0, 0.0)).L.tolist() == [0.0, 0.0, 0.0]    # at rest: allowed


def test_urdf_never_sees_a_rotor_without_polar_inertia():
    from gyro_platform.ros.urdf import equivalent_cylinder, platform_urdf

    assert "gyro_rotor6" in platform_urdf(NAV1, stabilised=True)
    with pytest.raises(ParameterError, match=REASON):
        NAV1.with_(rotor_C=(0.0, 2.0e-5, 2.0e-5))
    with pytest.raises(ParameterError, match=REASON):           # was ZeroDivisionError
        equivalent_cylinder(0.0, 1.2e-5, 7850.0)


@pytest.mark.parametrize("C", ["[0.0, 0.0, 0.0]", "[2.0e-5, 2.0e-5, 0.0]"])
def test_run_refuses_the_scene_with_exit_2_and_one_line(tmp_path, capsys, C):
    scene = tmp_path / "zero_c.yaml"
    scene.write_text(ZERO_SCENE.format(C=C))
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "r")]) == cli.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("gyro-platform run: error: ")
    assert "rotor_C[" in err and REASON in err and "Traceback" not in err
    assert not (tmp_path / "r").exists()


def test_replay_refuses_the_scene_before_anything_is_written(tmp_path, capsys):
    from test_replay import imu_msg, S, write_bag

    bag = write_bag(tmp_path / "in", [(1_000 * S + i * S // 100, imu_msg(1_000 * S + i * S // 100, (0.0, 0.0, 0.01)))
                                      for i in range(20)])
    scene = tmp_path / "zero_c.yaml"
    scene.write_text(ZERO_SCENE.format(C="[0.0, 0.0, 0.0]"))
    out = tmp_path / "out"
    assert cli.main(["replay", str(bag), "--out", str(out), "--scene", str(scene), "--quiet", "--no-plot"]) \
        == cli.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("gyro-platform replay: error: ")
    assert "rotor_C[0]" in err and REASON in err
    assert not out.exists()


def test_node_config_refuses_it_naming_the_parameter(tmp_path):
    """The DDS node's ROS-free path (``ros.command.build_config``, ``NodeConfig.from_yaml``): a
    ConfigError naming ``physics.rotor_C`` before any transport or /robot_description."""
    from gyro_platform.ros.command import build_config
    from gyro_platform.ros.config import NodeConfig
    from gyro_platform.ros.parameters import ConfigError, NODE_NAME

    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    physics: {rotor_C: [0.0, 0.0, 0.0]}\n")
    with pytest.raises(ConfigError) as e:
        build_config(argparse.Namespace(params_file=str(f), scene=""), NODE_NAME)
    assert e.value.parameter == "physics.rotor_C" and REASON in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_yaml(f)
    assert e.value.parameter == "physics.rotor_C" and REASON in str(e.value) and str(f) in str(e.value)
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_ros_params({"physics": {"rotor_C": [2.0e-5, 0.0, 2.0e-5]}})
    assert e.value.parameter == "physics.rotor_C" and REASON in str(e.value)
    scene = tmp_path / "zero_c.yaml"
    scene.write_text(ZERO_SCENE.format(C="[0.0, 0.0, 0.0]"))
    with pytest.raises(ConfigError) as e:
        NodeConfig.from_ros_params({"scene": str(scene)})
    assert REASON in str(e.value)


def test_node_command_exits_2_with_one_line(tmp_path, capsys):
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    physics: {rotor_C: [0.0, 0.0, 0.0]}\n")
    code = cli.main(["node", "--transport", "dds", "--params-file", str(f), "--duration", "1.0"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE, err
    assert "Traceback" not in err and "ZeroDivisionError" not in err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1 and REASON in lines[0] and "physics.rotor_C" in lines[0], err


def test_a_sweep_draw_without_polar_inertia_is_recorded_refused(tmp_path):
    pytest.importorskip("distributed", reason="sweeps run on Dask: pip install '.[sweep]'")
    from gyro_platform.sweep.runs import execute_run
    from gyro_platform.sweep.spec import load_sweep, SweepSpecError

    spec = tmp_path / "s.yaml"
    spec.write_text("scene: default\nduration: 1\nruns: 2\n"
                    'vary: {"rotor_C[2]": {dist: list, values: [2.0e-5, 0.0]}}\n')
    rec = execute_run(load_sweep(spec).task(1))
    assert rec["status"] == "refused" and REASON in rec["message"] and "rotor_C[2]" in rec["message"]
    json.dumps(rec, allow_nan=False)
    spec.write_text('scene: default\nduration: 1\nruns: 2\nvary: {"rotor_C[0]": {dist: fixed, value: 0.0}}\n')
    with pytest.raises(SweepSpecError, match=REASON):       # every run would be refused: refused at load
        load_sweep(spec)
