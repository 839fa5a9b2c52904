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

"""Jacobians ∂f/∂y of an ODE system: its own, or by forward differences.

Used by the methods that linearise (exprb, implicit midpoint) and by the hard-case catalogue
(the linear part of a model without one).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["fd_jacobian", "jacobian_of"]

_EPS = np.finfo(float).eps


def fd_jacobian(rhs, t: float, y: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian ∂f/∂y of ``rhs(t, y)`` at (t, y) (n extra rhs calls; n×n,
    units of f per unit of y). Step per component ``√eps·max(|y_j|, 1e-3·max(‖y‖∞, 1e-8))``:
    accurate to ~1e-8 relative, enough for Newton and for a linear part."""
    f0 = np.asarray(rhs(t, y), dtype=float).copy()
    n = y.size
    J = np.empty((n, n))
    scale = max(np.abs(y).max(), 1e-8) * 1e-3
    yp = y.copy()
    for j in range(n):
        dj = math.sqrt(_EPS) * max(abs(y[j]), scale)
        yp[j] = y[j] + dj
        J[:, j] = (np.asarray(rhs(t, yp), dtype=float) - f0) / (yp[j] - y[j])
        yp[j] = y[j]
    return J


def jacobian_of(system, t: float, y: np.ndarray) -> tuple[np.ndarray, int]:
    """(∂f/∂y, rhs calls): ``system.jacobian`` if it has one, else forward differences."""
    jac = getattr(system, "jacobian", None)
    if jac is not None:
        return np.asarray(jac(t, y), dtype=float), 0
    return fd_jacobian(system.rhs, t, y), y.size
