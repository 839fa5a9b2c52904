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

"""Carried mode's drift: the gyros' own reference triad (rotor 11's spin axis, rotor 6's made
normal to it), its refusal where it is undefined, and drift fits through angles beyond π."""
import math

import numpy as np
import pytest

from gyro_platform.engine.outputs import C_DRIFT, C_T, N_COL, OutputBlock
from gyro_platform.errors import SimulationError
from gyro_platform.replay.stats import Stats
from gyro_platform.reports.summary import fit_slope, unwrap_rotation_vectors
from gyro_platform.scenes.runner import run_scene
from gyro_platform.scenes.schema import scene_from_dict

#: oracle O2 (PHYSICS.md): mean precession rate of α9 under a 1e-4 N m torque on β10, rad/s
O2_RATE = -1.9894368e-3


def _carried(bias, duration, sample_rate=10.0, output_rate=1.0):
    return scene_from_dict({"name": "c", "mode": "carried", "fidelity": "precession",
                            "effects": ["defaults", "bias_torque"], "params": {"bias_torque": bias},
                            "duration": duration, "sample_rate": sample_rate, "output_rate": output_rate,
                            "motion": {"type": "constant", "omega": [0.0, 0.0, 0.0]}}, source="c.yaml")


def test_a_torque_on_beta10_drifts_the_carried_reference_about_z_at_the_precession_rate():
    """Unit B's precession about z (α9) is the drift about z, as the servo makes it in stabilised
    mode (O9 b): the triad took x from rotor 6 first, and rotor 11 turning about z was invisible
    (drift 0 while α9 precessed at 410 °/h)."""
    rec, summary, _ = run_scene(_carried([0, 0, 0, 0, 1.0e-4], 200.0))
    assert summary["drift_rate"]["z"] == pytest.approx(O2_RATE, rel=1e-4)
    assert summary["drift_rate"]["z"] == pytest.approx(summary["gimbal_angle_slope"]["alpha9"], rel=1e-6)
    assert abs(summary["drift_rate"]["x"]) < 1e-9 and abs(summary["drift_rate"]["y"]) < 1e-9
    assert summary["final_drift_angle"]["z"] == pytest.approx(rec.gimbal_angles[-1, 3], rel=1e-6)


def test_spin_axes_near_parallel_are_refused_not_flipped():
    """Rotor 11 precessed 90° towards rotor 6: the triad is undefined there; the run stops with
    a one-line reason (the reference flipped by π and the drift jumped)."""
    with pytest.raises(SimulationError) as e:
        run_scene(_carried([0, 0, 0, 0, 1.0e-3], 90.0, sample_rate=20.0, output_rate=20.0))
    text = str(e.value)
    assert "spin axes of rotors 6 and 11 are within 0.057° of parallel" in text and "\n" not in text
    t = float(text.split("at t = ")[1].split(" s")[0])
    assert 1.0e-3 / 1.0e-4 * t * abs(O2_RATE) == pytest.approx(math.pi / 2, abs=2e-3)   # α9 ≈ 90° there


def test_a_drift_beyond_pi_is_fitted_through_its_turns():
    """Unit A precessing at ~10 rad/s about y: the drift angle wraps at ±π every 0.63 s; the
    fitted rate follows α4 (it had the wrong sign and 2 % of the size)."""
    _, summary, _ = run_scene(_carried([0, 0.5, 0, 0, 0], 3.0, sample_rate=100.0, output_rate=100.0))
    assert summary["gimbal_angle_slope"]["alpha4"] < -9.0
    assert summary["drift_rate"]["y"] == pytest.approx(summary["gimbal_angle_slope"]["alpha4"], rel=1e-3)


def _turning(rate, axis, t):
    """Rotation vectors of a rotation at ``rate`` rad/s about the unit ``axis``, wrapped into
    angles ≤ π as a rotation vector is (the axis flips beyond π)."""
    ang = np.mod(rate * t + math.pi, 2 * math.pi) - math.pi
    return ang[:, None] * axis[None, :]


def test_unwrapping_rotation_vectors_restores_the_turning_angle_in_any_block_cuts():
    t = np.linspace(0.0, 10.0, 2001)
    axis = np.array([0.36, -0.48, 0.8])
    d = _turning(-2.5, axis, t)
    assert np.linalg.norm(np.diff(d, axis=0), axis=1).max() > 6.0   # wrapped
    whole = unwrap_rotation_vectors(d)
    assert np.allclose(whole, (-2.5 * t)[:, None] * axis, atol=1e-12)
    assert fit_slope(t, whole) == pytest.approx(-2.5 * axis, rel=1e-12)
    prev, parts = None, []
    for a, b in ((0, 1), (1, 700), (700, 1400), (1400, 2001)):     # as the replay's blocks come
        parts.append(unwrap_rotation_vectors(d[a:b], prev))
        prev = parts[-1][-1]
    assert np.array_equal(np.concatenate(parts), whole)
    small = 1e-6 * np.ones((5, 3))
    assert unwrap_rotation_vectors(small) is small or np.array_equal(unwrap_rotation_vectors(small), small)


def test_the_replay_drift_fit_unwraps_across_blocks():
    """``Stats`` fits the replay's drift block by block: the same unwrapping, carried over."""
    t = np.linspace(0.0, 6.0, 1201)
    rows = np.zeros((t.size, N_COL))
    rows[:, C_T] = t
    rows[:, C_DRIFT:C_DRIFT + 3] = _turning(3.0, np.array([0.0, 0.0, 1.0]), t)
    st = Stats()
    for a, b in ((0, 400), (400, 401), (401, 1201)):
        st.add_block(OutputBlock(rows[a:b], False), new_segment=a == 0)
    t0, slope = st.drift_fit()
    assert t0 == 0.0 and slope == pytest.approx([0.0, 0.0, 3.0], abs=1e-9)
