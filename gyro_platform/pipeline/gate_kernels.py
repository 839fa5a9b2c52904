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

"""The input gate's passes over a block of rows, compiled, and its rate averages.

:func:`usable_rows` (the rows whose values pass :func:`~gyro_platform.pipeline.gate_rules.row_verdict`),
:func:`accept_rows` (a run of plain rows accepted: times and the interval average),
:func:`arrival_ema` (the arrival-interval average of a block's receive times), :func:`ema_add` /
:func:`ema` (the same average, one interval or many, in Python), :func:`ns_floor` (a bound in s
as integer ns) and :func:`reading_of` (a block's row as the scalar gate's input).
Every pass does the float operations of :class:`~gyro_platform.pipeline.gate.TimeGate`'s scalar
path, so that ``offer_block`` decides as ``offer`` does row by row.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .gate_rules import NS, ROW_OK, row_verdict
from ..messages import Reading, Rejected
from ..messages.blocks import REJECT_REASONS
from ..physics.jit import njit

if TYPE_CHECKING:
    from ..messages.blocks import RateBlock

#: intervals (ns) at most this long convert to float exactly: ``d / NS`` is then the same
#: correctly rounded quotient in Python (int true division) and in compiled code
EXACT_NS = 2 ** 53


def ema_add(e: float | None, dt: float, a: float) -> float:
    """One interval ``dt`` (s) into the average ``e``: ``dt`` if none yet, else ``e + a·(dt − e)``
    (the scalar gate's update; the compiled passes' is ``_ema_step``)."""
    return dt if e is None else e + a * (dt - e)


def ema(e: float | None, d_ns: np.ndarray, a: float) -> float | None:
    """``e`` after ``e = dt if e is None else e + a·(dt − e)`` for every interval ``dt = d/NS``
    of ``d_ns`` (int64 ns) in order: the same float operations as the scalar gate's."""
    if not len(d_ns):
        return e
    if np.abs(d_ns).max() >= EXACT_NS:
        for dn in d_ns.tolist():
            e = ema_add(e, dn / NS, a)
        return e
    return float(_ema_kernel(np.nan if e is None else e, e is None, d_ns, a))


@njit(cache=True, inline="always")
def _ema_step(e, unset, d, a):  # pragma: no cover - compiled
    """One interval of ``d`` ns into the average: ``dt`` if none yet (``unset``), else
    ``e + a·(dt − e)``; the one update of every compiled pass below."""
    dt = d / 1_000_000_000
    return dt if unset else e + a * (dt - e)


@njit(cache=True)
def _ema_kernel(e, unset, d_ns, a):  # pragma: no cover - compiled
    for k in range(d_ns.shape[0]):
        e = _ema_step(e, unset, d_ns[k], a)
        unset = False
    return e


@njit(cache=True)
def usable_rows(w, f, has_force, reject, max_rate, max_force, require_f):  # pragma: no cover - compiled
    """bool (N,): the rows whose values the gate can take as they are: not rejected by the decoder
    (``reject`` 0) and :func:`~gyro_platform.pipeline.gate_rules.row_verdict` ok (the rule the
    scalar gate calls)."""
    n = w.shape[0]
    out = np.zeros(n, np.bool_)
    for k in range(n):
        out[k] = reject[k] == 0 and row_verdict(w[k, 0], w[k, 1], w[k, 2], f[k, 0], f[k, 1], f[k, 2],
                                                has_force[k], max_rate, max_force, require_f) == ROW_OK
    return out


@njit(cache=True)
def accept_rows(tn, i, j, last_ns, origin, e, unset, a, t, stamp):  # pragma: no cover - compiled
    """Rows i..j−1 of a plain run: ``t`` (s after ``origin``) and ``stamp`` (ns) filled, the
    interval EMA ``e`` (``unset``: none yet) advanced over each row's interval after the one
    before (``last_ns`` before row i); returns it. The float operations of :func:`ema`."""
    prev = last_ns
    for k in range(i, j):
        x = tn[k]
        e = _ema_step(e, unset, x - prev, a)
        unset = False
        prev = x
        t[k] = (x - origin) / 1_000_000_000
        stamp[k] = x
    return e


@njit(cache=True)
def arrival_ema(rx, first, has_first, gap_ns, e, unset, a):  # pragma: no cover - compiled
    """The arrival-interval EMA over receive times ``rx`` (int64 ns; ``first``: the one before,
    if ``has_first``), intervals outside (0, gap_ns] skipped; returns (e, unset)."""
    prev = first
    for k in range(rx.shape[0]):
        d = rx[k] - prev
        if (k > 0 or has_first) and 0 < d <= gap_ns:
            e = _ema_step(e, unset, d, a)
            unset = False
        prev = rx[k]
    return e, unset


def ns_floor(seconds: float) -> int:
    """Largest integer ns ≤ ``seconds``·1e9, so that ``d > seconds*NS`` ⟺ ``d > ns_floor`` for int d."""
    x = seconds * NS
    return 2**62 if x >= 2**62 else math.floor(x)       # (1e300 s: x is inf, which floor refuses)


def reading_of(rb: "RateBlock", i: int) -> Reading | Rejected:
    """Row ``i`` of a block as the scalar gate's input (what reading_from_msg gives)."""
    stamp = int(rb.stamp_ns[i]) if rb.has_header[i] else None
    rj = int(rb.reject[i])
    if rj:
        return Rejected(REJECT_REASONS[rj - 1], rb.detail.get(i, ""), stamp, rb.frame_id[i])
    w = rb.omega[i].tolist()
    f = tuple(rb.force[i].tolist()) if rb.has_force[i] else None
    return Reading((w[0], w[1], w[2]), f, stamp, rb.frame_id[i], bool(rb.identity[i]))
