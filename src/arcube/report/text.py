"""Readable terminal output of an evaluation (Rich tables)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rich.console import Console
from rich.table import Table

if TYPE_CHECKING:
    from arcube.evaluation.result import Evaluation

PAPER_DEXTERITY_PCT = (20.26, 40.25, 66.48)
"""The paper's min / mean / max inverted dexterity (Section 3.2), for comparison."""


def _console() -> Console:
    """A console that does not squeeze the table when output goes to a file or a pipe."""
    console = Console()
    return console if console.is_terminal else Console(width=160)


def print_evaluation(report: Evaluation, console: Console | None = None) -> None:
    """Per-trajectory table, failure counts and the summary."""
    out = console or _console()
    table = Table(
        title=f"{report.trajectories.source}: {len(report.task.ids)} trajectories x {report.task.n_points} points, mode {report.mode}"
    )
    with_anatomy = report.anatomy is not None
    cols = ["traj", "level", "side", "reachable", "dex min %", "dex mean %", "dex max %", "limiting", "first failure"]
    for col in cols + (["clearance mm"] if with_anatomy else []):
        table.add_column(col, justify="right" if col.startswith(("reach", "dex", "clear")) else "left")
    for row in report.per_trajectory():
        cells = [
            row.id,
            row.level,
            row.side,
            f"{100 * row.reachable_fraction:.0f}%",
            f"{row.dexterity_min:.2f}",
            f"{row.dexterity_mean:.2f}",
            f"{row.dexterity_max:.2f}",
            row.limiting_jacobian or "-",
            row.first_failure or "-",
        ]
        if with_anatomy:
            cells.append("-" if row.clearance_min_mm is None else f"{row.clearance_min_mm:.1f}")
        table.add_row(*cells)
    out.print(table)
    s = report.summary
    fails = report.failure_counts()
    if fails:
        out.print("unreachable points by first failure: " + ", ".join(f"{k}: {n}" for k, n in fails.items()))
        for line in report.diagnosis():
            out.print(f"  why: {line}", soft_wrap=True)
    eta = s["eta_G"]
    dex = s["dexterity_pct"]
    out.print(
        f"w_G = {int(s['w_G'])}   reachable {100 * s['reachable_fraction']:.1f}% of {s['n_points']} points   "
        f"eta_G = {eta:.4f} (100/eta_G = {100 / eta:.2f}%)"
        if eta is not None and math.isfinite(eta)
        else f"w_G = {int(s['w_G'])}   reachable {100 * s['reachable_fraction']:.1f}% of {s['n_points']} points   eta_G = inf (not every point is reachable)"
    )
    out.print(
        f"inverted dexterity %: min {dex['min']:.2f}  mean {dex['mean']:.2f}  max {dex['max']:.2f}   "
        f"(paper, Table 2: {PAPER_DEXTERITY_PCT[0]} / {PAPER_DEXTERITY_PCT[1]} / {PAPER_DEXTERITY_PCT[2]}; 0 counted at unreachable points)"
    )
    if report.anatomy is not None or s["self_clearance_min_mm"] is not None:
        clear = s["clearance_min_mm"]
        anat = (
            "no anatomy"
            if report.anatomy is None
            else ("no reachable point" if clear is None else f"{clear:.1f} mm ({s['clearance_min_part']})")
        )
        selfc = s["self_clearance_min_mm"]
        out.print(
            f"clearance to the anatomy: min {anat}   self clearance: min "
            + ("-" if selfc is None else f"{selfc:.1f} mm")
            + (f"   (anatomy: {report.anatomy.source})" if report.anatomy is not None else ""),
            soft_wrap=True,
        )
    print_tip_performance(report, out, s)


def print_tip_performance(report: Evaluation, console: Console | None = None, summary: dict | None = None) -> None:
    """The compact second table (model §15): what a surgeon and a motor supplier need, worst case over
    the reachable points of each trajectory and of the plan."""
    out = console or _console()
    o = report.options.loads
    enc = o.encoder_deg[0] if len(set(o.encoder_deg)) == 1 else ",".join(f"{v:g}" for v in o.encoder_deg)
    table = Table(
        title=(
            f"at the drill tip, worst case (encoders {enc} deg, thrust {o.thrust_N:g} N, "
            f"lateral {o.lateral_force_N:g} N)"
        )
    )
    cols = ["traj", "tip error mm", "lateral mm", "axial mm", "axis deg", "torque N·m", "deflection mm"]
    for col in cols:
        table.add_column(col, justify="left" if col == "traj" else "right")
    pts = report.results.points
    names = ("tip_error_mm", "lateral_error_mm", "axial_error_mm", "axis_error_deg", "torque_Nm", "deflection_mm")

    def worst(sel) -> list[str]:
        cells = []
        for name in names:
            v = getattr(pts, name)[sel & pts.reachable]
            cells.append("-" if v.size == 0 or not (v == v).any() else f"{float(max(v[v == v])):.3g}")
        return cells

    for t, tid in enumerate(report.task.ids):
        table.add_row(tid, *worst(report.task.trajectory == t))
    s = summary if summary is not None else report.summary
    table.add_row("all", *worst(report.task.trajectory >= 0), end_section=True)
    out.print(table)
    if s["torque_max_actuator"] is not None:
        out.print(f"largest torque: {s['torque_max_Nm']:.3g} N·m at {s['torque_max_actuator']}")
