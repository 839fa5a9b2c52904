"""Vehicle input samples: what drives the platform.

A sample is the vehicle's inertial angular rate ``omega`` (rad/s, vehicle body axes, FLU per
REP-103) and optionally its specific force ``specific_force`` (m/s², vehicle axes, what an
accelerometer measures: +9.81 up at rest, REP-145) at time ``t`` (s). Between two samples the
simulator interpolates linearly (so the angular acceleration is constant over the interval).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class RateSample:
    """One timed vehicle sample. ``omega`` rad/s and ``specific_force`` m/s², vehicle axes."""

    t: float
    omega: np.ndarray
    specific_force: np.ndarray | None = None

    @staticmethod
    def of(t: float, omega, specific_force=None) -> "RateSample":
        """Build a sample from any 3-sequences (copies into float arrays)."""
        f = None if specific_force is None else np.asarray(specific_force, dtype=float).reshape(3)
        return RateSample(float(t), np.asarray(omega, dtype=float).reshape(3), f)

    def is_finite(self) -> bool:
        ok = np.isfinite(self.t) and bool(np.all(np.isfinite(self.omega)))
        if self.specific_force is not None:
            ok = ok and bool(np.all(np.isfinite(self.specific_force)))
        return bool(ok)
