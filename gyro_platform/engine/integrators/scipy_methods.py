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

"""Adaptive methods of scipy (``dop853``, ``rk45``, ``radau``) behind the integrator contract.

scipy's ``OdeSolver`` step API, warm-started step size, bounded by ``max_step`` and the budget.
"""
from __future__ import annotations

import math

import numpy as np

from .base import Integrator, MAX_SUBSTEPS, StepStats
from ...errors import SimulationError

__all__ = ["DOP853", "RK45", "Radau"]


class _Scipy(Integrator):
    """Adaptive method through scipy's ``OdeSolver`` step API, one solver per call.

    The step size proposed at the end of a call is the first step of the next call (warm
    start); a last step shortened to hit ``t1`` does not shrink it. Steps never pass ``t1`` or
    ``max_step``; a proposed step below ``max_step / max_substeps`` is refused.
    """

    #: name of the ``scipy.integrate`` solver class (imported on first use: scipy.integrate
    #: costs ~0.2 s to import, which a replay on the compiled methods never needs)
    solver_name: str = "OdeSolver"

    @property
    def solver_cls(self) -> type:
        import scipy.integrate

        return getattr(scipy.integrate, self.solver_name)

    def __init__(self, max_step: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-12,
                 max_substeps: int = MAX_SUBSTEPS) -> None:
        super().__init__(max_step, rtol, atol, max_substeps)
        self._h: float | None = None

    def reset(self) -> None:
        self._h = None

    def _solver_kwargs(self, system) -> dict:
        return {}

    def _estimates(self, solver) -> tuple[float, float]:
        """(max-norm error estimate, weighted norm) of the step just accepted."""
        scale = self.atol + self.rtol * np.maximum(np.abs(solver.y_old), np.abs(solver.y))
        try:       # the norm scipy accepted the step with (DOP853 blends its 5th/3rd-order estimates)
            nrm = float(solver._estimate_error_norm(solver.K, solver.h_previous, scale))
        except (AttributeError, TypeError):
            return math.nan, math.nan
        return nrm * float(np.max(scale)), nrm

    def _advance(self, system, t0, y, t1):
        h = self._h
        h = None if h is None else min(h, t1 - t0, self.max_step)
        solver = self.solver_cls(system.rhs, t0, y, t1, rtol=self.rtol, atol=self.atol, first_step=h,
                                 max_step=self.max_step, **self._solver_kwargs(system))
        steps = 0
        est = worst = 0.0
        h_min = self.max_step / self.max_substeps
        proposal = solver.h_abs if h is None else max(h, solver.h_abs)
        while solver.status == "running":
            t_before = solver.t
            msg = solver.step()
            if solver.status == "failed":
                raise SimulationError(f"{self.name} failed at t={float(solver.t)!r}: {msg} "
                                      "(non-finite or too stiff right-hand side?)")
            steps += 1
            e, nrm = self._estimates(solver)
            est, worst = max(est, e), max(worst, nrm)
            if solver.t == t1 and proposal > t1 - t_before:
                # last step cut short to t1 (and so accepted at its first try): do not let
                # the short step shrink the proposal
                self._h = max(proposal, solver.h_abs)
            else:
                self._h = solver.h_abs
                if solver.status == "running" and solver.h_abs < h_min:
                    raise self.refuse(float(solver.t), e, nrm if nrm == nrm else 1.0, solver.h_abs,
                                      " (its step collapsed: non-finite or too stiff right-hand side?)")
            proposal = solver.h_abs
        return solver.y, StepStats(steps, solver.nfev, est, worst)


class DOP853(_Scipy):
    """Dormand–Prince 8(5,3) (scipy ``DOP853``)."""

    name, order, solver_name = "dop853", 8, "DOP853"


class RK45(_Scipy):
    """Dormand–Prince 5(4) (scipy ``RK45``)."""

    name, order, solver_name = "rk45", 5, "RK45"


class Radau(_Scipy):
    """Radau IIA order 5 (scipy ``Radau``); Jacobian from ``system.jacobian``, else the constant
    ``linear_part`` A, else scipy's finite differences. scipy keeps its error estimate to itself:
    the reported estimate is the acceptance bound (norm 1, ``atol + rtol·|y|``)."""

    uses_linear_part = True

    name, order, solver_name = "radau", 5, "Radau"

    def _solver_kwargs(self, system):
        jac = getattr(system, "jacobian", None)
        if jac is None and getattr(system, "linear_part", None) is not None:
            jac = np.asarray(system.linear_part()[0], dtype=float)
        return {"jac": jac}

    def _estimates(self, solver) -> tuple[float, float]:
        return float(np.max(self.atol + self.rtol * np.abs(solver.y))), 1.0
