"""Pictures of a breach Monte Carlo (model §22) a surgeon reads at a glance, as PNG bytes (matplotlib).

* :func:`breach_bars_png`: P(breach) per screw (with its Wilson interval), and beside it P(breach) with each source
  alone: which of the robot, the registration and the deflection decides the screw;
* :func:`worst_screw_png`: one screw's isthmus seen along the drill: the bone's ellipse, the screw's circle at the plan,
  the room it leaves (the ellipse the screw's centre must stay in) and the cloud of the sampled offsets, breaches in red.

This layer reads plain rows and arrays (:meth:`arcube.pedicles.monte_carlo.BreachResult.rows`), not the Monte Carlo.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from arcube.report.page import png_bytes

__all__ = ["breach_bars_png", "worst_screw_png"]

_SOURCES = (
    ("p_robot_alone", "robot alone", "#4C72B0"),
    ("p_registration_alone", "registration alone", "#DD8452"),
    ("p_deflection_alone", "deflection alone", "#55A868"),
)


def breach_bars_png(rows: Sequence[Mapping[str, Any]], subtitle: str = "") -> bytes:
    """P(breach) of every screw (dark bars, the 95 % Wilson interval as a line) and with each source alone (light bars);
    a screw the robot does not reach has no bar, and says so. ``subtitle``: whose robot, patient and dockings."""
    from matplotlib.figure import Figure

    n = len(rows)
    fig = Figure(figsize=(max(7.0, 0.75 * n + 2.5), 4.2))
    ax = fig.add_subplot()
    x = np.arange(n)
    width = 0.2
    p = np.nan_to_num(np.array([r["p_breach"] for r in rows], dtype=float), nan=0.0)
    lo = np.nan_to_num(np.array([r["p_breach_low"] for r in rows], dtype=float), nan=0.0)
    hi = np.nan_to_num(np.array([r["p_breach_high"] for r in rows], dtype=float), nan=0.0)
    ax.bar(x - 1.5 * width, 100 * p, width, color="#222222", label="all sources")
    ax.errorbar(
        x - 1.5 * width, 100 * p, yerr=[100 * (p - lo), 100 * (hi - p)], fmt="none", ecolor="#888888", capsize=2, lw=1
    )
    for k, (key, label, colour) in enumerate(_SOURCES):
        v = np.array(
            [0.0 if r[key] is None or (isinstance(r[key], float) and math.isnan(r[key])) else r[key] for r in rows]
        )
        ax.bar(x + (k - 0.5) * width, 100 * v, width, color=colour, label=label)
    for i, r in enumerate(rows):
        if r.get("status") == "not_reached":
            ax.text(i, 2, "not reached", ha="center", va="bottom", fontsize=7, color="#555555", rotation=90)
        elif r["too_wide"]:
            ax.text(i, 102, "too wide", ha="center", va="bottom", fontsize=7, color="#c00000", rotation=90)
    ax.set_xticks(x, [f"{r['trajectory']}\n{r['level']} {r['side']}" for r in rows], fontsize=8)
    ax.set_ylabel("P(breach), %")
    ax.set_ylim(0, 115)
    ax.set_title(
        "Probability that each screw leaves its pedicle, and what decides it" + (f"\n{subtitle}" if subtitle else ""),
        fontsize=10,
    )
    ax.legend(fontsize=8, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.18), frameon=False)
    ax.grid(axis="y", alpha=0.3)
    fig.subplots_adjust(bottom=0.3)
    return png_bytes(fig)


def worst_screw_png(
    offsets: Any,
    room: Any,
    half: tuple[float, float],
    radius: float,
    medial: float,
    cranial: float,
    title: str,
    p_breach: float,
) -> bytes:
    """One screw's isthmus (mm, in its plane: medio-lateral across, cranio-caudal up): the bone's ellipse (half
    extents ``half``), the screw's circle (``radius``) at the plan, the room (``room`` (a', b'): where the screw's
    centre must stay) and the sampled ``offsets`` ``(N, 2)``; ``medial``/``cranial`` +-1 orient the axes (medial left,
    cranial up)."""
    from matplotlib.figure import Figure

    d = np.asarray(offsets, dtype=float)
    d = d[np.all(np.isfinite(d), axis=1)]
    shown = np.column_stack([-medial * d[:, 0], cranial * d[:, 1]])  # medial to the left, cranial up
    a_r, b_r = float(room[0]), float(room[1])
    inside = (
        (shown[:, 0] / a_r) ** 2 + (shown[:, 1] / b_r) ** 2 <= 1.0
        if a_r > 0 and b_r > 0
        else np.zeros(len(shown), bool)
    )
    fig = Figure(figsize=(5.6, 5.2))
    ax = fig.add_subplot()
    t = np.linspace(0, 2 * np.pi, 200)
    ax.fill(half[0] * np.cos(t), half[1] * np.sin(t), color="#f2e6c9", label="pedicle (isthmus)")
    ax.plot(half[0] * np.cos(t), half[1] * np.sin(t), color="#a08850")
    if a_r > 0 and b_r > 0:
        ax.plot(a_r * np.cos(t), b_r * np.sin(t), "--", color="#666666", lw=1, label="room of the screw's centre")
    ax.plot(radius * np.cos(t), radius * np.sin(t), color="#222222", lw=1.5, label="screw, as planned")
    keep = slice(None, None, max(1, len(shown) // 4000))
    ax.scatter(
        shown[keep][inside[keep], 0],
        shown[keep][inside[keep], 1],
        s=2,
        color="#4C72B0",
        alpha=0.35,
        label="samples in bone",
    )
    ax.scatter(
        shown[keep][~inside[keep], 0],
        shown[keep][~inside[keep], 1],
        s=2,
        color="#c00000",
        alpha=0.5,
        label="samples that breach",
    )
    reach = max(half[0], half[1], float(np.percentile(np.abs(shown), 99)) if len(shown) else 0.0) * 1.25
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.set_xlabel("medial  <-  offset (mm)  ->  lateral")
    ax.set_ylabel("caudal  <-  (mm)  ->  cranial")
    ax.set_title(f"{title}: P(breach) {100 * p_breach:.1f} %", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    return png_bytes(fig)
