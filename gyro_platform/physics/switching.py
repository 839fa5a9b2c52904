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

"""Where the right-hand side has a kink: the switching times of the mount (support) friction.

The support friction ``−D_s rel − μ_s sat(rel/ε_s)`` (:mod:`.effects`) has a kink where the
relative rate rel_i = Ω_i − (R_PB ω_B)_i of a mount axis reaches ±ε_s (1e-4 rad/s): the platform's
angular acceleration jumps there by about 2μ_s/J (0.1 rad/s²). A vibrating vehicle sweeps rel
through zero tens of times a second per axis, and a Runge–Kutta step across such a kink is only
first-order accurate: the error controller then cuts the interval into many small substeps (3–8×
the right-hand sides of a smooth input). A step that *ends* at the kink is smooth on each side.

``support_switch_time`` predicts the next such time from the state and its derivative at the
start of a step; the step integrators (compiled RK4, ``integrators.rk.RK4``) end a piece a little
short of it and land on it with a micro step (``integrators.aimed_switch``).
``support_switch_passed`` looks back from the end of a step for a kink the prediction missed
(the step is then redone to end just before it: ``integrators.shortened_piece``).
Within one input interval the vehicle rate is linear in time, so rel is linear up to the
platform's own acceleration change and the rotation of R_PB: the prediction misses the kink by up
to ~1e-4 of its reach, and by ~1e-15 s over the micro step (the integrators ignore a switch closer
than ``SWITCH_MIN``·max_step to a piece's ends). Frames: platform axes for Ω and rel, vehicle axes
for ω_B. May import the physics room's kernels only.
"""
from __future__ import annotations

import math

from . import effects as fx
from .jit import njit
from .model import LAY_OM, LAY_QIB, LAY_QIP, LAY_STAB, seg_at, seg_slope, SEG_W0
from .rotations import rpb_elems

__all__ = ["support_switch_time", "support_switch_passed"]


@njit(cache=True, inline="always")
def _rel_and_rate(t, y, yd, I, seg):
    """(ok, rel_0, rel_1, rel_2, rel̇_0, rel̇_1, rel̇_2) of the three mount axes at (t, y), rad/s
    and rad/s², rel̇ to first order from yd = ẏ(t, y): rel̇_i = Ω̇_i − (R_PB ω̇_B)_i + (Ω × R_PB ω_B)_i
    (``seg``: the input interval, ω_B linear in t). ok is False (and the rest 0) when an attitude
    quaternion is degenerate (the step itself reports it)."""
    lay = I[0]
    iqp = lay[LAY_QIP]
    iqb = lay[LAY_QIB]
    for iq in (iqp, iqb):
        nq = y[iq] ** 2 + y[iq + 1] ** 2 + y[iq + 2] ** 2 + y[iq + 3] ** 2
        if not (nq > 0.0 and nq < math.inf):
            return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rpb_elems(y, iqp, iqb)      # R_PB = R_IPᵀ R_IB
    w0, w1, w2 = seg_at(seg, t, SEG_W0)
    d0, d1, d2 = seg_slope(seg, SEG_W0)
    p0 = r00 * w0 + r01 * w1 + r02 * w2          # ω_B in platform axes
    p1 = r10 * w0 + r11 * w1 + r12 * w2
    p2 = r20 * w0 + r21 * w1 + r22 * w2
    io = lay[LAY_OM]
    O0, O1, O2 = y[io], y[io + 1], y[io + 2]
    # rel̇ = Ω̇ − d(ω_B^P)/dt, d(ω_B^P)/dt = R_PB ω̇_B − Ω × ω_B^P
    g0 = yd[io] - (r00 * d0 + r01 * d1 + r02 * d2) + (O1 * p2 - O2 * p1)
    g1 = yd[io + 1] - (r10 * d0 + r11 * d1 + r12 * d2) + (O2 * p0 - O0 * p2)
    g2 = yd[io + 2] - (r20 * d0 + r21 * d1 + r22 * d2) + (O0 * p1 - O1 * p0)
    return True, O0 - p0, O1 - p1, O2 - p2, g0, g1, g2


@njit(cache=True)
def support_switch_time(t, y, yd, I, P, seg, t_end, h_min):
    """The first time in (t + h_min, t_end − h_min) (s, the interval's time base) at which a
    mount axis's relative rate rel_i reaches ±ε_s, predicted to first order from ``yd`` = ẏ at
    (t, y) (``seg``: the input interval). ``t_end`` when there is none, the platform is not
    stabilised or the effect is off."""
    if I[0, LAY_STAB] != 1 or I[1, fx.SUPPORT] == 0:
        return t_end
    ok, e0, e1, e2, g0, g1, g2 = _rel_and_rate(t, y, yd, I, seg)
    if not ok:
        return t_end
    eps = P[fx.K_EPS_S]
    best = t_end - h_min
    for ax in range(3):
        rel, g = (e0, g0) if ax == 0 else ((e1, g1) if ax == 1 else (e2, g2))
        if g == 0.0 or not math.isfinite(g):
            continue
        for c in (-eps, eps):
            tau = (c - rel) / g
            if tau > h_min and t + tau < best:
                best = t + tau
    return best if best < t_end - h_min else t_end


@njit(cache=True)
def support_switch_passed(t, y, yd, I, P, seg, lo, hi):
    """How long before ``t`` (s) the earliest kink inside the step just ended at (t, y) lies,
    judged backwards from its end: for each mount axis and threshold ±ε_s, d = (rel_i − c)/rel̇_i
    (``yd`` = ẏ(t, y)) is the time since rel_i crossed c; the largest d in (lo, hi), else 0.0
    (none, not stabilised, effect off). ``hi`` a little short of the step's length leaves out
    the kink the step starts at."""
    if I[0, LAY_STAB] != 1 or I[1, fx.SUPPORT] == 0:
        return 0.0
    ok, e0, e1, e2, g0, g1, g2 = _rel_and_rate(t, y, yd, I, seg)
    if not ok:
        return 0.0
    eps = P[fx.K_EPS_S]
    best = 0.0
    for ax in range(3):
        rel, g = (e0, g0) if ax == 0 else ((e1, g1) if ax == 1 else (e2, g2))
        if g == 0.0 or not math.isfinite(g):
            continue
        for c in (-eps, eps):
            d = (rel - c) / g
            if lo < d < hi and d > best:
                best = d
    return best
