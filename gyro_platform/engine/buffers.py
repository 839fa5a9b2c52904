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

"""The flat buffers of the compiled engine (``engine.batch``): their layout, views and packing.

A simulator's compiled step reads everything from two flat buffers, ``fb`` (float64) and ``ib``
(int64). Each holds arrays in slots: ``fb`` the float slots ``F_*`` (the system's kernel arrays
first, in ``kernel_args`` order after ``I``, then the state, the controller's and the stages'
work arrays, the 2-row input of the current interval …), ``ib`` the offset table (``SLOT_W``
ints per slot: offset and up to three dimensions, float slots then int slots) and the int slots
``I_*``. The float header slot ``F_HDR`` holds the scalars ``H_*``, the int header ``I_HDR`` the
counters and switches ``J_*``. :func:`pack` lays the arrays out (Python, once per engine);
``fview1/2/3`` and ``iview1/2`` (compiled, inlined) give a slot back as a 1-, 2- or 3-D view,
borrowed (:mod:`.views`: no reference counted; valid for the kernel call that made it).
"""
from __future__ import annotations

import numpy as np

from .views import view1, view2, view3
from ..physics.jit import njit

# ---- float buffer slots (system kernel arrays first, in ``kernel_args`` order after I) -----
(F_P, F_SEG, F_MATS, F_AXIS, F_INERTIA, F_RAXIS, F_R, F_WB, F_WD, F_J, F_FO, F_MM, F_CC, F_TAU, F_FB, F_CHOL,
 F_F, F_A, F_Q, F_RR, F_V, F_W,
 F_HDR, F_Y, F_YW, F_Y1, F_K, F_K5, F_U, F_UL, F_AU, F_C, F_TR, F_WR, F_FR, F_SEGSAVE, F_YC, F_YK, F_PUSH,
 F_TW) = range(40)
N_FSLOT = 40
I_I, I_RHOST, I_HDR, I_TABLE = range(4)
N_ISLOT = 4
SLOT_W = 4                          # table entry: offset, d0, d1, d2
TABLE_LEN = SLOT_W * (N_FSLOT + N_ISLOT)
# float header
(H_MAX_STEP, H_RTOL, H_ATOL, H_T_START, H_T_REL, H_EST, H_NORM, H_T_BAD, H_E_BAD, H_N_BAD, H_H_BAD) = range(11)
N_FH = 11
# int header
(J_METHOD, J_FID, J_Q1, J_MAX_LEVEL, J_LEVEL, J_NSAMP, J_NSTEPS, J_NRHS, J_NEED_R, J_NEED_L, J_NEED_H,
 J_STARTED, J_HAS_F, J_NLEV, J_REJ, J_DONE, J_JOUT, J_K1) = range(18)
N_IH = 18
#: system attributes rebound to buffer views: (slot, owner path, attribute)
SYSTEM_F = ((F_P, "", "P"), (F_SEG, "", "seg"), (F_MATS, "", "mats"), (F_R, "work", "R"), (F_WB, "work", "w"),
            (F_WD, "work", "wd"), (F_J, "work", "J"), (F_FO, "work", "f"), (F_MM, "work", "M"),
            (F_CC, "work", "c"), (F_TAU, "work", "tau_ext"), (F_FB, "", "_fb"), (F_CHOL, "", "_chol"),
            (F_F, "", "_F"), (F_A, "", "_a"), (F_Q, "", "_Q"), (F_RR, "", "_RR"), (F_V, "", "_V"),
            (F_W, "", "_W"))


# ---- views of the slots (compiled, inlined into the kernels) -------------------------------
@njit(cache=True, inline="always")
def fview1(fb, ib, k):
    return view1(fb, ib[SLOT_W * k], (ib[SLOT_W * k + 1],))


@njit(cache=True, inline="always")
def fview2(fb, ib, k):
    o = ib[SLOT_W * k]
    d0 = ib[SLOT_W * k + 1]
    d1 = ib[SLOT_W * k + 2]
    return view2(fb, o, (d0, d1))


@njit(cache=True, inline="always")
def fview3(fb, ib, k):
    o = ib[SLOT_W * k]
    d0 = ib[SLOT_W * k + 1]
    d1 = ib[SLOT_W * k + 2]
    d2 = ib[SLOT_W * k + 3]
    return view3(fb, o, (d0, d1, d2))


@njit(cache=True, inline="always")
def iview1(ib, k):
    return view1(ib, ib[SLOT_W * (N_FSLOT + k)], (ib[SLOT_W * (N_FSLOT + k) + 1],))


@njit(cache=True, inline="always")
def iview2(ib, k):
    o = ib[SLOT_W * (N_FSLOT + k)]
    d0 = ib[SLOT_W * (N_FSLOT + k) + 1]
    d1 = ib[SLOT_W * (N_FSLOT + k) + 2]
    return view2(ib, o, (d0, d1))


# ---- packing (Python) ------------------------------------------------------------------------
def pack(f_arrays: dict, i_arrays: dict) -> tuple[np.ndarray, np.ndarray, dict, dict]:
    """Lay out the float arrays ``f_arrays`` (slot ``F_*`` → array, all ``N_FSLOT``) and the int
    arrays ``i_arrays`` (slot ``I_*`` → array, all ``N_ISLOT``) in two new flat buffers, the
    offset table first in ``ib``. Returns ``(fb, ib, views, iviews)``: the buffers and, per slot,
    the view of its array in them (holding a copy of the values)."""
    fsize = sum(np.asarray(a).size for a in f_arrays.values())
    isize = TABLE_LEN + sum(np.asarray(a).size for a in i_arrays.values())
    fb = np.zeros(fsize)
    ib = np.zeros(isize, np.int64)
    views: dict[int, np.ndarray] = {}
    off = 0
    for k in range(N_FSLOT):
        a = np.asarray(f_arrays[k], float)
        _slot(ib, k, off, a.shape)
        v = fb[off:off + a.size].reshape(a.shape)
        v[...] = a
        views[k] = v
        off += a.size
    off = TABLE_LEN
    iviews: dict[int, np.ndarray] = {}
    for k in range(N_ISLOT):
        a = np.asarray(i_arrays[k], np.int64)
        _slot(ib, N_FSLOT + k, off, a.shape)
        v = ib[off:off + a.size].reshape(a.shape)
        v[...] = a
        iviews[k] = v
        off += a.size
    return fb, ib, views, iviews


def _slot(ib: np.ndarray, k: int, off: int, shape: tuple) -> None:
    """Table entry ``k``: offset and dimensions (missing ones 1)."""
    e = ib[SLOT_W * k:SLOT_W * (k + 1)]
    e[0] = off
    dims = list(shape) + [1] * (3 - len(shape))
    if len(shape) == 0:
        dims = [1, 1, 1]
    e[1:4] = dims[:3]
