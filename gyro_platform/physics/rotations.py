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

"""Quaternion kinematics (numba), scalar-last ``(x, y, z, w)`` like scipy's Rotation.

``q_AB`` maps components in frame B to frame A (``v_A = R(q_AB) v_B``). Its derivative with
the body rate ω of B (B axes) is ``q̇ = ½ q ⊗ (ω, 0)``.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit


@njit(cache=True)
def quat_to_matrix(q, R):
    """R (3×3) of the unit quaternion q = (x, y, z, w) (normalised on the fly)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n
    R[0, 0] = 1.0 - s * (y * y + z * z)
    R[0, 1] = s * (x * y - z * w)
    R[0, 2] = s * (x * z + y * w)
    R[1, 0] = s * (x * y + z * w)
    R[1, 1] = 1.0 - s * (x * x + z * z)
    R[1, 2] = s * (y * z - x * w)
    R[2, 0] = s * (x * z - y * w)
    R[2, 1] = s * (y * z + x * w)
    R[2, 2] = 1.0 - s * (x * x + y * y)


@njit(cache=True, inline="always")
def quat_rate_at(y, i, wx, wy, wz, out):
    """out[i:i+4] = ½ q ⊗ (ω, 0) for q = y[i:i+4] (no array views: hot path)."""
    x, yy, z, s = y[i], y[i + 1], y[i + 2], y[i + 3]
    out[i] = 0.5 * (s * wx + yy * wz - z * wy)
    out[i + 1] = 0.5 * (s * wy + z * wx - x * wz)
    out[i + 2] = 0.5 * (s * wz + x * wy - yy * wx)
    out[i + 3] = -0.5 * (x * wx + yy * wy + z * wz)


@njit(cache=True, inline="always")
def quat_matrix_elems(y, i):
    """The nine elements (row-major) of R(q) for the quaternion q = y[i:i+4], normalised on the
    fly (no arrays: the kernels' hot path)."""
    x, yy, z, w = y[i], y[i + 1], y[i + 2], y[i + 3]
    s = 2.0 / (x * x + yy * yy + z * z + w * w)
    return (1.0 - s * (yy * yy + z * z), s * (x * yy - z * w), s * (x * z + yy * w),
            s * (x * yy + z * w), 1.0 - s * (x * x + z * z), s * (yy * z - x * w),
            s * (x * z - yy * w), s * (yy * z + x * w), 1.0 - s * (x * x + yy * yy))


@njit(cache=True, inline="always")
def rpb_elems(y, iqp, iqb):
    """The nine elements (row-major) of R_PB = R_IPᵀ R_IB (platform <- vehicle) for the attitude
    quaternions y[iqp:iqp+4] (platform) and y[iqb:iqb+4] (vehicle), each normalised on the fly
    (no arrays: the kernels' hot path; every caller sums in this order)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = quat_matrix_elems(y, iqp)
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = quat_matrix_elems(y, iqb)
    return (a00 * b00 + a10 * b10 + a20 * b20, a00 * b01 + a10 * b11 + a20 * b21, a00 * b02 + a10 * b12 + a20 * b22,
            a01 * b00 + a11 * b10 + a21 * b20, a01 * b01 + a11 * b11 + a21 * b21, a01 * b02 + a11 * b12 + a21 * b22,
            a02 * b00 + a12 * b10 + a22 * b20, a02 * b01 + a12 * b11 + a22 * b21, a02 * b02 + a12 * b12 + a22 * b22)


@njit(cache=True)
def quat_to_matrix_at(y, i, RR, k):
    """RR[k] = R(q) for the quaternion q = y[i:i+4] (normalised on the fly; no views)."""
    (RR[k, 0, 0], RR[k, 0, 1], RR[k, 0, 2], RR[k, 1, 0], RR[k, 1, 1], RR[k, 1, 2],
     RR[k, 2, 0], RR[k, 2, 1], RR[k, 2, 2]) = quat_matrix_elems(y, i)


# ---- small numpy helpers for the output path (no scipy Rotation objects: ~µs, not ~50 µs) ----

def quat_matrix(q) -> np.ndarray:
    """3×3 rotation matrix of the quaternion q = (x, y, z, w) (normalised)."""
    R = np.empty((3, 3))
    quat_to_matrix(np.asarray(q, dtype=float), R)
    return R


@njit(cache=True)
def rotvec_matrix_into(v, R):
    """R = rotation matrix of the rotation vector v (rad), Rodrigues (no allocation)."""
    th = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    for i in range(3):
        for j in range(3):
            R[i, j] = 1.0 if i == j else 0.0
    if th < 1e-300:
        return
    kx, ky, kz = v[0] / th, v[1] / th, v[2] / th
    s, c = math.sin(th), 1.0 - math.cos(th)
    R[0, 0] += c * (-ky * ky - kz * kz)
    R[1, 1] += c * (-kx * kx - kz * kz)
    R[2, 2] += c * (-kx * kx - ky * ky)
    R[0, 1] += -s * kz + c * kx * ky
    R[1, 0] += s * kz + c * kx * ky
    R[0, 2] += s * ky + c * kx * kz
    R[2, 0] += -s * ky + c * kx * kz
    R[1, 2] += -s * kx + c * ky * kz
    R[2, 1] += s * kx + c * ky * kz


@njit(cache=True)
def rotvec_matrix(v) -> np.ndarray:
    """Rotation matrix of the rotation vector v (rad), Rodrigues."""
    R = np.empty((3, 3))
    rotvec_matrix_into(v, R)
    return R


@njit(cache=True)
def matrix_rotvec_into(R, out):
    """out = rotation vector (rad) of the rotation matrix R, via the quaternion (accurate for
    small and large angles alike; no allocation)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        w, x, y, z = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2.0
        w, x, y, z = (R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2.0
        w, x, y, z = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2.0
        w, x, y, z = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    n = math.sqrt(x * x + y * y + z * z)
    out[0], out[1], out[2] = 0.0, 0.0, 0.0
    if n < 1e-300:
        return
    ang = 2.0 * math.atan2(n, w) / n
    out[0], out[1], out[2] = x * ang, y * ang, z * ang


@njit(cache=True)
def matrix_rotvec(R) -> np.ndarray:
    """Rotation vector (rad) of the rotation matrix R, via the quaternion (accurate for small
    and large angles alike)."""
    out = np.zeros(3)
    matrix_rotvec_into(R, out)
    return out


def matrix_quat(R) -> np.ndarray:
    """Quaternion (x, y, z, w), w ≥ 0, of the rotation matrix R."""
    v = matrix_rotvec(R)
    th = math.sqrt(float(v @ v))
    if th < 1e-300:
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.concatenate([v / th * math.sin(th / 2), [math.cos(th / 2)]])


@njit(cache=True)
def euler_xyz_into(R, out):
    """out = intrinsic X-Y-Z angles (rad) with R = Rx(a) Ry(b) Rz(c) (no allocation)."""
    out[1] = math.asin(max(-1.0, min(1.0, R[0, 2])))
    out[0] = math.atan2(-R[1, 2], R[2, 2])
    out[2] = math.atan2(-R[0, 1], R[0, 0])


@njit(cache=True)
def euler_xyz(R) -> np.ndarray:
    """Intrinsic X-Y-Z angles (rad) with R = Rx(a) Ry(b) Rz(c): the mount's roll, pitch, yaw."""
    out = np.empty(3)
    euler_xyz_into(R, out)
    return out


def euler_xyz_axes(angles) -> np.ndarray:
    """Joint axes of the intrinsic X-Y-Z chain ``R = Rx(a) Ry(b) Rz(c)`` (the mount joints
    ``mount_roll``, ``mount_pitch``, ``mount_yaw``), as the columns of a 3×3 matrix in the axes
    of the last body (the platform): ``ω_rel = A (ȧ, ḃ, ċ)`` and a torque ``τ`` (child axes)
    has the joint torques ``Aᵀ τ``."""
    a, b, c = (float(x) for x in angles)
    cb, sb, cc, sc = math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    return np.array([[cb * cc, sc, 0.0],
                     [-cb * sc, cc, 0.0],
                     [sb, 0.0, 1.0]])


def euler_xyz_rates(angles, omega) -> np.ndarray:
    """Rates (rad/s) of the intrinsic X-Y-Z angles for the relative angular velocity ``omega``
    (rad/s, child axes). At the chain's singularity (cos b = 0) the minimum-norm solution,
    so the result is always finite for finite input."""
    A = euler_xyz_axes(angles)
    return np.linalg.lstsq(A, np.asarray(omega, float), rcond=1e-12)[0]


#: |cos b| below which ``euler_xyz_rates_into`` treats the X-Y-Z chain as singular (the
#: rcond = 1e-12 of ``euler_xyz_rates``' least squares, relative to |A| ~ 1)
EULER_SINGULAR_COS = 1e-12


@njit(cache=True)
def euler_xyz_rates_into(angles, omega, out):
    """Compiled ``euler_xyz_rates``: out = rates (rad/s) of the intrinsic X-Y-Z angles for the
    relative angular velocity ``omega`` (rad/s, child axes), by the closed-form inverse of
    ``euler_xyz_axes``; at the singularity (|cos b| < EULER_SINGULAR_COS) the minimum-norm
    least-squares solution, so the result is finite for finite input."""
    b, c = angles[1], angles[2]
    cb, sb, cc, sc = math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    w0, w1, w2 = omega[0], omega[1], omega[2]
    out[1] = sc * w0 + cc * w1
    if abs(cb) >= EULER_SINGULAR_COS:
        out[0] = (cc * w0 - sc * w1) / cb
        out[2] = w2 - sb * out[0]
    else:
        out[0] = sb * w2 / (1.0 + sb * sb)
        out[2] = w2 / (1.0 + sb * sb)
