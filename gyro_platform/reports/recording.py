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

"""Recording of simulator outputs: arrays per field, CSV/JSON files, a summary and a plot.

Units: time s, angles rad, rates rad/s, torques N m; drift rates also in °/h
(``1 rad/s = 206 264.8 °/h``). The summary's figures, names and units are those of
:mod:`gyro_platform.reports.summary`: a *drift* is the slowly growing part of the drift angle, so
the drift rate is the slope of a least-squares straight line through the drift angle over time —
an oscillation on top of it averages out, a bounded offset does not count.

Frames: ``drift_angle`` is the platform attitude error (rotation vector, platform axes; see
``outputs.Outputs``); bearing torques are in the axes of ``outputs.BEARING_FRAMES``; servo
torques in platform axes; vehicle rates in vehicle body axes (FLU).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from .jsonio import write_json
from .summary import AXES, figures_of_arrays, ROTORS, RunFigures, summary_dict, SUMMARY_UNITS
from .. import quaternions
from ..engine.outputs import BEARING_NAMES, GIMBAL_NAMES, MOUNT_NAMES, Outputs

QUAT = ("qx", "qy", "qz", "qw")

#: columns of ``outputs.csv`` (and keys of the replay summary's ``ranges``): (pattern, unit,
#: meaning). ``<…>`` stands for each name listed in the meaning; the unit is also the name's
#: suffix (``_rad``, ``_rad_s`` = rad/s, ``_N_m`` = N m; quaternions and counts have none).
CSV_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("t_s", "s", "output instant, s since the first accepted input sample (synthetic scene: its start; bag: its "
                 "first sample, whose stamp the output messages' header stamps continue)"),
    ("<gimbal>_rad", "rad", "gimbal angle; <gimbal> = alpha4, beta5, beta7, alpha9, beta10"),
    ("<gimbal>_rate_rad_s", "rad/s", "gimbal angle rate"),
    ("<gimbal>_axial_torque_N_m", "N m", "torque applied about the gimbal axis (spring, damper, friction, torquer)"),
    ("platform_rate_<axis>_rad_s", "rad/s", "platform inertial angular rate, platform axes; <axis> = x, y, z"),
    ("platform_attitude_<q>", "1", "platform attitude quaternion, platform -> inertial frame; <q> = qx, qy, qz, qw"),
    ("drift_angle_<axis>_rad", "rad", "platform attitude error against its reference (rotation vector, platform axes; "
     "carried mode: the gyros' inertial reference)"),
    ("drift_rate_<axis>_rad_s", "rad/s", "instantaneous rate of the drift angle (follows the vehicle's oscillations; "
     "the summary's drift rate is the least-squares slope of the drift angle)"),
    ("<bearing>_torque_<axis>_N_m", "N m", "bearing reaction torque in the axes of outputs.BEARING_FRAMES; <bearing> = "
     "support, gimbal4, gimbal5, gimbal7, gimbal9, gimbal10, rotor6, rotor8, rotor11"),
    ("motor_torque_<rotor>_N_m", "N m", "rotor motor torque about the spin axis; <rotor> = rotor6, rotor8, rotor11"),
    ("<mount>_rad", "rad", "stabilised mode: mount angles (XYZ Euler, vehicle -> platform); <mount> = mount_roll, "
                           "mount_pitch, mount_yaw"),
    ("servo_torque_<axis>_N_m", "N m", "stabilised mode: servo torque on the mount, platform axes"),
    ("gimbal_lock_margin", "1", "smallest |cos| of the inner gimbal angles beta5, beta7, beta10 (0 = gimbal lock)"),
    ("max_gimbal_angle_rad", "rad", "largest |gimbal angle| at that instant"),
    ("n_steps", "1", "integrator steps taken since the start"),
    ("vehicle_rate_<axis>_rad_s", "rad/s", "scenes: the vehicle angular rate fed in, vehicle body axes (FLU)"),
    ("vehicle_attitude_<q>", "1", "synthetic scenes: vehicle attitude quaternion, body -> navigation frame (ENU)"),
)
#: what each ``<name>`` of ``CSV_COLUMNS`` stands for
COLUMN_PLACEHOLDERS: dict[str, tuple[str, ...]] = {
    "gimbal": GIMBAL_NAMES, "axis": AXES, "q": QUAT, "bearing": BEARING_NAMES, "rotor": ROTORS,
    "mount": MOUNT_NAMES}
#: unit suffix of the simulator's status figures (``Outputs.status``)
STATUS_SUFFIX = {"gimbal_lock_margin": "", "max_gimbal_angle": "_rad", "n_steps": ""}
#: Recorder extra series -> (column stem, component names, unit suffix)
EXTRA_COLUMNS = {"vehicle_omega": ("vehicle_rate", AXES, "_rad_s"), "vehicle_attitude": ("vehicle_attitude", QUAT, "")}


def csv_row(o: Outputs) -> dict[str, float]:
    """One output instant as ``column -> value`` with the units in the names (``CSV_COLUMNS``)."""
    one = lambda v: None if v is None else np.asarray(v, dtype=float)[None]  # noqa: E731
    cols = _columns(lambda name: one(getattr(o, name)), lambda b: one(o.bearing_torques.get(b)),
                    {k: [v] for k, v in o.status.items()}, np.array([float(o.t)]))
    return {k: float(v[0]) for k, v in cols.items()}


def block_columns(block: Any) -> dict[str, np.ndarray]:
    """Every instant of an ``OutputBlock`` as columns (K,): the names and order of :func:`csv_row`."""
    return _columns(lambda name: getattr(block, name), lambda b: block.bearing_torques[:, BEARING_NAMES.index(b)],
                    block.status, np.asarray(block.t, dtype=float))


def _columns(field: Any, bearing: Any, status: dict, t: np.ndarray) -> dict[str, np.ndarray]:
    """Columns from ``field(name)`` / ``bearing(name)`` arrays (K, n) (None: absent) and ``status``."""
    cols: dict[str, np.ndarray] = {"t_s": t}

    def vec(stem: str, names: tuple[str, ...], suffix: str, v: Any) -> None:
        if v is not None:
            for i, n in enumerate(names):
                cols[f"{stem}_{n}{suffix}" if stem else n + suffix] = v[:, i]

    q, qd, tq = field("gimbal_angles"), field("gimbal_rates"), field("gimbal_axial_torques")
    for i, g in enumerate(GIMBAL_NAMES):
        cols[g + "_rad"], cols[g + "_rate_rad_s"], cols[g + "_axial_torque_N_m"] = q[:, i], qd[:, i], tq[:, i]
    vec("platform_rate", AXES, "_rad_s", field("platform_rate"))
    vec("platform_attitude", QUAT, "", field("platform_attitude"))
    vec("drift_angle", AXES, "_rad", field("drift_angle"))
    vec("drift_rate", AXES, "_rad_s", field("drift_rate"))
    for b in BEARING_NAMES:
        vec(b + "_torque", AXES, "_N_m", bearing(b))
    vec("motor_torque", ROTORS, "_N_m", field("motor_torques"))
    vec("", MOUNT_NAMES, "_rad", field("mount_angles"))
    vec("servo_torque", AXES, "_N_m", field("servo_torque"))
    for k, v in status.items():
        cols[k + STATUS_SUFFIX.get(k, "")] = np.asarray(v, dtype=float)
    return cols


class Recorder:
    """Collects :class:`~gyro_platform.engine.outputs.Outputs` (one per output instant).

    ``append(outputs, **extra)`` stores the outputs and optional extra per-instant series, e.g.
    ``vehicle_omega`` (3,) rad/s and ``vehicle_attitude`` (4,) quaternion x, y, z, w
    (vehicle → navigation frame) when the vehicle motion is known.
    """

    def __init__(self) -> None:
        self._outs: list[Outputs] = []
        self._extra: dict[str, list[np.ndarray]] = {}
        self._cache: dict[str, np.ndarray] = {}

    # ---- collection ---------------------------------------------------------------------
    def append(self, outputs: Outputs, **extra: Any) -> None:
        """Record one output instant; ``extra`` arrays must be given at every instant."""
        if self._outs and set(extra) != set(self._extra):
            raise ValueError(f"extra series must be the same at every instant: "
                             f"{sorted(extra)} vs {sorted(self._extra)}")
        if not self._outs:
            self._extra = {k: [] for k in extra}
        self._outs.append(outputs)
        for k, v in extra.items():
            self._extra[k].append(np.atleast_1d(np.asarray(v, dtype=float)).copy())
        self._cache.clear()

    def extend(self, block: Any, **extra: np.ndarray) -> None:
        """Record the K instants of an ``OutputBlock``; ``extra`` arrays (K, n)."""
        for i in range(len(block)):
            self.append(block[i], **{k: v[i] for k, v in extra.items()})

    def __len__(self) -> int:
        return len(self._outs)

    # ---- arrays -------------------------------------------------------------------------
    def field(self, name: str) -> np.ndarray:
        """Stack the values of an ``Outputs`` field, e.g. ``gimbal_angles`` → (N, 5), or of an
        extra series. Optional fields that are ``None`` give ``None``."""
        if name in self._cache:
            return self._cache[name]
        if name in self._extra:
            arr = np.array(self._extra[name])
        elif name == "t":
            arr = np.array([o.t for o in self._outs], dtype=float)
        else:
            vals = [getattr(o, name) for o in self._outs]
            if not vals or vals[0] is None:
                return None  # type: ignore[return-value]
            arr = np.array(vals, dtype=float)
        self._cache[name] = arr
        return arr

    @property
    def t(self) -> np.ndarray:
        """Output instants (s), as given by the simulator."""
        return self.field("t")

    @property
    def t_rel(self) -> np.ndarray:
        """Output instants relative to the first one (s)."""
        t = self.t
        return t - t[0] if t.size else t

    @property
    def gimbal_angles(self) -> np.ndarray:
        """(N, 5) rad, order ``GIMBAL_NAMES``."""
        return self.field("gimbal_angles")

    @property
    def drift_angle(self) -> np.ndarray:
        """(N, 3) rad, platform axes."""
        return self.field("drift_angle")

    def bearing(self, name: str) -> np.ndarray | None:
        """(N, 3) N m bearing torque of ``name`` (``None`` if the simulator does not report it)."""
        key = "bearing:" + name
        if key not in self._cache:
            if not self._outs or self._outs[0].bearing_torques.get(name) is None:
                return None
            self._cache[key] = np.array([o.bearing_torques[name] for o in self._outs], dtype=float)
        return self._cache[key]

    def bearings(self) -> list[str]:
        """Names of the bearings present in the outputs, in ``BEARING_NAMES`` order."""
        if not self._outs:
            return []
        have = self._outs[0].bearing_torques
        return [n for n in BEARING_NAMES if have.get(n) is not None]

    def arrays(self) -> dict[str, np.ndarray]:
        """Every recorded series as arrays: Outputs fields, ``bearing:<name>`` and extras."""
        out: dict[str, np.ndarray] = {}
        for name in ("t", "gimbal_angles", "gimbal_rates", "gimbal_axial_torques", "platform_rate",
                     "platform_attitude", "drift_angle", "drift_rate", "motor_torques",
                     "mount_angles", "servo_torque"):
            a = self.field(name)
            if a is not None:
                out[name] = a
        for b in self.bearings():
            out["bearing:" + b] = self.bearing(b)
        for k in self._extra:
            out[k] = self.field(k)
        return out

    def rows(self, start: int = 0) -> list[dict[str, float]]:
        """One flat row per instant from ``start`` on: :func:`csv_row` plus the extra series
        (``EXTRA_COLUMNS`` names them; any other extra ``k`` gives columns ``k_0, k_1, …``)."""
        rows = []
        for i, o in enumerate(self._outs[start:], start):
            r = csv_row(o)
            for k, v in self._extra.items():
                stem, names, suffix = EXTRA_COLUMNS.get(k, (k, tuple(map(str, range(len(v[i])))), ""))
                for j, x in enumerate(v[i]):
                    r[f"{stem}_{names[j]}{suffix}"] = float(x)
            rows.append(r)
        return rows

    # ---- files --------------------------------------------------------------------------
    def write_csv(self, path) -> Path:
        """All instants as CSV: a header of column names with their units (``CSV_COLUMNS``),
        then one row per instant (``repr`` of each float: round-trips exactly)."""
        with CsvWriter(path) as w:
            w.write(self.rows())
        if w.rows_written == 0:                 # no instant: an empty file
            w.path.parent.mkdir(parents=True, exist_ok=True)
            w.path.write_text("")
        return w.path

    def write_json(self, path, extra: dict | None = None) -> Path:
        """``{"summary": summary(), **extra}`` as strict JSON (:func:`jsonio.write_json`: numpy
        values converted, a non-finite number ``null``)."""
        doc = dict(extra or {})
        if "summary" not in doc:
            doc = {"summary": self.summary(), **doc}
        return write_json(path, doc)

    # ---- analysis -----------------------------------------------------------------------
    def summary(self, fit_start: float = 0.0, mounting=(0.0, 0.0, 0.0, 1.0)) -> dict[str, Any]:
        """Key figures of the run (:func:`summary.figures_of_arrays`, named by :func:`summary.summary_dict`).

        ``fit_start`` (s after the first instant) starts the window of the least-squares
        drift fits. ``mounting`` (quaternion x, y, z, w, ``R_BP``) is the platform orientation
        relative to the vehicle at the first instant, used for ``platform_vs_vehicle_*``.
        """
        if len(self) == 0:
            return summary_dict(RunFigures(0))
        extra = self._extra
        return summary_dict(figures_of_arrays(
            self.t, self.gimbal_angles, self.drift_angle, {b: self.bearing(b) for b in self.bearings()},
            self.field("motor_torques"), self.field("servo_torque"),
            self.field("vehicle_omega") if "vehicle_omega" in extra else None,
            (lambda: self.platform_vs_vehicle(mounting)) if "vehicle_attitude" in extra else None, fit_start))

    def platform_vs_vehicle(self, mounting=(0.0, 0.0, 0.0, 1.0)) -> np.ndarray:
        """(N, 3) rad: rotation of the platform relative to the vehicle since the first
        instant, ``Log(Mᵀ A_B(t)ᵀ M A_P(t))`` with ``A_X(t) = R_IX(0)ᵀ R_IX(t)`` and ``M = R_BP``
        (platform axes). Each attitude is taken in its own inertial frame, so only their
        changes are compared; the platform is assumed to start at the mounting orientation."""
        P = quaternions.normalized(self.field("platform_attitude"))
        B = quaternions.normalized(self.field("vehicle_attitude"))
        M = quaternions.normalized(mounting)
        AP = quaternions.mul(quaternions.conj(P[0]), P)
        AB = quaternions.mul(quaternions.conj(B[0]), B)
        Mi = quaternions.conj(M)
        return quaternions.as_rotvec(quaternions.mul(quaternions.mul(quaternions.mul(Mi, quaternions.conj(AB)), M), AP))

    # ---- plot ---------------------------------------------------------------------------
    def plot_data(self) -> PlotData:
        """The series the figure shows (:class:`PlotData`)."""
        st = self.field("servo_torque")
        return PlotData(self.t_rel, self.gimbal_angles, self.drift_angle,
                        {b: np.linalg.norm(self.bearing(b), axis=1) for b in self.bearings()},
                        None if st is None else np.linalg.norm(st, axis=1),
                        self.field("vehicle_omega") if "vehicle_omega" in self._extra else None)

    def plot(self, path_png, title: str | None = None, summary: dict | None = None) -> Path:
        """:meth:`figure` written as PNG (:func:`save_plot`)."""
        return save_plot(self.plot_data(), path_png, title, summary if summary is not None else self.summary())

    def figure(self, title: str | None = None, summary: dict | None = None):
        """:func:`make_figure` of :meth:`plot_data` (``summary``: :meth:`summary` if not given)."""
        return make_figure(self.plot_data(), title, summary if summary is not None else self.summary())


@dataclass
class PlotData:
    """What a run's figure shows, at N points: ``t_rel`` (N,) s since the first output,
    ``gimbal_angles`` (N, 5) rad, ``drift_angle`` (N, 3) rad, ``bearings`` name → (N,) N m
    torque magnitudes (``BEARING_NAMES`` order, the reported ones), ``servo_torque`` (N,) N m
    magnitude or None, ``vehicle_omega`` (N, 3) rad/s body axes or None. The points are the
    output instants, or (a long replay, ``replay.stats.PlotSeries``) each bucket of outputs'
    minimum and maximum. Small to pickle (``reports.plot_process``)."""

    t_rel: np.ndarray
    gimbal_angles: np.ndarray
    drift_angle: np.ndarray
    bearings: dict[str, np.ndarray]
    servo_torque: np.ndarray | None
    vehicle_omega: np.ndarray | None


def save_plot(data: PlotData, path_png: Any, title: str | None, summary: dict) -> Path:
    """:func:`make_figure` written as PNG (folders made)."""
    path = Path(path_png)
    path.parent.mkdir(parents=True, exist_ok=True)
    # zlib level 1: the same pixels, ~25 ms less than PIL's default level 6 (the file ~15 % larger)
    make_figure(data, title, summary).savefig(path, dpi=100, pil_kwargs={"compress_level": 1})
    return path


def make_figure(data: PlotData, title: str | None, summary: dict):
    """Gimbal angles, drift angle (with fitted drift rates in °/h from ``summary``), bearing
    torques and the vehicle rate against time (matplotlib Agg backend). Every panel has a
    title, axis labels with units and a legend; ``title`` (wrapped, never cut) heads the
    figure; margins fixed in inches (room for the labels, the wrapped title and the panel
    titles). A plain ``matplotlib.figure.Figure`` on an Agg canvas (no pyplot: nothing to
    close, ~0.1 s less to import)."""
    import textwrap

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogFormatter

    s = summary
    t = data.t_rel
    has_vehicle = data.vehicle_omega is not None
    n = 4 if has_vehicle else 3
    height = 2.8 * n + 0.8                      # inches
    fig = Figure(figsize=(10, height))
    FigureCanvasAgg(fig)                    # the Agg canvas: draw(), get_renderer(), savefig
    axs = fig.subplots(n, 1, sharex=True)
    q = data.gimbal_angles
    for i, g in enumerate(GIMBAL_NAMES):
        axs[0].plot(t, q[:, i] * 1e3, label=g, lw=1)
    axs[0].set_ylabel("gimbal angle [mrad]")
    # panel titles at y=1.0 as given (where matplotlib would place them: no tick labels above the
    # panels) instead of where it measures each axis's bounding box at every draw to put them
    # (~25 ms of the figure); the same pixels
    axs[0].set_title("gimbal angles", fontsize=10, y=1.0)
    axs[0].legend(loc="upper right", ncol=5, fontsize=8)
    d = data.drift_angle
    rates = s.get("drift_rate_deg_per_h", {})
    t0f = s.get("drift_fit_start", 0.0)
    for i, ax in enumerate(AXES):
        lbl = f"{ax}: {rates.get(ax, float('nan')):+.4g} °/h"
        line, = axs[1].plot(t, d[:, i] * 1e6, label=lbl, lw=1)
        r = s.get("drift_rate", {}).get(ax)
        win = t >= t0f
        if r is not None and t.size > 1 and win.any():
            c = d[win, i].mean() - r * t[win].mean()
            tw = t[win][[0, -1]]            # a straight line: its two ends (the same pixels as every point's)
            axs[1].plot(tw, (c + r * tw) * 1e6, ls="--", lw=0.8, color=line.get_color())
    axs[1].set_ylabel("drift angle [µrad]")
    axs[1].set_title("drift angle (platform attitude error, platform axes)", fontsize=10, y=1.0)
    axs[1].legend(loc="upper left", fontsize=8, title="drift rate (LSQ fit, dashed)", title_fontsize=8)
    for b, torque in data.bearings.items():
        axs[2].plot(t, torque, label=b, lw=1)
    st = data.servo_torque
    if st is not None:
        axs[2].plot(t, st, label="servo", lw=1, ls=":")
    axs[2].set_ylabel("|torque| [N m]")
    axs[2].set_title("bearing reaction torques" + (" and servo torque" if st is not None else "")
                     + " (magnitude)", fontsize=10, y=1.0)
    if data.bearings:
        axs[2].set_yscale("symlog", linthresh=1e-9)
        # plain-text tick labels ("1e-06"): the default ones are mathtext, whose parser is
        # built on its first use (~0.15 s of a replay's plot, measured)
        axs[2].yaxis.set_major_formatter(LogFormatter(labelOnlyBase=True))
    if data.bearings or st is not None:
        axs[2].legend(loc="upper right", ncol=5, fontsize=7)
    if has_vehicle:
        w = data.vehicle_omega
        for i, ax in enumerate(AXES):
            axs[3].plot(t, w[:, i], label=f"ω_{ax}", lw=1)
        axs[3].set_ylabel("vehicle rate [rad/s]")
        axs[3].set_title("vehicle angular rate (input, body axes FLU)", fontsize=10, y=1.0)
        axs[3].legend(loc="upper right", ncol=3, fontsize=8)
    axs[-1].set_xlabel("time since the first output [s]")
    for a in axs:
        a.grid(True, alpha=0.3)
    head = textwrap.fill(title or "gyro_platform outputs", 100)
    fig.suptitle(head)
    # fixed margins (inches) instead of a layout engine: constrained layout draws the whole
    # figure once more to measure it (~0.25 s of the ~0.6 s a replay's plot takes)
    fig.subplots_adjust(left=0.95 / 10, right=1 - 0.25 / 10, bottom=0.55 / height,
                        top=1 - (0.55 + 0.22 * (head.count("\n") + 1)) / height, hspace=0.22)
    return fig


class CsvWriter:
    """``outputs.csv`` written as the run goes: :meth:`write` appends whole rows and flushes,
    so an interrupt, a kill or a full disk leaves a file that ends on a whole row. A failed
    write (OSError: disk full, file too large …) cuts the file back to the last whole row and
    raises ``OSError`` naming the file; the file (and its folder) is made at the first rows;
    the header (column names with units, ``CSV_COLUMNS``)
    is the keys of the first rows (every row has the same columns). Values: ``repr`` of each
    float (round-trips exactly)."""

    def __init__(self, path: Any):
        self.path = Path(path)
        self._fh: Any = None            # opened (folder made) at the first rows: nothing before
        self.cols: list[str] | None = None
        self.rows_written = 0
        self._good = 0                  # file size after the last whole row

    def write(self, rows: list[dict[str, float]]) -> None:
        """Append ``rows`` (dicts column -> float) and flush."""
        if not rows:
            return
        if self._fh is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._fh = self.path.open("w", newline="")

        if self.cols is None:
            self.cols = list(rows[0])
            self._put(self._lines([self.cols]), 0)
        for a in range(0, len(rows), self.BATCH):      # small flushed batches: a failure keeps
            part = rows[a:a + self.BATCH]              # every whole batch before it
            for r in part:
                if len(r) != len(self.cols) or r.keys() != set(self.cols):
                    raise ValueError(f"{self.path}: row columns differ from the header: "
                                     f"{sorted(set(r) ^ set(self.cols))}")
            self._put(self._lines([[repr(r[k]) for k in self.cols] for r in part]), len(part))

    #: rows per flushed write
    BATCH = 64

    @staticmethod
    def _lines(rows: list[list[str]]) -> str:
        import io

        buf = io.StringIO()
        csv.writer(buf).writerows(rows)
        return buf.getvalue()

    def _put(self, text: str, n_rows: int) -> None:
        """Append ``text`` (whole rows) and flush; on failure cut back to the last whole row."""
        try:
            self._fh.write(text)
            self._fh.flush()
        except BaseException as e:      # disk full, file size limit, a second Ctrl-C …
            self._cut()
            if isinstance(e, OSError):
                raise OSError(e.errno, f"{e.strerror or e} (writing {self.path}; it ends on row "
                                       f"{self.rows_written})") from None
            raise
        self._good = self._fh.tell()
        self.rows_written += n_rows

    def _cut(self) -> None:
        """Back to the last whole row (a truncate needs no free space)."""
        import os

        try:
            os.ftruncate(self._fh.fileno(), self._good)
        except OSError:
            pass
        try:
            self._fh.close()
        except OSError:
            pass

    def close(self) -> None:
        if self._fh is not None and not self._fh.closed:
            try:
                self._fh.close()
            except OSError:
                self._cut()
                raise

    def __enter__(self) -> "CsvWriter":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


# ---- summary table ----------------------------------------------------------------------
#: rows of the summary table: (summary key, number format); units from ``summary.SUMMARY_UNITS``
_TABLE = [
    ("max_abs_gimbal_angle", "{:.3e}"),
    ("final_gimbal_angle", "{:+.3e}"),
    ("gimbal_angle_slope", "{:+.3e}"),
    ("max_abs_bearing_torque", "{:.3e}"),
    ("max_abs_motor_torque", "{:.3e}"),
    ("max_abs_servo_torque", "{:.3e}"),
    ("final_drift_angle", "{:+.3e}"),
    ("max_abs_drift_angle", "{:.3e}"),
    ("drift_rate", "{:+.4e}"),
    ("drift_rate_deg_per_h", "{:+.5f}"),
    ("platform_vs_vehicle_rate_deg_per_h", "{:+.5f}"),
    ("mean_vehicle_rate", "{:+.3e}"),
    ("max_abs_vehicle_rate", "{:.3e}"),
]


def print_summary_table(summary: dict, file: TextIO | None = None) -> None:
    """Print the summary as a compact aligned table: one line per quantity, one column per
    joint / bearing / axis."""
    import sys

    out = file if file is not None else sys.stdout
    head = []
    if "scene" in summary:
        head.append(f"scene {summary['scene']}")
    if "duration" in summary:
        head.append(f"{summary['duration']:.6g} s simulated")
    if "n_samples" in summary:
        head.append(f"{summary['n_samples']} input samples")
    head.append(f"{summary.get('n_outputs', 0)} outputs")
    if "wall_time" in summary:
        head.append(f"wall {summary['wall_time']:.3g} s")
    print(" | ".join(head), file=out)
    rows: list[tuple[str, list[str]]] = []
    for key, fmt in _TABLE:
        d = summary.get(key)
        if not isinstance(d, dict) or not d:
            continue
        cells = [f"{k}={fmt.format(v)}" for k, v in d.items()]
        rows.append((f"{key} [{SUMMARY_UNITS[key]}]", cells))
    if not rows:
        return
    w0 = max(len(r[0]) for r in rows)
    ncol = max(len(r[1]) for r in rows)
    widths = [max((len(r[1][j]) for r in rows if j < len(r[1])), default=0) for j in range(ncol)]
    for name, cells in rows:
        line = name.ljust(w0) + "  " + "  ".join(c.ljust(widths[j]) for j, c in enumerate(cells))
        print(line.rstrip(), file=out)


__all__ = ["Recorder", "print_summary_table"]
