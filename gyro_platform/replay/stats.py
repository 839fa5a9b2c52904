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

"""Statistics of a replay's outputs, streamed: min/max per output column, the least-squares
drift rate of the last segment, and bounded min/max buckets of the plotted quantities for the
figure and the summary's maxima."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..engine.outputs import BEARING_NAMES
from ..reports.summary import axes_dict, RAD_S_TO_DEG_H, RunFigures, summary_dict, unwrap_rotation_vectors

N_BEARINGS = len(BEARING_NAMES)
PLOT_BUCKETS = 2000             # at most this many min/max buckets of outputs are kept for the plot


class Stats:
    """Streaming min/max of every output column (``recording.csv_row`` names, units in the
    names) and a streaming least-squares fit of the drift angle over the last segment (the
    outputs since the last reset), so the drift rate is a slope over the whole segment and not
    the instantaneous rate, which follows the vehicle's oscillations."""

    def __init__(self) -> None:
        self.lo: dict[str, float] = {}
        self.hi: dict[str, float] = {}
        self.non_finite: dict[str, int] = {}
        self.n = 0
        self.last = None
        self._fit = LineFit()
        self._drift_prev: np.ndarray | None = None   # the last unwrapped drift angle of the fit
        self._key: tuple | None = None          # block layout of _names/_idx (see _plain_columns)
        self._names: tuple[str, ...] = ()
        self._idx: np.ndarray | None = None
        self._anames: tuple[str, ...] | None = None     # columns of the array ranges (add_block)
        self._alo = self._ahi = np.zeros(0)
        self._order: list[str] = []             # their names in the order they got a finite value

    def add(self, out: Any, new_segment: bool) -> None:
        from ..reports.recording import csv_row

        self._fold()
        self.n += 1
        for k, v in csv_row(out).items():
            if not math.isfinite(v):
                self.non_finite[k] = self.non_finite.get(k, 0) + 1
                continue
            if k not in self.lo or v < self.lo[k]:
                self.lo[k] = v
            if k not in self.hi or v > self.hi[k]:
                self.hi[k] = v
        if new_segment or self.last is None:
            self._fit, self._drift_prev = LineFit(), None
        d = np.asarray(out.drift_angle, float)
        if np.all(np.isfinite(d)):
            self._drift_prev = unwrap_rotation_vectors(d[None], self._drift_prev)[0]
            self._fit.add(out.t, self._drift_prev)
        self.last = out

    def add_block(self, block: Any, new_segment: bool) -> None:
        """K outputs of an ``OutputBlock`` at once (vectorised; ``new_segment``: the first of
        them starts a new segment); the same ranges and counts as K calls of :meth:`add`.
        The columns are read straight from ``block.rows`` where they are its columns
        (:meth:`_plain_columns`); the ranges are kept as arrays until :meth:`ranges`."""
        k = len(block)
        if k == 0:
            return
        self.n += k
        idx = self._plain_columns(block)
        if idx is None:
            from ..reports.recording import block_columns

            cols = block_columns(block)
            names, m = tuple(cols), np.column_stack(list(cols.values()))
        else:
            names, m = self._names, block.rows[:, idx]
        self._add_matrix(names, m)
        if new_segment or self.last is None:
            self._fit, self._drift_prev = LineFit(), None
        d = np.asarray(block.drift_angle, dtype=float)
        ok = np.all(np.isfinite(d), axis=1)
        if ok.any():
            du = unwrap_rotation_vectors(d[ok], self._drift_prev)      # the fit of a drift that turns on
            self._drift_prev = du[-1]
            self._fit.add_many(np.asarray(block.t, dtype=float)[ok], du)
        self.last = _Last(float(block.t[-1]), d[-1].copy())

    def _plain_columns(self, block: Any) -> np.ndarray | None:
        """Index into ``block.rows`` of every ``recording.block_columns`` column (names in
        ``self._names``), found once per block layout by two probe blocks whose cells hold
        their own column number; None when a column is not a plain column of ``rows``."""
        key = (block.stabilised, block.status_keys, tuple(block.extra_status), block.rows.shape[1])
        if key != self._key:
            from ..reports.recording import block_columns

            n = block.rows.shape[1]
            found = []
            for scale, offset in ((1.0, 0.0), (3.0, 1000.0)):
                probe = type(block)((np.arange(n) * scale + offset)[None, :], block.stabilised, block.status_keys,
                                    {k: np.full(1, np.nan) for k in block.extra_status})
                cols = block_columns(probe)
                found.append((tuple(cols), [(float(v[0]) - offset) / scale for v in cols.values()]))
            (names, a), (_, b) = found
            plain = a == b and all(v == v and v == int(v) and 0 <= v < n for v in a)
            self._key, self._names = key, names
            self._idx = np.array(a, dtype=np.int64) if plain else None
        return self._idx

    def _add_matrix(self, names: tuple[str, ...], m: np.ndarray) -> None:
        """Columns ``m`` (K, len(names)) into the ranges (arrays per ``names``) and counts."""
        if names != self._anames:
            self._fold()
            self._anames = names
            self._alo = np.full(len(names), np.nan)
            self._ahi = np.full(len(names), np.nan)
        ok = np.isfinite(m)
        if ok.all():
            lo, hi = m.min(axis=0), m.max(axis=0)
            some = None
        else:
            k = m.shape[0]
            bad = k - np.count_nonzero(ok, axis=0)
            for j in np.flatnonzero(bad).tolist():
                self.non_finite[names[j]] = self.non_finite.get(names[j], 0) + int(bad[j])
            some = bad < k
            lo = np.where(some, np.where(ok, m, np.inf).min(axis=0), np.nan)
            hi = np.where(some, np.where(ok, m, -np.inf).max(axis=0), np.nan)
        fresh = np.isnan(self._alo) if some is None else np.isnan(self._alo) & some
        if fresh.any():                          # first finite values: the key order of add()
            self._order += [names[j] for j in np.flatnonzero(fresh).tolist()]
        self._alo = np.fmin(self._alo, lo)
        self._ahi = np.fmax(self._ahi, hi)

    def _fold(self) -> None:
        """The array ranges of :meth:`add_block` into ``lo``/``hi``."""
        if self._anames is None:
            return
        pos = {n: j for j, n in enumerate(self._anames)}
        for name in self._order:
            lo, hi = float(self._alo[pos[name]]), float(self._ahi[pos[name]])
            if name not in self.lo or lo < self.lo[name]:
                self.lo[name] = lo
            if name not in self.hi or hi > self.hi[name]:
                self.hi[name] = hi
        self._anames, self._order = None, []

    def ranges(self) -> dict[str, list[float]]:
        self._fold()
        return {k: [self.lo[k], self.hi[k]] for k in self.lo}

    def drift_fit(self) -> tuple[float, np.ndarray] | None:
        """``(first time s, slope (3,) rad/s)`` of the drift fit over the last segment, or None
        (fewer than 2 outputs with a finite drift angle)."""
        slope = self._fit.slope()
        return None if slope is None else (self._fit.t0, slope)

    def drift(self) -> dict[str, Any]:
        """Final drift angle (rad) and the least-squares drift rate of the last segment (rad/s
        and deg/h, per platform axis and norm; absent with fewer than 2 outputs)."""
        if self.last is None:
            return {}
        res: dict[str, Any] = {"final_drift_angle_rad": axes_dict(np.asarray(self.last.drift_angle, float))}
        slope = self._fit.slope()
        if slope is not None:
            res["drift_rate_rad_s"] = axes_dict(slope)
            res["drift_rate_deg_h"] = axes_dict(slope * RAD_S_TO_DEG_H)
            res["fit_s"] = self._fit.span
            res["fit_outputs"] = self._fit.n
        return res


class LineFit:
    """Streaming least-squares slope of y (k,) against t (s); times taken relative to the first
    for conditioning. ``slope()`` is None with fewer than 2 distinct times."""

    def __init__(self) -> None:
        self.n, self.t0, self.span = 0, 0.0, 0.0
        self.st = self.stt = 0.0
        self.sy = self.sty = None

    def add(self, t: float, y: np.ndarray) -> None:
        if self.n == 0:
            self.t0, self.sy, self.sty = t, np.zeros_like(y), np.zeros_like(y)
        x = t - self.t0
        self.n += 1
        self.st += x
        self.stt += x * x
        self.sy += y
        self.sty += x * y
        self.span = x

    def add_many(self, t: np.ndarray, y: np.ndarray) -> None:
        """Points t (K,), y (K, k) at once."""
        if self.n == 0:
            self.t0, self.sy, self.sty = float(t[0]), np.zeros(y.shape[1]), np.zeros(y.shape[1])
        x = t - self.t0
        self.n += len(t)
        self.st += float(x.sum())
        self.stt += float(x @ x)
        self.sy += y.sum(axis=0)
        self.sty += x @ y
        self.span = float(x[-1])

    def slope(self) -> np.ndarray | None:
        den = self.n * self.stt - self.st ** 2
        if self.n < 2 or den <= 1e-300:
            return None
        return (self.n * self.sty - self.st * self.sy) / den


class _Last:
    """The last output's time and drift angle (what :meth:`Stats.drift` reads)."""

    def __init__(self, t: float, drift_angle: np.ndarray):
        self.t, self.drift_angle = t, drift_angle


class PlotSeries:
    """What a replay's figure and its summary's ``recorder`` figures need of every output, in
    bounded memory: the outputs in buckets of ``stride`` consecutive ones (at most ``cap``
    buckets; when full, neighbouring buckets merge and the stride doubles), each bucket
    holding the smallest and largest value of every plotted quantity (:func:`plot_columns`:
    gimbal angles, drift angle, bearing torque magnitudes …), its first and last time and
    the last output's values. The figure draws each bucket as a stroke from its minimum to its
    maximum, so a peak between two thinned instants still shows (no aliasing: at
    ``cap`` = 2000 a bucket is about half a pixel wide), and the maxima reported are those of
    all outputs. ``add`` (one ``Outputs``) and ``add_block`` (an ``OutputBlock``) keep the
    same buckets."""

    def __init__(self, cap: int = PLOT_BUCKETS):
        if cap < 2 or cap % 2:
            raise ValueError(f"cap must be an even number >= 2, not {cap}")
        self.cap, self.stride, self.n, self.nb = cap, 1, 0, 0
        self.stabilised: bool | None = None
        self.lo = self.hi = self.last = np.zeros(0)
        self.t_first = self.t_last = np.zeros(0)

    def add(self, out: Any) -> None:
        """One output instant (``Outputs``)."""
        from ..engine.outputs import OutputBlock

        self.add_block(OutputBlock.stack([out]))

    def add_block(self, block: Any) -> None:
        """The K outputs of an ``OutputBlock``, in order after the ones added before."""
        k = len(block)
        if k == 0:
            return
        m = plot_columns(block)
        t = np.asarray(block.t, dtype=float)
        if self.stabilised is None:
            self.stabilised = bool(block.stabilised)
            c = m.shape[1]
            self.lo, self.hi = np.empty((self.cap, c)), np.empty((self.cap, c))
            self.t_first, self.t_last = np.empty(self.cap), np.empty(self.cap)
        elif bool(block.stabilised) != self.stabilised:
            raise ValueError("outputs of one mode only (stabilised or carried) in a plot series")
        j = 0
        while j < k:
            room = self.cap * self.stride - self.n      # rows the buckets take before a merge
            if room <= 0:
                self._merge()
                continue
            r = min(k - j, room)
            self._fill(t[j:j + r], m[j:j + r])
            j += r
        self.last = m[-1].copy()

    def _fill(self, t: np.ndarray, m: np.ndarray) -> None:
        """Rows ``m`` (r, C) at times ``t`` into the buckets from output ``self.n`` on (they fit:
        no merge needed): the open bucket topped up, whole buckets reduced as one
        (nb, stride, C) array, the rest opening a new bucket."""
        r, st = len(t), self.stride
        b = self.n // st
        head = min(r, (st - self.n % st) % st)          # rows that complete the open bucket
        if head:
            self.lo[b] = np.fmin(self.lo[b], np.fmin.reduce(m[:head], axis=0))
            self.hi[b] = np.fmax(self.hi[b], np.fmax.reduce(m[:head], axis=0))
            self.t_last[b] = t[head - 1]
            b += 1
        full = (r - head) // st
        e = head + full * st
        if full:
            if st == 1:
                self.lo[b:b + full] = self.hi[b:b + full] = m[head:e]
                self.t_first[b:b + full] = self.t_last[b:b + full] = t[head:e]
            else:
                g = m[head:e].reshape(full, st, -1)
                self.lo[b:b + full] = np.fmin.reduce(g, axis=1)
                self.hi[b:b + full] = np.fmax.reduce(g, axis=1)
                self.t_first[b:b + full] = t[head:e:st]
                self.t_last[b:b + full] = t[head + st - 1:e:st]
            b += full
        if e < r:                                      # a new bucket, open
            self.lo[b] = np.fmin.reduce(m[e:], axis=0)
            self.hi[b] = np.fmax.reduce(m[e:], axis=0)
            self.t_first[b], self.t_last[b] = t[e], t[-1]
            b += 1
        self.nb = max(self.nb, b)
        self.n += r

    def _merge(self) -> None:
        """Neighbouring buckets pairwise into one (the buckets are full: ``nb == cap``)."""
        h = self.cap // 2
        self.lo[:h] = np.fmin(self.lo[0::2], self.lo[1::2])
        self.hi[:h] = np.fmax(self.hi[0::2], self.hi[1::2])
        self.t_first[:h], self.t_last[:h] = self.t_first[0::2], self.t_last[1::2]
        self.nb, self.stride = h, self.stride * 2

    def columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(t, lo, hi)``: per bucket its first time (s), the minima and maxima (nb, C)."""
        nb = self.nb
        return self.t_first[:nb], self.lo[:nb], self.hi[:nb]

    def plot_data(self) -> Any:
        """The figure's series (``recording.PlotData``): one point per output while every
        bucket holds one, else two per bucket — its minimum at its first time, its maximum
        halfway to its last — so the line strokes each bucket's whole range."""
        from ..reports.recording import PlotData

        t, lo, hi = self.columns()
        if self.stride > 1:
            t = np.column_stack([t, 0.5 * (t + self.t_last[:self.nb])]).ravel()
            v = np.stack([lo, hi], axis=1).reshape(2 * len(lo), -1)
        else:
            v = lo
        t = t - t[0] if t.size else t
        c = column_slices(bool(self.stabilised))
        return PlotData(t, v[:, c["gimbal"]], v[:, c["drift"]],
                        {b: v[:, c["bearing"].start + i] for i, b in enumerate(BEARING_NAMES)},
                        v[:, c["servo_norm"]] if self.stabilised else None, None)

    def summary(self, drift: tuple[float, np.ndarray] | None) -> dict[str, Any]:
        """The figures ``Recorder.summary`` gives that bounded data keeps exactly, over every
        output, named as there (``summary.summary_dict``): maxima of |value| (from the buckets'
        minima and maxima), final values, and the drift rate of ``drift`` = ``(fit start time s,
        slope (3,) rad/s)`` (the replay's least-squares fit over the last segment,
        ``Stats.drift_fit``; the plot's legend); then ``plot``: the buckets."""
        if self.n == 0:
            return summary_dict(RunFigures(0))
        t, lo, hi = self.columns()
        big = np.fmax(np.abs(lo), np.abs(hi)).max(axis=0)
        c = column_slices(bool(self.stabilised))
        last = self.last
        f = RunFigures(self.n, t_start=float(t[0]), duration=float(self.t_last[self.nb - 1] - t[0]),
                       max_abs_gimbal_angle=big[c["gimbal"]], final_gimbal_angle=last[c["gimbal"]],
                       max_abs_bearing_torque=dict(zip(BEARING_NAMES, big[c["bearing"]].tolist())),
                       max_abs_motor_torque=big[c["motor"]], final_drift_angle=last[c["drift"]],
                       max_abs_drift_angle=np.append(big[c["drift"]], big[c["drift_norm"]]))
        if self.stabilised:
            f.max_abs_servo_torque = np.append(big[c["servo"]], big[c["servo_norm"]])
        if drift is not None:
            f.drift_fit_start, f.drift_rate = float(drift[0] - t[0]), drift[1]
        s = summary_dict(f)
        s["plot"] = {"buckets": self.nb, "outputs_per_bucket": self.stride}
        return s


def column_slices(stabilised: bool) -> dict[str, Any]:
    """Where each quantity sits in a :func:`plot_columns` row."""
    c = {"gimbal": slice(0, 5), "drift": slice(5, 8), "drift_norm": 8, "bearing": slice(9, 9 + N_BEARINGS),
         "motor": slice(9 + N_BEARINGS, 12 + N_BEARINGS)}
    if stabilised:
        c["servo"] = slice(12 + N_BEARINGS, 15 + N_BEARINGS)
        c["servo_norm"] = 15 + N_BEARINGS
    return c


def plot_columns(block: Any) -> np.ndarray:
    """(K, C) per output of an ``OutputBlock``: gimbal angles (5) rad, drift angle (3) and its
    norm rad, bearing torque magnitudes (``BEARING_NAMES``) N m, motor torques (3) N m and, in
    stabilised mode, the servo torque (3) and its magnitude N m (:func:`column_slices`)."""
    d = np.asarray(block.drift_angle, dtype=float)
    parts = [block.gimbal_angles, d, _norms(d)[:, None], _norms(block.bearing_torques), block.motor_torques]
    if block.stabilised:
        st = np.asarray(block.servo_torque, dtype=float)
        parts += [st, _norms(st)[:, None]]
    return np.concatenate(parts, axis=1)


def _norms(v: np.ndarray) -> np.ndarray:
    """Euclidean norms over the last axis (of length 3)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.sqrt(x * x + y * y + z * z)
