"""The drill-tip figures of the HTML report (model §14-15): each metric along the plan, like the
paper's Fig 4, with the requirement line where a limit is set, and the anatomy in the 3D scene."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.report.figures import dexterity_series

if TYPE_CHECKING:
    import plotly.graph_objects as go

    from arcube.evaluation.result import Evaluation

PANELS: tuple[tuple[str, str, str], ...] = (
    ("lateral_error_mm", "lateral error (mm)", "lateral_error"),
    ("axial_error_mm", "axial error (mm)", "axial_error"),
    ("axis_error_deg", "axis error (deg)", "axis_error"),
    ("torque_Nm", "largest actuator torque (N·m)", "torque"),
    ("deflection_mm", "lateral deflection (mm)", "deflection"),
    ("clearance_mm", "clearance to the anatomy (mm)", "clearance"),
)
"""(PointResults field, axis title, --max / --min name) of each panel."""


def tip_figure(report: Evaluation, limits: dict[str, float] | None = None) -> go.Figure:
    """One panel per metric along the plan's points (x as in the dexterity plot), dashed trajectory
    boundaries, and a red line at ``limits[name]`` (e.g. a run's ``--max lateral_error=0.2``)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    s = dexterity_series(report)
    pts = report.results.points
    panels = [p for p in PANELS if p[0] != "clearance_mm" or np.isfinite(pts.clearance_mm).any()]
    rows = (len(panels) + 1) // 2
    fig = make_subplots(
        rows=rows, cols=2, subplot_titles=[p[1] for p in panels], vertical_spacing=0.12 / max(rows - 1, 1) * 1.5
    )
    hover = [f"traj {s.labels[int(t)]}, k={int(k)}" for t, k in zip(report.task.trajectory, report.task.k)]
    for j, (field, title, name) in enumerate(panels):
        r, c = j // 2 + 1, j % 2 + 1
        y = np.where(pts.reachable, getattr(pts, field), np.nan)
        fig.add_trace(
            go.Scatter(
                x=s.index.tolist(),
                y=[None if not np.isfinite(v) else float(v) for v in y],
                mode="lines+markers",
                marker={"size": 4},
                line={"width": 1},
                name=title,
                text=hover,
                showlegend=False,
                hovertemplate="%{text}<br>%{y:.4g}<extra></extra>",
            ),
            row=r,
            col=c,
        )
        for b in s.boundaries:
            fig.add_vline(x=float(b), line={"color": "#999", "width": 1, "dash": "dot"}, row=r, col=c)
        if limits and name in limits:
            fig.add_hline(
                y=float(limits[name]),
                line={"color": "#d62728", "width": 2},
                row=r,
                col=c,
                annotation_text=f"limit {limits[name]:g}",
                annotation_position="top left",
            )
    o = report.options.loads
    enc = ", ".join(f"{v:g}" for v in sorted(set(o.encoder_deg)))
    fig.update_layout(
        title={
            "text": f"At the drill tip, per reachable point (encoders {enc} deg, thrust {o.thrust_N:g} N, lateral force "
            f"{o.lateral_force_N:g} N; model §15)",
            "font": {"size": 13},
        },
        height=300 * rows,
        margin={"t": 80, "b": 40},
    )
    return fig


def anatomy_trace(report: Evaluation) -> Any:
    """A translucent mesh of the evaluation's anatomy for the 3D scene (None without anatomy)."""
    from arcube.report.mechanism3d import mesh_trace

    return None if report.anatomy is None else mesh_trace(report.anatomy.meshes)
