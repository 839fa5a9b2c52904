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

"""The output grid: an output is taken when a sample's stamp starts a new slot
``floor((t − t_origin)·rate)`` (times ns on the input's time base, rates Hz)."""
from __future__ import annotations

import math

import numpy as np

#: Hz: the highest output (and diagnostics) grid rate. Above it the slot numbers of a long run
#: would leave int64 (1e20 Hz: slot ~1e20 after a second); any rate above the input's gives an
#: output after every sample, which rate 0 asks for directly
MAX_GRID_RATE = 1e6


def check_grid_rate(rate: float | None, name: str, zero_ok: bool = True) -> None:
    """ValueError (one line naming ``name``) unless ``rate`` is None, 0 (``zero_ok``) or a
    finite rate in (0, ``MAX_GRID_RATE``] Hz."""
    if rate is None or (zero_ok and rate == 0):
        return
    if not (math.isfinite(rate) and 0 < rate <= MAX_GRID_RATE):
        what = f"0 (every sample) or a finite rate in (0, {MAX_GRID_RATE:g}] Hz" if zero_ok else \
            f"a finite rate in (0, {MAX_GRID_RATE:g}] Hz"
        raise ValueError(f"{name} {rate!r}: must be {what}")


def grid_index(t_ns: int, origin_ns: int, rate: float) -> int:
    """Index of the output slot of ``t_ns``: floor((t − origin)·rate) (times in ns, rate in Hz)."""
    return math.floor((t_ns - origin_ns) * 1e-9 * rate + 1e-9)


#: the slot before any (no output yet)
NO_SLOT = np.iinfo(np.int64).min


def grid_indices(t_ns: np.ndarray, origin_ns: int, rate: float) -> np.ndarray:
    """:func:`grid_index` of every stamp (int64; the same float operations, so the same slots)."""
    d = (np.asarray(t_ns, dtype=np.int64) - np.int64(origin_ns)).astype(np.float64)
    return np.floor(d * 1e-9 * rate + 1e-9).astype(np.int64)


def new_slots(slots: np.ndarray, last: int | None) -> np.ndarray:
    """Rows whose slot is beyond every slot before them (and ``last``, None = none): where a
    grid on these slots emits (bool (N,))."""
    run = np.maximum.accumulate(np.concatenate([[NO_SLOT if last is None else last], slots]))
    return slots > run[:-1]
