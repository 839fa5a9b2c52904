"""``auto``: a cheap primary method with a robust fallback for the intervals it refuses."""
from __future__ import annotations

from ...errors import ToleranceError
from .base import Controlled, Integrator

__all__ = ["Auto", "AUTO_STICKY"]


class Auto(Integrator):
    """``auto``: a cheap primary method (compiled batch path); an interval it cannot bring within
    the tolerance within the budget is done by the fallback (exprb, re-linearised at every
    step), and so are the next ``AUTO_STICKY`` intervals (the hard stretch usually lasts), then
    the primary is tried again. Both honour rtol/atol."""

    def __init__(self, primary: "Controlled", fallback: Integrator) -> None:
        super().__init__(fallback.max_step, fallback.rtol, fallback.atol, fallback.max_substeps)
        self.primary, self.fallback = primary, fallback
        self.name = f"auto:{primary.name}+{fallback.name}"
        self.order = primary.order
        self.uses_linear_part = primary.uses_linear_part
        self.n_fallback = 0
        self.sticky = 0

    def _advance(self, system, t0, y, t1):
        if self.sticky == 0:
            try:
                return self.primary._advance(system, t0, y.copy(), t1)
            except ToleranceError:
                self.sticky = AUTO_STICKY
        self.sticky -= 1
        self.n_fallback += 1
        return self.fallback._advance(system, t0, y, t1)

    def reset(self) -> None:
        self.primary.reset()
        self.fallback.reset()
        self.n_fallback = 0
        self.sticky = 0


#: intervals auto gives to its fallback after the primary refused one
AUTO_STICKY = 100
