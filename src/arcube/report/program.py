"""The drilling program's timeline (model §17) as a figure: segments, joint rates and joint
accelerations against their limits, over time. ``arcube program`` and ``arcube design`` write it as
``program.png`` beside ``program.csv``."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from arcube.evaluation.performance import (
    ACTUATOR_NAMES as JOINTS,
)  # q's order in a program (arcube.motion.output.JOINTS)
from arcube.io.files import atomic_write_bytes
from arcube.report.figures import _png_bytes

__all__ = ["SEGMENT_COLOURS", "timeline_figure", "timeline_png"]

SEGMENT_COLOURS = {"approach": "#4c72b0", "drill": "#c44e52", "retract": "#55a868", "transit": "#8172b2"}


def _spans(segment: np.ndarray, trajectory: np.ndarray) -> list[tuple[int, int, str, str]]:
    """Runs of equal (segment, trajectory) rows: (first row, last row, segment, trajectory)."""
    out: list[tuple[int, int, str, str]] = []
    start = 0
    for i in range(1, len(segment) + 1):
        if i == len(segment) or segment[i] != segment[start] or trajectory[i] != trajectory[start]:
            out.append((start, i - 1, str(segment[start]), str(trajectory[start])))
            start = i
    return out


def timeline_figure(prog: Any) -> Any:
    """A matplotlib Figure of ``prog`` (an :class:`arcube.motion.Program`): the segments (top), the
    five joint rates (deg/s) and their accelerations (deg/s^2, central differences of the rates) with
    the limits of ``prog.summary["limits"]`` as dashed lines."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    t = np.asarray(prog.t_s, dtype=float)
    rate = np.asarray(prog.q_dot_deg, dtype=float)
    accel = np.gradient(rate, t, axis=0) if len(t) > 2 else np.zeros_like(rate)
    limits = prog.summary.get("limits", {})
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    ax_seg, ax_rate, ax_acc = fig.subplots(3, 1, sharex=True, height_ratios=(0.5, 1, 1))
    for first, last, seg, traj in _spans(np.asarray(prog.segment), np.asarray(prog.trajectory)):
        t0, t1 = t[first], t[last]
        ax_seg.axvspan(t0, t1, color=SEGMENT_COLOURS.get(seg, "#999999"), alpha=0.85, lw=0)
        if seg == "drill":
            ax_seg.text(0.5 * (t0 + t1), 0.5, traj, ha="center", va="center", color="white", fontsize=9)
    ax_seg.set_yticks([])
    ax_seg.legend(
        handles=[Patch(color=c, label=s) for s, c in SEGMENT_COLOURS.items()], ncols=4, loc="upper right", fontsize=8
    )
    summary = prog.summary
    ax_seg.set_title(
        f"order {' '.join(str(k) for k in summary.get('order', []))}: {summary.get('total_s', t[-1]):.1f} s in total, "
        f"{summary.get('drilling_s', float('nan')):.1f} s drilling"
    )
    for j, name in enumerate(JOINTS):
        ax_rate.plot(t, rate[:, j], lw=1, label=name)
        ax_acc.plot(t, accel[:, j], lw=1, label=name)
    for ax, key, unit in ((ax_rate, "max_joint_speed_deg", "deg/s"), (ax_acc, "max_joint_accel_deg", "deg/s²")):
        if key in limits:
            for sign in (-1, 1):
                ax.axhline(sign * float(limits[key]), color="black", ls="--", lw=0.8)
        ax.set_ylabel(f"joint {'rate' if ax is ax_rate else 'acceleration'} ({unit})")
        ax.grid(alpha=0.3)
    ax_rate.legend(ncols=5, fontsize=8, loc="upper right")
    ax_acc.set_xlabel("time (s)")
    return fig


def timeline_png_bytes(prog: Any) -> bytes:
    """:func:`timeline_figure` of ``prog`` as PNG bytes."""
    return _png_bytes(timeline_figure(prog))


def timeline_png(prog: Any, path: str | os.PathLike[str]) -> Path:
    """Write :func:`timeline_figure` of ``prog`` to ``path`` as a PNG (atomically); returns the path."""
    atomic_write_bytes(path, _png_bytes(timeline_figure(prog)))
    return Path(path)
