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

"""Oracle O12: a physical pendulum on the rotating Earth ([MBB] (24), (25)) — the body-tree
engine as a "rigid body in a rotating frame" routine (its ω × Iω terms)."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from gyro_platform.physics.tree import BodyTree, REVOLUTE, ROOT, tree_mass_and_bias, TreeWork

U = 7.292115e-5          # rad/s
G = 9.80620              # m/s², g' of the oracle
LAT = math.radians(45.0)
RATIO = 0.5              # Θ_B / (m a), m
M, A_CG = 1.0, 0.375     # kg, m (rod of length 0.75 m: Θ_B = m L²/3, a = L/2 → Θ_B/(m a) = 0.5 m)
THETA_B = RATIO * M * A_CG


def pendulum(axis_east: bool) -> BodyTree:
    """Root: the local level frame (x East, y North, z Up) turning with the Earth. Body: a thin
    rod hanging down (−z) from a pivot about x (East–West) or y (North–South); Θ_A = 0 about
    the rod."""
    inertia = np.zeros((2, 3, 3))
    inertia[1] = np.diag([THETA_B, THETA_B, 0.0])
    return BodyTree(names=("earth", "rod"), parent=np.array([-1, 0]), jtype=np.array([ROOT, REVOLUTE]),
                    axis=np.array([[0, 0, 0], [1.0, 0, 0] if axis_east else [0, 1.0, 0]]),
                    qidx=np.array([-1, 0]), vidx=np.array([-1, 0]), inertia=inertia,
                    rotor_host=np.zeros(0, dtype=np.int64), rotor_axis=np.zeros((0, 3)),
                    rotor_C=np.zeros(0), rotor_A=np.zeros(0), root_dynamic=False, nq=1, nv=1)


def angular_acceleration(tree, phi, w_earth):
    """Acceleration of the rod angle (rad/s²) at rest relative to the Earth, gravity applied
    as a body torque (mass centre a below the pivot)."""
    wk = TreeWork(tree)
    n = tree.axis[1]
    c, s = math.cos(phi), math.sin(phi)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    R = np.eye(3) + s * K + (1 - c) * K @ K                    # body → root
    f_body = R.T @ np.array([0.0, 0.0, -M * G])
    tau = np.zeros((2, 3))
    tau[1] = np.cross([0.0, 0.0, -A_CG], f_body)
    Mm, cvec = tree_mass_and_bias(tree, wk, np.array([phi]), np.zeros(1), w_earth, np.zeros(3), np.zeros(0),
                                  tau_ext=tau)
    return -cvec[0] / Mm[0, 0]


def test_O12_equilibrium_tilt_and_period():
    w = U * np.array([0.0, math.cos(LAT), math.sin(LAT)])
    tree = pendulum(axis_east=True)
    phi0 = brentq(lambda p: angular_acceleration(tree, p, w), -1e-8, 1e-8, xtol=1e-22, rtol=1e-14)
    expect = THETA_B * U**2 * math.sin(2 * LAT) / (2 * M * A_CG * G)
    assert expect == pytest.approx(1.3556e-10, rel=1e-4)
    assert abs(phi0) == pytest.approx(expect, rel=1e-6)
    assert abs(math.degrees(phi0) * 3600) == pytest.approx(2.796e-5, rel=1e-3)       # arc seconds
    # small-oscillation period 2π sqrt(Θ/(m a g')) from the linearised restoring acceleration
    h = 1e-6
    k = -(angular_acceleration(tree, phi0 + h, w) - angular_acceleration(tree, phi0 - h, w)) / (2 * h)
    assert 2 * math.pi / math.sqrt(k) == pytest.approx(1.418778, rel=1e-6)
    # the Earth's rotation changes it by a relative amount of order (Θ_B−Θ_A) u²/(2 m a g') only
    k0 = -(angular_acceleration(tree, h, np.zeros(3)) - angular_acceleration(tree, -h, np.zeros(3))) / (2 * h)
    assert abs(math.sqrt(k0 / k) - 1) < 2e-10


def test_O12_no_tilt_with_the_axis_north_south():
    """With the pivot axis North–South (α = 0 in (24)) the Earth rate lies in the rod's plane of
    symmetry about that axis: sin α = 0, no equilibrium tilt."""
    w = U * np.array([0.0, math.cos(LAT), math.sin(LAT)])
    tree = pendulum(axis_east=False)
    assert abs(angular_acceleration(tree, 0.0, w)) < 1e-22
