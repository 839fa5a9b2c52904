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

"""Model options: how the vehicle drives the platform, which fidelity, which effects are on.

Every effect is off unless named. An effect that is off is not evaluated at all (its branch in
the kernels is skipped), so a scene pays only for what it asks for. See ``effects`` for what
each one adds.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Iterable

MODES = ("carried", "stabilised")
FIDELITIES = ("full", "linear", "precession")
EFFECTS: dict[str, str] = {
    "rotor_gyroscopic": "rotor relative momenta L: gyroscopic coupling G_R ẋ and Ω × Bᵀ L",
    "coriolis": "velocity-quadratic terms without L (Coriolis/centrifugal G_A, ω × Iω)",
    "vehicle_angular_acceleration": "carried mode: inertia of the gyros against the vehicle's Ω̇ (J·Ω̇ terms)",
    "gimbal_springs": "restraint springs −c q on each gimbal axis",
    "gimbal_dampers": "viscous dampers −d q̇ on each gimbal axis",
    "gimbal_friction": "gimbal bearing friction: viscous + smoothed Coulomb (causes drift)",
    "bias_torque": "constant g-insensitive gimbal torques b_k",
    "support_friction": "stabilised mode: vehicle-to-platform mount friction, viscous + smoothed Coulomb",
    "servo": "stabilised mode: PID pick-off servo on the mount axes, saturated",
    "earth_rate": "local-level reference rotating with the Earth, gyro torquer compensation (9.4)",
    "mass_unbalance": "CG of each housing+rotor offset along the spin axis: torque −m r × f (needs specific force)",
    "anisoelastic": "compliance difference along/across the spin axis: r = −m ΔK (s·f) s, then as unbalance",
}
#: effects that need the vehicle specific force in the input
NEEDS_SPECIFIC_FORCE = frozenset({"mass_unbalance", "anisoelastic"})
STABILISED_ONLY = frozenset({"support_friction", "servo"})
#: the effects that evaluate a ``PlatformParams`` field (any of them); the fields not named here
#: (inertias, rotor speeds, mounting) are used whatever the effects
PARAM_EFFECTS: dict[str, frozenset[str]] = {
    "spring": frozenset({"gimbal_springs"}),
    "damper": frozenset({"gimbal_dampers"}),
    "gimbal_coulomb": frozenset({"gimbal_friction"}),
    "gimbal_viscous_friction": frozenset({"gimbal_friction"}),
    "friction_rate_eps": frozenset({"gimbal_friction"}),
    "bias_torque": frozenset({"bias_torque"}),
    "support_viscous": frozenset({"support_friction"}),
    "support_coulomb": frozenset({"support_friction"}),
    "support_rate_eps": frozenset({"support_friction"}),
    "servo_kp": frozenset({"servo"}),
    "servo_kd": frozenset({"servo"}),
    "servo_ki": frozenset({"servo"}),
    "servo_limit": frozenset({"servo"}),
    "gyro_mass": frozenset({"mass_unbalance", "anisoelastic"}),
    "unbalance": frozenset({"mass_unbalance"}),
    "anisoelastic": frozenset({"anisoelastic"}),
    "latitude": frozenset({"earth_rate"}),
    "earth_rate": frozenset({"earth_rate"}),
}

DEFAULT_EFFECTS = {
    "carried": frozenset({"rotor_gyroscopic", "coriolis", "vehicle_angular_acceleration"}),
    "stabilised": frozenset({"rotor_gyroscopic", "coriolis", "support_friction", "servo"}),
}


#: default fidelity per mode: a stabilised platform keeps its gimbals within ~1e-8 rad, where
#: the linear model (spec 6.3) equals the full one to the integration error (see ``bench``);
#: a carried platform's gimbals swing through large angles, so it takes the full model.
DEFAULT_FIDELITY = {"carried": "full", "stabilised": "linear"}


#: bounds of ``max_step`` (s) and the smallest ``rtol`` (double precision round-off ~1e-16 per
#: step, accumulated over a step's stages and a run's steps)
MAX_STEP_RANGE = (1e-6, 1.0)
RTOL_MIN = 1e-13


class OptionsError(ValueError):
    """Bad model options; the message names the option and what is allowed."""


@dataclass(frozen=True)
class ModelOptions:
    """``mode``: carried | stabilised; ``fidelity``: full | linear | precession;
    ``effects``: names from ``EFFECTS``; ``integrator``: a name from ``integrators`` or
    ``auto``; ``max_step`` (s): the largest internal step of a fixed-step integrator (the
    equal-step ones take an input interval up to 1.1·max_step as one step: ``STEP_SLACK``);
    ``rtol``/``atol``: the local error tolerance every integrator is held to (weighted RMS
    norm of its error estimate ≤ 1, scale ``atol + rtol·|y|``; state units: rad, rad/s, …);
    ``max_substeps``: budget, no step shorter than ``max_step / max_substeps`` (a method that
    cannot meet the tolerance with it raises ``SimulationError``). Bounds: ``max_step`` in
    ``MAX_STEP_RANGE`` (1 µs … 1 s), ``rtol`` in [``RTOL_MIN`` = 1e-13, 1), ``atol`` in (0, 1),
    ``max_substeps`` an integer in [1, 2^24]; anything else: ``OptionsError`` naming the option."""

    mode: str = "stabilised"
    fidelity: str = DEFAULT_FIDELITY["stabilised"]
    effects: frozenset[str] = field(default_factory=lambda: DEFAULT_EFFECTS["stabilised"])
    integrator: str = "auto"
    max_step: float = 1e-3
    rtol: float = 1e-6
    atol: float = 1e-9
    max_substeps: int = 4096

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise OptionsError(f"option 'mode' = {self.mode!r}; allowed: {', '.join(MODES)}")
        if self.fidelity not in FIDELITIES:
            raise OptionsError(f"option 'fidelity' = {self.fidelity!r}; allowed: {', '.join(FIDELITIES)}")
        eff = frozenset(self.effects)
        unknown = sorted(eff - set(EFFECTS))
        if unknown:
            raise OptionsError(f"option 'effects': unknown effect(s) {unknown}; known: {sorted(EFFECTS)}")
        if self.mode == "carried" and eff & STABILISED_ONLY:
            raise OptionsError(f"option 'effects': {sorted(eff & STABILISED_ONLY)} need mode 'stabilised'")
        for name in ("max_step", "rtol", "atol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v:
                raise OptionsError(f"option '{name}' = {v!r}: a real number is needed")
        if not (MAX_STEP_RANGE[0] <= self.max_step <= MAX_STEP_RANGE[1]):
            raise OptionsError(f"option 'max_step' = {self.max_step} s; allowed [{MAX_STEP_RANGE[0]:g}, "
                               f"{MAX_STEP_RANGE[1]:g}] s (shorter steps cost more than 1000 steps per 1 ms sample)")
        if not (RTOL_MIN <= self.rtol < 1.0):
            raise OptionsError(f"option 'rtol' = {self.rtol}; allowed [{RTOL_MIN:g}, 1) (below {RTOL_MIN:g} the "
                               "error estimate is round-off: the tolerance cannot be met)")
        if not (0.0 < self.atol < 1.0):
            raise OptionsError(f"option 'atol' = {self.atol}; allowed (0, 1)")
        if not (isinstance(self.max_substeps, int) and 1 <= self.max_substeps <= 2 ** 24):
            raise OptionsError(f"option 'max_substeps' = {self.max_substeps!r}; allowed: an integer in [1, 2^24]")
        object.__setattr__(self, "effects", eff)

    def has(self, effect: str) -> bool:
        return effect in self.effects

    def with_(self, **changes: Any) -> "ModelOptions":
        return replace(self, **changes)

    @staticmethod
    def make(mode: str = "stabilised", fidelity: str | None = None,
             effects: Iterable[str] | None = None, **kw: Any) -> "ModelOptions":
        """Options with the mode's default fidelity and effects unless given."""
        eff = DEFAULT_EFFECTS.get(mode, frozenset()) if effects is None else frozenset(effects)
        fid = DEFAULT_FIDELITY.get(mode, "full") if fidelity is None else fidelity
        return ModelOptions(mode=mode, fidelity=fid, effects=eff, **kw)
