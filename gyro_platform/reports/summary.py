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

"""A run's summary, made in one place: its figures, their names and their units.

:func:`summary_dict` names and orders the figures of a run (:class:`RunFigures`) and adds their
units (``SUMMARY_UNITS``); :func:`figures_of_arrays` computes them from a run's whole arrays
(``Recorder.summary``). A replay keeps bounded data instead (``replay.stats.PlotSeries``): it
finds the same figures from its buckets and names them with :func:`summary_dict` too, so both
summaries have the same keys, entries and units.

A *drift* is the slowly growing part of the drift angle, so the drift rate is the slope of a
least-squares straight line through the drift angle over time (``1 rad/s = 206 264.8 °/h``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable

import numpy as np

from ..engine.outputs import BEARING_NAMES, GIMBAL_NAMES

RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0
AXES = ("x", "y", "z")
#: entries of a vector figure: the platform (or vehicle) axes and the vector's norm
AXIS_KEYS = AXES + ("norm",)
ROTORS = ("rotor6", "rotor8", "rotor11")

#: every figure of a summary: key -> (unit, what names its entries: ``joint`` ``GIMBAL_NAMES``,
#: ``bearing`` ``BEARING_NAMES``, ``rotor`` ``ROTORS``, ``axis`` ``AXIS_KEYS``; None: one number)
SUMMARY_FIGURES: dict[str, tuple[str, str | None]] = {
    "n_outputs": ("1", None),
    "t_start": ("s", None),
    "duration": ("s", None),
    "max_abs_gimbal_angle": ("rad", "joint"),
    "final_gimbal_angle": ("rad", "joint"),
    "gimbal_angle_slope": ("rad/s", "joint"),
    "max_abs_bearing_torque": ("N m", "bearing"),
    "max_abs_motor_torque": ("N m", "rotor"),
    "max_abs_servo_torque": ("N m", "axis"),
    "final_drift_angle": ("rad", "axis"),
    "max_abs_drift_angle": ("rad", "axis"),
    "drift_fit_start": ("s", None),
    "drift_rate": ("rad/s", "axis"),
    "drift_rate_deg_per_h": ("°/h", "axis"),
    "platform_vs_vehicle_rate_deg_per_h": ("°/h", "axis"),
    "mean_vehicle_rate": ("rad/s", "axis"),
    "max_abs_vehicle_rate": ("rad/s", "axis"),
}
#: unit of every number in a summary (per key; a dict's entries share the unit)
SUMMARY_UNITS: dict[str, str] = {k: unit for k, (unit, _) in SUMMARY_FIGURES.items()}
#: the entry names of each kind of ``SUMMARY_FIGURES``
ENTRY_NAMES: dict[str, tuple[str, ...]] = {"joint": GIMBAL_NAMES, "bearing": BEARING_NAMES, "rotor": ROTORS,
                                           "axis": AXIS_KEYS}

#: why the relative rate of platform and vehicle is left out of a summary
UNSTEADY_VEHICLE_NOTE = ("platform_vs_vehicle_rate_deg_per_h omitted: the vehicle does not turn at a steady rate, "
                         "so a slope of the platform's attitude relative to the vehicle would measure the vehicle's "
                         "motion, not a departure of the platform")


@dataclass
class RunFigures:
    """The numbers of a run's summary, before they are named (:func:`summary_dict`).

    Vectors are arrays in the order of their names: gimbals (5,) ``GIMBAL_NAMES``, rotors (3,)
    ``ROTORS``, axes (3,) x, y, z — or (4,) x, y, z, norm for a maximum of |value|, whose norm is
    the largest norm, not the norm of the maxima. Times in s (``t_start`` the first output's time,
    ``drift_fit_start`` since it); rates in rad/s. None: the figure is not in the summary.
    """

    n_outputs: int
    t_start: float = 0.0
    duration: float = 0.0
    max_abs_gimbal_angle: np.ndarray | None = None
    final_gimbal_angle: np.ndarray | None = None
    gimbal_angle_slope: np.ndarray | None = None
    max_abs_bearing_torque: dict[str, float] | None = None     # bearing name -> largest |torque|
    max_abs_motor_torque: np.ndarray | None = None
    max_abs_servo_torque: np.ndarray | None = None
    final_drift_angle: np.ndarray | None = None
    max_abs_drift_angle: np.ndarray | None = None
    drift_fit_start: float | None = None
    drift_rate: np.ndarray | None = None
    mean_vehicle_rate: np.ndarray | None = None
    max_abs_vehicle_rate: np.ndarray | None = None
    platform_vs_vehicle_rate: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)


def summary_dict(f: RunFigures) -> dict[str, Any]:
    """The summary of a run: the figures ``f`` by name, in the order of ``SUMMARY_FIGURES``
    (drift rates also in °/h), then ``units`` (of the figures present) and ``notes`` (if any).
    Only ``n_outputs`` when the run has no output."""
    s: dict[str, Any] = {"n_outputs": f.n_outputs}
    if f.n_outputs == 0:
        return s
    s["t_start"] = float(f.t_start)
    s["duration"] = float(f.duration)
    s["max_abs_gimbal_angle"] = _named(GIMBAL_NAMES, f.max_abs_gimbal_angle)
    s["final_gimbal_angle"] = _named(GIMBAL_NAMES, f.final_gimbal_angle)
    if f.gimbal_angle_slope is not None:
        s["gimbal_angle_slope"] = _named(GIMBAL_NAMES, f.gimbal_angle_slope)
    s["max_abs_bearing_torque"] = {b: float(v) for b, v in (f.max_abs_bearing_torque or {}).items()}
    if f.max_abs_motor_torque is not None:
        s["max_abs_motor_torque"] = _named(ROTORS, f.max_abs_motor_torque)
    if f.max_abs_servo_torque is not None:
        s["max_abs_servo_torque"] = _named(AXIS_KEYS, f.max_abs_servo_torque)
    s["final_drift_angle"] = axes_dict(f.final_drift_angle)
    s["max_abs_drift_angle"] = _named(AXIS_KEYS, f.max_abs_drift_angle)
    if f.drift_rate is not None:
        s["drift_fit_start"] = float(f.drift_fit_start)
        s["drift_rate"] = axes_dict(f.drift_rate)
        s["drift_rate_deg_per_h"] = axes_dict(f.drift_rate * RAD_S_TO_DEG_H)
    if f.mean_vehicle_rate is not None:
        s["mean_vehicle_rate"] = axes_dict(f.mean_vehicle_rate)
        s["max_abs_vehicle_rate"] = _named(AXIS_KEYS, f.max_abs_vehicle_rate)
    if f.platform_vs_vehicle_rate is not None:
        s["platform_vs_vehicle_rate_deg_per_h"] = axes_dict(f.platform_vs_vehicle_rate * RAD_S_TO_DEG_H)
    s["units"] = {k: SUMMARY_UNITS[k] for k in s if k in SUMMARY_UNITS}
    if f.notes:
        s["notes"] = list(f.notes)
    return s


def figures_of_arrays(t: np.ndarray, gimbal_angles: np.ndarray, drift_angle: np.ndarray,
                      bearings: dict[str, np.ndarray], motor_torques: np.ndarray | None = None,
                      servo_torque: np.ndarray | None = None, vehicle_omega: np.ndarray | None = None,
                      relative_attitude: Callable[[], np.ndarray] | None = None,
                      fit_start: float = 0.0) -> RunFigures:
    """The figures of a run from its arrays at N output instants: ``t`` (N,) s, ``gimbal_angles``
    (N, 5) rad, ``drift_angle`` (N, 3) rad, ``bearings`` name -> (N, 3) N m (the reported ones),
    ``motor_torques`` (N, 3) and ``servo_torque`` (N, 3) N m, ``vehicle_omega`` (N, 3) rad/s
    (None: absent). ``relative_attitude`` (given when the vehicle's attitude is known) returns
    the platform's rotation relative to the vehicle (N, 3) rad, whose slope is reported when the
    vehicle turns at a steady rate (:func:`steady`).

    ``fit_start`` (s after the first instant) starts the window of the least-squares fits
    (gimbal angle slopes, drift rate, relative rate); a window of fewer than two outputs gives
    way to the whole run, and a note says so.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    if n == 0:
        return RunFigures(0)
    t_rel = t - t[0]
    q, d = gimbal_angles, drift_angle
    notes: list[str] = []
    win = t_rel >= fit_start - 1e-12
    if np.count_nonzero(win) < 2:
        if fit_start > 0:
            notes.append(f"the fits cover the whole run: the window from fit_start {fit_start:g} s holds "
                         f"{np.count_nonzero(win)} output(s), a fit needs two")
        win = np.ones_like(t_rel, dtype=bool)
    f = RunFigures(n, t_start=float(t[0]), duration=float(t_rel[-1]), notes=notes,
                   max_abs_gimbal_angle=np.max(np.abs(q), axis=0), final_gimbal_angle=q[-1],
                   gimbal_angle_slope=fit_slope(t_rel[win], q[win]),
                   max_abs_bearing_torque={b: float(np.max(np.linalg.norm(v, axis=1))) for b, v in bearings.items()},
                   final_drift_angle=d[-1], max_abs_drift_angle=max_abs_axes(d))
    if motor_torques is not None:
        f.max_abs_motor_torque = np.max(np.abs(motor_torques), axis=0)
    if servo_torque is not None:
        f.max_abs_servo_torque = max_abs_axes(servo_torque)
    f.drift_fit_start = float(t_rel[win][0])
    f.drift_rate = fit_slope(t_rel[win], unwrap_rotation_vectors(d)[win])
    if vehicle_omega is not None:
        # the time average (trapezoid over the outputs): a plain mean of the instants counts both
        # ends of the run and depends on the output rate (one period of a roll: 0.026 rad/s at 10 Hz)
        span = float(t_rel[-1])
        area = 0.5 * np.sum((vehicle_omega[1:] + vehicle_omega[:-1]) * np.diff(t_rel)[:, None], axis=0)
        f.mean_vehicle_rate = area / span if span > 0 else vehicle_omega.mean(axis=0)
        f.max_abs_vehicle_rate = max_abs_axes(vehicle_omega)
    if relative_attitude is not None:
        if vehicle_omega is not None and steady(vehicle_omega[win]):
            rel = unwrap_rotation_vectors(relative_attitude())
            f.platform_vs_vehicle_rate = fit_slope(t_rel[win], rel[win])
        else:
            notes.append(UNSTEADY_VEHICLE_NOTE)
    return f


def fit_slope(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares slope of ``y`` (N,) or (N, k) against ``t`` (N,): units of y per second."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.size < 2:
        return np.zeros(y.shape[1:]) if y.ndim > 1 else np.float64(0.0)
    tc = t - t.mean()
    den = float(tc @ tc)
    if den == 0.0:
        return np.zeros(y.shape[1:]) if y.ndim > 1 else np.float64(0.0)
    yc = y - y.mean(axis=0)
    return (tc @ yc) / den


def unwrap_rotation_vectors(d: np.ndarray, prev: np.ndarray | None = None) -> np.ndarray:
    """Rotation vectors ``d`` (N, 3) rad made continuous for a slope fit: each becomes the
    equivalent ``d + 2πm·d/|d|`` (the same rotation) nearest the one before (``prev``: the
    unwrapped vector before ``d[0]``, if any). A rotation vector's angle is at most π; a drift
    that turns on (a carried gyro precessing, 410 °/h about z) wraps there, and a line through
    the wrapped angles has the wrong slope. Rows with a non-finite value stay as they are; a
    series that stays within π/2 of zero (every stabilised platform) is returned unchanged."""
    d = np.asarray(d, dtype=float)
    r = np.sqrt(np.einsum("ij,ij->i", d, d)) if d.size else np.zeros(0)
    near = not (r > 0.5 * math.pi).any() and (prev is None or not np.linalg.norm(prev) > 0.5 * math.pi)
    if near:
        return d
    out = d.copy()
    last = None if prev is None else np.asarray(prev, dtype=float)
    two_pi = 2.0 * math.pi
    for k in range(len(d)):
        if not math.isfinite(r[k]):
            continue
        if last is not None and r[k] > 0.0:
            u = d[k] / r[k]
            m = round(float(np.dot(last - d[k], u)) / two_pi)
            if m:
                out[k] = d[k] + (two_pi * m) * u
        last = out[k]
    return out


def axes_dict(v: np.ndarray) -> dict[str, float]:
    """A vector (3,) as ``{x, y, z, norm}``."""
    v = np.asarray(v, dtype=float)
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2]), "norm": float(np.linalg.norm(v))}


def max_abs_axes(a: np.ndarray) -> np.ndarray:
    """(4,): the largest |component| of vectors ``a`` (N, 3) per axis, then their largest norm."""
    return np.append(np.max(np.abs(a), axis=0), np.max(np.linalg.norm(a, axis=1)))


def steady(w: np.ndarray) -> bool:
    """True when the angular rate samples ``w`` (N, 3) rad/s are constant to 1e-3 of their
    mean (plus 1e-12 rad/s): the only case where a rate of relative attitude is a drift."""
    if len(w) < 2:
        return False
    mean = w.mean(axis=0)
    return float(np.max(np.linalg.norm(w - mean, axis=1))) <= 1e-3 * float(np.linalg.norm(mean)) + 1e-12


def _named(names: tuple[str, ...], v: Any) -> dict[str, float]:
    """``v`` (len(names),) as ``{name: float}``."""
    return dict(zip(names, np.asarray(v, dtype=float).tolist()))


__all__ = ["RunFigures", "summary_dict", "figures_of_arrays", "fit_slope", "unwrap_rotation_vectors", "axes_dict",
           "max_abs_axes", "steady", "RAD_S_TO_DEG_H", "AXES", "AXIS_KEYS", "ROTORS", "SUMMARY_FIGURES",
           "SUMMARY_UNITS", "ENTRY_NAMES"]
