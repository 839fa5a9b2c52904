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

"""Compiled stepping: one numba call per input sample (``push``) or per chunk (``block``).

``Engine`` owns a simulator's integration state and every array the compiled step touches, in
two flat buffers (``fb`` float64, ``ib`` int64: the system's kernel tables and work arrays, the
state, the controller's scalars, the 2-row input of the current interval, the stage work
arrays) plus the exponential methods' stage matrices (``mi`` int64 CSR pointers/indices,
``md`` float64 values; slots, headers and views: :mod:`.buffers`). A call passes these four
arrays and the sample; the kernel rebuilds its views from the offset table at the start of ``ib``, borrowed
(:mod:`.views`; numba's dispatch costs ~0.1 µs per array argument: four buffers, not ~45). The
system's named arrays (``system.seg``, ``system.P`` …) are rebound to views into ``fb``/``ib``,
so the Python code sees the same memory.

Methods: explicit RK4 (embedded third-order estimate, FSAL), and explicit exponential Runge–Kutta
methods (``etd2``, ``etd4``) given their stage matrices ``M_i`` (``U_i = y + Σ_j M_ij f_j``; see
``integrators.exponential``; estimate ``y1 − U_last``, etd2: the defect). The step-size controller
is the one of ``integrators.base.Controlled`` (levels of ``nsub·level_substeps(level)`` substeps per
interval, the same acceptance test and the same level rules) and, for the exponential methods, the
plan of ``_ETD._plan``: whole grid steps (matrices per (friction regime, level, grid step), built on
demand, :mod:`.stages`) and a last short etd2 step to the sample time (φ-functions by Taylor series;
slot (regime, 0, 0) holds A): the results equal the Python integrators' to round-off and the
failures are the same. Compiled RK4 on a stabilised platform also reuses the last stage across
intervals (first same as last: the next interval's input starts where this one ends and the
right-hand side does not see its slope), one right-hand side fewer per interval; the check
``_k1_carried`` makes any change of state or input row recompute it. RK4 with the mount friction on
also ends a piece of a chunk at the friction's next kink (predicted from K[0],
``physics.switching``) and goes on with the rest of the chunk, as ``Controlled._advance``/``_chunk``
with ``locates_switches`` (the kink found looking back, ``piece_substeps``, ``held_level``,
``is_micro_step``). A sample is committed (state, time, input, counters) only when its interval
succeeded; otherwise everything, ``seg`` too, is as before.
"""
from __future__ import annotations

import math

import numpy as np

from .buffers import (F_A, F_AU, F_AXIS, F_C, F_CC, F_CHOL, F_F, F_FB, F_FO, F_FR, F_HDR, F_INERTIA, F_J, F_K, F_K5,
                      F_MATS, F_MM, F_P, F_PUSH, F_Q, F_R, F_RAXIS, F_RR, F_SEG, F_SEGSAVE, F_TAU, F_TR, F_TW, F_U,
                      F_UL, F_V, F_W, F_WB, F_WD, F_WR, F_Y, F_Y1, F_YC, F_YK, F_YW, fview1, fview2, fview3, H_ATOL,
                      H_E_BAD, H_EST, H_H_BAD, H_MAX_STEP, H_N_BAD, H_NORM, H_RTOL, H_T_BAD, H_T_REL, H_T_START, I_HDR,
                      I_I, I_RHOST, I_TABLE, iview1, iview2, J_DONE, J_FID, J_HAS_F, J_JOUT, J_K1, J_LEVEL, J_MAX_LEVEL,
                      J_METHOD, J_NEED_H, J_NEED_L, J_NEED_R, J_NLEV, J_NRHS, J_NSAMP, J_NSTEPS, J_Q1, J_REJ, N_FH,
                      N_IH, pack, SLOT_W, SYSTEM_F)
from .integrators import (aimed_switch, coarser_level, ETD2, held_level, is_micro_step, level_substeps, MAX_SWITCHES,
                          next_level, next_piece_level, piece_substeps, shortened_piece, STEP_SLACK, SWITCH_EDGE,
                          SWITCH_MIN, TAIL_MIN, TAIL_ULP)
from .stages import csr_axpy, csr_mv, phi_taylor, stage_matrices
from .views import borrow, view1, view2
from ..physics.effects import SUPPORT
from ..physics.jit import njit, plain
from ..physics.model import commit_attitudes
from ..physics.rhs_linear import takes_linear_path
from ..physics.switching import support_switch_passed, support_switch_time
from ..physics.system import (FASTMATH, LAY_QIB, LAY_QIP, LAY_STAB, model_rhs, SEG_DT, SEG_F0, SEG_F1, SEG_N, SEG_T0,
                              SEG_W0, SEG_W1, support_regime)

RK4, EXPRK, EXPRK_D = 0, 1, 2
#: integrators with a compiled path → method code
COMPILED = {"rk4": RK4, "etd2": EXPRK_D, "etd4": EXPRK}
#: status bits of a compiled call: 1 gimbal lock (precession), 2 mass matrix not positive
#: definite, 4 non-finite state, 8 matrices for a new (regime, level, step) needed, 16
#: tolerance not met within the budget, 32 non-finite sample, 64 sample time not after the last
ST_LOCK, ST_NOT_PD, ST_NONFINITE, NEED_REGIME, ST_TOLERANCE, ST_BAD_SAMPLE, ST_ORDER = 1, 2, 4, 8, 16, 32, 64
#: exponential steps are multiples of max_step / GRID (as the Python etd2/etd4)
GRID = ETD2.GRID


# ---------------------------------------------------------------------------- kernels
@njit(cache=True, inline="always")
def _quat_ok(x, y, z, w):
    """The quaternion (x, y, z, w) can be turned into a matrix (finite, non-zero)."""
    s = x * x + y * y + z * z + w * w
    return s > 0.0 and s < math.inf


@njit(cache=True, inline="always")
def _k1_carried(ih, yk, y, tr, wr, fr, n):
    """The last interval left K[0] = f(t, y) for exactly this state and input row 0."""
    if ih[J_K1] != 1 or yk[n] != tr[0]:
        return False
    for m in range(n):
        if yk[m] != y[m]:
            return False
    for m in range(3):
        if yk[n + 1 + m] != wr[0, m] or yk[n + 4 + m] != fr[0, m]:
            return False
    return True


@njit(cache=True, fastmath=FASTMATH, nogil=True)
def block_kernel(fb, ib, mi, md, ts, ws, fs, has_f, first, out_idx, y_out, seg_out, ns_out, gen, expo):
    """Samples ``first…N−1`` of a chunk (ts (N,) s in the samples' time base, ws (N, 3) rad/s,
    fs (N, 3) m/s², vehicle axes; ``fs`` ignored unless ``has_f``); after each sample listed in
    ``out_idx`` (increasing) its snapshot goes to ``y_out``/``seg_out``/``ns_out`` (the rows from
    ``ih[J_JOUT]`` on). Stops at the first failing sample with its status; ``ih[J_DONE]`` is
    then the index of that sample (all before it are committed).

    One interval per sample: integrate the state from input row 0 to row 1 (``F_TR``, ``F_WR``,
    ``F_FR``) with the controller of ``Controlled``. On success the state, level,
    counters and input rows are committed and ``seg`` is the interval's; otherwise the state
    and level are unchanged, ``seg`` is restored from ``F_SEGSAVE`` and the float header
    describes a refusal (``H_T_BAD`` …) or the int header names the missing matrices
    (``NEED_REGIME``). ``gen``: None when the engine takes the linear stabilised model
    (``takes_linear_path``), else 0; ``expo``: None for RK4, else 0. numba compiles a kernel
    per combination: ``physics.system.model_rhs`` takes the right-hand side of ``gen``'s type
    while typing (linear or general, never both), and numba prunes the branches an ``expo`` of
    None rules out (the exponential methods' stage and regime code): a command compiles only
    what its model and method run. Everything is in this one function: the views of the buffers are made
    once per call, and no array is handed to a function per sample (numba's reference
    counting of array arguments would cost more than the step)."""
    mi, md = borrow(mi), borrow(md)         # (engine.views: the stage matrices' calls count no references)
    fh = fview1(fb, ib, F_HDR)
    ih = iview1(ib, I_HDR)
    I = iview2(ib, I_I)
    P = fview1(fb, ib, F_P)
    seg = fview1(fb, ib, F_SEG)
    mats = fview3(fb, ib, F_MATS)
    axis = fview2(fb, ib, F_AXIS)
    inertia = fview3(fb, ib, F_INERTIA)
    rhost = iview1(ib, I_RHOST)
    raxis = fview2(fb, ib, F_RAXIS)
    R = fview3(fb, ib, F_R)
    wb = fview2(fb, ib, F_WB)
    wd = fview2(fb, ib, F_WD)
    J = fview3(fb, ib, F_J)
    fo = fview2(fb, ib, F_FO)
    Mm = fview2(fb, ib, F_MM)
    cc = fview1(fb, ib, F_CC)
    tau_ext = fview2(fb, ib, F_TAU)
    fbb = fview2(fb, ib, F_FB)
    chol = fview2(fb, ib, F_CHOL)
    F = fview1(fb, ib, F_F)
    a = fview1(fb, ib, F_A)
    Q = fview1(fb, ib, F_Q)
    RR = fview3(fb, ib, F_RR)
    V = fview2(fb, ib, F_V)
    W = fview2(fb, ib, F_W)
    y = fview1(fb, ib, F_Y)
    yw = fview1(fb, ib, F_YW)
    y1 = fview1(fb, ib, F_Y1)
    K = fview2(fb, ib, F_K)
    k5 = fview1(fb, ib, F_K5)
    U = fview1(fb, ib, F_U)
    Ul = fview1(fb, ib, F_UL)
    AU = fview1(fb, ib, F_AU)
    c = fview1(fb, ib, F_C)
    tr = fview1(fb, ib, F_TR)
    wr = fview2(fb, ib, F_WR)
    fr = fview2(fb, ib, F_FR)
    segsave = fview1(fb, ib, F_SEGSAVE)
    yc = fview1(fb, ib, F_YC)
    yk = fview1(fb, ib, F_YK)
    TW = fview2(fb, ib, F_TW)
    Ta, Tb = TW[0], TW[1]
    table = iview1(ib, I_TABLE)
    method = ih[J_METHOD]
    fid = ih[J_FID]
    q1 = ih[J_Q1]
    max_level = ih[J_MAX_LEVEL]
    nlev = ih[J_NLEV]
    max_step = fh[H_MAX_STEP]
    rtol = fh[H_RTOL]
    atol = fh[H_ATOL]
    n = y.shape[0]
    s = c.shape[0]
    Kf = view1(fb, ib[SLOT_W * F_K], (s * n,))     # K flat (no reshape)
    qa = I[0, LAY_QIB]
    qp = I[0, LAY_QIP]
    nout = out_idx.shape[0]
    jo = ih[J_JOUT]
    locate = method == RK4 and I[0, LAY_STAB] == 1 and I[1, SUPPORT] == 1
    h_min = SWITCH_MIN * max_step
    for i in range(first, ts.shape[0]):
        ih[J_DONE] = i
        # ---- the sample: finite, after the last one; it becomes input row 1
        tsi = ts[i]
        w0, w1, w2 = ws[i, 0], ws[i, 1], ws[i, 2]
        if has_f:
            f0, f1, f2 = fs[i, 0], fs[i, 1], fs[i, 2]
        else:
            f0, f1, f2 = 0.0, 0.0, 0.0
        if not (math.isfinite(tsi) and math.isfinite(w0) and math.isfinite(w1) and math.isfinite(w2)
                and math.isfinite(f0) and math.isfinite(f1) and math.isfinite(f2)):
            ih[J_JOUT] = jo
            return ST_BAD_SAMPLE
        t1s = tsi - fh[H_T_START]
        if not t1s > fh[H_T_REL]:
            ih[J_JOUT] = jo
            return ST_ORDER
        tr[1] = t1s
        wr[1, 0] = w0
        wr[1, 1] = w1
        wr[1, 2] = w2
        fr[1, 0] = f0
        fr[1, 1] = f1
        fr[1, 2] = f2
        # ---- the interval
        for m in range(SEG_N):
            segsave[m] = seg[m]
        t0 = tr[0]
        t1 = tr[1]
        seg[SEG_T0] = t0
        seg[SEG_DT] = t1 - t0
        for m in range(3):
            seg[SEG_W0 + m] = wr[0, m]
            seg[SEG_W1 + m] = wr[1, m]
            seg[SEG_F0 + m] = fr[0, m]
            seg[SEG_F1 + m] = fr[1, m]
        hq = 0
        extra = 0
        q = 0.0
        tail = 0
        t_tail = t1
        # chunks as Controlled._base (RK4: up to (1 + STEP_SLACK)·max_step each) or _ETD._plan
        nsub0 = int(math.ceil((t1 - t0) / max_step - (STEP_SLACK if method == RK4 else 1e-9)))
        if nsub0 < 1:
            nsub0 = 1
        nchunk = nsub0
        if method == RK4:
            h0 = (t1 - t0) / nsub0
            r = 0
        elif expo is None:                  # (not reached: an RK4 engine; pruned at compile time)
            h0 = 0.0
            r = 0
        else:
            # the plan of _ETD._plan: nsub0 chunks of G grid steps q in all, then a tail to t1
            q = max_step / GRID
            eps = max(TAIL_MIN * max_step, TAIL_ULP * abs(t1))
            G = int(math.floor(((t1 - t0) + eps) / q))
            hq = G // nsub0
            extra = G - hq * nsub0
            h0 = hq * q
            if G == 0:
                nchunk = 0
            t_tail = t0 + (nsub0 * h0 + extra * q)
            if t1 - t_tail > eps:
                tail = 1
            r = support_regime(y, I, P, seg, RR)
        level = ih[J_LEVEL]
        po = 0
        io = 0
        do = 0
        nrhs = 0
        nrej = 0
        steps = 0
        est_all = 0.0
        worst_all = 0.0
        for m in range(n):
            yw[m] = y[m]
        have_k1 = _k1_carried(ih, yk, y, tr, wr, fr, n) if method == RK4 else False
        ih[J_K1] = 0                          # K[0] is overwritten from here on
        main_level = level
        chunk_level = level         # the level a chunk began at (integrators.held_level)
        chunk = 0
        n_sw = 0                    # pieces of this chunk ended at a switch so far
        t_sw = 0.0                  # where the rest of the chunk starts (n_sw > 0)
        while chunk < nchunk + tail:
            # the tail (last chunk, exponential methods): etd2 steps to t1 exactly with the
            # φ-functions by Taylor series (_ETD._tail), its own level from 0; stage matrix
            # slot (r, 0, 0) holds the linear part A alone
            in_tail = chunk == nchunk
            meth = EXPRK_D if in_tail else method
            ss = 2 if in_tail else s
            arow = 0 if in_tail else s
            hqc = hq
            if in_tail:
                tc = t_tail
                hc = t1 - t_tail
                hqc = 0
                main_level = level
                level = 0
            elif extra == 0:
                tc = t0 + chunk * h0
                hc = h0
            else:
                tc = t0 + (chunk * h0 + min(chunk, extra) * q)
                hc = h0
                if chunk < extra:
                    hqc = hq + 1
                    hc = hqc * q
            # RK4 with the support friction: the piece ends at its next kink (Controlled._advance)
            end = tc + hc
            t_end = end
            if n_sw > 0:
                hc = end - t_sw
                tc = t_sw
            else:
                chunk_level = level
            can_pass = False
            if locate and n_sw < MAX_SWITCHES:
                can_pass = True
                if not have_k1:
                    if model_rhs(gen, tc, yw, K[0], fid, I, P, seg, mats, axis, inertia, rhost, raxis, R, wb, wd,
                                 J, fo, Mm, cc, tau_ext, fbb, chol, F, a, Q, RR, V, W) == 0:
                        have_k1 = True
                    nrhs += 1
                if have_k1:
                    t_end = support_switch_time(tc, yw, K[0], I, P, seg, end, h_min)
                    if t_end < end:
                        t_end = aimed_switch(tc, t_end, max_step)
                        hc = t_end - tc
            for m in range(n):
                yc[m] = yw[m]
            piece = can_pass                # a piece of the chunk: substeps as long as the level's
            a2 = 0.0                        # (set in the tail)
            rk_retry = False                # an Euler attempt (is_micro_step) missed: its RK4 step
            while True:
                if method != RK4:
                    key = 2 * ((r * nlev + (0 if in_tail else level)) * (GRID + 1) + hqc)
                    po = table[key]
                    if po < 0:
                        ih[J_NEED_R] = r
                        ih[J_NEED_L] = 0 if in_tail else level
                        ih[J_NEED_H] = hqc
                        for m in range(SEG_N):
                            seg[m] = segsave[m]
                        ih[J_JOUT] = jo
                        return NEED_REGIME
                    do = table[key + 1]
                    io = po + (1 if in_tail else s + (1 if method == EXPRK_D else 0)) * (n + 1)
                    if in_tail:                     # the Taylor series' bound, after A's data
                        a2 = md[do + mi[po + n]]
                nsub = piece_substeps(hc, h0, level) if piece else level_substeps(level)
                h = hc / nsub
                eul = method == RK4 and not rk_retry and is_micro_step(nsub, h, max_step)
                rk_retry = False
                sse = 1 if eul else ss      # Euler: f(t, y), then y1 = y + h f and f(t + h, y1)
                est = 0.0
                worst = 0.0
                bad = False
                status = 0
                t_bad = tc
                nrm = 0.0
                for sub in range(nsub):
                    t = tc + sub * h
                    # one call site of the right-hand side: stage j evaluates f at U_j
                    for j in range(sse + 1):
                        if j == 0:
                            if have_k1:
                                continue
                            for m in range(n):
                                U[m] = yw[m]
                        elif j == sse:
                            if meth == EXPRK:
                                break
                            if eul:
                                for m in range(n):
                                    y1[m] = yw[m] + h * K[0, m]
                            elif meth == RK4:
                                for m in range(n):
                                    y1[m] = yw[m] + h / 6.0 * (K[0, m] + 2.0 * K[1, m] + 2.0 * K[2, m] + K[3, m])
                            elif expo is None:  # (not reached: RK4)
                                pass
                            elif in_tail:       # y1 = U + hφ2(hA)(f1 − f0 − A(U − y))
                                for m in range(n):
                                    Ul[m] = U[m] - yw[m]
                                csr_mv(mi, po, 0, io, md, do, Ul, AU)
                                for m in range(n):
                                    Tb[m] = (K[1, m] - K[0, m]) - AU[m]
                                if not phi_taylor(mi, po, io, md, do, h * h * a2, h, 2, Tb, U, y1, Ta, Tb):
                                    status |= ST_NONFINITE
                                    break
                            else:
                                csr_axpy(mi, po, s - 1, io, md, do, Kf, yw, y1)
                            for m in range(n):   # FSAL stage k5 = f(t + h, y1); Ul keeps the last stage
                                Ul[m] = U[m]
                                U[m] = y1[m]
                        elif meth == RK4:
                            cj = c[j] * h
                            for m in range(n):
                                U[m] = yw[m] + cj * K[j - 1, m]
                        elif expo is None:      # (not reached: RK4)
                            pass
                        elif in_tail:           # U = y + hφ1(hA) f0
                            if not phi_taylor(mi, po, io, md, do, h * h * a2, h, 1, K[0], yw, U, Ta, Tb):
                                status |= ST_NONFINITE
                                break
                        else:
                            csr_axpy(mi, po, j - 1, io, md, do, Kf, yw, U)
                        if not ((qa < 0 or _quat_ok(U[qa], U[qa + 1], U[qa + 2], U[qa + 3]))
                                and (qp < 0 or _quat_ok(U[qp], U[qp + 1], U[qp + 2], U[qp + 3]))):
                            status |= ST_NONFINITE
                            break
                        nrhs += 1
                        tj = h if j == sse or (in_tail and j == 1) else c[j] * h
                        status |= model_rhs(gen, t + tj, U, k5 if j == sse else K[j], fid, I,
                                            P, seg, mats, axis, inertia, rhost, raxis, R, wb, wd, J, fo, Mm,
                                            cc, tau_ext, fbb, chol, F, a, Q, RR, V, W)
                    if status & (ST_LOCK | ST_NOT_PD):
                        break
                    if status & ST_NONFINITE:
                        nrm = math.inf
                        bad = True
                        t_bad = t
                        break
                    if expo is None:        # RK4: y1 made with the last stage
                        pass
                    elif meth == EXPRK:
                        # output y1 = y + M_s [f_0 … f_{s−1}]; U holds the last stage (c = 1)
                        csr_axpy(mi, po, s - 1, io, md, do, Kf, yw, y1)
                    elif meth == EXPRK_D:
                        # defect estimate (h/3)(f(y1) − f(U) − A (y1 − U)); A is matrix row arow
                        for m in range(n):
                            U[m] = y1[m] - Ul[m]
                        csr_mv(mi, po, arow, io, md, do, U, AU)
                    if eul:                 # Euler's estimate h/2 (k5 − k1) as RK4's h/6 (K3 − k5)
                        for m in range(n):
                            K[3, m] = 4.0 * k5[m] - 3.0 * K[0, m]
                    # error estimate and its weighted RMS norm
                    acc = 0.0
                    emax = 0.0
                    for m in range(n):
                        if meth == RK4:
                            ee = h / 6.0 * (K[3, m] - k5[m])
                        elif meth == EXPRK_D:
                            ee = h / 3.0 * (k5[m] - K[ss - 1, m] - AU[m])
                        else:
                            ee = y1[m] - U[m]
                        sc = atol + rtol * max(abs(yw[m]), abs(y1[m]))
                        acc += (ee / sc) ** 2
                        if abs(ee) > emax:
                            emax = abs(ee)
                        if not math.isfinite(ee):
                            emax = math.inf
                    nrm = math.sqrt(acc / n)
                    if emax > est:
                        est = emax
                    if not nrm <= 1.0:
                        if not math.isfinite(nrm):
                            nrm = math.inf
                        bad = True
                        t_bad = t
                        break
                    if nrm > worst:
                        worst = nrm
                    for m in range(n):
                        yw[m] = y1[m]
                    if meth != EXPRK:
                        for m in range(n):
                            K[0, m] = k5[m]
                        have_k1 = True
                if status & (ST_LOCK | ST_NOT_PD):
                    for m in range(SEG_N):
                        seg[m] = segsave[m]
                    ih[J_NRHS] += nrhs
                    ih[J_JOUT] = jo
                    return status & (ST_LOCK | ST_NOT_PD)   # as the Python controller: level not updated
                if eul and bad:             # the Euler estimate over the tolerance: RK4 from the same k1
                    rk_retry = True
                    have_k1 = True
                    continue
                if (can_pass and (not bad or t_bad == tc + (nsub - 1) * h) and nrm < math.inf
                        and not status & ST_NONFINITE):
                    # a kink inside the piece (judged from its end: y1, k5)? redo it to end just before
                    d = support_switch_passed(tc + hc, y1, k5, I, P, seg, h_min,
                                              hc - max(SWITCH_EDGE * hc, 4.0 * h_min))
                    if d > 0.0:
                        hc = shortened_piece(hc, d)
                        t_end = tc + hc
                        can_pass = False
                        nrej += 1
                        for m in range(n):
                            yw[m] = yc[m]
                        have_k1 = False
                        continue
                if not bad:
                    break
                # rejected: redo the chunk from its start at a finer level
                nrej += 1
                for m in range(n):
                    yw[m] = yc[m]
                have_k1 = False
                new = next_piece_level(level, nrm, q1, hc, h0, nsub) if piece else next_level(level, nrm, q1)
                if new > max_level:
                    if level < max_level:
                        new = max_level
                    else:
                        fh[H_T_BAD] = t_bad
                        fh[H_E_BAD] = est
                        fh[H_N_BAD] = nrm
                        fh[H_H_BAD] = h
                        for m in range(SEG_N):
                            seg[m] = segsave[m]
                        ih[J_NRHS] += nrhs
                        ih[J_REJ] += nrej
                        ih[J_JOUT] = jo
                        return ST_TOLERANCE if nrm < math.inf else ST_NONFINITE | ST_TOLERANCE
                level = new
            # chunk accepted
            steps += nsub
            if est > est_all:
                est_all = est
            if worst > worst_all:
                worst_all = worst
            if in_tail:
                level = main_level
            elif level > 0:
                level = held_level(coarser_level(level, worst, q1), chunk_level, t_end < end, n_sw)
            if t_end < end:             # the rest of the chunk from the switch
                t_sw = t_end
                n_sw += 1
            else:
                chunk += 1
                n_sw = 0
        # accepted: normalise, check, commit
        ih[J_NRHS] += nrhs
        ih[J_REJ] += nrej
        commit_attitudes(y, yw, qa, qp, seg, method == EXPRK_D)     # etd2: the vehicle's by quadrature
        for m in range(n):
            if not math.isfinite(yw[m]):
                for k in range(SEG_N):
                    seg[k] = segsave[k]
                ih[J_JOUT] = jo
                return ST_NONFINITE
        ih[J_NSTEPS] += steps
        ih[J_LEVEL] = level
        if method == RK4 and I[0, LAY_STAB] == 1 and have_k1:
            # FSAL across intervals: K[0] = f(t1, y1) holds for the next interval, whose input
            # starts where this one ends; stabilised only (the right-hand side does not see the
            # input's slope). Valid while the committed state and input row equal yk.
            for m in range(n):
                yk[m] = yw[m]
            yk[n] = t1
            for m in range(3):
                yk[n + 1 + m] = wr[1, m]
                yk[n + 4 + m] = fr[1, m]
            ih[J_K1] = 1
        if est_all > fh[H_EST]:
            fh[H_EST] = est_all
        if worst_all > fh[H_NORM]:
            fh[H_NORM] = worst_all
        for m in range(n):
            y[m] = yw[m]
        # ---- commit the sample
        tr[0] = t1s
        for m in range(3):
            wr[0, m] = wr[1, m]
            fr[0, m] = fr[1, m]
        fh[H_T_REL] = t1s
        ih[J_NSAMP] += 1
        ih[J_HAS_F] = 1 if has_f else 0
        while jo < nout and out_idx[jo] == i:
            for m in range(n):
                y_out[jo, m] = y[m]
            for m in range(SEG_N):
                seg_out[jo, m] = seg[m]
            ns_out[jo] = ih[J_NSTEPS]
            jo += 1
    ih[J_DONE] = ts.shape[0]
    ih[J_JOUT] = jo
    return 0


@njit(cache=True)
def push_kernel(fb, ib, mi, md, t, w, f, has_f, gen, expo):
    """One sample (``w``, ``f`` (3,) arrays; ``f`` ignored unless ``has_f``): ``block_kernel``
    on a one-row chunk kept in the buffers (``F_PUSH``). Returns the status."""
    if has_f:
        return push_values_kernel(fb, ib, mi, md, t, w[0], w[1], w[2], f[0], f[1], f[2], True, gen, expo)
    return push_values_kernel(fb, ib, mi, md, t, w[0], w[1], w[2], 0.0, 0.0, 0.0, False, gen, expo)


@njit(cache=True)
def push_values_kernel(fb, ib, mi, md, t, wx, wy, wz, fx, fy, fz, has_f, gen, expo):
    """``push_kernel`` of a sample given as scalars (no input arrays to make or unbox: the
    node's per-message path; ``fx, fy, fz`` ignored unless ``has_f``)."""
    fb, ib = borrow(fb), borrow(ib)         # (engine.views: the chunk's views count no references)
    o = ib[SLOT_W * F_PUSH]
    fb[o] = t
    fb[o + 1], fb[o + 2], fb[o + 3] = wx, wy, wz
    if has_f:
        fb[o + 4], fb[o + 5], fb[o + 6] = fx, fy, fz
    else:
        fb[o + 4], fb[o + 5], fb[o + 6] = 0.0, 0.0, 0.0
    n = ib[SLOT_W * F_Y + 1]
    # ``first`` as an int64, not the literal 0: the replay's block_kernel is then this one (numba
    # would otherwise compile a second block_kernel for Literal[int](0), ~10 s at first contact)
    return block_kernel(fb, ib, mi, md, fb[o:o + 1], view2(fb, o + 1, (1, 3)), view2(fb, o + 4, (1, 3)),
                        has_f, np.int64(0), ib[0:0], view2(fb, 0, (0, n)), view2(fb, 0, (0, SEG_N)), ib[0:0], gen, expo)


# ---------------------------------------------------------------------------- Python side
class Engine:
    """The compiled integration state of one simulator (see module doc).

    ``y`` (n,): the state (a view: in-place edits change the state); ``seg``: the system's input
    interval; ``fh``/``ih``: float and int headers (``H_*``, ``J_*``); ``rows()``: the current
    sample (t_rel, w, f). ``stepper``: the compiled integrator (``rk4``/``etd2``/``etd4``) or
    None (every sample then goes through the Python integrator)."""

    def __init__(self, system, stepper=None):
        self.system = system
        self.stepper = stepper
        n = system.layout.n
        tree, wk = system.tree, system.work
        method = COMPILED.get(stepper.name) if stepper is not None else None
        c = (np.array([0.0, 0.5, 0.5, 1.0]) if method in (None, RK4) else np.asarray(stepper.c, float))
        max_level = stepper.max_level if stepper is not None else 0
        nlev = max_level + 1
        fl = [getattr(wk if o == "work" else system, a) for _, o, a in SYSTEM_F]
        f_arrays = {slot: arr for (slot, _, _), arr in zip(SYSTEM_F, fl)}
        f_arrays.update({F_AXIS: tree.axis, F_INERTIA: tree.inertia, F_RAXIS: tree.rotor_axis,
                         F_HDR: np.zeros(N_FH), F_Y: np.zeros(n), F_YW: np.zeros(n), F_Y1: np.zeros(n),
                         F_K: np.zeros((len(c), n)), F_K5: np.zeros(n), F_U: np.zeros(n), F_UL: np.zeros(n),
                         F_AU: np.zeros(n), F_C: c, F_TR: np.zeros(2), F_WR: np.zeros((2, 3)),
                         F_FR: np.zeros((2, 3)), F_SEGSAVE: np.zeros(SEG_N), F_YC: np.zeros(n),
                         F_YK: np.zeros(n + 7), F_PUSH: np.zeros(7), F_TW: np.zeros((2, n))})
        table_n = 2 * 8 * nlev * (GRID + 1) if method in (EXPRK, EXPRK_D) else 2
        i_arrays = {I_I: system.I, I_RHOST: np.asarray(tree.rotor_host, np.int64), I_HDR: np.zeros(N_IH, np.int64),
                    I_TABLE: -np.ones(table_n, np.int64)}
        self.fb, self.ib, views, iviews = pack(f_arrays, i_arrays)
        # the system's arrays become views into the buffers (same values)
        for (slot, o, name) in SYSTEM_F:
            setattr(wk if o == "work" else system, name, views[slot])
        system.rebind(iviews[I_I])
        self.fh, self.ih = views[F_HDR], iviews[I_HDR]
        self.y, self.seg = views[F_Y], views[F_SEG]
        self.tr, self.wr, self.fr = views[F_TR], views[F_WR], views[F_FR]
        self.segsave = views[F_SEGSAVE]
        self.table = iviews[I_TABLE]
        self.mi, self.md = np.zeros(1, np.int64), np.zeros(1)
        self.method = method
        ih, fh = self.ih, self.fh
        ih[J_METHOD] = -1 if method is None else method
        ih[J_FID] = system.fid
        ih[J_Q1] = stepper.q1 if stepper is not None else 4
        ih[J_MAX_LEVEL], ih[J_NLEV] = max_level, nlev
        #: the kernels' compile-time switches (block_kernel): None rules the code out
        self.gen = None if plain(takes_linear_path)(system.fid == 1, iviews[I_I]) else 0
        self.expo = None if method == RK4 else 0
        if stepper is not None:
            fh[H_MAX_STEP], fh[H_RTOL], fh[H_ATOL] = stepper.max_step, stepper.rtol, stepper.atol

    # ---- calls -------------------------------------------------------------------------
    def push(self, t: float, w: np.ndarray, f: np.ndarray, has_f: bool) -> int:
        """One sample through the compiled step (building missing matrices on the way)."""
        while True:
            st = push_kernel(self.fb, self.ib, self.mi, self.md, t, w, f, has_f, self.gen, self.expo)
            if st != NEED_REGIME:
                return st
            self.add_matrices()

    def push_values(self, t: float, wx: float, wy: float, wz: float, fx: float, fy: float, fz: float,
                    has_f: bool) -> int:
        """:meth:`push` of a sample given as floats."""
        while True:
            st = push_values_kernel(self.fb, self.ib, self.mi, self.md, t, wx, wy, wz, fx, fy, fz, has_f, self.gen,
                                    self.expo)
            if st != NEED_REGIME:
                return st
            self.add_matrices()

    def block(self, t, w, f, has_f: bool, first: int, out_idx, y_out, seg_out, ns_out) -> int:
        """Samples ``first…`` of a chunk; returns the status (``ih[J_DONE]``: samples reached)."""
        self.ih[J_JOUT] = int(np.searchsorted(out_idx, first))
        while True:
            st = block_kernel(self.fb, self.ib, self.mi, self.md, t, w, f, has_f, first, out_idx, y_out,
                              seg_out, ns_out, self.gen, self.expo)
            if st != NEED_REGIME:
                return st
            first = int(self.ih[J_DONE])
            self.add_matrices()

    def add_matrices(self) -> None:
        """Build the stage matrices the last call asked for (regime, level, grid step)."""
        r, level, hq = int(self.ih[J_NEED_R]), int(self.ih[J_NEED_L]), int(self.ih[J_NEED_H])
        h = hq * (float(self.fh[H_MAX_STEP]) / GRID) / plain(level_substeps)(level)
        sys_ = self.system
        saved = sys_.regime
        sys_.regime = r
        try:
            ptr, idx, dat = stage_matrices(self.stepper, sys_, h)
        finally:
            sys_.regime = saved
        key = 2 * ((r * int(self.ih[J_NLEV]) + level) * (GRID + 1) + hq)
        self.table[key], self.table[key + 1] = self.mi.size, self.md.size
        self.mi = np.concatenate([self.mi, ptr.reshape(-1), idx])
        self.md = np.concatenate([self.md, dat])

    # ---- state -------------------------------------------------------------------------
    def clear(self, y0: np.ndarray) -> None:
        """Fresh start: state y0, no sample, counters and controller at zero; matrices kept."""
        self.y[:] = y0
        self.fh[H_T_START:] = 0.0
        keep = self.ih[[J_METHOD, J_FID, J_Q1, J_MAX_LEVEL, J_NLEV]].copy()
        self.ih[:] = 0
        self.ih[[J_METHOD, J_FID, J_Q1, J_MAX_LEVEL, J_NLEV]] = keep
        self.tr[:] = self.wr[:] = self.fr[:] = 0.0
