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

"""Scene schema (every bad key names its path), recording (drift fit, files) and the ``run`` CLI."""
import copy
import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyro_platform import cli
from gyro_platform.engine.outputs import BEARING_NAMES, GIMBAL_NAMES, Outputs
from gyro_platform.physics.options import DEFAULT_EFFECTS, ModelOptions
from gyro_platform.physics.params import PlatformParams
from gyro_platform.reports.recording import print_summary_table, Recorder
from gyro_platform.reports.summary import fit_slope, RAD_S_TO_DEG_H
from gyro_platform.scenes.schema import Check, load_scene, ScenarioError, Scene, scene_from_dict

REPO = Path(__file__).resolve().parents[1]
SCENES = sorted((REPO / "config" / "scenes").glob("*.yaml"))

BASE = {
    "name": "t",
    "mode": "stabilised",
    "effects": ["defaults", "bias_torque"],
    "params": {"bias_torque": [0, 0, 0, 0, 1.0e-7]},
    "duration": 2.0,
    "sample_rate": 100.0,
    "output_rate": 10.0,
    "motion": {"type": "sinusoidal", "roll": {"amplitude_deg": 10.0, "frequency_hz": 0.1}},
    "expect": [{"quantity": "drift_rate_deg_per_h", "axis": "z", "value": -0.41, "rtol": 0.05}],
}


def load(d, base_dir=None):
    return scene_from_dict(d, source="x.yaml", base_dir=base_dir)


# ---- shipped scenes ------------------------------------------------------------------------
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_shipped_scene_loads(path):
    sc = load_scene(path)
    assert isinstance(sc, Scene)
    assert isinstance(sc.params, PlatformParams) and isinstance(sc.options, ModelOptions)
    assert sc.output_rate > 0 and sc.duration > 0
    assert sc.expect, "every shipped scene states what it expects"
    assert all(c.why for c in sc.expect), "every expectation says where its number comes from"


def test_required_scenes_are_shipped():
    names = {p.stem for p in SCENES}
    assert {"default", "earth_rest", "coordinated_turn", "ship_rolling", "coning", "rate_step_shock",
            "husky_replay"} <= names


def test_valid_scene_fields():
    sc = load(BASE)
    # default fidelity of a stabilised scene
    assert sc.name == "t" and sc.mode == "stabilised" and sc.fidelity == "linear"
    assert set(sc.effects) == set(DEFAULT_EFFECTS["stabilised"]) | {"bias_torque"}
    assert sc.options.effects == frozenset(sc.effects)
    assert sc.params.bias_torque[4] == 1e-7
    assert sc.motion.type == "sinusoidal" and sc.motion.generator is not None
    assert sc.expect[0] == Check("drift_rate_deg_per_h", "z", -0.41, 0.05, 0.0, None, None, "")
    assert sc.with_duration(5.0).duration == 5.0
    with pytest.raises(ScenarioError):
        sc.with_duration(0.0)


def test_effects_default_to_the_mode_defaults():
    d = copy.deepcopy(BASE)
    del d["effects"], d["params"]
    d["mode"] = "carried"
    assert set(load(d).effects) == set(DEFAULT_EFFECTS["carried"])


def test_numeric_strings_from_yaml_are_numbers(tmp_path):
    """PyYAML reads ``1e-7`` (no dot) as a string; the schema accepts it as a number."""
    p = tmp_path / "s.yaml"
    p.write_text("duration: 2\nmax_step: 5e-4\nparams: {bias_torque: [0, 0, 0, 0, 1e-7]}\n"
                 "motion: {type: constant, omega: [0, 0, 1e-3]}\n")
    sc = load_scene(p)
    assert sc.max_step == 5e-4 and sc.params.bias_torque[4] == 1e-7 and sc.name == "s"


def _set(d, path, value):
    """Set (or with value=DEL delete) a dotted/indexed key path in a nested dict copy."""
    d = copy.deepcopy(d)
    keys = path.replace("]", "").replace("[", ".").split(".")
    cur = d
    for k in keys[:-1]:
        cur = cur[int(k)] if isinstance(cur, list) else cur[k]
    last = keys[-1]
    if value is DEL:
        del cur[last]
    elif isinstance(cur, list):
        cur[int(last)] = value
    else:
        cur[last] = value
    return d


DEL = object()
TURN = {"type": "coordinated_turn", "speed": 60.0, "bank_deg": 30.0}
STEPS = {"type": "rate_steps", "steps": [{"t": 0.1, "omega": [0, 0, 5]}, {"t": 0.2, "omega": [0, 0, 0]}]}
RANDOM = {"type": "random", "seed": 1, "angle_rms_deg": 2.0}

BAD = [
    # (change path, value, motion override or None, expected key path in the message, words)
    ("colour", "red", None, "colour", "unknown key"),
    ("duration", DEL, None, "duration", "missing"),
    ("duration", "long", None, "duration", "expected a number"),
    ("duration", -1.0, None, "duration", "> 0"),
    ("duration", True, None, "duration", "expected a number"),
    ("name", "a/b", None, "name", "letters"),
    ("name", "..", None, "name", "not dots alone"),        # results/.. is the working folder
    ("name", ".", None, "name", "not dots alone"),
    ("name", 3, None, "name", "expected a string"),
    ("description", ["x"], None, "description", "expected a string"),
    ("mode", "floating", None, "mode", "expected one of"),
    ("fidelity", "exact", None, "fidelity", "expected one of"),
    ("effects", "servo", None, "effects", "expected a list"),
    ("effects", ["defaults", "magic"], None, "effects[1]", "expected one of"),
    ("effects", [3], None, "effects[0]", "expected one of"),
    ("params", [1, 2], None, "params", "expected a mapping"),
    ("params.spin", 3.0, None, "params.spin", "unknown key"),
    ("params.bias_torque", [0, 1], None, "params.bias_torque", "expected 5 values"),
    ("params.servo_kp", "stiff", None, "params.servo_kp", "number"),
    ("params.servo_kp", -5.0, None, "params.servo_kp", "outside"),
    ("integrator", "euler", None, "integrator", "expected one of"),
    ("max_step", 0.0, None, "max_step", "> 0"),
    ("rtol", "tight", None, "rtol", "expected a number"),
    ("sample_rate", 0, None, "sample_rate", "> 0"),
    ("output_rate", 500.0, None, "output_rate", "≤ sample_rate"),
    ("fit_start", 5.0, None, "fit_start", "must leave the drift fits two outputs: ≤ duration − 1/output_rate (1.9 s)"),
    ("fit_start", 1.95, None, "fit_start", "two outputs"),     # [1.95, 2] s holds one output at 10 Hz
    ("test_duration", 10.0, None, "test_duration", "≤ 2"),
    ("motion", DEL, None, "motion", "missing"),
    ("motion", "ship", None, "motion", "expected a mapping"),
    ("motion.type", DEL, None, "motion.type", "missing"),
    ("motion.type", "loop", None, "motion.type", "expected one of"),
    ("motion.wobble", 1, None, "motion.wobble", "unknown key"),
    ("motion.roll.amplitude_deg", "big", None, "motion.roll.amplitude_deg", "expected a number"),
    ("motion.roll.amplitude_deg", False, None, "motion.roll.amplitude_deg", "expected a number"),
    ("motion.roll.period", 10, None, "motion.roll.period", "unknown key"),
    ("motion.roll.frequency_hz", DEL, None, "motion.roll.frequency_hz", "missing"),
    ("motion.heave", {"amplitude_deg": 1, "frequency_hz": 0.1}, None, "motion.heave.amplitude_deg", "unknown key"),
    ("motion.omega", [1, 2], {"type": "constant", "omega": [0, 0, 1]}, "motion.omega", "list of 3"),
    ("motion.omega", [0, "x", 0], {"type": "constant", "omega": [0, 0, 1]}, "motion.omega[1]", "expected a number"),
    ("motion.initial_rpy_deg", 5, {"type": "constant", "omega": [0, 0, 1]}, "motion.initial_rpy_deg", "list of 3"),
    ("motion.speed", DEL, TURN, "motion.speed", "missing"),
    ("motion.speed", 0.0, TURN, "motion.speed", "> 0"),
    ("motion.bank_deg", "steep", TURN, "motion.bank_deg", "expected a number"),
    ("motion.bank_deg", 85.0, TURN, "motion.bank_deg", "≤ 80"),
    ("motion.roll_time", -1.0, TURN, "motion.roll_time", "> 0"),
    ("motion.axis", "w", {"type": "coning", "half_angle_deg": 2, "frequency_hz": 1}, "motion.axis", "one of"),
    ("motion.half_angle_deg", DEL, {"type": "coning", "half_angle_deg": 2, "frequency_hz": 1},
     "motion.half_angle_deg", "missing"),
    ("motion.steps", [], STEPS, "motion.steps", "non-empty list"),
    ("motion.steps[1].t", 0.05, STEPS, "motion.steps[1].t", "increase"),
    ("motion.steps[0].omega", [1, 2, 3, 4], STEPS, "motion.steps[0].omega", "list of 3"),
    ("motion.steps[0].w", 1, STEPS, "motion.steps[0].w", "unknown key"),
    ("motion.rise_time", 0.5, STEPS, "motion", "rise_time"),
    ("motion.seed", 1.5, RANDOM, "motion.seed", "integer"),
    ("motion.band_hz", [2.0, 1.0], RANDOM, "motion.band_hz", "lo < hi"),
    ("motion.angle_rms_deg", [1, 2], RANDOM, "motion.angle_rms_deg", "list of 3"),
    ("motion.components", 0, RANDOM, "motion.components", "≥ 1"),
    ("motion.latitude_deg", 100.0, {"type": "earth_fixed"}, "motion.latitude_deg", "≤ 90"),
    ("motion.path", "no/such/bag", {"type": "bag", "path": "x"}, "motion.path", "bag not found"),
    ("motion.topic", 5, {"type": "bag", "path": "."}, "motion.topic", "expected a string"),
    ("expect", {"quantity": "duration"}, None, "expect", "expected a list"),
    ("expect[0].colour", 1, None, "expect[0].colour", "unknown key"),
    ("expect[0].quantity", "wobble", None, "expect[0].quantity", "expected one of"),
    ("expect[0].quantity", DEL, None, "expect[0].quantity", "missing"),
    ("expect[0].axis", "w", None, "expect[0].axis", "expected one of"),
    ("expect[0].axis", DEL, None, "expect[0].axis", "required"),
    ("expect[0].joint", "beta10", None, "expect[0].joint", "not a selector"),
    ("expect[0].value", "big", None, "expect[0].value", "expected a number"),
    ("expect[0].rtol", -0.1, None, "expect[0].rtol", "≥ 0"),
    ("expect[0].rtol", DEL, None, "expect[0].value", "tolerance"),
    ("expect[0].value", DEL, None, "expect[0].rtol", "only used with 'value'"),
    ("expect[0].why", 3, None, "expect[0].why", "expected a string"),
]


@pytest.mark.parametrize("path,value,motion,where,words", BAD, ids=[f"{b[0]}={b[1]!r}"[:40] for b in BAD])
def test_bad_scene_names_the_key_path(path, value, motion, where, words, tmp_path):
    d = copy.deepcopy(BASE)
    if motion is not None:
        d["motion"] = copy.deepcopy(motion)
    d = _set(d, path, value)
    with pytest.raises(ScenarioError) as ei:
        load(d, base_dir=tmp_path)
    msg = str(ei.value)
    assert msg.startswith(f"scene 'x.yaml': {where}:"), msg
    assert words in msg, msg


def test_effect_combination_rejected_by_options_names_effects():
    d = _set(BASE, "mode", "carried")
    d["effects"] = ["rotor_gyroscopic", "servo"]          # the servo needs the stabilised mode
    with pytest.raises(ScenarioError, match=r"^scene 'x.yaml': effects: .*servo.*stabilised"):
        load(d)


def test_bag_with_sample_rate_is_rejected(tmp_path):
    (tmp_path / "b").mkdir()
    d = copy.deepcopy(BASE)
    d["motion"] = {"type": "bag", "path": "b"}
    with pytest.raises(ScenarioError, match=r"^scene 'x.yaml': sample_rate: not used"):
        load(d, base_dir=tmp_path)
    del d["sample_rate"]
    assert load(d, base_dir=tmp_path).motion.path == (tmp_path / "b").resolve()


def test_expectation_without_criterion_and_inverted_bounds():
    d = _set(BASE, "expect", [{"quantity": "drift_rate", "axis": "z"}])
    with pytest.raises(ScenarioError, match=r"expect\[0\]: give 'value'"):
        load(d)
    d = _set(BASE, "expect", [{"quantity": "drift_rate", "axis": "z", "min": 1, "max": 0}])
    with pytest.raises(ScenarioError, match=r"expect\[0\]\.min: min"):
        load(d)


def test_yaml_errors(tmp_path):
    p = tmp_path / "broken.yaml"
    p.write_text("duration: [1,\n")
    with pytest.raises(ScenarioError, match="scene 'broken.yaml': not valid YAML"):
        load_scene(p)
    p.write_text("- 1\n- 2\n")
    with pytest.raises(ScenarioError, match="scene 'broken.yaml': expected a mapping"):
        load_scene(p)
    with pytest.raises(ScenarioError, match="no such file or scene name"):
        load_scene(tmp_path / "missing.yaml")


def test_repeated_scene_keys_are_refused_and_merge_keys_still_work(tmp_path):
    p = tmp_path / "dup.yaml"
    p.write_text("duration: 2\nmotion: {type: constant, omega: [0.0, 0.0, 0.0], type: sines}\n")
    with pytest.raises(ScenarioError, match=r"^scene 'dup.yaml': not valid YAML: line 2:50: duplicate key 'type' "
                                            r"\(first at line 2:10\)$"):
        load_scene(p)
    p.write_text("duration: 2\nname: &n a\nmotion: {type: constant, omega: [0.0, 0.0, 0.0]}\ndescription: *n\n"
                 "params:\n  <<: {unbalance: 1.0e-8}\n  unbalance: 2.0e-8\n")
    assert load_scene(p).params.unbalance == 2.0e-8     # a merge key may be overridden (YAML's rule)


def test_husky_bag_path_resolves_against_the_repository_root():
    sc = load_scene(REPO / "config" / "scenes" / "husky_replay.yaml")
    assert sc.motion.path == (REPO / ".." / "shared" / "data" / "bags" / "robot_localization_husky_test1").resolve()
    assert sc.sample_rate is None and sc.motion.topic == "/imu/data"


def test_check_evaluation():
    s = {"drift_rate_deg_per_h": {"z": -0.40}, "max_abs_gimbal_angle": {"beta10": 2e-5}}
    assert Check("drift_rate_deg_per_h", "z", value=-0.41, rtol=0.05).evaluate(s)[0]
    assert not Check("drift_rate_deg_per_h", "z", value=-0.41, rtol=0.01).evaluate(s)[0]
    assert Check("drift_rate_deg_per_h", "z", value=-0.41, atol=0.011).evaluate(s)[0]
    assert Check("max_abs_gimbal_angle", "beta10", max=1e-4).evaluate(s)[0]
    assert not Check("max_abs_gimbal_angle", "beta10", max=1e-5).evaluate(s)[0]
    assert not Check("max_abs_gimbal_angle", "beta10", min=1e-4).evaluate(s)[0]
    ok, detail = Check("max_abs_gimbal_angle", "alpha4", max=1.0).evaluate(s)
    assert not ok and "not available" in detail
    assert not Check("drift_rate_deg_per_h", "z", max=1.0).evaluate({"drift_rate_deg_per_h": {"z": math.nan}})[0]


# ---- recorder --------------------------------------------------------------------------------
def synthetic_outputs(t, drift, gimbal=None, bearing_scale=1.0):
    n = len(t)
    gimbal = np.zeros((n, 5)) if gimbal is None else gimbal
    outs = []
    for i in range(n):
        bt = {b: np.array([0.0, 0.0, bearing_scale * (j + 1) * math.sin(t[i])]) for j, b in enumerate(BEARING_NAMES)}
        outs.append(Outputs(t=float(t[i]), gimbal_angles=gimbal[i], gimbal_rates=np.zeros(5),
                            gimbal_axial_torques=np.zeros(5), platform_rate=np.zeros(3),
                            platform_attitude=np.array([0, 0, 0, 1.0]), drift_angle=drift[i],
                            drift_rate=np.zeros(3), bearing_torques=bt, motor_torques=np.zeros(3),
                            servo_torque=np.array([0.0, 0.0, 1e-3])))
    return outs


def test_drift_fit_recovers_slope_under_oscillation():
    """A known drift slope under an oscillation 50× larger than the drift over one period and a
    constant offset: the least-squares fit returns the slope, not the oscillation."""
    t = 1000.0 + np.arange(0, 120.0, 0.05)          # absolute stamps; the fit uses t − t0
    slope = np.array([2e-7, -1.98944e-6, 0.0])        # rad/s
    osc = 5e-5 * np.sin(2 * np.pi * 0.37 * t)[:, None] * np.array([1.0, 1.0, 1.0])
    drift = 3e-6 + slope * (t - t[0])[:, None] + osc
    gimbal = np.zeros((t.size, 5))
    gimbal[:, 4] = 1e-3 * np.sin(t)
    gimbal[:, 1] = 4e-6 * (t - t[0])
    rec = Recorder()
    for o in synthetic_outputs(t, drift, gimbal):
        rec.append(o)
    s = rec.summary()
    est = np.array([s["drift_rate"][a] for a in "xyz"])
    assert np.allclose(est, slope, atol=0.01 * 1.98944e-6), est
    assert s["drift_rate_deg_per_h"]["y"] == pytest.approx(-0.41035, rel=0.01)
    assert s["drift_rate_deg_per_h"]["y"] == pytest.approx(s["drift_rate"]["y"] * RAD_S_TO_DEG_H)
    assert RAD_S_TO_DEG_H == pytest.approx(206264.806247, rel=1e-9)
    assert s["duration"] == pytest.approx(t[-1] - t[0])
    assert s["n_outputs"] == t.size
    assert s["max_abs_gimbal_angle"]["beta10"] == pytest.approx(1e-3, rel=1e-3)
    assert s["gimbal_angle_slope"]["beta5"] == pytest.approx(4e-6, rel=1e-9)
    assert s["max_abs_bearing_torque"]["rotor11"] == pytest.approx(9.0, rel=1e-3)
    assert s["max_abs_servo_torque"]["z"] == pytest.approx(1e-3)
    # a pure oscillation gives (almost) no drift
    rec2 = Recorder()
    for o in synthetic_outputs(t, osc):
        rec2.append(o)
    assert abs(rec2.summary()["drift_rate"]["x"]) < 0.02 * 1.98944e-6


def test_fit_start_window():
    t = np.arange(0, 20.0, 0.1)
    d = np.where(t[:, None] < 5.0, 1e-3 * t[:, None], 5e-3 + 1e-6 * (t[:, None] - 5.0)) * np.ones(3)
    rec = Recorder()
    for o in synthetic_outputs(t, d):
        rec.append(o)
    assert rec.summary(fit_start=5.0)["drift_rate"]["x"] == pytest.approx(1e-6, rel=1e-9)
    assert rec.summary()["drift_rate"]["x"] > 1e-5
    assert "notes" not in rec.summary(fit_start=19.8)
    # a window with one output cannot be fitted: the whole run is, and the summary says so
    late = rec.summary(fit_start=19.85)
    assert late["drift_fit_start"] == 0.0 and late["drift_rate"] == rec.summary()["drift_rate"]
    assert any("fit_start 19.85 s holds 1 output(s)" in n for n in late["notes"]), late.get("notes")


def test_fit_slope_shapes():
    t = np.linspace(0, 1, 11)
    assert fit_slope(t, 3 * t + 1) == pytest.approx(3.0)
    assert np.allclose(fit_slope(t, np.stack([t, -2 * t], axis=1)), [1, -2])
    assert fit_slope(t[:1], t[:1]) == 0.0


def test_recorder_files_and_table(tmp_path):
    t = np.arange(0, 5.0, 0.1)
    rec = Recorder()
    for i, o in enumerate(synthetic_outputs(t, 1e-6 * t[:, None] * np.ones(3))):
        rec.append(o, vehicle_omega=np.array([0.1, 0.0, 0.0]))
    with pytest.raises(ValueError):
        rec.append(synthetic_outputs(t[:1], np.zeros((1, 3)))[0])  # extras must not change
    assert rec.gimbal_angles.shape == (t.size, 5) and rec.drift_angle.shape == (t.size, 3)
    assert rec.bearing("support").shape == (t.size, 3)
    arr = rec.arrays()
    assert arr["vehicle_omega"].shape == (t.size, 3) and "bearing:rotor11" in arr
    p = rec.write_csv(tmp_path / "o" / "outputs.csv")
    rows = list(csv.DictReader(p.open()))
    assert len(rows) == t.size
    assert float(rows[3]["t_s"]) == pytest.approx(t[3])
    for name in ("t_s", "drift_angle_x_rad", *(g + "_rad" for g in GIMBAL_NAMES), "rotor11_torque_z_N_m",
                 "vehicle_rate_x_rad_s", "platform_attitude_qw", "motor_torque_rotor8_N_m"):
        assert name in rows[0]
    assert float(rows[3]["drift_angle_y_rad"]) == pytest.approx(1e-6 * t[3])
    j = json.loads(rec.write_json(tmp_path / "s.json", extra={"scene": {"name": "x"}}).read_text())
    assert j["scene"]["name"] == "x" and j["summary"]["n_outputs"] == t.size
    png = rec.plot(tmp_path / "p.png", title="test")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    buf = io.StringIO()
    print_summary_table({**rec.summary(), "scene": "x"}, buf)
    text = buf.getvalue()
    assert "drift_rate_deg_per_h [°/h]" in text and "beta10=" in text and "scene x" in text
    lines = [ln for ln in text.splitlines()[1:] if ln.strip()]
    first_cell = {len(ln) - len(ln[ln.index("]") + 1:].lstrip()) for ln in lines}
    assert len(lines) >= 8 and len(first_cell) == 1, "cells start in one aligned column"


# ---- the run CLI (real simulator) ------------------------------------------------------------
QUICK = """\
name: quick_shock
description: carried gyros, short yaw pulse
mode: carried
duration: 0.3
sample_rate: 500
output_rate: 100
motion:
  type: rate_steps
  rise_time: 0.01
  steps: [{t: 0.05, omega: [0, 0, 2.0]}, {t: 0.15, omega: [0, 0, 0]}]
expect:
  - {quantity: final_gimbal_angle, joint: alpha9, value: -0.2, atol: 1.0e-5, why: "O6"}
"""


def test_cli_run_writes_files_and_passes(tmp_path, capsys):
    p = tmp_path / "quick.yaml"
    p.write_text(QUICK)
    out = tmp_path / "res"
    assert cli.main(["run", str(p), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "PASS" in text and "final_gimbal_angle[alpha9]" in text and "max_abs_gimbal_angle" in text
    for f in ("outputs.csv", "summary.json", "plot.png"):
        assert (out / f).stat().st_size > 0
    j = json.loads((out / "summary.json").read_text())
    assert j["expectations"][0]["passed"] is True and j["scene"]["mode"] == "carried"
    assert j["summary"]["n_samples"] == 151


def test_cli_run_exit_status_on_failed_expectation_and_bad_scene(tmp_path, capsys):
    p = tmp_path / "quick.yaml"
    p.write_text(QUICK.replace("value: -0.2", "value: -0.3"))
    assert cli.main(["run", str(p), "--no-files"]) == 1
    assert "FAIL" in capsys.readouterr().out
    # the duration override applies: after 0.1 s the pulse has turned 0.01 + 2 x 0.04 = 0.09 rad
    p.write_text(QUICK.replace("value: -0.2", "value: -0.09") + "test_duration: 0.1\n")
    assert cli.main(["run", str(p), "--no-files", "--duration", "0.1"]) == 0
    # shorter than test_duration: the expectations are not judged on too little data (exit 1)
    capsys.readouterr()
    assert cli.main(["run", str(p), "--no-files", "--duration", "0.05"]) == 1
    out = capsys.readouterr().out
    assert "N/A" in out and "not evaluable" in out and "PASS" not in out
    p.write_text(QUICK.replace("mode: carried", "mode: hovering"))
    assert cli.main(["run", str(p), "--no-files"]) == 2
    assert "mode: expected one of" in capsys.readouterr().err


# ---- runs in chunks: the output grid after a loop, the CSV under interrupts and full disks ----
def _looped_bag(path: Path) -> Path:
    """2 s of 100 Hz Imu, then the recording loops (header stamps jump back 2 s) for 1.5 s more."""
    from test_chunked import imu, S, T0, vehicle_rate, write_bag

    rows, dt = [], S // 100
    for i in range(350):
        stamp = T0 + (i if i < 200 else i - 200) * dt
        rows.append((T0 + i * dt, imu(stamp, vehicle_rate(i * 0.01))))
    return write_bag(path, rows)


def test_bag_scene_restarts_its_output_grid_after_a_loop_like_replay(tmp_path):
    """A looped bag: after the jump back the scene's grid starts again (issue 17), the same
    output instants as ``replay`` at the scene's output rate, plus the last sample."""
    from gyro_platform import replay as rp
    from gyro_platform.scenes.runner import run_scene

    bag = _looped_bag(tmp_path / "loop")
    d = copy.deepcopy(BASE)
    d.update(duration=10.0, output_rate=5.0, effects=["defaults"], params={}, expect=[],
             motion={"type": "bag", "path": str(bag), "topic": "/imu"})
    d.pop("sample_rate")
    rec, summary, _ = run_scene(load(d))
    s = rp.replay(bag, tmp_path / "out", rp.ReplayConfig(output_rate=5.0, progress=False, plot=False))
    assert s["counts"]["resets_by_reason"] == {"jump_back": 1} and summary["bag"]["reset"] == 1
    # replay's instants: joint state stamps, as s since the first accepted stamp (the scene's t)
    from rosbags.typesys import get_typestore, Stores
    from imubag import raw_by_topic

    store = get_typestore(Stores.ROS2_JAZZY)
    js = [
        store.deserialize_cdr(raw, "sensor_msgs/msg/JointState")
        for _, raw in raw_by_topic(tmp_path / "out")["/gimbal/joint_states"]
    ]
    t_replay = [(x.header.stamp.sec * 10**9 + x.header.stamp.nanosec - s["gate"]["origin_ns"]) / 1e9 for x in js]
    assert len(t_replay) == 10 + 8                      # 2 s and 1.5 s at 5 Hz
    t_scene = rec.t.tolist()
    assert t_scene[:-1] == pytest.approx(t_replay, abs=1e-12) and t_scene[-1] == pytest.approx(1.49)
    assert summary["n_samples"] == 350


SLOW = """
name: slow
mode: stabilised
integrator: rk4
max_step: 1.0e-5
duration: 120.0
sample_rate: 100.0
output_rate: 100.0
motion: {type: sinusoidal, roll: {amplitude_deg: 10.0, frequency_hz: 0.1}}
"""


def _read(path: Path) -> str:
    with open(path, newline="") as fh:
        return fh.read()


def _lines_whole(text: str) -> list[list[str]]:
    assert text.endswith("\r\n") or text == ""
    rows = list(csv.reader(io.StringIO(text)))
    assert rows and all(len(r) == len(rows[0]) for r in rows), "a cut row"
    for r in rows[1:]:
        [float(x) for x in r]
    return rows


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_run_interrupted_leaves_a_csv_of_whole_rows_and_exits_130_or_143(tmp_path, sig):
    import os
    import signal
    import subprocess
    import sys
    import time

    scene = tmp_path / "slow.yaml"
    scene.write_text(SLOW)
    out = tmp_path / "res"
    proc = subprocess.Popen([sys.executable, "-m", "gyro_platform", "run", str(scene), "--out", str(out)], cwd=REPO,
                            env={**os.environ, "PYTHONPATH": str(REPO)}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    csv_path = out / "outputs.csv"
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline and not (csv_path.exists() and csv_path.stat().st_size):
        time.sleep(0.05)
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=600)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal")
    assert proc.returncode == (143 if sig == "SIGTERM" else 130), err
    word = "terminated" if sig == "SIGTERM" else "interrupted"
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith(f"gyro-platform run: {word}"), err
    rows = _lines_whole(_read(csv_path))
    # 3 chunks of <= 4096 samples: the signal after the first stops the run after the second
    assert 1 < len(rows) < 12002 and rows[0][0] == "t_s"


def test_run_on_a_full_disk_leaves_whole_rows_and_one_line(tmp_path):
    """RLIMIT_FSIZE stands for a full disk: the CSV write that does not fit is cut back to
    the last whole row, ``run`` says so in one line (an error exit, no traceback)."""
    import os
    import resource
    import signal
    import subprocess
    import sys

    from gyro_platform.scenes.runner import run_scene

    d = copy.deepcopy(BASE)
    d.update(duration=60.0, expect=[])
    ref = tmp_path / "ref"
    run_scene(load(d), out_dir=ref)                      # the whole CSV (2 chunks of 4096 samples)
    full = _read(ref / "outputs.csv")
    limit = int(len(full.encode()) * 0.8)
    p = tmp_path / "s.yaml"
    import yaml

    p.write_text(yaml.safe_dump(d))

    def fsize() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    out = tmp_path / "res"
    proc = subprocess.run([sys.executable, "-m", "gyro_platform", "run", str(p), "--out", str(out)], cwd=REPO,
                          env={**os.environ, "PYTHONPATH": str(REPO)},   # numba caches: those the parent used
                          capture_output=True, text=True, preexec_fn=fsize, timeout=600)
    assert proc.returncode not in (0, 130), proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot write the results" in lines[0] and "Traceback" not in proc.stderr, proc.stderr
    got = _read(out / "outputs.csv")
    rows = _lines_whole(got)
    assert 1 < len(rows) < full.count("\n") and full.startswith(got)


@pytest.mark.parametrize("motion, top", [
    ({"type": "sinusoidal", "roll": {"amplitude_deg": 1.0, "frequency_hz": 80.0}}, 80.0),
    ({"type": "coning", "half_angle_deg": 1.0, "frequency_hz": 50.0}, 50.0),
    ({"type": "random", "seed": 1, "angle_rms_deg": 1.0, "band_hz": [1.0, 60.0]}, 60.0),
])
def test_a_motion_at_or_above_half_the_sample_rate_is_refused(motion, top):
    """An 80 Hz roll sampled at 100 Hz ran (exit 0) as its alias: drift 1.1e-4 rad where 5 kHz
    samples give 1.1e-5. Now the scene is refused naming sample_rate; below half it loads."""
    d = {**copy.deepcopy(BASE), "motion": motion, "expect": []}
    with pytest.raises(ScenarioError, match=rf"sample_rate: 100 Hz cannot carry the motion's {top:g} Hz.*"
                                            rf"more than {2 * top:g} Hz"):
        load(d)
    assert load({**d, "sample_rate": 2.0 * top + 1.0}).sample_rate == 2.0 * top + 1.0


def test_a_duration_shorter_than_an_output_period_names_duration():
    """It blamed fit_start ('must leave the drift fits two outputs … (-0.099 s), got 0'), a key the
    scene did not set."""
    with pytest.raises(ScenarioError, match=r"duration: must span one output period .*0\.1 s.*got 0\.001 s"):
        load({**copy.deepcopy(BASE), "duration": 0.001, "expect": []})


@pytest.mark.parametrize("output_rate", [10.0, 1000.0])
def test_the_mean_vehicle_rate_is_a_time_average(tmp_path, output_rate):
    """One period of a 10°, 0.5 Hz roll: the mean rate is 0, whatever the output rate (the mean
    of the output instants, both ends counted, read 0.026 rad/s at 10 Hz and 2.7e-4 at 1 kHz)."""
    d = {**copy.deepcopy(BASE), "duration": 2.0, "sample_rate": 1000.0, "output_rate": output_rate,
         "motion": {"type": "sinusoidal", "roll": {"amplitude_deg": 10.0, "frequency_hz": 0.5}}, "expect": []}
    path = tmp_path / "mean.yaml"
    path.write_text(json.dumps(d))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    mean = json.loads((tmp_path / "out" / "summary.json").read_text())["summary"]["mean_vehicle_rate"]
    assert abs(mean["x"]) < 1e-9, mean
