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

"""``auto``: a cheap primary method with a robust fallback for the intervals it refuses, a last
resort for the intervals both refuse, and the rule that picks the primary (:func:`auto_method`,
from the system's fastest mode; the registry builds ``auto`` with it)."""
from __future__ import annotations

from .base import Controlled, Integrator
from ...errors import ToleranceError

__all__ = ["Auto", "AUTO_STICKY", "AUTO_FALLBACK", "AUTO_RESCUE", "auto_method", "AUTO_RK4_LIMIT", "AUTO_RK4_MAX_RTOL",
           "AUTO_RK4_MIN_RTOL", "AUTO_ETD4_BELOW"]

#: the method ``auto`` falls back to (re-linearised at every step: large angles, fast rotors)
AUTO_FALLBACK = "exprb"
#: the method ``auto`` tries where its primary and its fallback both refuse an interval. Only
#: RK4 ends its steps at the support friction's regime changes (``locates_switches``); the
#: exponential methods step over them, and below rtol ~1e-9 the error of a step holding a change
#: stays above the tolerance however short the step (the 1 kHz vehicle IMU at rtol 1e-10: etd4
#: and exprb report 17–220× the tolerance at steps of max_step/4096, and deliver without the
#: friction), while RK4 delivers (37–77 right-hand sides a sample). Like every method it refuses
#: what it cannot bring within tolerance.
AUTO_RESCUE = "rk4"
#: ``auto`` (see ``auto_method``): RK4 where the fastest mode λ is resolved at the step
#: (h·λ < AUTO_RK4_LIMIT; RK4's stability boundary is 2.8 on the imaginary axis) and the
#: tolerance is tight enough that its numerical damping of the nutation stays negligible
#: (rtol ≤ AUTO_RK4_MAX_RTOL); otherwise etd2, which integrates the gyroscopic linear part
#: exactly at any spin. Intervals the primary cannot bring within tolerance go to exprb, then rk4.
AUTO_RK4_LIMIT = 1.5
AUTO_RK4_MAX_RTOL = 1e-6
#: below this rtol an excited nutation costs RK4 ≥ 1/(24 rtol)^¼·ωh ≈ 100 substeps per 1 ms
#: sample at ×1: etd2 (exact on the nutation) is cheaper
AUTO_RK4_MIN_RTOL = 1e-9
#: below this rtol auto's exponential method is etd4 (order 4: its error falls much faster
#: with the step than etd2's, and it keeps invariants to 1e-10 over 1000 nutation periods)
AUTO_ETD4_BELOW = 1e-9


def auto_method(h_lambda: float, rtol: float, excited: bool, switches: bool = False) -> str:
    """The primary method of ``auto``: the cheaper one that reaches the tolerance without
    damping the nutation. ``h_lambda``: the system's fastest characteristic rate λ (rad/s or
    1/s) times the step bound max_step; ``rtol``: the relative tolerance; ``excited``: the
    motion excites the nutation (a carried platform, whose gimbals the vehicle drives directly);
    ``switches``: the model has regime changes that only RK4 ends its steps at (a stabilised
    platform's mount friction, ``AUTO_RESCUE``): RK4 whatever the rest (below).

    RK4 (compiled, 4 right-hand sides per step) is the cheapest per step and its substeps
    follow what the motion excites; but it must resolve the fastest mode λ for stability
    (h·λ < 2.8), and it damps a nutation ω by ≈ (hω)⁶/72 per step. Held to rtol its local error
    (hω)⁴/24 ≤ rtol gives hω ≤ (24 rtol)^¼, i.e. a T2 loss ≤ 1000·2π(hω)⁵/72 ≤ 1e-4 over 1000
    nutation periods for rtol ≤ 1e-6; below rtol 1e-9 resolving an excited nutation costs RK4
    more than etd2. Beyond the stability limit (fast rotors), at looser or at tighter tolerance:
    etd2 (exact on the gyroscopic linear part, cost independent of the spin), etd4 below
    rtol 1e-9 (fourth order: fewer substeps at tight tolerance).

    An excited nutation is integrated exactly by an exponential method and only resolved by
    RK4 (damping it a little every step). A stabilised platform is held by its servo and the
    nutation stays quiet: RK4, the cheapest there (husky: rk4 61 substeps, 262 rhs per sample
    against etd2's 98 and 209, 2.8× less CPU; 1 kHz: 2.7× less; session 3).

    An excited system takes etd4 at every tolerance: a carried platform's free gyros integrate
    every step's error, and etd2's local errors there add up far beyond what it reports (ship
    motion at 1 kHz, rtol 1e-6: gimbal angles 5.6e-6 rad off after 10 s, 1.0e-4 after 30 s,
    largest local estimate 2.3e-8; etd4 3.9e-11 after 30 s at 1.4× etd2's CPU, 3.4× on rate
    steps).

    A model with regime changes (``switches``) takes RK4 at every tolerance and spin: it alone
    ends its steps at the mount friction's kinks. The exponential methods step over them:
    below rtol ~1e-9 they refuse at the first one however short the step, so every interval
    went down the chain to the rescue, RK4 itself in Python (the 1 kHz vehicle IMU at rtol
    1e-10 … 1e-12: 60–145× the CPU of RK4 alone; rotors at ×3: 150–400×); above it etd2's
    defect estimate does not see what a step across a kink loses (the true local error of 1 ms
    intervals holding one 100–6000× the tolerance at an estimate ≤ 1, rtol 1e-4 … 1e-6), so its
    delivered error stays at 1.3e-7–2e-6 rad whatever the tolerance asked, where RK4 delivers
    1e-11 in less CPU (the 1 kHz vehicle IMU, 10 s: 1.9–2.1 µs a sample against 3.0–3.6 at rtol
    1e-4 … 3e-6, a parked vehicle 6.3–6.7 against 5.0–29; rotors at ×10 3.3 against 3.7–4.9).
    RK4 pays for a fast nutation with its substeps (rotors at ×10: 14 right-hand sides a
    sample, ×1: 4.2); a stabilised platform's servo keeps the nutation quiet, and the error
    control holds what RK4's damping of it changes to the tolerance."""
    if switches:
        return "rk4"
    if h_lambda < AUTO_RK4_LIMIT and not excited and AUTO_RK4_MIN_RTOL <= rtol <= AUTO_RK4_MAX_RTOL:
        return "rk4"
    return "etd2" if rtol >= AUTO_ETD4_BELOW and not excited else "etd4"


class Auto(Integrator):
    """``auto``: a cheap primary method (compiled batch path); an interval it cannot bring within
    the tolerance within the budget is done by the fallback (exprb, re-linearised at every
    step) or, where that refuses too, the rescue (``AUTO_RESCUE``, unless it is the primary).
    The method that delivered keeps the next ``AUTO_STICKY`` intervals (the hard stretch
    usually lasts) and is tried first at the next hard stretch; then the primary is tried
    again. Every method honours rtol/atol; where none delivers, the last refusal is raised.

    ``n_fallback``: intervals done by a method other than the primary; ``n_rescue``: those of
    them done by the rescue. ``primary_refused``: set by a caller whose own (compiled) run of
    the primary refused the next interval; that interval starts at the fallback."""

    def __init__(self, primary: "Controlled", fallback: Integrator, rescue: Integrator | None = None) -> None:
        super().__init__(fallback.max_step, fallback.rtol, fallback.atol, fallback.max_substeps)
        self.primary, self.fallback, self.rescue = primary, fallback, rescue
        self.name = f"auto:{primary.name}+{fallback.name}"
        self.order = primary.order
        self.uses_linear_part = primary.uses_linear_part
        self._chain = (fallback,) if rescue is None else (fallback, rescue)
        #: the methods after the primary in the order they are tried (the last to deliver first)
        self.others = list(self._chain)
        self.n_fallback = 0
        self.n_rescue = 0
        self.sticky = 0
        self.primary_refused = False

    def _advance(self, system, t0, y, t1):
        refused, self.primary_refused = self.primary_refused, False
        if self.sticky == 0 and not refused:
            try:
                return self.primary.advance(system, t0, y, t1)
            except ToleranceError:
                pass
        refusal = None
        for i, method in enumerate(self.others):
            try:
                out = method.advance(system, t0, y, t1)
            except ToleranceError as e:
                refusal = e
                continue
            if i:                        # a later method delivered: it goes first next time
                self.others.insert(0, self.others.pop(i))
            self.sticky = self.sticky - 1 if self.sticky else AUTO_STICKY - 1
            self.n_fallback += 1
            self.n_rescue += method is self.rescue
            return out
        self.sticky = 0
        raise refusal

    def reset(self) -> None:
        self.primary.reset()
        for method in self._chain:
            method.reset()
        self.others = list(self._chain)
        self.n_fallback = 0
        self.n_rescue = 0
        self.sticky = 0
        self.primary_refused = False


#: intervals auto gives to the method that delivered after the primary refused one
AUTO_STICKY = 100
