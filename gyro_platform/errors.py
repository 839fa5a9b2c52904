"""Exceptions of the simulator. All derive from ``SimulationError`` (a ``ValueError``)."""


class SimulationError(ValueError):
    """The simulation cannot go on as asked; the state is left as it was before the call."""


class GimbalLockError(SimulationError):
    """A gimbal came so close to ±90° that the model's equations are singular there."""


class PrecessionInvalidError(SimulationError):
    """The precession approximation is invalid for this configuration (det G_R = 0, …)."""


class InputError(SimulationError):
    """An input sample cannot be used (non-finite, out of order, out of range)."""


class ToleranceError(SimulationError):
    """The integrator cannot meet the asked tolerance (rtol/atol) within its step budget
    (``max_substeps``); the message names the time, the method, the estimate and the tolerance."""
