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

"""The single gimballed gyro with massive gimbals ([MBB] section 7) on the same body-tree engine.

Base (prescribed rate, usually at rest) → outer ring (α about base +z) → inner ring
(β about outer +x) → rotor spinning freely about inner +y (its spin rate γ̇ is a velocity DOF:
``rotor_speed = free``). Coordinates ``q = (α, β)``, velocities ``v = (α̇, β̇, γ̇)`` (rad, rad/s).

With massless rings the rotor obeys Euler's equations of a free symmetric top and the mass
matrix has ``det = A² C cos² β`` (spec O7 d): singular at gimbal lock β = ±90°. With massive
rings ``det = C (A + Ix_in)(Iz_out + (A + Iz_in) cos² β + Iy_in sin² β)`` stays positive.
Near lock the massless case raises ``GimbalLockError`` instead of returning Inf/NaN.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .params import ParameterError
from .tree import BodyTree, REVOLUTE, ROOT, SPIN, tree_inverse_dynamics, tree_mass_and_bias, TreeWork
from ..errors import GimbalLockError

#: reciprocal condition number of the mass matrix below which the gyro is reported locked
LOCK_RCOND = 1e-12


@dataclass(frozen=True)
class GimballedGyro:
    """Rotor (axial C, equatorial A) in an inner ring (principal moments ``inner``) in an outer
    ring (``outer``), kg m². Zero ring moments give the massless-gimbal (Euler) limit."""

    C: float = 2.0e-5
    A: float = 1.2e-5
    inner: tuple[float, float, float] = (3.0e-5, 2.0e-5, 3.0e-5)
    outer: tuple[float, float, float] = (8.0e-5, 8.0e-5, 6.0e-5)

    def __post_init__(self) -> None:
        for name, vals in (("C", (self.C,)), ("A", (self.A,)), ("inner", self.inner), ("outer", self.outer)):
            for x in vals:
                if not np.isfinite(x) or x < 0:
                    raise ParameterError(f"parameter '{name}' = {vals} must be finite and ≥ 0")
        if self.C <= 0 or self.A <= 0 or self.C > 2 * self.A:
            raise ParameterError(f"rotor moments C = {self.C}, A = {self.A}: need 0 < C ≤ 2A")

    def tree(self) -> BodyTree:
        inertia = np.zeros((4, 3, 3))
        inertia[1] = np.diag(self.outer)
        inertia[2] = np.diag(self.inner)
        inertia[3] = np.diag([self.A, self.C, self.A])
        return BodyTree(
            names=("base", "outer", "inner", "rotor"),
            parent=np.array([-1, 0, 1, 2], dtype=np.int64),
            jtype=np.array([ROOT, REVOLUTE, REVOLUTE, SPIN], dtype=np.int64),
            axis=np.array([[0, 0, 0], [0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]]),
            qidx=np.array([-1, 0, 1, -1], dtype=np.int64),
            vidx=np.array([-1, 0, 1, 2], dtype=np.int64),
            inertia=inertia,
            rotor_host=np.zeros(0, dtype=np.int64), rotor_axis=np.zeros((0, 3)),
            rotor_C=np.zeros(0), rotor_A=np.zeros(0),
            root_dynamic=False, nq=2, nv=3)


class GyroModel:
    """Equations of motion ``M(q) v̇ + c(q, v) = Q`` of a ``GimballedGyro`` on a base turning
    at the constant rate ``base_rate`` (rad/s, base axes)."""

    def __init__(self, gyro: GimballedGyro, base_rate=(0.0, 0.0, 0.0)):
        self.gyro = gyro
        self.tree = gyro.tree()
        self.work = TreeWork(self.tree)
        self.w0 = np.asarray(base_rate, float)
        self._z3 = np.zeros(3)
        self._noL = np.zeros(0)

    def mass_matrix(self, q) -> np.ndarray:
        M, _ = tree_mass_and_bias(self.tree, self.work, np.asarray(q, float), np.zeros(3), self.w0,
                                  self._z3, self._noL)
        return M.copy()

    def accelerations(self, q, v, Q=(0.0, 0.0, 0.0)) -> np.ndarray:
        """v̇ (rad/s²). Raises ``GimbalLockError`` where M is singular (massless rings at lock)."""
        M, c = tree_mass_and_bias(self.tree, self.work, np.asarray(q, float), np.asarray(v, float),
                                  self.w0, self._z3, self._noL)
        ev = np.linalg.eigvalsh(M)
        if ev[0] <= LOCK_RCOND * ev[-1]:
            raise GimbalLockError(
                f"gimbal lock: inner ring angle β = {np.degrees(q[1]):.6f}° makes the mass matrix singular "
                f"(reciprocal condition {ev[0] / ev[-1]:.3g}); massless rings cannot carry the rotor through "
                "±90° — give the rings mass (massive gimbals) or keep β away from ±90°")
        return np.linalg.solve(M, np.asarray(Q, float) - c)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """State y = (α, β, α̇, β̇, γ̇)."""
        return np.concatenate([y[2:4], self.accelerations(y[:2], y[2:])])

    def simulate(self, y0, t_end: float, rtol: float = 1e-10, atol: float = 1e-12, **kw):
        """Torque-free motion from y0 with scipy's DOP853 (the reference integrator)."""
        return solve_ivp(self.rhs, (0.0, t_end), np.asarray(y0, float), method="DOP853", rtol=rtol,
                         atol=atol, **kw)

    def rotor_state(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """Rotor angular velocity in rotor(=inner ring) axes and its angular momentum in base
        axes (N m s)."""
        tree, wk = self.tree, self.work
        F, f, _ = tree_inverse_dynamics(tree, wk, np.asarray(q, float), np.asarray(v, float), np.zeros(3),
                                        self.w0, self._z3, self._noL)
        w_r = wk.w[3].copy()
        H_r = tree.inertia[3] @ w_r
        R_base_rotor = wk.R[1] @ wk.R[2] @ wk.R[3]
        return w_r, R_base_rotor @ H_r
