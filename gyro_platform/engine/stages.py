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

"""The exponential methods' stage matrices in CSR form and the compiled products with them.

``stage_matrices`` turns an etd2/etd4 integrator's stage matrices for one step (and the linear
part A) into CSR arrays; the compiled batch loop (:mod:`.batch`) keeps them per friction regime,
level and grid step and steps with ``csr_axpy`` / ``csr_mv``; ``phi_taylor`` applies
``h φ_k(hA)`` to a vector by its Taylor series for the last short step of an interval (as
``integrators.exponential``). Imports ``integrators`` and ``physics.system`` (FASTMATH) only.
"""
from __future__ import annotations

import numpy as np

from .integrators import taylor_bound, TAYLOR_MAX, TAYLOR_TOL
from ..physics.jit import njit
from ..physics.system import FASTMATH

__all__ = ["stage_matrices", "csr_axpy", "csr_mv", "phi_taylor"]


@njit(cache=True, fastmath=FASTMATH)
def csr_mv(mi, po, row, io, md, do, x, out):
    """out = M_row x for the CSR set at (pointers mi[po:], indices mi[io:], values md[do:])."""
    n = out.shape[0]
    base = po + row * (n + 1)
    for r in range(n):
        acc = 0.0
        for e in range(mi[base + r], mi[base + r + 1]):
            acc += md[do + e] * x[mi[io + e]]
        out[r] = acc


@njit(cache=True, fastmath=FASTMATH)
def csr_axpy(mi, po, row, io, md, do, x, y, out):
    """out = y + M_row x (``out`` neither ``x`` nor ``y``)."""
    csr_mv(mi, po, row, io, md, do, x, out)
    for r in range(out.shape[0]):
        out[r] = y[r] + out[r]


@njit(cache=True, inline="always")
def phi_taylor(mi, po, io, md, do, x2, h, k, v, base, out, T, T2):
    """out = base + h φ_k(hA) v (k = 1, 2; A: row 0 of the CSR set at po/io/do) by the series
    and stopping rule of ``integrators.exponential`` (x2 = h²·‖|A|²·1‖∞); v may be
    T2. False when it did not converge within ``TAYLOR_MAX`` terms."""
    n = out.shape[0]
    c0 = h if k == 1 else 0.5 * h
    prev = 0.0
    for m in range(n):
        T[m] = c0 * v[m]
        out[m] = T[m]
        prev = max(prev, abs(T[m]))
    ok = False
    for j in range(1, TAYLOR_MAX + 1):
        for r in range(n):
            acc = 0.0
            for e in range(mi[po + r], mi[po + r + 1]):
                acc += md[do + e] * T[mi[io + e]]
            T2[r] = acc
        f = h / (j + k)
        cur = 0.0
        smax = 0.0
        for m in range(n):
            T[m] = f * T2[m]
            out[m] += T[m]
            cur = max(cur, abs(T[m]))
            smax = max(smax, abs(out[m]))
        if cur + prev <= TAYLOR_TOL * smax and 4.0 * x2 <= (j + k) * (j + k + 1):
            ok = True
            break
        prev = cur
    for m in range(n):
        out[m] += base[m]
    return ok


def stage_matrices(integrator, system, h: float):
    """CSR stage matrices (ptr (s', n+1), idx, data) of an exponential integrator for step h,
    relative offsets: stage j's matrix maps the stacked stage derivatives [f_0 … f_{j−1}] to
    U_j − y; etd2 adds the linear part A as a last row (for its defect estimate). h = 0: the
    linear part A alone (for the tail step), its ``taylor_bound`` stored after the data."""
    n = system.layout.n
    if integrator.name not in ("etd2", "etd4"):
        raise ValueError(f"integrator {integrator.name!r} has no stage matrices (etd2, etd4 have)")
    A, key = system.linear_part()
    Ms = list(integrator.matrices(np.asarray(A, float), key, h)) if h > 0 else []
    if integrator.defect or h == 0:
        Ms.append(np.asarray(A, float))
    ptr = np.zeros((len(Ms), n + 1), np.int64)
    idx: list[int] = []
    dat: list[float] = []
    for j, Mj in enumerate(Ms):
        for r in range(n):
            cols = np.nonzero(Mj[r])[0]
            ptr[j, r] = len(idx)
            idx.extend(cols.tolist())
            dat.extend(Mj[r, cols].tolist())
        ptr[j, n] = len(idx)
    if h == 0:
        dat.append(taylor_bound(np.asarray(A, float)))
    return ptr, np.asarray(idx, np.int64), np.asarray(dat, float)
