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

"""A scene run near gimbal lock is checked by a run at a tighter tolerance (``engine.conditioning``).

A carried platform swung hard enough drives an inner gimbal through ±90°: every method meets its
local tolerance at every step, but the tumbling after the lock amplifies any difference, so the
outputs from there are not what the tolerance promises. The check run's difference is compared
here with the true error (DOP853 at rtol 1e-12): it is the run's error, flagged where it is
beyond the bound and not flagged where a run through the lock stays well conditioned."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from gyro_platform import cli
from gyro_platform.engine.conditioning import (CHECK_TIGHTER, compare, GIMBAL_LOCK_WARN, ILL_CONDITIONED, lock_margin,
                                               LockMargin)
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import scene_from_dict


def _swung(scale: float) -> dict:
    """A carried platform (full model, default effects and tolerance) on a vehicle rolling 30°,
    pitching 20° and yawing 40° at 1, 0.7 and 0.5 Hz, times ``scale``; 1 s at 1 kHz."""
    motion = {"type": "sinusoidal", "roll": {"amplitude_deg": 30.0 * scale, "frequency_hz": 1.0},
              "pitch": {"amplitude_deg": 20.0 * scale, "frequency_hz": 0.7},
              "yaw": {"amplitude_deg": 40.0 * scale, "frequency_hz": 0.5}}
    return {"name": f"swung_{scale:g}", "mode": "carried", "duration": 1.0, "sample_rate": 1000.0,
            "output_rate": 100.0, "motion": motion}


def _true_error(scene, rec) -> np.ndarray:
    """The run's largest gimbal-angle error at each instant against DOP853 at rtol 1e-12 (rad)."""
    tight = dataclasses.replace(scene, options=scene.options.with_(integrator="dop853", rtol=1e-12, atol=1e-14))
    ref, _, _ = run_scene(tight)
    return np.abs(rec.gimbal_angles - ref.gimbal_angles).max(axis=1)


def test_the_closest_approach_counts_a_pass_between_instants():
    t = np.array([0.0, 0.1, 0.2])
    q = np.zeros((3, 5))
    q[:, 1] = np.radians([80.0, 88.0, 80.0])          # beta5 up to 2° from lock
    m = lock_margin(t, q)
    assert (m.joint, m.t) == ("beta5", 0.1) and m.degrees == pytest.approx(2.0, rel=1e-9) and m.near
    q[:, 4] = np.radians([70.0, 85.0, 95.0])          # beta10 through 90° between 0.1 and 0.2 s
    m = lock_margin(t, q)
    assert (m.joint, m.t, m.margin) == ("beta10", 0.2, 0.0)
    q[:, 0] = math.pi / 2                             # an outer gimbal at 90° is no lock
    q[:, 1] = q[:, 4] = 0.0
    assert not lock_margin(t, q).near and lock_margin(t, q).margin == 1.0
    assert GIMBAL_LOCK_WARN == pytest.approx(math.cos(math.radians(84.26)), abs=1e-4)


def test_the_check_is_held_to_a_thousand_tolerances_of_the_run():
    lock = LockMargin(0.0, "beta5", 0.5)
    t = np.array([0.0, 0.5, 1.0])
    a = np.zeros((3, 5))
    a[:, 2] = 2.0                                     # the angle scale: 2 rad
    bound = ILL_CONDITIONED * (1e-9 + 1e-6 * 2.0)
    b = a.copy()
    b[1:, 2] += 0.9 * bound
    c = compare(lock, t, a, b, 1e-6, 1e-9)
    assert c.bound == pytest.approx(bound) and not c.ill_conditioned
    assert (c.check_rtol, c.check_atol) == (1e-6 / CHECK_TIGHTER, 1e-9 / CHECK_TIGHTER)
    b[2, 2] += 0.2 * bound
    c = compare(lock, t, a, b, 1e-6, 1e-9)
    assert c.ill_conditioned and c.t_beyond == 1.0 and c.difference == pytest.approx(1.1 * bound)
    short = compare(lock, t, a, b[:1], 1e-6, 1e-9)                       # a check run that stopped at once
    assert short.difference == 0.0 and short.checked_to == 0.0 and "stopped early" in short.sentence()
    assert c.checked_to is None


def test_a_run_tumbling_through_gimbal_lock_is_flagged_where_its_error_is_beyond_the_bound(tmp_path):
    """The swung platform at full scale: beta5 goes through ±90° at ~0.57 s. The run (auto, rtol
    1e-6) meets its local tolerance at every step (max_error_norm ≤ 1), yet from ~0.8 s it is
    0.8 rad from the reference; the check run at rtol 1e-8 sees the same difference from the
    same instant, the summary says so and ``run`` exits 1 with everything written."""
    scene = scene_from_dict(_swung(1.0))
    rec, summary, _ = run_scene(scene)
    assert summary["max_error_norm"] <= 1.0
    c = summary["gimbal_lock_check"]
    assert c["ill_conditioned"] and c["lock"]["joint"] == "beta5" and 0.5 < c["lock"]["t"] < 0.65
    err = _true_error(scene, rec)
    beyond = rec.t[np.flatnonzero(err > c["bound"])]
    assert beyond[0] == c["t_beyond"] > c["lock"]["t"]
    assert err.max() > 100 * c["bound"]
    assert 0.5 < c["difference"] / err.max() < 2.0            # the check measures the run's error
    assert any("not held to the asked tolerance" in w for w in summary["warnings"])
    path = tmp_path / "swung.yaml"
    path.write_text(json.dumps(_swung(1.0)))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == cli.EXIT_FAILED
    written = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert written["summary"]["gimbal_lock_check"]["ill_conditioned"]


def test_a_run_through_gimbal_lock_that_stays_well_conditioned_is_not_flagged():
    """At 0.8 of the swing beta7 also goes through ±90° (at ~0.79 s), but the motion after it
    does not amplify the run's errors: the check run agrees to ~2e-6 rad, the reference too."""
    scene = scene_from_dict(_swung(0.8))
    rec, summary, _ = run_scene(scene)
    c = summary["gimbal_lock_check"]
    assert c["lock"]["margin"] == 0.0 and not c["ill_conditioned"]
    err = _true_error(scene, rec)
    assert err.max() < c["bound"]
    assert 0.5 < c["difference"] / err.max() < 2.0


def test_a_run_far_from_lock_is_not_checked():
    """Half the swing: the inner gimbals stay beyond the warning margin; no check run."""
    rec, summary, _ = run_scene(scene_from_dict(_swung(0.3)))
    assert lock_margin(rec.t, rec.gimbal_angles).margin > GIMBAL_LOCK_WARN
    assert "gimbal_lock_check" not in summary


def test_a_refused_check_run_is_compared_instant_for_instant_up_to_where_it_stopped(monkeypatch):
    """A check run asked more than it can meet (rtol 1e-13, atol 1e-22) refuses before the end:
    the instants it gave are compared with the run's same instants. Its last chunk's outputs were
    appended twice (once as the chunk the run generator yields before it re-raises, once from the
    error), shifting every later instant: 2.1 rad and "ill-conditioned" where the two agree to
    ~6e-7 rad."""
    from gyro_platform.scenes import runner

    monkeypatch.setattr(runner, "check_tolerance", lambda rtol, atol: (1e-13, 1e-22))
    rec, summary, _ = run_scene(scene_from_dict(_swung(1.0)))
    c = summary["gimbal_lock_check"]
    assert c["checked_to"] is not None and c["checked_to"] < rec.t[-1]
    assert not c["ill_conditioned"] and c["difference"] < 1e-5, c
    assert "stopped early" in next(w for w in summary["warnings"] if "gimbal lock" in w)
