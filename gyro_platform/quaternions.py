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

"""Attitudes as arrays of unit quaternions, for the scene motions, the run summary and the URDF
(imports numpy only).

Rows ``(x, y, z, w)``, scalar last (ROS, SciPy); ``a ⊗ b`` is the rotation ``b`` followed by
``a`` (SciPy's ``A * B``). What SciPy's ``Rotation`` would do for these few operations, at the
cost of numpy's: ``scipy.spatial`` takes ~0.2 s to import (its KD-tree pulls ``scipy.sparse``,
whose array-API layer imports numpy's ``f2py`` and ``testing``), a seventh of ``gyro-platform
run default`` and a fifth of the DDS node's start. The formulas are SciPy's (``from_euler`` by
elementary quaternions, ``from_rotvec``/``as_rotvec`` with their small-angle series, ``as_euler``
by half-angle sums); ``test_quaternions.py`` checks them against ``Rotation`` on random and edge
attitudes. Everything else about attitudes uses ``scipy.spatial.transform.Rotation``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["normalized", "conj", "mul", "from_euler_zyx", "from_rotvec", "rotate_inv", "as_rotvec", "as_euler_xyz"]


def normalized(q) -> np.ndarray:
    """``q`` (…, 4) scaled to unit length."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def conj(q) -> np.ndarray:
    """The inverse (…, 4) of unit quaternions ``q``."""
    return np.asarray(q, dtype=float) * np.array([-1.0, -1.0, -1.0, 1.0])


def mul(a, b) -> np.ndarray:
    """``a ⊗ b`` (…, 4), broadcast over the leading axes: ``b`` first, then ``a``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bx + bw * ax + ay * bz - az * by,
                     aw * by + bw * ay + az * bx - ax * bz,
                     aw * bz + bw * az + ax * by - ay * bx,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def from_euler_zyx(psi, theta, phi) -> np.ndarray:
    """``R3(ψ) R2(θ) R1(φ)`` (intrinsic Z-Y-X: yaw, pitch, roll; rad) as (N, 4) quaternions,
    SciPy's ``Rotation.from_euler("ZYX", …)``."""
    psi, theta, phi = (np.asarray(v, dtype=float) for v in (psi, theta, phi))
    z = np.zeros(np.broadcast(psi, theta, phi).shape)

    def axis(angle, i):
        q = np.zeros(z.shape + (4,))
        q[..., i] = np.sin(angle / 2.0)
        q[..., 3] = np.cos(angle / 2.0)
        return q

    return mul(mul(axis(psi + z, 2), axis(theta + z, 1)), axis(phi + z, 0))


def from_rotvec(v) -> np.ndarray:
    """Quaternions (…, 4) of rotation vectors ``v`` (…, 3) rad (SciPy's ``from_rotvec``)."""
    v = np.asarray(v, dtype=float)
    angle = np.linalg.norm(v, axis=-1)
    small = angle <= 1e-3
    a = np.where(small, 1.0, angle)
    scale = np.where(small, 0.5 - angle ** 2 / 48.0 + angle ** 4 / 3840.0, np.sin(a / 2.0) / a)
    return np.concatenate([scale[..., None] * v, np.cos(angle / 2.0)[..., None]], axis=-1)


def rotate_inv(q, v) -> np.ndarray:
    """``R(q)ᵀ v`` (…, 3): the vectors ``v`` in the rotated frame's axes."""
    q = normalized(q)
    u, w = q[..., :3], q[..., 3:]
    v = np.broadcast_to(np.asarray(v, dtype=float), u.shape)
    t = 2.0 * np.cross(v, u)              # R(q)ᵀ v = v + w t + t × u with t = 2 v × u
    return v + w * t + np.cross(t, u)


def as_rotvec(q) -> np.ndarray:
    """Rotation vectors (…, 3) rad of ``q``, angle in [0, π] (SciPy's ``as_rotvec``)."""
    q = normalized(q)
    q = np.where(q[..., 3:] < 0.0, -q, q)
    u, w = q[..., :3], q[..., 3]
    angle = 2.0 * np.arctan2(np.linalg.norm(u, axis=-1), w)
    small = angle <= 1e-3
    a = np.where(small, 0.0, angle)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(small, 2.0 + angle ** 2 / 12.0 + 7.0 * angle ** 4 / 2880.0, a / np.sin(a / 2.0))
    return scale[..., None] * u


def as_euler_xyz(q) -> np.ndarray:
    """Fixed-axes x-y-z angles (…, 3) rad (URDF ``rpy``: ``R = Rz(y) Ry(p) Rx(r)``) of ``q``:
    SciPy's ``as_euler("xyz")`` (Bernardes and Viollet's half-angle sums, accurate up to gimbal
    lock). At pitch ±π/2 exactly, roll and yaw share what is left (SciPy sets one to 0 instead:
    the same rotation)."""
    x, y, z, w = np.moveaxis(normalized(q), -1, 0)
    a, b, c, d = w - y, x + z, y + w, z - x
    pitch = 2.0 * np.arctan2(np.hypot(c, d), np.hypot(a, b)) - np.pi / 2.0
    half_sum, half_diff = np.arctan2(b, a), np.arctan2(d, c)
    roll, yaw = half_sum - half_diff, half_sum + half_diff
    roll, yaw = (np.where(v < -np.pi, v + 2.0 * np.pi, np.where(v > np.pi, v - 2.0 * np.pi, v)) for v in (roll, yaw))
    return np.stack([roll, pitch, yaw], axis=-1)
