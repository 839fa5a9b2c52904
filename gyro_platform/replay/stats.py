"""Statistics of a replay's outputs, streamed: min/max per output column, the least-squares
drift rate of the last segment, and a bounded, evenly thinned series for the plot."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

PLOT_POINTS = 4000              # at most this many outputs are kept for the plot


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
        self._key: tuple | None = None          # block layout of _names/_idx (see _plain_columns)
        self._names: tuple[str, ...] = ()
        self._idx: np.ndarray | None = None
        self._anames: tuple[str, ...] | None = None     # columns of the array ranges (add_block)
        self._alo = self._ahi = np.zeros(0)
        self._order: list[str] = []             # their names in the order they got a finite value

    def add(self, out: Any, new_segment: bool) -> None:
        from ..io.recording import csv_row

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
            self._fit = LineFit()
        if np.all(np.isfinite(out.drift_angle)):
            self._fit.add(out.t, np.asarray(out.drift_angle, float))
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
            from ..io.recording import block_columns

            cols = block_columns(block)
            names, m = tuple(cols), np.column_stack(list(cols.values()))
        else:
            names, m = self._names, block.rows[:, idx]
        self._add_matrix(names, m)
        if new_segment or self.last is None:
            self._fit = LineFit()
        d = np.asarray(block.drift_angle, dtype=float)
        ok = np.all(np.isfinite(d), axis=1)
        if ok.any():
            self._fit.add_many(np.asarray(block.t, dtype=float)[ok], d[ok])
        self.last = _Last(float(block.t[-1]), d[-1].copy())

    def _plain_columns(self, block: Any) -> np.ndarray | None:
        """Index into ``block.rows`` of every ``recording.block_columns`` column (names in
        ``self._names``), found once per block layout by two probe blocks whose cells hold
        their own column number; None when a column is not a plain column of ``rows``."""
        key = (block.stabilised, block.status_keys, tuple(block.extra_status), block.rows.shape[1])
        if key != self._key:
            from ..io.recording import block_columns

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

    def drift(self) -> dict[str, Any]:
        """Final drift angle (rad) and the least-squares drift rate of the last segment (rad/s
        and deg/h, per platform axis and norm; absent with fewer than 2 outputs)."""
        if self.last is None:
            return {}
        ax = lambda v: {"x": float(v[0]), "y": float(v[1]), "z": float(v[2]),  # noqa: E731
                        "norm": float(np.linalg.norm(v))}
        res: dict[str, Any] = {"final_drift_angle_rad": ax(np.asarray(self.last.drift_angle, float))}
        slope = self._fit.slope()
        if slope is not None:
            res["drift_rate_rad_s"] = ax(slope)
            res["drift_rate_deg_h"] = ax(slope * 180 / math.pi * 3600)
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
    """At most ``cap`` outputs, evenly thinned (stride doubles when full): bounded memory.
    ``items``: ``Outputs`` (:meth:`add`) or ``(block, row)`` of a thinned copy of an
    ``OutputBlock`` (:meth:`add_block`); :meth:`outputs` gives them all as ``Outputs``."""

    def __init__(self, cap: int = PLOT_POINTS):
        self.cap, self.stride, self.i, self.items = cap, 1, 0, []

    def add(self, out: Any) -> None:
        if self.i % self.stride == 0:
            self.items.append(out)
            if len(self.items) >= self.cap:
                self.items = self.items[::2]
                self.stride *= 2
        self.i += 1

    def add_block(self, block: Any) -> None:
        """The outputs of an ``OutputBlock``: the same items as one :meth:`add` each; the kept
        rows are copied out of the block at once (one fancy index per field)."""
        k, j = len(block), 0
        new: list[int] = []             # block rows kept, in order: the last len(new) items
        while j < k:
            first = j + (-self.i) % self.stride     # the next index whose count is a multiple of the stride
            room = self.cap - len(self.items)
            take = range(first, k, self.stride)[:room]
            new += take
            self.items += [None] * len(take)
            if len(self.items) >= self.cap:
                stop = int(take[-1]) + 1            # halve after the item that filled it
                self.i += stop - j
                j = stop
                at = len(self.items) - len(new)     # where the new rows start; even places stay
                new = new[at % 2::2]
                self.items = self.items[::2]
                self.stride *= 2
            else:
                self.i += k - j
                j = k
        if new:
            sub = take_rows(block, np.array(new, dtype=np.int64))
            self.items[len(self.items) - len(new):] = [(sub, r) for r in range(len(new))]

    def outputs(self) -> list[Any]:
        """The kept outputs as ``Outputs``, in order."""
        return [it[0][it[1]] if type(it) is tuple else it for it in self.items]


#: the per-instant array fields of an OutputBlock (first axis K; ``rotor_rates`` is not one)
def take_rows(block: Any, idx: np.ndarray) -> Any:
    """Rows ``idx`` of an ``OutputBlock`` (a copy)."""
    return block[np.asarray(idx, dtype=np.int64)]
