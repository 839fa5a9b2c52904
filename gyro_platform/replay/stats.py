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

    def add(self, out: Any, new_segment: bool) -> None:
        from ..io.recording import csv_row

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

    def ranges(self) -> dict[str, list[float]]:
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

    def slope(self) -> np.ndarray | None:
        den = self.n * self.stt - self.st ** 2
        if self.n < 2 or den <= 1e-300:
            return None
        return (self.n * self.sty - self.st * self.sy) / den


class PlotSeries:
    """At most ``cap`` outputs, evenly thinned (stride doubles when full): bounded memory."""

    def __init__(self, cap: int = PLOT_POINTS):
        self.cap, self.stride, self.i, self.items = cap, 1, 0, []

    def add(self, out: Any) -> None:
        if self.i % self.stride == 0:
            self.items.append(out)
            if len(self.items) >= self.cap:
                self.items = self.items[::2]
                self.stride *= 2
        self.i += 1


