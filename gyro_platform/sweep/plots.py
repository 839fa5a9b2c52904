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

"""Budget figures and plots of a sweep (matplotlib, Agg).

* :func:`budget_stats` — per platform axis over the ``ok`` runs: mean, standard deviation σ,
  the 1σ and 3σ bounds ``|mean| + kσ`` and the empirical 99.73 % quantile of ``|drift rate|``
  (°/h);
* :func:`sensitivity` — Spearman rank correlation of each varied parameter with the drift rate
  of each axis (robust to the parameters' units and to monotone non-linearity);
* :func:`plot_budget` — Monte Carlo: histogram with mean, ±1σ, ±3σ; empirical CDF with the 1σ
  and 3σ quantiles; a tornado chart of the rank correlations. Fleet: drift rate per bag and axis.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .store import replacing

AXES = ("x", "y", "z")
SIGMA_QUANTILES = {"-3σ": 0.00135, "-1σ": 0.15866, "+1σ": 0.84134, "+3σ": 0.99865}


def _ok(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in records if r.get("status") == "ok"]


def drift_matrix(records: list[dict[str, Any]]) -> np.ndarray:
    """(n_ok, 3) drift rates °/h of the ``ok`` runs."""
    ok = _ok(records)
    return np.array([[r.get(f"drift_rate_{a}_deg_per_h", math.nan) for a in AXES] for r in ok],
                    dtype=float).reshape(len(ok), 3)


def budget_stats(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per axis: n, mean, std, 1σ and 3σ bounds, 99.73 % quantile of |rate| (°/h)."""
    d = drift_matrix(records)
    rows = []
    for i, a in enumerate(AXES):
        x = d[:, i][np.isfinite(d[:, i])]
        n = x.size
        mean = float(x.mean()) if n else math.nan
        std = float(x.std(ddof=1)) if n > 1 else math.nan
        rows.append({"axis": a, "n": n, "mean_deg_per_h": mean, "std_deg_per_h": std,
                     "bound_1sigma_deg_per_h": abs(mean) + std, "bound_3sigma_deg_per_h": abs(mean) + 3 * std,
                     "q99.73_abs_deg_per_h": float(np.quantile(np.abs(x), 0.9973)) if n else math.nan})
    return rows


def sensitivity(records: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Varied parameter -> Spearman ρ with the drift rate of x, y, z (NaN where undefined)."""
    from scipy.stats import spearmanr

    ok = _ok(records)
    params = sorted({k for r in ok for k in r if k.startswith("param:")})
    d = drift_matrix(records)
    out = {}
    for p in params:
        v = np.array([r.get(p, math.nan) for r in ok], dtype=float)
        rho = np.full(3, math.nan)
        for i in range(3):
            m = np.isfinite(v) & np.isfinite(d[:, i])
            if m.sum() >= 3 and np.ptp(v[m]) > 0 and np.ptp(d[m, i]) > 0:
                rho[i] = float(spearmanr(v[m], d[m, i]).statistic)
        out[p[len("param:"):]] = rho
    return out


def plot_budget(records: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Write the budget plot of a Monte Carlo sweep, or the per-bag plot of a fleet sweep."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    fleet = any(r.get("bag") for r in records)
    d = drift_matrix(records)
    if fleet:
        ok = _ok(records)
        names = [Path(r["bag"]).name for r in ok]
        fig, ax = plt.subplots(figsize=(10, 4 + 0.15 * len(ok)), layout="constrained")
        y = np.arange(len(ok))
        for i, a in enumerate(AXES):
            ax.barh(y + (i - 1) * 0.27, d[:, i], height=0.27, label=f"axis {a}")
        ax.set_yticks(y, names)
        ax.set_xlabel("drift rate (°/h, least-squares fit)")
        ax.set_ylabel("bag")
        ax.axvline(0.0, color="k", lw=0.6)
        ax.legend()
        ax.set_title(title)
    else:
        stats = budget_stats(records)
        sens = sensitivity(records)
        fig, axes = plt.subplots(3, 3, figsize=(14, 11), layout="constrained")
        for i, a in enumerate(AXES):
            x = d[:, i][np.isfinite(d[:, i])]
            s = stats[i]
            ax = axes[0, i]
            if x.size:
                ax.hist(x, bins=max(5, min(50, int(math.sqrt(x.size)) * 2)), color="C0", alpha=0.75,
                        label=f"{x.size} runs")
                for k, style in ((0, "-"), (1, "--"), (3, ":")):
                    for sign in ((1,) if k == 0 else (-1, 1)):
                        ax.axvline(s["mean_deg_per_h"] + sign * k * (s["std_deg_per_h"] if k else 0.0),
                                   color="C3", ls=style, lw=1.2,
                                   label=("mean" if k == 0 else f"±{k}σ") if sign >= 0 or k == 0 else None)
            ax.set_title(f"drift rate, axis {a}: σ = {s['std_deg_per_h']:.3g} °/h")
            ax.set_xlabel("drift rate (°/h)")
            ax.set_ylabel("runs")
            ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))
            ax.legend(fontsize=8)
            ax = axes[1, i]
            if x.size:
                xs = np.sort(x)
                ax.step(xs, np.arange(1, xs.size + 1) / xs.size, where="post", label="empirical CDF")
                for lab, q in SIGMA_QUANTILES.items():
                    ax.axhline(q, color="C3" if "3" in lab else "C1", ls=":", lw=1.0,
                               label=("1σ quantiles" if lab == "+1σ" else "3σ quantiles" if lab == "+3σ" else None))
            ax.set_title(f"CDF, axis {a}: 3σ bound {s['bound_3sigma_deg_per_h']:.3g} °/h")
            ax.set_xlabel("drift rate (°/h)")
            ax.set_ylabel("fraction of runs")
            ax.set_ylim(0, 1)
            ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))
            ax.legend(fontsize=8, loc="lower right")
            ax = axes[2, i]
            names = sorted(sens, key=lambda p: -abs(np.nan_to_num(sens[p][i])))
            rho = [sens[p][i] for p in names]
            r = np.nan_to_num(rho)
            ax.barh(range(len(names)), np.where(r >= 0, r, 0.0), color="C2", label="ρ > 0: drift grows with it")
            ax.barh(range(len(names)), np.where(r < 0, r, 0.0), color="C3", label="ρ < 0: drift falls with it")
            ax.set_yticks(range(len(names)), names, fontsize=8)
            ax.invert_yaxis()
            ax.set_xlim(-1, 1)
            ax.axvline(0, color="k", lw=0.6)
            ax.set_title(f"sensitivity of axis-{a} drift (rank correlation)")
            ax.set_xlabel("Spearman ρ (−1 … 1)")
            ax.legend(fontsize=8, loc="lower right")
        fig.suptitle(title)
    path = Path(path)
    try:
        with replacing(path, suffix=path.suffix) as tmp:
            fig.savefig(tmp, dpi=90)
    finally:
        plt.close(fig)
    return path
