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

"""``gyro_platform.quaternions`` against SciPy's ``Rotation`` (the library it stands in for on
the default scene's path), on random attitudes and the edges (the identity, angles near 0 and
π, the small-angle series' switch at 1e-3 rad, non-unit input); and the default scene's path
imports no ``scipy.spatial`` (the reason the module exists: ~0.2 s of ``run default``), nor does
the URDF the DDS node publishes before it is ready.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_platform import quaternions as Q
from gyro_platform.scenes.motions import Sine, Sinusoidal

ROOT = Path(__file__).resolve().parents[1]
RNG = np.random.default_rng(20261129)
R = Rotation.random(400, random_state=7)
S = Rotation.random(400, random_state=8)


def test_products_and_inverses_are_scipys():
    assert np.allclose(Q.mul(R.as_quat(), S.as_quat()), (R * S).as_quat(), rtol=0, atol=1e-15)
    assert np.allclose(Q.mul(R.as_quat()[0], S.as_quat()), (R[0] * S).as_quat(), rtol=0, atol=1e-15)   # broadcast
    assert np.allclose(Q.conj(R.as_quat()), R.inv().as_quat(), rtol=0, atol=0)
    ident = Q.mul(Q.conj(R.as_quat()), R.as_quat())
    assert np.allclose(ident, [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-15)


def test_zyx_euler_angles_are_scipys_quaternions_sign_included():
    a = RNG.uniform(-4.0, 4.0, size=(500, 3))
    q = Q.from_euler_zyx(a[:, 0], a[:, 1], a[:, 2])
    assert np.allclose(q, Rotation.from_euler("ZYX", a).as_quat(), rtol=0, atol=1e-15)
    edge = np.array([[0.0, 0.0, 0.0], [np.pi, 0.0, 0.0], [0.0, np.pi / 2, 0.0], [0.3, -np.pi / 2, 1.2]])
    assert np.allclose(Q.from_euler_zyx(*edge.T), Rotation.from_euler("ZYX", edge).as_quat(), rtol=0, atol=1e-15)


def test_vectors_in_the_rotated_axes_are_r_transpose_v():
    v = RNG.normal(size=(400, 3))
    assert np.allclose(Q.rotate_inv(R.as_quat(), v), R.inv().apply(v), rtol=0, atol=1e-14)
    g = np.array([0.0, 0.0, 9.80665])
    assert np.allclose(Q.rotate_inv(R.as_quat(), g), R.inv().apply(g), rtol=0, atol=1e-14)
    assert np.allclose(Q.rotate_inv(3.0 * R.as_quat(), v), R.inv().apply(v), rtol=0, atol=1e-14)     # not unit


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, 0.9999e-3, 1.0001e-3, 0.5, 2.0, np.pi - 1e-9, np.pi])
def test_rotation_vectors_are_scipys_from_zero_to_pi(angle):
    axes = RNG.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    rot = Rotation.from_rotvec(axes * angle)
    q = rot.as_quat()
    q[::2] *= -1.0                                          # the same rotations, w of either sign
    ref = rot.as_rotvec()
    got = Q.as_rotvec(q)
    if angle < np.pi - 1e-6:
        assert np.allclose(got, ref, rtol=1e-14, atol=1e-18)
    else:                                                   # at π, v and −v are the same rotation
        assert np.allclose(np.abs(got), np.abs(ref), rtol=1e-9, atol=1e-12)
    assert np.allclose(Q.as_rotvec(R.as_quat()), R.as_rotvec(), rtol=1e-13, atol=1e-15)


def test_rotation_vectors_to_quaternions_are_scipys():
    for scale in (1.0, 1e-3, 1e-6, 0.0):
        v = RNG.normal(size=(300, 3)) * scale
        assert np.allclose(Q.from_rotvec(v), Rotation.from_rotvec(v).as_quat(), rtol=0, atol=1e-16)


def test_urdf_rpy_are_scipys_and_exact_at_gimbal_lock():
    assert np.allclose(Q.as_euler_xyz(R.as_quat()), R.as_euler("xyz"), rtol=0, atol=1e-14)
    for pitch in (np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-9, -np.pi / 2 + 1e-12):   # scipy would warn here
        a = np.column_stack([RNG.uniform(-3, 3, 40), np.full(40, pitch), RNG.uniform(-3, 3, 40)])
        q = Rotation.from_euler("xyz", a).as_quat()
        back = Rotation.from_euler("xyz", Q.as_euler_xyz(q)).as_matrix()     # the same rotation
        assert np.allclose(back, Rotation.from_quat(q).as_matrix(), rtol=0, atol=1e-14)
    assert np.allclose(Q.as_euler_xyz([1.0, 0.0, 0.0, 0.0]), [np.pi, 0.0, 0.0], rtol=0, atol=0)


def test_an_euler_motion_gives_scipys_attitude_and_specific_force():
    m = Sinusoidal(roll=Sine(0.3, 0.2), pitch=Sine(0.1, 0.125, 0.5), yaw=Sine(1.5, 0.05), heave=Sine(1.0, 0.1))
    t = np.linspace(0.0, 20.0, 401)
    psi, theta, phi = m.euler(t)[:3]
    ref = Rotation.from_euler("ZYX", np.stack([psi, theta, phi], axis=-1))
    assert np.allclose(m.quaternion(t), ref.as_quat(), rtol=0, atol=1e-15)
    assert np.allclose(m.specific_force(t), ref.inv().apply(m.accel_n(t) + [0.0, 0.0, 9.80665]), rtol=0, atol=1e-13)
    assert np.allclose(m.attitude(t).as_quat(), ref.as_quat(), rtol=0, atol=1e-15)


def _after(code: str) -> str:
    """The last line a new process prints after running ``code`` and then printing the
    ``scipy.spatial`` modules it imported."""
    probe = code + "\nimport sys\nprint(sorted(m for m in sys.modules if m.startswith('scipy.spatial')))\n"
    out = subprocess.run([sys.executable, "-c", probe], env=dict(os.environ, PYTHONPATH=str(ROOT)),
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip().splitlines()[-1]


def test_the_urdf_imports_no_scipy_spatial():
    assert _after("from gyro_platform.ros.urdf import config_model, config_urdf\n"
                  "from gyro_platform.ros.config import NodeConfig\n"
                  "c = NodeConfig.from_ros_params({})\nassert len(config_urdf(c)) > 1000\n"
                  "config_model(c).transforms({'alpha4': 0.3})") == "[]"


def test_the_default_scene_imports_no_scipy_spatial():
    assert _after("from gyro_platform.scenes.runner import run_scene\n"
                  "from gyro_platform.scenes.schema import load_scene\n"
                  "run_scene(load_scene('default').with_duration(1.0))") == "[]"
