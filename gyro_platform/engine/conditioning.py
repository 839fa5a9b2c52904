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

"""How far a run near gimbal lock can be trusted: the lock margin and the check by a tighter run.

An inner gimbal (β5, β7, β10) at ±90° puts its rotor's spin axis on its outer gimbal's axis:
the gyro loses its stiffness about one axis (gimbal lock). The full model (massive gimbals)
integrates through it, but a motion driven through it tumbles, and the tumbling amplifies any
difference: on a carried platform swung by 30° / 20° / 40° at 1 / 0.7 / 0.5 Hz every method
met its local tolerance at every step while a tolerance-sized difference at the transit grew
×1e5 in 0.25 s (rk4 at rtol 1e-8 ended 0.2 rad from the reference; ``auto`` at rtol 1e-6,
0.8 rad). No local error estimate sees that; a second run at a tighter tolerance does.

:func:`lock_margin` finds the closest approach (``Outputs.status['gimbal_lock_margin']``, the
smallest ``|cos β|``, from the recorded angles); :func:`compare` judges a run against its check
run. Pure functions on arrays: the caller (``scenes.runner``) makes the check run. Imports numpy,
``engine.outputs`` and ``physics.options`` only.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
import math

import numpy as np

from .outputs import GIMBAL_NAMES
from ..physics.options import RTOL_MIN

__all__ = ["GIMBAL_LOCK_WARN", "INNER", "CHECK_TIGHTER", "ILL_CONDITIONED", "LockMargin", "LockCheck",
           "lock_margin", "check_tolerance", "compare"]

#: near gimbal lock: the smallest |cos| of the inner gimbal angles below this (within 5.7° of
#: ±90°); the node's /diagnostics WARN there, a scene run is checked by a tighter run
GIMBAL_LOCK_WARN = 0.1
#: the inner gimbals, by index into ``GIMBAL_NAMES``
INNER = tuple(i for i, n in enumerate(GIMBAL_NAMES) if n.startswith("beta"))
#: the check run asks rtol and atol this many times tighter (rtol ≥ ``RTOL_MIN``)
CHECK_TIGHTER = 100.0
#: the run is ill-conditioned where the check run's gimbal angles differ from its own by more
#: than this many of its tolerances, ``atol + rtol·max(1, max |angle|)`` (rad): a stable run
#: accumulates a few local errors a step; the tumbling runs measured differ by 1e5–1e9
ILL_CONDITIONED = 1e3


@dataclass(frozen=True)
class LockMargin:
    """The closest approach to gimbal lock of a run: ``margin`` (smallest |cos β| of the inner
    gimbals, 0 = lock), the ``joint`` and the time ``t`` (s) where it was reached."""

    margin: float
    joint: str
    t: float

    @property
    def near(self) -> bool:
        """Within ``GIMBAL_LOCK_WARN`` of lock."""
        return self.margin < GIMBAL_LOCK_WARN

    @property
    def degrees(self) -> float:
        """How far from ±90° the closest inner gimbal came, degrees."""
        return math.degrees(math.asin(min(1.0, self.margin)))

    def phrase(self) -> str:
        """Where and how close, for a warning."""
        if self.margin == 0:
            return f"{self.joint} went through gimbal lock (±90°) by t = {self.t:.6g} s"
        return f"{self.joint} came within {self.degrees:.3g}° of gimbal lock at t = {self.t:.6g} s"


@dataclass(frozen=True)
class LockCheck:
    """A run near gimbal lock against its check run at ``check_rtol``/``check_atol``: the
    largest gimbal-angle difference ``difference`` (rad) over the recorded instants, the
    ``bound`` it is held to (rad), the first instant ``t_beyond`` (s) where the difference
    exceeds it (None: nowhere), the approach ``lock``, and ``checked_to`` (s): the last instant
    compared when the check run stopped early (refused), else None."""

    lock: LockMargin
    check_rtol: float
    check_atol: float
    difference: float
    bound: float
    t_beyond: float | None
    checked_to: float | None = None

    @property
    def ill_conditioned(self) -> bool:
        return self.t_beyond is not None

    def as_dict(self) -> dict:
        """For ``summary.json``: the fields, ``ill_conditioned`` and the approach in degrees."""
        d = asdict(self)
        d["lock"]["degrees_from_lock"] = self.lock.degrees
        d["ill_conditioned"] = self.ill_conditioned
        return d

    def sentence(self) -> str:
        """One line for the run's warnings."""
        near = self.lock.phrase()
        if self.checked_to is not None:
            near += f" (its check run stopped early: compared up to t = {self.checked_to:.6g} s)"
        if self.ill_conditioned:
            return (f"{near}; a check run at rtol {self.check_rtol:g} differs by up to {self.difference:.3g} rad, "
                    f"beyond {self.bound:.3g} rad from t = {self.t_beyond:.6g} s: the motion through the lock "
                    f"amplifies errors and the outputs from there are not held to the asked tolerance")
        return (f"{near}; a check run at rtol {self.check_rtol:g} agrees within {self.difference:.3g} rad "
                f"(bound {self.bound:.3g} rad)")


def lock_margin(t: np.ndarray, gimbal_angles: np.ndarray) -> LockMargin | None:
    """The closest approach to lock over instants ``t`` (N,) s of ``gimbal_angles`` (N, 5) rad,
    order ``GIMBAL_NAMES``; an inner gimbal whose cosine changes sign between two instants went
    through ±90° between them (margin 0 at the later one). None without instants."""
    if not len(t):
        return None
    c = np.cos(np.asarray(gimbal_angles, dtype=float)[:, INNER])
    m = np.abs(c)
    m[1:][c[1:] * c[:-1] <= 0.0] = 0.0
    k, j = np.unravel_index(int(np.argmin(m)), m.shape)
    return LockMargin(float(m[k, j]), GIMBAL_NAMES[INNER[j]], float(t[k]))


def check_tolerance(rtol: float, atol: float) -> tuple[float, float]:
    """(rtol, atol) of the check run: ``CHECK_TIGHTER`` times tighter, rtol not below ``RTOL_MIN``."""
    return max(rtol / CHECK_TIGHTER, RTOL_MIN), atol / CHECK_TIGHTER


def compare(lock: LockMargin, t: np.ndarray, angles: np.ndarray, check_angles: np.ndarray,
            rtol: float, atol: float) -> LockCheck:
    """Judge a run's ``angles`` (N, 5) rad at instants ``t`` (N,) s, asked ``rtol``/``atol``,
    against ``check_angles`` of its check run at the same instants (fewer: the check run
    stopped early, compared where both exist)."""
    n = min(len(angles), len(check_angles))
    a = np.asarray(angles, dtype=float)[:n]
    d = np.abs(a - np.asarray(check_angles, dtype=float)[:n]).max(axis=1, initial=0.0)
    bound = ILL_CONDITIONED * (atol + rtol * max(1.0, float(np.abs(a).max(initial=0.0))))
    beyond = np.flatnonzero(d > bound)
    short = None if n == len(angles) else (float(t[n - 1]) if n else float("nan"))
    return LockCheck(lock, *check_tolerance(rtol, atol), float(d.max(initial=0.0)), bound,
                     float(t[beyond[0]]) if beyond.size else None, short)
