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

"""Run size of a synthetic scene: refuse what cannot run before it starts.

A run is refused when its estimate needs more than ``MAX_MEMORY_BYTES`` (8 GiB:
``BYTES_PER_SAMPLE`` per input sample, ``BYTES_PER_OUTPUT`` per recorded output) or more than
``MAX_STEPS`` (1e9 internal steps: at least ``duration / max_step`` and one per sample,
~``SECONDS_PER_STEP`` each). Imports only ``physics.options`` (its rtol floor).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..physics.options import RTOL_MIN

MAX_MEMORY_BYTES = 8 * 2 ** 30      # 8 GiB
MAX_STEPS = 1e9                     # internal integrator steps
BYTES_PER_SAMPLE = 88               # synthetic input: t, omega, force (float64) and attitude quaternion
BYTES_PER_OUTPUT = 5 * 2 ** 10      # one recorded output (measured ~4.6 kB with Recorder)
SECONDS_PER_STEP = 1.2e-6           # compiled kernel, one linear RK4 step (the README's figure)
MIN_RTOL = RTOL_MIN                 # the options' floor (~500 float64 epsilons): one check, one message


@dataclass(frozen=True)
class RunBudget:
    """Size estimate of a synthetic run: input ``samples``, recorded ``outputs``, internal
    ``steps`` (lower bound), ``memory_bytes`` and CPU ``seconds`` (lower bound)."""

    samples: float
    outputs: float
    steps: float
    memory_bytes: float
    seconds: float

    def describe(self) -> str:
        return (f"~{self.samples:.3g} samples, {self.outputs:.3g} outputs, ≥ {self.steps:.3g} steps: "
                f"~{self.memory_bytes / 2 ** 30:.3g} GiB of memory (bound {MAX_MEMORY_BYTES / 2 ** 30:g} GiB), "
                f"≥ {_human_seconds(self.seconds)} of CPU (bound {MAX_STEPS:.0e} steps)")

    @property
    def too_big(self) -> bool:
        return self.memory_bytes > MAX_MEMORY_BYTES or self.steps > MAX_STEPS


def _human_seconds(s: float) -> str:
    for unit, size in (("years", 3.15576e7), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.3g} s"


def run_budget(duration: float, sample_rate: float, output_rate: float, max_step: float) -> RunBudget:
    """Estimate of a synthetic run of ``duration`` s sampled at ``sample_rate`` Hz, recorded at
    ``output_rate`` Hz, internal steps ≤ ``max_step`` s."""
    samples = duration * sample_rate
    outputs = duration * output_rate
    steps = max(duration / max_step, samples)
    return RunBudget(samples, outputs, steps, samples * BYTES_PER_SAMPLE + outputs * BYTES_PER_OUTPUT,
                     steps * SECONDS_PER_STEP)


def oversize(duration: float, sample_rate: float, output_rate: float, max_step: float) -> tuple[str, str] | None:
    """``(key, one line)`` when the run is too big, naming the key furthest from the usual
    60 s, 100 Hz, 1 ms (``duration``, ``sample_rate`` or ``max_step``); None when it fits."""
    b = run_budget(duration, sample_rate, output_rate, max_step)
    if not b.too_big:
        return None
    excess = {"duration": duration / 60.0, "sample_rate": sample_rate / 100.0, "max_step": 1e-3 / max_step}
    key = max(excess, key=excess.get)
    value = {"duration": duration, "sample_rate": sample_rate, "max_step": max_step}[key]
    return key, (f"{value:g} makes the run too big to start: {b.describe()}; "
                 f"shorten duration, lower sample_rate or raise max_step")


__all__ = ["RunBudget", "run_budget", "oversize", "MAX_MEMORY_BYTES", "MAX_STEPS", "MIN_RTOL", "BYTES_PER_SAMPLE",
           "BYTES_PER_OUTPUT", "SECONDS_PER_STEP"]
