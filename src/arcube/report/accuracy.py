"""Pictures of an accuracy budget (model §20) a manufacturer reads at a glance, as PNG bytes (matplotlib).

* :func:`sources_png`: the error sources ranked by their share of the lateral variance;
* :func:`histogram_png`: each built robot's largest lateral error over the plan, with the 95th percentile marked;
* :func:`trajectories_png`: the lateral error along each trajectory: Monte Carlo p50 and p95, first-order worst case;
* :func:`write_budget`: the whole output folder of ``arcube tolerance`` (data and pictures), all or nothing.

Drawn on bare :class:`matplotlib.figure.Figure` objects (no pyplot, no global backend state).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from arcube.accuracy.budget import ToleranceResult
from arcube.accuracy.output import write
from arcube.report.page import png_bytes

MAX_BARS = 20
"""Sources drawn by :func:`sources_png`; the rest are summed into one bar."""


def _png(fig: object) -> bytes:
    return png_bytes(fig)


def _subtitle(result: ToleranceResult) -> str:
    s = result.settings
    return (
        f"ISO 2768-1 class {s.tolerance_class}, zero offsets {s.q0_deg:g} deg, encoders {s.encoder_deg:g} deg, "
        f"backlash {s.backlash_arcmin:g}', {s.distribution}"
    )


def sources_png(result: ToleranceResult) -> bytes:
    """Horizontal bars: each source's share (%) of the lateral variance, averaged over the plan, largest on top."""
    from matplotlib.figure import Figure

    ranked = [r for r in result.ranked_sources() if r[3] > 0.0]
    shown, rest = ranked[:MAX_BARS], ranked[MAX_BARS:]
    labels = [f"{name}  (±{tol:.3g} {unit})" for name, tol, unit, _ in shown]
    values = [100.0 * share for *_, share in shown]
    if rest:
        labels.append(f"{len(rest)} other sources")
        values.append(100.0 * sum(r[3] for r in rest))
    fig = Figure(figsize=(8, 0.32 * max(len(values), 4) + 1.6), layout="constrained")
    ax = fig.add_subplot()
    y = np.arange(len(values))[::-1]
    ax.barh(y, values, color="#1f77b4")
    for yi, v in zip(y, values):
        ax.text(v, yi, f" {v:.1f} %", va="center", fontsize=8)
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_xlim(0.0, max(values, default=1.0) * 1.18)
    ax.set_xlabel("share of the lateral error variance (%), averaged over the plan")
    ax.set_title(f"Which tolerance to tighten first\n{_subtitle(result)}", fontsize=10)
    ax.grid(True, axis="x", alpha=0.3)
    return _png(fig)


def histogram_png(result: ToleranceResult) -> bytes:
    """Histogram of each robot's largest lateral error over the plan, p95 marked, beside the first-order worst case."""
    from matplotlib.figure import Figure

    a = result.robot_lateral_max_mm
    finite = a[np.isfinite(a)]
    summary = result.summary
    p95, wc = summary["lateral_error_p95_mm"], summary["lateral_error_wc_mm"]
    fig = Figure(figsize=(8, 4.2), layout="constrained")
    ax = fig.add_subplot()
    if finite.size:
        ax.hist(finite, bins=min(50, max(10, finite.size // 20)), color="#9ecae1", edgecolor="#3182bd")
    ax.axvline(p95, color="#d62728", lw=2.0, label=f"p95 = {p95:.3g} mm")
    ax.axvline(wc, color="0.2", lw=1.2, ls="--", label=f"first-order worst case = {wc:.3g} mm")
    note = f" ({a.size - finite.size} robots cannot assemble somewhere)" if finite.size < a.size else ""
    ax.set_xlabel("largest lateral error of a built robot over the plan (mm)")
    ax.set_ylabel("robots")
    ax.set_title(
        f"95 % of {a.size} robots built to these tolerances drill every point within {p95:.3g} mm{note}\n"
        f"{_subtitle(result)}",
        fontsize=10,
    )
    ax.legend(fontsize=8)
    return _png(fig)


def trajectories_png(result: ToleranceResult) -> bytes:
    """Lateral error along the trajectories, in plan order: Monte Carlo p50 and p95, first-order worst case and RMS."""
    from matplotlib.figure import Figure

    P = len(result.trajectory)
    x = np.arange(P)
    fig = Figure(figsize=(11, 4.6), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(x, result.first.lateral_wc_mm, color="0.2", lw=1.2, ls="--", label="first-order worst case")
    ax.plot(x, result.lateral_mm[:, 1], color="#d62728", lw=1.6, label="Monte Carlo p95")
    ax.plot(x, result.lateral_mm[:, 0], color="#1f77b4", lw=1.4, label="Monte Carlo p50")
    ax.plot(x, result.first.lateral_rms_mm, color="#2ca02c", lw=1.0, ls=":", label="first-order RMS")
    bad = ~result.reachable
    if bad.any():
        ax.scatter(x[bad], np.zeros(int(bad.sum())), marker="x", color="#d62728", s=20, label="not reached")
    ids = result.trajectory
    starts = [k for k in range(P) if k == 0 or ids[k] != ids[k - 1]]
    top = float(np.nanmax(result.first.lateral_wc_mm)) * 1.15
    for i, s in enumerate(starts):
        end = starts[i + 1] if i + 1 < len(starts) else P
        if s > 0:
            ax.axvline(s - 0.5, color="0.5", lw=0.8, ls="--")
        ax.text((s + end - 1) / 2.0, top * 0.98, ids[s], ha="center", va="top", fontsize=8)
    ax.set_ylim(0.0, top)
    ax.set_xlim(-1.0, P)
    ax.set_xlabel("point along the trajectories (entry to target), trajectory after trajectory")
    ax.set_ylabel("lateral error (mm)")
    ax.set_title(f"Lateral error of built robots along the plan\n{_subtitle(result)}", fontsize=10)
    ax.grid(True, axis="y", alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=8, ncols=5, frameon=False)
    return _png(fig)


FIGURES = {"sources.png": sources_png, "lateral_histogram.png": histogram_png, "trajectories.png": trajectories_png}
"""File name -> drawing function of the budget's pictures."""


def write_budget(result: ToleranceResult, out_dir: str | os.PathLike[str]) -> Path:
    """The budget's folder (:func:`arcube.accuracy.output.write`) with every picture of :data:`FIGURES`; returns its path."""
    return write(result, out_dir, FIGURES)
