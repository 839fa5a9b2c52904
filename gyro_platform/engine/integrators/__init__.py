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

"""Time integrators for the simulator: one ``advance(system, t0, y0, t1)`` per input sample.

One contract (:mod:`.base`: ``Integrator``, ``StepStats``, the weighted error norm, the
step-size controller of the fixed-grid methods, ``OdeSystem``), one module per family, one front
door (:mod:`.registry`: ``INTEGRATORS``, ``INTEGRATOR_CHOICES``, ``make_integrator``). Every
method is given ``rtol``/``atol`` and ``max_step``, estimates its local error and refuses
(``ToleranceError``) rather than return a state outside the tolerance; see :mod:`.base`.

Methods (see ``INTEGRATORS``):

- ``rk4`` (:mod:`.rk`): classic RK4 with an embedded third-order estimate.
- ``etd2``, ``etd4``, ``exprb`` (:mod:`.exponential`): exponential integrators about the rest
  state (ETD2RK, ETDRK4) or re-linearised at every step (exprb32); their φ-functions.
- ``implicit_midpoint`` (:mod:`.implicit`): A-stable, symplectic, step doubling.
- ``dop853``, ``rk45``, ``radau`` (:mod:`.scipy_methods`): scipy's ``OdeSolver`` step API.
- ``auto`` (:mod:`.auto`): a primary method chosen from the system's fastest mode, with the
  exprb fallback and the rk4 rescue (built by the registry like the others; the simulator
  gives the model's rate).

:mod:`.jacobian` holds the Jacobians (a system's own or forward differences) the linearising
methods share. Imports only ``errors`` and ``physics.jit`` (and numpy, scipy, numba).
"""
from .auto import (Auto, AUTO_ETD4_BELOW, AUTO_FALLBACK, auto_method, AUTO_RESCUE, AUTO_RK4_LIMIT,
                   AUTO_RK4_MAX_RTOL, AUTO_RK4_MIN_RTOL, AUTO_STICKY)
from .base import (aimed_switch, COARSEN, coarser_level, Controlled, error_norm, finest_level, held_level, HOLD_KINKS,
                   Integrator, is_micro_step, level_substeps, LOOKBACK_AIM, MAX_JUMP, MAX_PIECE_JUMP, MAX_SUBSTEPS,
                   MAX_SWITCHES, MICRO_STEP, next_level, next_piece_level, OdeSystem, piece_substeps, shortened_piece,
                   STEP_SLACK, StepStats, SWITCH_AIM, SWITCH_EDGE, SWITCH_MIN)
from .exponential import ETD2, ETD4, ExpRosenbrock, TAIL_MIN, TAIL_ULP, taylor_bound, TAYLOR_MAX, TAYLOR_TOL
from .implicit import ImplicitMidpoint
from .jacobian import fd_jacobian, jacobian_of
from .registry import INTEGRATOR_CHOICES, INTEGRATORS, make_integrator
from .rk import RK4
from .scipy_methods import DOP853, Radau, RK45

__all__ = ["OdeSystem", "StepStats", "Integrator", "Controlled", "make_integrator", "INTEGRATORS",
           "INTEGRATOR_CHOICES", "error_norm", "MAX_SUBSTEPS", "COARSEN", "MAX_JUMP", "STEP_SLACK", "SWITCH_MIN",
           "MAX_SWITCHES", "SWITCH_EDGE", "SWITCH_AIM", "aimed_switch", "LOOKBACK_AIM", "shortened_piece",
           "piece_substeps", "next_piece_level", "MAX_PIECE_JUMP",
           "is_micro_step", "MICRO_STEP", "held_level", "HOLD_KINKS",
           "level_substeps", "next_level", "coarser_level",
           "finest_level", "Auto",
           "AUTO_STICKY", "AUTO_FALLBACK", "AUTO_RESCUE", "auto_method", "AUTO_RK4_LIMIT", "AUTO_RK4_MAX_RTOL",
           "AUTO_RK4_MIN_RTOL",
           "AUTO_ETD4_BELOW", "RK4", "ETD2",
           "ETD4",
           "ExpRosenbrock", "ImplicitMidpoint", "DOP853", "RK45", "Radau", "fd_jacobian", "jacobian_of",
           "TAIL_MIN", "TAIL_ULP", "TAYLOR_MAX", "TAYLOR_TOL", "taylor_bound"]
