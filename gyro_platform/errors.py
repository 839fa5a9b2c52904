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

"""Exceptions, exit codes and the one finite-number rule shared by every room (the leaf: imports
only the standard library).

Simulation errors derive from ``SimulationError`` (a ``ValueError``); bag errors from
``BagReadError``; ``ReplayError`` is a replay that cannot start; ``OutputError`` an output that
cannot be written. ``EXIT_*``/``EXIT_CODES``: the exit status of every ``gyro-platform``
command; :func:`check_number`: the one rule for numbers of options, parameters and flags
(finite, within bounds). Stop signals are in ``signals``, output paths in ``filesystem``.
"""
import math
import numbers


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


class RunStopped(Exception):
    """A run ended between two chunks because its caller asked it to (a Dask worker closing
    under an interrupted sweep: ``scenes.runner.run_scene``'s ``stop``); what it computed is
    dropped with the stopped sweep."""


class OutputError(Exception):
    """An output cannot be written: refused before the start (read-only or missing folder, a path
    under a file, a folder where a file goes) or failed during the run (disk full, file size
    limit, I/O error). The message names the path and the cause in one line."""


# ---- numbers ---------------------------------------------------------------------------------
def not_finite(x) -> str | None:
    """The one rule of every numeric flag and parameter (command-line flags, scene and sweep
    files, node parameters, ``GateConfig``): a real number, and finite. None if ``x`` is one,
    else why not in words the caller prefixes with the name (``expected a finite number, got
    inf``): ``inf`` is no "no limit" anywhere."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        return f"expected a number, got {type(x).__name__} {x!r}"
    return None if math.isfinite(x) else f"expected a finite number, got {float(x)!r}"


def check_number(name: str, x, unit: str = "", *, gt: float | None = None, ge: float | None = None,
                 le: float | None = None) -> float:
    """``x`` as a float if :func:`not_finite` has nothing against it and it is within the bounds
    (``> gt``, ``>= ge``, ``<= le``); else ValueError ``"{name} = {x} {unit}; …"`` (one line)."""
    what = f"{name} = {x!r}{' ' + unit if unit else ''}"
    why = not_finite(x)
    if why is None and gt is not None and not x > gt:
        why = f"must be > {gt:g}"
    elif why is None and ge is not None and not x >= ge:
        why = f"must be >= {ge:g}"
    elif why is None and le is not None and not x <= le:
        why = f"must be <= {le:g}"
    if why is not None:
        raise ValueError(f"{what}; {why}")
    return float(x)


# ---- exit status of every command (re-exported by ``gyro_platform.cli``) ----------------
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DATA, EXIT_WRITE = 0, 1, 2, 3, 4
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143          # 128 + SIGINT, 128 + SIGTERM
EXIT_CODES: dict[int, str] = {
    EXIT_OK: "success",
    EXIT_FAILED: "ran but failed: an expectation failed or was not evaluable, the simulation failed or "
                 "went through gimbal lock ill-conditioned, or the transport could not start",
    EXIT_USAGE: "bad argument or path, refused before anything is written (unknown flag, value out of "
                "range, missing file, not a bag/scene, invalid scene, unwritable output path, a run "
                "beyond the memory/step bounds)",
    EXIT_DATA: "unusable input data: a damaged bag (the readable part is processed and written), or no "
               "usable input sample (empty topic, every sample dropped or refused: no outputs)",
    EXIT_WRITE: "an output could not be written during the run (disk full, file size limit, I/O error); "
                "what was written is closed",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C, SIGINT); files written so far are closed and readable",
    EXIT_TERMINATED: "terminated (SIGTERM: systemd, docker stop, CI time-outs); the same orderly stop as Ctrl-C",
}
