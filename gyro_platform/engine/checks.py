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

"""Input checks of the simulator: what a sample or a block must be before it touches the state.

Every check ends in ``InputError`` (one line naming the input and what is wrong): times are real
scalars (s), rates and specific forces 3 real numbers each (rad/s, m/s²; no complex, string,
boolean or object values, no other shape), blocks strictly increasing in time after the last
sample, output indices increasing within the block.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

__all__ = ["as_time", "as_vec3", "real_array", "rows3", "check_block"]


def as_time(t, what: str = "sample time") -> float:
    """A finite-or-not real scalar time (s) as float; anything else: InputError."""
    if isinstance(t, (bool, np.bool_)) or not isinstance(t, (int, float, np.integer, np.floating)):
        raise InputError(f"{what} must be a real number (s), got {type(t).__name__} {t!r:.40}")
    return float(t)


def as_vec3(x, what: str) -> np.ndarray:
    """A 3-vector of reals as a float64 (3,) array; anything else: InputError (one line)."""
    try:
        a = np.asarray(x)
    except Exception as e:                                   # ragged sequences, odd objects
        raise InputError(f"{what} must be 3 real numbers: {type(e).__name__}") from None
    if a.dtype.kind not in "iuf" or a.size != 3 or a.ndim > 2:
        raise InputError(f"{what} must be 3 real numbers, got {a.dtype} of shape {a.shape}")
    return np.ascontiguousarray(a, dtype=float).reshape(3)


def real_array(x, what: str) -> np.ndarray:
    try:
        a = np.asarray(x)
    except Exception as e:
        raise InputError(f"{what} must be an array of real numbers: {type(e).__name__}") from None
    if a.dtype.kind not in "iuf":
        raise InputError(f"{what} must be an array of real numbers, got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=float)


def rows3(x, n: int, what: str) -> np.ndarray:
    a = real_array(x, what)
    if a.shape == (3,) and n == 1:
        a = a.reshape(1, 3)
    if a.shape != (n, 3):
        raise InputError(f"{what} must have shape ({n}, 3) to match t, got {a.shape}")
    return a


def check_block(t, omega, specific_force, out_idx, t_start: float | None, t_rel: float, needs_f=()):
    """Validated (t, w, f, has_f, out_idx) of a block for a simulator whose time base starts at
    ``t_start`` (None: not started) and stands at ``t_rel``; ``needs_f``: the effects that need
    the specific force (non-empty: it must be given). InputError (one line) otherwise."""
    t = real_array(t, "t")
    if t.ndim == 0:
        t = t.reshape(1)
    if t.ndim != 1:
        raise InputError(f"t must be 1-D, got shape {t.shape}")
    n = len(t)
    w = rows3(omega, n, "omega")
    has_f = specific_force is not None
    f = rows3(specific_force, n, "specific_force") if has_f else np.zeros((n, 3))
    # whole-array tests first (a reduction over the rows' 3 columns costs ~10x more); the
    # row only when one fails
    if not (np.isfinite(t).all() and np.isfinite(w).all() and (not has_f or np.isfinite(f).all())):
        ok = np.isfinite(t) & np.all(np.isfinite(w), 1) & np.all(np.isfinite(f), 1)
        raise InputError(f"non-finite sample at index {int(np.argmin(ok))}")
    if needs_f and not has_f:
        raise InputError("effects " + ", ".join(sorted(needs_f)) + " need the specific force, which the samples "
                         "do not carry")
    if n:
        t0 = t_start if t_start is not None else float(t[0])
        rel = np.concatenate([[t_rel if t_start is not None else -math.inf], t - t0])
        later = np.diff(rel) > 0
        if not later.all():
            bad = int(np.argmin(later))
            raise InputError(f"sample time at index {bad} ({t[bad]!r}) is not after the previous one")
    idx = (out_idx if isinstance(out_idx, np.ndarray) and out_idx.dtype.kind in "iu"
           else real_array(out_idx, "out_idx"))
    if idx.dtype.kind == "f" and idx.size and not np.all(idx == np.round(idx)):
        raise InputError("out_idx must hold integer indices")
    idx = np.ascontiguousarray(idx, dtype=np.int64).reshape(-1) if idx.size else np.zeros(0, np.int64)
    if idx.size and (idx[0] < 0 or idx[-1] >= n or np.any(np.diff(idx) <= 0)):
        raise InputError(f"out_idx must be increasing indices in [0, {n}), got {idx[:5]}…")
    return t, w, f, has_f, idx
