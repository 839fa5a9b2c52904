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

"""One rule for every number a user gives: finite (``errors.not_finite``).

The README promises finite flag values (exit 2, the flag named, nothing written). ``replay
--max-rate inf``, ``--reset-on-jump-back inf`` and ``--max-specific-force inf`` ran with exit 0
and wrote ``Infinity`` into the summary while ``--max-gap inf`` was refused (as "must be > 0");
``node --duration inf`` ran for ever. Now every float flag of every command is checked by the
same rule before the command starts, ``GateConfig`` (the replay's and the node's gate) refuses a
non-finite bound itself, and the node's parameters, scene and sweep files say the same words.
"""
from __future__ import annotations

import argparse
import math

import pytest
from test_cli import small_bag

from gyro_platform import cli
from gyro_platform.errors import check_number, not_finite
from gyro_platform.pipeline.gate_rules import GateConfig

WORDS = "expected a finite number, got"
GATE_FLAGS = ("--max-gap", "--reset-on-jump-back", "--max-rate", "--max-specific-force")


def float_flags(command: str) -> list[str]:
    """Every float-valued flag of ``command``, read from its parser (new flags are covered too)."""
    parser = cli.build_parser(command)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    return [a.option_strings[-1] for a in sub._actions if a.type is float and a.option_strings]


def test_the_gate_flags_and_the_command_flags_are_all_found():
    assert set(GATE_FLAGS) | {"--output-rate", "--diagnostics-rate"} <= set(float_flags("replay"))
    assert {"--duration", "--max-step"} <= set(float_flags("run"))
    assert "--duration" in float_flags("node")


def _args(command: str, flag: str, value: str, tmp_path) -> list[str]:
    given = [f"{flag}={value}"] if value.startswith("-") else [flag, value]
    if command == "replay":
        bag = small_bag(tmp_path / "b", seconds=0.2)
        return ["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--no-plot", *given]
    if command == "run":
        return ["run", "default", "--out", str(tmp_path / "o"), *given]
    # node: a params file that does not exist, so that a flag let through ends in another error
    # at once instead of a node running for ever
    return ["node", "--transport", "dds", "--params-file", str(tmp_path / "absent.yaml"), *given]


@pytest.mark.parametrize("command, flag", [(c, f) for c in ("replay", "run", "node") for f in float_flags(c)])
@pytest.mark.parametrize("value, shown", [("inf", "inf"), ("-inf", "-inf"), ("nan", "nan"), ("1e400", "inf")])
def test_every_float_flag_refuses_non_finite_values_alike(command, flag, value, shown, tmp_path, capsys):
    assert cli.main(_args(command, flag, value, tmp_path)) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert err == f"gyro-platform {command}: error: argument {flag}: {WORDS} {shown}\n", err
    assert not (tmp_path / "o").exists() and not (tmp_path / "o.summary.json").exists()


@pytest.mark.parametrize("flag", GATE_FLAGS)
def test_the_gate_flags_of_the_issue_write_no_infinity(flag, tmp_path, capsys):
    """The three that ran with exit 0 and wrote ``Infinity`` into ``OUT.summary.json``."""
    assert cli.main(_args("replay", flag, "inf", tmp_path)) == cli.EXIT_USAGE
    assert flag in capsys.readouterr().err
    assert not list(tmp_path.glob("o*"))


@pytest.mark.parametrize("field, unit", [("max_gap", "s"), ("reset_on_jump_back", "s"), ("max_rate", "rad/s"),
                                         ("max_specific_force", "m/s²"), ("rate_smoothing", "")])
@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_gate_config_refuses_a_non_finite_bound_itself(field, unit, value):
    with pytest.raises(ValueError) as e:
        GateConfig(**{field: value})
    assert str(e.value).startswith(f"{field} = {value!r}") and f"{WORDS} {value!r}" in str(e.value)
    assert "\n" not in str(e.value)


def test_gate_config_keeps_its_range_words():
    with pytest.raises(ValueError, match=r"^max_gap = 0.0 s; must be > 0$"):
        GateConfig(max_gap=0.0)
    with pytest.raises(ValueError, match=r"^reset_on_jump_back = -1.0 s; must be >= 0$"):
        GateConfig(reset_on_jump_back=-1.0)
    with pytest.raises(ValueError, match=r"rate_smoothing = 2.0; must be <= 1"):
        GateConfig(rate_smoothing=2.0)
    assert GateConfig(reset_on_jump_back=0.0, max_specific_force=1e308).max_specific_force == 1e308


def test_the_rule_itself():
    assert not_finite(1.0) is None and not_finite(0) is None and not_finite(-1e308) is None
    assert not_finite(math.inf) == f"{WORDS} inf" and not_finite(math.nan) == f"{WORDS} nan"
    assert "expected a number" in not_finite(True) and "expected a number" in not_finite("1.0")
    assert check_number("x", 2, "s", gt=0) == 2.0
    with pytest.raises(ValueError, match=r"^x = inf s; expected a finite number, got inf$"):
        check_number("x", math.inf, "s", gt=0)


def test_node_parameters_say_the_same_words():
    """Every double parameter of the node (params file and live ``set_parameters``)."""
    from gyro_platform.ros.config import NodeConfig
    from gyro_platform.ros.parameters import ConfigError, PARAMETERS

    doubles = [p for p in PARAMETERS if p.type == "double"]
    assert {"gate.max_rate", "gate.max_specific_force", "gate.reset_on_jump_back", "gate.max_gap"} <= {
        p.name for p in doubles}
    for p in doubles:
        with pytest.raises(ConfigError) as e:
            NodeConfig.from_ros_params({p.name: math.inf})
        assert e.value.parameter == p.name and f"{WORDS} inf" in str(e.value), p.name
    with pytest.raises(ConfigError, match=f"'physics.bias_torque': {WORDS} inf"):
        NodeConfig.from_ros_params({"physics": {"bias_torque": [0.0, 0.0, 0.0, 0.0, math.inf]}})


def test_scene_and_sweep_files_say_the_same_words(tmp_path):
    from gyro_platform.scenes.schema import load_scene, ScenarioError
    from gyro_platform.sweep.spec import load_sweep, SweepSpecError

    scene = tmp_path / "s.yaml"
    scene.write_text("duration: 1.0\nparams: {servo_kp: .inf}\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\n")
    with pytest.raises(ScenarioError, match=f"params.servo_kp: {WORDS} inf"):
        load_scene(scene)
    sweep = tmp_path / "w.yaml"
    sweep.write_text("scene: default\nruns: 2\nvary: {unbalance: {dist: normal, mean: 0.0, std: .inf}}\n")
    with pytest.raises(SweepSpecError, match=f"std: {WORDS}"):
        load_sweep(sweep)
