"""Exceptions and exit codes shared by every room (the leaf: imports nothing).

Simulation errors derive from ``SimulationError`` (a ``ValueError``); bag errors from
``BagReadError``; ``ReplayError`` is a replay that cannot start. ``EXIT_*``/``EXIT_CODES``: the
exit status of every ``gyro-platform`` command.
"""


class SimulationError(ValueError):
    """The simulation cannot go on as asked; the state is left as it was before the call."""


class GimbalLockError(SimulationError):
    """A gimbal came so close to ±90° that the model's equations are singular there."""


class PrecessionInvalidError(SimulationError):
    """The precession approximation is invalid for this configuration (det G_R = 0, …)."""


class InputError(SimulationError):
    """An input sample cannot be used (non-finite, out of order, out of range)."""


class NonFiniteOutputError(SimulationError):
    """An output quantity came out NaN or infinite although the state is finite (e.g. bearing
    torques overflowing under an absurd specific force). The message names the quantity and the
    time; ``quantity`` (str), ``t`` (s) and, for a block of instants, ``block`` (the
    ``OutputBlock`` of the instants before it) tell a program. Nothing non-finite is published."""

    def __init__(self, message: str, quantity: str = "", t: float = float("nan")):
        super().__init__(message)
        self.quantity = quantity
        self.t = t


class ToleranceError(SimulationError):
    """The integrator cannot meet the asked tolerance (rtol/atol) within its step budget
    (``max_substeps``); the message names the time, the method, the estimate and the tolerance."""


# ---- bags and replay (not simulation errors: a bad file or option, not a bad state) -------
class BagReadError(Exception):
    """The input bag cannot be read (further); the message names the file and what failed."""


class BagPathError(BagReadError):
    """The input path is not a rosbag2 bag at all (missing, a ROS 1 bag, a YAML or other file,
    a folder without storage file): a bad input path, not damaged data."""


class ReplayError(Exception):
    """The replay cannot start as asked (no input topic, output exists, topic clash …)."""


# ---- exit status of every command (re-exported by ``gyro_platform.cli``) ----------------
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DATA, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
EXIT_CODES: dict[int, str] = {
    EXIT_OK: "success",
    EXIT_FAILED: "ran but failed: an expectation failed or was not evaluable, or the transport could not start",
    EXIT_USAGE: "bad argument or input path (unknown flag, missing file, not a bag/scene, invalid scene)",
    EXIT_DATA: "corrupt input data (damaged bag; the readable part is processed and written)",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C); files written so far are closed and readable",
}
