"""Quaternion kinematics (numba), scalar-last ``(x, y, z, w)`` like scipy's Rotation.

``q_AB`` maps components in frame B to frame A (``v_A = R(q_AB) v_B``). Its derivative with
the body rate ω of B (B axes) is ``q̇ = ½ q ⊗ (ω, 0)``.
"""
from __future__ import annotations

import numpy as np
from numba import njit


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


@njit(cache=True)
def quat_rate(q, w, out):
    """out = q̇ = ½ q ⊗ (ω, 0) for body rate ω (rad/s, body axes)."""
    x, y, z, s = q[0], q[1], q[2], q[3]
    out[0] = 0.5 * (s * w[0] + y * w[2] - z * w[1])
    out[1] = 0.5 * (s * w[1] + z * w[0] - x * w[2])
    out[2] = 0.5 * (s * w[2] + x * w[1] - y * w[0])
    out[3] = -0.5 * (x * w[0] + y * w[1] + z * w[2])


@njit(cache=True)
def quat_rate_at(y, i, wx, wy, wz, out):
    """out[i:i+4] = ½ q ⊗ (ω, 0) for q = y[i:i+4] (no array views: hot path)."""
    x, yy, z, s = y[i], y[i + 1], y[i + 2], y[i + 3]
    out[i] = 0.5 * (s * wx + yy * wz - z * wy)
    out[i + 1] = 0.5 * (s * wy + z * wx - x * wz)
    out[i + 2] = 0.5 * (s * wz + x * wy - yy * wx)
    out[i + 3] = -0.5 * (x * wx + yy * wy + z * wz)


@njit(cache=True)
def quat_to_matrix_at(y, i, RR, k):
    """RR[k] = R(q) for the quaternion q = y[i:i+4] (normalised on the fly; no views)."""
    x, yy, z, w = y[i], y[i + 1], y[i + 2], y[i + 3]
    s = 2.0 / (x * x + yy * yy + z * z + w * w)
    RR[k, 0, 0] = 1.0 - s * (yy * yy + z * z)
    RR[k, 0, 1] = s * (x * yy - z * w)
    RR[k, 0, 2] = s * (x * z + yy * w)
    RR[k, 1, 0] = s * (x * yy + z * w)
    RR[k, 1, 1] = 1.0 - s * (x * x + z * z)
    RR[k, 1, 2] = s * (yy * z - x * w)
    RR[k, 2, 0] = s * (x * z - yy * w)
    RR[k, 2, 1] = s * (yy * z + x * w)
    RR[k, 2, 2] = 1.0 - s * (x * x + yy * yy)


def quat_exp_rate(w: np.ndarray, t: float) -> np.ndarray:
    """Quaternion of a constant body rate w (rad/s) held for time t (s)."""
    th = float(np.linalg.norm(w)) * t
    if th < 1e-300:
        return np.array([0.0, 0.0, 0.0, 1.0])
    ax = w / np.linalg.norm(w)
    return np.concatenate([ax * np.sin(th / 2), [np.cos(th / 2)]])
