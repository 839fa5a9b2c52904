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

"""Gate decisions applied to a simulator (:func:`apply_decision`, :func:`restart_at`) and the
names of what came of them: the outcome names and codes of ``Pipeline.outcomes``, and the hint
when a drop reason took every sample."""
from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

from .gate_rules import Action, Decision
from ..engine.inputs import RateSample
from ..errors import InputError, SimulationError

#: outcomes of :func:`apply_decision` after which the simulator holds a new instant
ADVANCED = ("pushed", "reset", "restarted")


# the members as plain globals: an Enum attribute lookup costs ~60 ns, several per message
_ACT_DROP, _ACT_RESET = Action.DROP, Action.RESET


#: how a sample the simulator refused begins its line in ``Pipeline.errors``
REFUSED = "refused: "


def refusal(e: InputError) -> str:
    """The ``Pipeline.errors`` line of a sample the simulator refused (read by :func:`no_sample_hint`)."""
    return f"{REFUSED}{e}"


def apply_decision(sim: Any, decision: Decision, refused: Callable[[str], None] | None = None) -> str:
    """Apply a gate decision to a ``Simulator``. Returns ``"pushed"``, ``"reset"`` (reset, then
    pushed), ``"dropped"``, ``"rejected"`` (the simulator refused the sample: InputError, state
    unchanged; its message to ``refused``) or ``"restarted"`` (the integration failed:
    SimulationError; the simulator is reset and restarted at this sample). Outputs already
    taken are never touched."""
    action = decision.action
    if action is _ACT_DROP or decision.sample is None:
        return "dropped"
    if action is _ACT_RESET:
        sim.reset()
    try:
        sim.push(decision.sample)
    except InputError as e:
        if refused is not None:
            refused(refusal(e))
        return "rejected"
    except SimulationError:
        return restart_at(sim, decision.sample)
    return "reset" if action is _ACT_RESET else "pushed"


def restart_at(sim: Any, sample: RateSample) -> str:
    """After a failed integration: reset the simulator and start it again at ``sample``.
    Returns ``"restarted"``, or ``"rejected"`` when even that fails."""
    sim.reset()
    try:
        sim.push(sample)
    except SimulationError:
        return "rejected"
    return "restarted"


#: why a drop reason took every sample, and the fix
DROP_HINTS = {
    "zero_stamp": "every header stamp is 0; time by receive time instead (--time-source receive or auto)",
    "unknown_frame": "the input frame has no mounting; give --mount FRAME=... or --unknown-frame identity",
    "over_rate": "every rate exceeds --max-rate; raise it if the rates are real",
    "over_specific_force": "every specific force exceeds --max-specific-force; raise it if the accelerations are real",
    "no_rate": "the messages carry no angular rate",
    "non_finite": "every rate is NaN or infinite",
    "bad_message": "no message could be decoded",
}


def no_sample_hint(dropped_by_reason: dict[str, int], n_in: int, errors: Sequence[str] = ()) -> str:
    """One line: no sample of ``n_in`` was accepted, the main drop reason and its fix (for
    ``refused``: the simulator's first error, ``errors``, says why)."""
    if not dropped_by_reason:
        return f"none of the {n_in} input messages was accepted: no outputs"
    reason, count = max(dropped_by_reason.items(), key=lambda kv: kv[1])
    hint = DROP_HINTS.get(reason, "see dropped_by_reason in the summary")
    if reason == "refused" and errors:
        hint = f"the simulator refused them: {errors[0].removeprefix(REFUSED)}"
    return f"none of the {n_in} input messages was accepted ({count} dropped as {reason}): {hint}"


def nothing_integrated_hint(outcomes: Mapping[str, int], resets_by_reason: Mapping[str, int],
                            accepted: int, max_gap: float) -> str | None:
    """One line when ``accepted`` (≥ 2) samples gave no integrated interval: each started a run
    of its own (a restart: the gate's reset or the simulator's), so every output is the initial
    state; None when some interval was integrated (more than one sample ``pushed``)."""
    if accepted < 2 or outcomes.get("pushed", 0) > 1:
        return None
    restarts = sum(resets_by_reason.values()) + outcomes.get("restarted", 0)
    why = ", ".join(f"{n} by {r}" for r, n in sorted(resets_by_reason.items(), key=lambda kv: -kv[1]))
    hint = (f": the samples are further apart than the gate's max_gap ({max_gap:g} s); raise it (--max-gap) "
            "above the input's sample interval" if resets_by_reason.get("gap", 0) * 2 >= restarts else "")
    return (f"none of the {accepted} accepted samples was integrated: each started a new run ({restarts} restarts"
            f"{': ' + why if why else ''}), so the outputs are the initial state{hint}")


#: per-row outcome codes of a block; the names are the keys of ``Pipeline.outcomes``
OUTCOMES = ("dropped", "pushed", "reset", "rejected", "restarted")
O_DROPPED, O_PUSHED, O_RESET, O_REJECTED, O_RESTARTED = range(len(OUTCOMES))
MAX_ERRORS = 100                    # simulator error messages kept by a Pipeline
