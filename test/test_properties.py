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

"""Property tests (hypothesis) over the public entry points, in process: random flag values,
random scene mutations and random simulator inputs end in a documented refusal (one line, the
flag or key named, the documented exception or exit code) or are taken exactly as given —
never a traceback, never a silently changed value.

Oracles are independent of the code under test: the flag ranges are restated here from the
``--help`` texts, accepted namespaces are checked with the node's rcl name rules
(``ros.dds_names``), and a simulator that refused a sample must continue exactly like a fresh
one that never saw it.
"""
from __future__ import annotations

import math
from pathlib import Path

from hypothesis import assume, given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from test_replay import imu_msg, S, write_bag
import yaml

from gyro_platform import cli
from gyro_platform.engine.inputs import RateSample
from gyro_platform.errors import InputError
from gyro_platform.pipeline.grid import MAX_GRID_RATE
from gyro_platform.replay.command import config_from_args
from gyro_platform.ros.dds_names import expand_topic_name, NameError_, normalize_namespace
from gyro_platform.scenes.schema import ScenarioError, scene_from_dict

REPO = Path(__file__).resolve().parents[1]
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    d = tmp_path_factory.mktemp("props")
    t0 = 1_700_000_000 * S
    return write_bag(d / "b", [(t0 + i * S // 50, imu_msg(t0 + i * S // 50, (0.0, 0.0, 0.01))) for i in range(20)])


def _one_line(err: str, command: str, flag: str) -> str:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"gyro-platform {command}: error: "), lines[0]
    assert flag in lines[0], (flag, lines[0])
    return lines[0]


def _main(argv: list[str]) -> int:
    """``cli.main`` with argparse's SystemExit turned into its code."""
    try:
        return cli.main(argv)
    except SystemExit as e:
        return int(e.code)


# ---- CLI flag values ----------------------------------------------------------------------------
FLOAT_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["nan", "inf", "-inf", "-0", "1e309", "-1e-300", "0", "abc", "", " ", "1,5", "0x10", "1e", "--"]),
)
#: flag -> is the value (a float or None when it is not a number) valid?
RATE_FLAGS = {
    "--output-rate": lambda x: x is not None and math.isfinite(x) and 0 <= x <= MAX_GRID_RATE,
    "--diagnostics-rate": lambda x: x is not None and math.isfinite(x) and 0 < x <= MAX_GRID_RATE,
    "--max-gap": lambda x: x is not None and math.isfinite(x) and x > 0,
    "--reset-on-jump-back": lambda x: x is not None and math.isfinite(x) and x >= 0,
    "--max-rate": lambda x: x is not None and math.isfinite(x) and x > 0,
}


def _as_float(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


@SETTINGS
@given(flag=st.sampled_from(sorted(RATE_FLAGS)), text=FLOAT_TEXT)
def test_replay_number_flags_are_taken_exactly_or_refused_naming_the_flag(bag, tmp_path, capsys, flag, text):
    out = tmp_path / "o"
    valid = RATE_FLAGS[flag](_as_float(text))
    argv = ["replay", str(bag), "--out", str(out), "--quiet", "--no-plot", f"{flag}={text}"]
    if valid:                   # taken as given (checked on the parsed config; nothing is run)
        args = cli.build_parser().parse_args(argv)
        cfg = config_from_args(args)
        got = {"--output-rate": cfg.output_rate, "--diagnostics-rate": cfg.diagnostics_rate,
               "--max-gap": cfg.gate.max_gap, "--reset-on-jump-back": cfg.gate.reset_on_jump_back,
               "--max-rate": cfg.gate.max_rate}[flag]
        want = float(text)
        assert got == (None if flag == "--output-rate" and want == 0 else want)
        return
    code = _main(argv)
    assert code == cli.EXIT_USAGE
    _one_line(capsys.readouterr().err, "replay", flag)
    assert not out.exists()


NAME_CHARS = st.one_of(st.text(alphabet="abcAB_09/ -!.~{}é", max_size=12),
                       st.sampled_from(["a//", "//", "/a/", "a__b", "{node}", "~/a", " a", "/", ""]))


@SETTINGS
@given(ns=st.one_of(NAME_CHARS, st.integers(1, 300).map(lambda n: "a" * n)))
def test_accepted_namespaces_give_valid_ros_topic_names(bag, tmp_path, capsys, ns):
    """Accepted: every output topic passes rcl's topic name rules (an independent
    implementation: ``ros.dds_names``) and their length limit; refused: exit 2 naming the flag."""
    from gyro_platform.messages import output_topics

    argv = ["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--no-plot", f"--namespace={ns}"]
    try:
        config_from_args(cli.build_parser().parse_args(argv))
        accepted = True
    except Exception:           # noqa: BLE001 - judged below through cli.main
        accepted = False
    if accepted:
        for topic in output_topics(ns):
            assert expand_topic_name(topic, "n", "/") == topic
            assert len(topic) <= 247 and "__" not in topic
        return
    assert _main(argv) == cli.EXIT_USAGE
    _one_line(capsys.readouterr().err, "replay", "--namespace")
    try:                        # rmw_validate_namespace (leading '/' added, one trailing '/' allowed)
        normalize_namespace(ns)
        ok_for_rcl = (ns == ns.strip() and "//" not in ns
                      and all(expand_topic_name(t, "n", "/") == t for t in output_topics(ns)))
    except (NameError_, ValueError):
        ok_for_rcl = False
    # refused although rcl takes it: only for the documented stricter rules (no "__", length)
    assert not ok_for_rcl or "__" in ns or max(map(len, output_topics(ns))) > 247


@SETTINGS
@given(repeats=st.integers(-5, 0))
def test_bench_repeats_below_one_are_refused_before_any_timing(tmp_path, capsys, repeats):
    code = _main(["bench", "hotpath", "--repeats", str(repeats), "--out", str(tmp_path / "b")])
    assert code == cli.EXIT_USAGE
    _one_line(capsys.readouterr().err, "bench", "--repeats")
    assert not (tmp_path / "b").exists()


# ---- scene files ------------------------------------------------------------------------------------
BASE_SCENE = yaml.safe_load((REPO / "config" / "scenes" / "default.yaml").read_text())
NUMERIC_KEYS = ("duration", "sample_rate", "output_rate", "max_step", "rtol", "atol", "fit_start")
PARAM_KEYS = ("servo_kp", "support_viscous", "bias_torque", "rotor_speed", "spring")
BAD_NUMBERS = st.one_of(st.booleans(), st.none(), st.text(alphabet="abc xyz", min_size=1, max_size=5),
                        st.lists(st.lists(st.floats(-1, 1), min_size=1, max_size=3), min_size=1, max_size=3),
                        st.dictionaries(st.sampled_from(["a", "b"]), st.integers(), min_size=1))
ANY_NUMBER = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 15, 10 ** 15))


def _scene_refused(d: dict, key: str) -> str:
    with pytest.raises(ScenarioError) as e:
        scene_from_dict(d, source="s.yaml")
    text = str(e.value)
    assert "\n" not in text and text.startswith("scene 's.yaml': ") and key in text, text
    return text


@SETTINGS
@given(key=st.sampled_from(NUMERIC_KEYS), value=BAD_NUMBERS)
def test_scene_numbers_that_are_not_numbers_are_refused_naming_the_key(key, value):
    _scene_refused({**BASE_SCENE, key: value}, key)


@SETTINGS
@given(key=st.sampled_from(NUMERIC_KEYS), value=ANY_NUMBER)
def test_scene_numbers_are_taken_exactly_or_refused_naming_the_key(key, value):
    d = {**BASE_SCENE, key: value}
    try:
        sc = scene_from_dict(d, source="s.yaml")
    except ScenarioError as e:
        text = str(e)
        assert "\n" not in text and text.startswith("scene 's.yaml': "), text
        return
    assert math.isfinite(float(value))
    got = getattr(sc.options, key) if key in ("rtol", "atol") else getattr(sc, key)
    assert got == float(value)


@SETTINGS
@given(key=st.sampled_from(PARAM_KEYS), value=BAD_NUMBERS)
def test_scene_params_must_be_numbers_or_flat_lists(key, value):
    _scene_refused({**BASE_SCENE, "params": {key: value}}, f"params.{key}")


@SETTINGS
@given(duration=st.floats(1e7, 1e300), rate=st.floats(1.0, 1e12), step=st.floats(1e-6, 1e-3))
def test_runs_beyond_the_size_bounds_are_refused_with_an_estimate(duration, rate, step):
    """Whatever combination crosses 8 GiB or 1e9 steps is refused before it runs, with the
    estimate; the refusal names one of the three keys. (``max_step`` below 1e-6 s is refused
    by the model options themselves: ``test_engine``.)"""
    from gyro_platform.scenes.schema import run_budget

    d = {**BASE_SCENE, "duration": duration, "sample_rate": rate, "max_step": step,
         "output_rate": min(10.0, rate), "test_duration": None, "fit_start": 0}
    b = run_budget(duration, rate, min(10.0, rate), step)
    assume(b.too_big)
    text = _scene_refused(d, "")
    assert "too big to start" in text and "GiB" in text and "steps" in text
    assert any(f": {k}: " in text for k in ("duration", "sample_rate", "max_step"))


# ---- simulator inputs --------------------------------------------------------------------------------
def _bad_vectors():
    return st.one_of(
        st.integers(0, 6).filter(lambda n: n != 3).map(lambda n: np.ones(n)),
        st.just(np.ones((3, 3))), st.just(np.float64(1.0)),
        st.just(np.array([1 + 1j, 0, 0])), st.just(np.array(["a", "b", "c"])), st.just(["x", 1, 2]),
        st.just(np.array([0.0, np.nan, 0.0])), st.just(np.array([np.inf, 0.0, 0.0])),
        st.just(None), st.just({"x": 1}))


def _fresh_after(sim_cls, samples):
    sim = sim_cls()
    for s in samples:
        sim.push(s)
    return sim.outputs()


@SETTINGS
@given(omega=_bad_vectors(), where=st.sampled_from(["omega", "force"]))
def test_a_refused_sample_is_an_input_error_and_leaves_no_trace(omega, where):
    """A sample of the wrong shape, type, complex or non-finite: InputError, and the simulator
    goes on exactly like one that never saw it."""
    from gyro_platform.engine.simulator import Simulator

    assume(not (where == "force" and omega is None))       # no force at all is a valid sample
    good = [RateSample(0.0, np.array([0.0, 0.0, 0.01])), RateSample(0.01, np.array([0.0, 0.01, 0.01]))]
    nxt = RateSample(0.02, np.array([0.01, 0.0, 0.01]))
    sim = Simulator()
    for s in good:
        sim.push(s)
    bad = (RateSample(0.015, omega) if where == "omega"
           else RateSample(0.015, np.array([0.0, 0.0, 0.01]), omega))
    with pytest.raises(InputError):
        sim.push(bad)
    sim.push(nxt)
    ref = _fresh_after(Simulator, [*good, nxt])
    got = sim.outputs()
    assert got.t == ref.t and np.array_equal(got.gimbal_angles, ref.gimbal_angles)
    assert np.array_equal(got.platform_attitude, ref.platform_attitude)


@SETTINGS
@given(n=st.integers(2, 8), swap=st.integers(0, 6), shape=st.sampled_from([(None, 3), (None, 2), (None, 4), (3,)]),
       started=st.booleans())
def test_push_many_refuses_before_touching_the_state(n, swap, shape, started):
    """Non-monotonic times or omega of the wrong shape: InputError, and the state (time, sample
    count, outputs) is what it was, on a fresh simulator as on a started one."""
    from gyro_platform.engine.simulator import Simulator

    sim = Simulator()
    if started:
        sim.push(RateSample(0.0, np.zeros(3)))
    before = (sim.t, sim.n_samples, sim.outputs().gimbal_angles.copy() if started else None)
    t = 0.01 * (1 + np.arange(n, dtype=float))
    shp = tuple(n if s is None else s for s in shape)
    w = np.full(shp, 0.01)
    if shp == (n, 3):
        k = swap % (n - 1)
        t[k], t[k + 1] = t[k + 1], t[k]           # times out of order
    with pytest.raises(InputError):
        sim.push_many(t, w)
    assert (sim.t, sim.n_samples) == before[:2]
    if started:
        assert np.array_equal(sim.outputs().gimbal_angles, before[2])
