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

"""The input gate's vocabulary and its one rule for a row's values.

What the gate decides (:class:`Action`, the reason tables :data:`REASONS` …, :class:`Decision`,
:class:`GateBlock` for a block's rows, :func:`plain_decision`), its settings (:class:`GateConfig`),
and :func:`row_verdict`: the bounds of a row's rate and specific force (finite, ‖ω‖ ≤ ``max_rate``,
‖f‖ ≤ ``max_specific_force``, f present if required). That rule is written once, here: the
per-message gate (:meth:`~gyro_platform.pipeline.gate.TimeGate.offer`, ``offer_plain``) and the
block pass (:func:`~gyro_platform.pipeline.gate_kernels.usable_rows`) call it. The gate itself is in
:mod:`gyro_platform.pipeline.gate`, its compiled block passes in
:mod:`gyro_platform.pipeline.gate_kernels`.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
import math

import numpy as np

from ..engine.inputs import RateSample
from ..errors import check_number
from ..physics.jit import njit

NS = 1_000_000_000


class Action(str, Enum):
    """What the caller does with a sample."""

    ACCEPT = "accept"
    DROP = "drop"
    RESET = "reset"   # reset the simulator, then push the sample


DROP_REASONS = ("no_rate", "unknown_frame", "bad_message", "non_finite", "over_rate", "over_specific_force",
                "no_specific_force", "zero_stamp", "no_time", "repeated_stamp", "backward_stamp", "refused")
RESET_REASONS = ("jump_back", "gap")
ACCEPT_REASONS = ("start", "ok")
#: every decision reason; ``GateBlock.reason`` indexes this tuple
REASONS = DROP_REASONS + RESET_REASONS + ACCEPT_REASONS
ALL_REASONS = REASONS
REASON_INDEX = {r: i for i, r in enumerate(REASONS)}
NOTES = ("receive_time", "gap_integrated", "identity_frame")
#: ``GateBlock.action`` codes
ACCEPT, DROP, RESET = 0, 1, 2
ACTION_CODE = {Action.ACCEPT: ACCEPT, Action.DROP: DROP, Action.RESET: RESET}
# a plain global: an Enum attribute lookup costs ~60 ns
_A_ACCEPT = Action.ACCEPT


@dataclass(slots=True)
class Decision:
    """The gate's verdict on one message.

    ``sample`` (ACCEPT/RESET only): time ``t`` s since ``origin_ns``, omega rad/s and specific
    force m/s² in base_link. ``stamp_ns``: the chosen time in the input's time base (ns), None if
    none could be chosen. ``source``: ``"header"`` or ``"receive"``.
    """

    action: Action
    reason: str
    sample: RateSample | None = None
    stamp_ns: int | None = None
    source: str | None = None
    detail: str = ""

    @property
    def accepted(self) -> bool:
        """True for ACCEPT and RESET (the sample goes to the simulator)."""
        return self.action is not Action.DROP


def plain_decision(p: tuple) -> Decision:
    """The ``Decision`` of a plain reading from :attr:`TimeGate.last_plain`'s tuple ``(t,
    omega, specific_force, stamp_ns, source)``: what :meth:`TimeGate.offer` returns for it."""
    t, w, f, t_ns, source = p
    return Decision(_A_ACCEPT, "ok", RateSample(t, np.array(w), None if f is None else np.array(f)), t_ns, source, "")


@dataclass(frozen=True)
class GateConfig:
    """Gate settings. ``max_gap`` s; ``on_gap``: ``reset`` | ``integrate``;
    ``reset_on_jump_back`` s; ``max_rate`` rad/s; ``max_specific_force`` m/s²; ``time_source``: ``auto`` | ``header`` |
    ``receive``; ``rate_smoothing``: weight of a new interval in the rate estimates;
    ``require_specific_force``: drop samples without specific force (``no_specific_force``),
    set when the model's effects need it (the simulator would refuse them);
    ``rebase_on_reset``: a reset (gap, jump back) also moves the origin to the reset sample
    (its ``sample.t`` is 0, as for a fresh gate: a reset is a fresh start; the node uses this);
    default False: one origin for the whole stream."""

    max_gap: float = 1.0
    on_gap: str = "reset"
    reset_on_jump_back: float = 1.0
    max_rate: float = 35.0
    max_specific_force: float = 2000.0
    time_source: str = "auto"
    rate_smoothing: float = 0.05
    require_specific_force: bool = False
    rebase_on_reset: bool = False

    def __post_init__(self) -> None:       # numbers: errors.check_number, the rule of every flag (finite)
        check_number("max_gap", self.max_gap, "s", gt=0)
        check_number("reset_on_jump_back", self.reset_on_jump_back, "s", ge=0)
        check_number("max_rate", self.max_rate, "rad/s", gt=0)
        check_number("max_specific_force", self.max_specific_force, "m/s²", gt=0)
        check_number("rate_smoothing", self.rate_smoothing, gt=0, le=1)
        for k in ("max_gap", "reset_on_jump_back", "max_rate", "max_specific_force", "rate_smoothing"):
            object.__setattr__(self, k, float(getattr(self, k)))    # one compiled row_verdict (float64 bounds)
        if self.on_gap not in ("reset", "integrate"):
            raise ValueError(f"on_gap = {self.on_gap!r}; allowed: reset, integrate")
        if self.time_source not in ("auto", "header", "receive"):
            raise ValueError(f"time_source = {self.time_source!r}; allowed: auto, header, receive")


@dataclass(slots=True)
class GateBlock:
    """The gate's decisions on the N rows of a RateBlock (:meth:`TimeGate.offer_block`).

    ``action`` int8 (N,): ``ACCEPT`` 0, ``DROP`` 1, ``RESET`` 2; ``reason`` int16 (N,): index
    into :data:`REASONS`; ``t`` float64 (N,): sample time s since the gate's origin as valid
    after that row's decision (NaN if dropped); ``stamp_ns`` int64 (N,): the chosen time in
    the input's time base (-1 if none)."""

    action: np.ndarray
    reason: np.ndarray
    t: np.ndarray
    stamp_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.action)

    @property
    def accepted(self) -> np.ndarray:
        """bool (N,): the sample goes to the simulator (ACCEPT or RESET)."""
        return self.action != DROP

    def reason_name(self, i: int) -> str:
        return REASONS[int(self.reason[i])]


# ---- the bounds of a row's values -------------------------------------------------------------
#: :func:`row_verdict` codes; :data:`ROW_REASONS` names them (the gate's drop reasons)
ROW_OK, ROW_NON_FINITE, ROW_OVER_RATE, ROW_OVER_SPECIFIC_FORCE, ROW_NO_SPECIFIC_FORCE = 0, 1, 2, 3, 4
ROW_REASONS = ("ok", "non_finite", "over_rate", "over_specific_force", "no_specific_force")


@njit(cache=True)
def row_verdict(w0, w1, w2, f0, f1, f2, has_force, max_rate, max_force, require_f):  # pragma: no cover - compiled
    """The gate's rule for a row's values, compiled: :data:`ROW_OK` (0) if the rate ``w`` (rad/s)
    and the specific force ``f`` (m/s²; looked at only if ``has_force``) can be taken as they are,
    else the code of the first rule broken, in the gate's order: :data:`ROW_NON_FINITE` (NaN/±Inf
    in ``w`` or in a present ``f``), :data:`ROW_OVER_RATE` (not ‖w‖ ≤ ``max_rate``, a norm that
    overflows included), :data:`ROW_OVER_SPECIFIC_FORCE` (likewise ‖f‖ and ``max_force``),
    :data:`ROW_NO_SPECIFIC_FORCE` (no ``f`` although ``require_f``).

    The one place of these bounds: the per-message gate runs this source in Python
    (``row_verdict.py_func`` in ``offer_plain`` and ``offer``: a call of the compiled dispatcher
    would cost ~0.3 µs more), the block pass the compiled function (``gate_kernels.usable_rows``).
    Plain float operations only (‖v‖ = sqrt(x² + y² + z²), no fast-math), so that
    ``row_verdict.py_func`` (the same source, not compiled) gives the same verdicts."""
    # x - x is 0.0 for a finite x and NaN for NaN or ±Inf: the sum is 0.0 only if all are finite
    if not (w0 - w0) + (w1 - w1) + (w2 - w2) == 0.0:
        return ROW_NON_FINITE
    if has_force and not (f0 - f0) + (f1 - f1) + (f2 - f2) == 0.0:
        return ROW_NON_FINITE
    if not math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) <= max_rate:
        return ROW_OVER_RATE
    if has_force:
        if not math.sqrt(f0 * f0 + f1 * f1 + f2 * f2) <= max_force:
            return ROW_OVER_SPECIFIC_FORCE
    elif require_f:
        return ROW_NO_SPECIFIC_FORCE
    return ROW_OK
