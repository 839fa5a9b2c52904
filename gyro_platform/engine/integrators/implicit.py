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

"""Implicit midpoint rule (A-stable, symplectic) on the controlled grid of :class:`~.base.Controlled`.

``implicit_midpoint``: keeps quadratic invariants to round-off; estimate by step doubling (the
two half steps are kept, ``err = (y_½½ − y_1)/3``).
"""
from __future__ import annotations

import math

import numpy as np

from .base import Controlled, is_rejected
from .jacobian import fd_jacobian

__all__ = ["ImplicitMidpoint"]

_EPS = np.finfo(float).eps
_NEWTON_TOL = 2 * _EPS    # Newton to round-off (relative, 2-norm), so quadratic invariants
# drift by round-off only, not by 1e-14 per step
_NEWTON_MAXITER = 10


class ImplicitMidpoint(Controlled):
    """Implicit midpoint rule ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)``, by step doubling.

    Each substep is taken once with h and twice with h/2; the two half steps are kept (so the
    map stays a composition of midpoint steps: symplectic, quadratic invariants to round-off)
    and ``err = (y_½½ − y_1)/3``. The midpoint stage ``Y = y0 + (h/2) f(t + h/2, Y)`` is solved by
    simplified Newton with ``(I − h/2 J)⁻¹`` (J: ``system.jacobian`` at (t0, y0) per call, else
    ``linear_part`` A cached by (key, h), else a forward-difference Jacobian per call), until
    the increment, or the remainder estimated from the contraction rate, is ≤ 2 eps·‖Y‖₂ (or the
    iteration has stalled within 100× that). A stage that does not converge in 10 iterations
    rejects the interval (it is redone with smaller substeps).
    """

    uses_linear_part = True

    name, order, q1 = "implicit_midpoint", 2, 3

    def _prepare(self, system, t0, y0):
        jac = getattr(system, "jacobian", None)
        lp = getattr(system, "linear_part", None)
        nrhs = 0
        if jac is not None:
            self._J, self._key = np.asarray(jac(t0, y0), dtype=float), None
        elif lp is not None:
            J, self._key = lp()
            self._J = np.asarray(J, dtype=float)
        else:
            self._J, self._key = fd_jacobian(system.rhs, t0, y0), None
            nrhs = y0.size
        self._call_cache: dict[float, np.ndarray] = {}
        return nrhs

    def _newton_matrix(self, h: float) -> np.ndarray:
        J, key, n = self._J, self._key, self._J.shape[0]

        def make():
            return _inv(np.eye(n) - 0.5 * h * J)
        if key is not None:
            return self._cached(key, h, make)
        M = self._call_cache.get(h)
        if M is None:
            M = self._call_cache[h] = make()
        return M

    def _stage(self, rhs, t: float, y: np.ndarray, h: float, fp: np.ndarray):
        """One midpoint step; returns (y1, f at the midpoint, rhs calls) or (None, None, calls)."""
        Minv = self._newton_matrix(h)
        hh = 0.5 * h
        Y = y + hh * fp
        tm = t + hh
        dprev = math.inf
        dot, sqrt = np.dot, math.sqrt
        for it in range(_NEWTON_MAXITER):
            f = np.asarray(rhs(tm, Y))
            d = Minv @ (Y - y - hh * f)
            Y = Y - d
            dn = sqrt(dot(d, d))
            tol = _NEWTON_TOL * sqrt(dot(Y, Y))
            if not math.isfinite(dn):
                return None, None, it + 1
            if dn <= tol:
                return 2.0 * Y - y, f, it + 1
            if dprev < math.inf:
                theta = dn / dprev              # contraction rate of the simplified Newton
                if theta < 1.0 and theta * dn <= (1.0 - theta) * tol:
                    return 2.0 * Y - y, f, it + 1
                if theta >= 0.5 and dn <= 100.0 * tol:
                    return 2.0 * Y - y, f, it + 1
            dprev = dn
        if dn <= 100.0 * tol:
            return 2.0 * Y - y, f, _NEWTON_MAXITER
        return None, None, _NEWTON_MAXITER

    def _substeps(self, system, t0, y0, nsub, h):
        rhs = system.rhs
        y = y0.copy()
        fp = np.zeros_like(y)
        worst = est = 0.0
        nrhs = 0
        for i in range(nsub):
            t = t0 + i * h
            y_full, _, n1 = self._stage(rhs, t, y, h, fp)
            ya, fa, n2 = self._stage(rhs, t, y, 0.5 * h, fp) if y_full is not None else (None, None, 0)
            yb, fb, n3 = self._stage(rhs, t + 0.5 * h, ya, 0.5 * h, fa) if ya is not None else (None, None, 0)
            nrhs += n1 + n2 + n3
            if yb is None:
                return y, math.inf, math.nan, nrhs, t
            err = (yb - y_full) / 3.0
            nrm, est, worst = self._judge(err, y, yb, est, worst)
            if is_rejected(nrm):
                return yb, (math.inf if nrm != nrm else nrm), est, nrhs, t
            y, fp = yb, fb
        return y, worst, est, nrhs, t0


def _inv(M: np.ndarray) -> np.ndarray:
    """Inverse via LU (used once per (key, h) or per call, never in the step loop)."""
    import scipy.linalg  # here, not at import (see exponential._phi_blocks)

    return scipy.linalg.lu_solve(scipy.linalg.lu_factor(M), np.eye(M.shape[0]))
