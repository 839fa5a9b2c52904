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

"""The integrators by name: ``INTEGRATORS`` (name → description), ``INTEGRATOR_CHOICES`` (every
name an ``integrator`` option accepts: ``auto`` and the methods) and :func:`make_integrator`,
which builds them all, ``auto`` included."""
from __future__ import annotations

import math

from .auto import Auto, AUTO_FALLBACK, auto_method, AUTO_RESCUE
from .base import Integrator, MAX_SUBSTEPS
from .exponential import ETD2, ETD4, ExpRosenbrock
from .implicit import ImplicitMidpoint
from .rk import RK4
from .scipy_methods import DOP853, Radau, RK45

__all__ = ["INTEGRATORS", "INTEGRATOR_CHOICES", "make_integrator"]

INTEGRATORS: dict[str, str] = {
    "rk4": "classic explicit Runge-Kutta 4 with embedded 3rd-order estimate, substeps to rtol/atol "
           "(explicit: needs h*|lambda| < 2.8)",
    "dop853": "Dormand-Prince 8(5,3), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "rk45": "Dormand-Prince 5(4), adaptive (rtol/atol), scipy OdeSolver, warm-started step",
    "radau": "Radau IIA order 5, implicit adaptive (rtol/atol), for stiff damped systems",
    "implicit_midpoint": ("implicit midpoint, step doubling to rtol/atol, A-stable, symplectic, "
                          "keeps quadratic invariants"),
    "etd2": "exponential ETD2RK (Cox-Matthews) about the rest state, embedded estimate, substeps to rtol/atol",
    "etd4": "exponential ETDRK4 (Krogstad) about the rest state, embedded estimate, substeps to rtol/atol",
    "exprb": "exponential Rosenbrock exprb32, re-linearised every step, embedded estimate; large angles, fast rotors",
}

#: every name an ``integrator`` option accepts: ``auto`` (a primary method chosen by
#: ``auto.auto_method`` with the ``AUTO_FALLBACK`` fallback) and the methods of ``INTEGRATORS``
INTEGRATOR_CHOICES: tuple[str, ...] = ("auto", *INTEGRATORS)

_CLASSES: dict[str, type[Integrator]] = {
    "rk4": RK4, "dop853": DOP853, "rk45": RK45, "radau": Radau,
    "implicit_midpoint": ImplicitMidpoint, "etd2": ETD2, "etd4": ETD4, "exprb": ExpRosenbrock,
}


def make_integrator(name: str, *, max_step: float = 1e-3, rtol: float = 1e-8,
                    atol: float = 1e-12, max_substeps: int = MAX_SUBSTEPS, fastest_rate: float = 0.0,
                    excited: bool = False, switches: bool = False) -> Integrator:
    """A new integrator by name (see ``INTEGRATOR_CHOICES``).

    ``max_step`` (s): step bound; ``rtol``, ``atol`` (state units): local error tolerance;
    ``max_substeps``: budget (shortest step ``max_step/max_substeps``). ``auto`` only:
    ``fastest_rate`` (rad/s or 1/s), the system's fastest characteristic rate, ``excited``,
    whether its motion excites the nutation, and ``switches``, whether it has regime changes
    only RK4 locates, choose the primary method (``auto.auto_method``);
    the fallback is ``AUTO_FALLBACK``, the last resort ``AUTO_RESCUE`` (unless it is the
    primary). Raises ``ValueError`` for an unknown name or bad values.
    """
    if name == "auto":
        kw = {"max_step": max_step, "rtol": rtol, "atol": atol, "max_substeps": max_substeps}
        primary = auto_method(fastest_rate * max_step, rtol, excited, switches)
        rescue = make_integrator(AUTO_RESCUE, **kw) if primary != AUTO_RESCUE else None
        return Auto(make_integrator(primary, **kw), make_integrator(AUTO_FALLBACK, **kw), rescue)
    cls = _CLASSES.get(name)
    if cls is None:
        raise ValueError(f"unknown integrator {name!r}; known: {', '.join(INTEGRATOR_CHOICES)}")
    if not (0.0 < max_step < math.inf):
        raise ValueError(f"{name}: max_step must be a positive finite time in s, got {max_step!r}")
    if not (rtol > 0.0 and atol > 0.0):
        raise ValueError(f"{name}: rtol and atol must be positive, got {rtol!r}, {atol!r}")
    if not (int(max_substeps) >= 1):
        raise ValueError(f"{name}: max_substeps must be ≥ 1, got {max_substeps!r}")
    return cls(max_step, rtol, atol, int(max_substeps))
