"""The drilling program in the HTML report (model §17-18), read from its files (program.csv,
program.json: :mod:`arcube.report.program_data`), never recomputed:

* a summary and the per-trajectory times (program.json);
* div ``fig-program-timeline``: the segments over time (approach / drill / retract / transit, each
  drill labelled with its trajectory), the joint rates and accelerations (central differences of the
  CSV's rates) against program.json's limits, and the actuator torques when the CSV has them;
* the smallest clearances, the largest eta_L, joint rate and acceleration against their limits
  (program.json records only the extremes over the program, not a clearance per row);
* div ``fig-program-motors``, when the CSV has the torque columns: per actuator its operating points
  (speed |q_dot|, torque |tau|) as on a motor datasheet, the peak and the RMS torque marked; and the
  table of program.json's ``motors`` figures (model §18.3) when it has them;
* div ``fig-program-playback``: the robot with the anatomy along the program
  (:mod:`arcube.report.program_scene`), when the design is known.

Long series are drawn through :func:`~arcube.report.program_data.envelope` (every peak kept).
:func:`write_program_report` writes a program folder's own ``report.html`` (``arcube report DIR``).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.io.files import atomic_write_text
from arcube.report.page import CSS, esc, fmt, plotly_div
from arcube.report.program import SEGMENT_COLOURS
from arcube.report.program_data import JOINTS, ProgramFiles, envelope, find_design, read_program

if TYPE_CHECKING:
    import plotly.graph_objects as go

__all__ = ["DIV_IDS", "MAX_POINTS", "motors_figure", "program_section", "timeline_figure", "write_program_report"]

DIV_IDS = {"timeline": "fig-program-timeline", "motors": "fig-program-motors", "playback": "fig-program-playback"}
MAX_POINTS = 3000
"""At most about this many points per drawn series (:func:`~arcube.report.program_data.envelope`)."""
JOINT_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b")
GRID = 400
"""A torque-speed plot keeps one operating point per cell of a GRID x GRID grid (and the peak)."""


def _series(t: np.ndarray, y: np.ndarray) -> dict[str, list[float | None]]:
    keep = envelope(y, MAX_POINTS)
    return {"x": t[keep].tolist(), "y": [float(v) if math.isfinite(v) else None for v in y[keep]]}


def timeline_figure(prog: ProgramFiles) -> go.Figure:
    """Segments (horizontal bars from each span's first row to the next span's), joint rates (deg/s),
    accelerations (deg/s^2) and, when present, torques (N m) over time; dashed lines at +-limit."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    clear = prog.summary.get("clearances_along_time")
    clear = clear if isinstance(clear, dict) and clear.get("t_s") else None
    panels = ["segments", "joint rate (deg/s)", "joint acceleration (deg/s²)"] + (
        ["actuator torque (N·m)"] if prog.tau_Nm is not None else []
    )
    panels += ["clearance (mm)"] if clear else []
    fig = make_subplots(
        rows=len(panels),
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.04,
        row_heights=[0.35] + [1.0] * (len(panels) - 1),
        subplot_titles=panels,
    )
    spans = prog.spans()
    for kind, colour in SEGMENT_COLOURS.items():
        mine = [s for s in spans if s.segment == kind]
        if mine:
            fig.add_trace(
                go.Bar(
                    name=kind,
                    orientation="h",
                    y=["segment"] * len(mine),
                    base=[s.t0 for s in mine],
                    x=[s.t1 - s.t0 for s in mine],
                    marker={"color": colour},
                    text=[s.trajectory if kind == "drill" else "" for s in mine],
                    textposition="inside",
                    insidetextanchor="middle",
                    customdata=[[s.first, s.last, s.trajectory] for s in mine],
                    legendgroup="segments",
                    hovertemplate=f"{kind} %{{customdata[2]}}<br>rows %{{customdata[0]}}-%{{customdata[1]}}<br>"
                    "%{base:.2f} s + %{x:.2f} s<extra></extra>",
                ),
                row=1,
                col=1,
            )
    series = [prog.q_dot_deg, prog.accel_deg_s2()] + ([prog.tau_Nm] if prog.tau_Nm is not None else [])
    for r, values in enumerate(series, start=2):
        for j, name in enumerate(JOINTS):
            fig.add_trace(
                go.Scatter(
                    name=name,
                    mode="lines",
                    line={"width": 1, "color": JOINT_COLOURS[j]},
                    legendgroup=name,
                    showlegend=r == 2,
                    **_series(prog.t_s, values[:, j]),
                ),
                row=r,
                col=1,
            )
    lim = prog.limits
    for r, key in ((2, "max_joint_speed_deg"), (3, "max_joint_accel_deg")):
        if isinstance(lim.get(key), (int, float)):
            dash = {"color": "black", "width": 1, "dash": "dash"}
            fig.add_hline(
                y=float(lim[key]),
                line=dash,
                row=r,
                col=1,
                annotation_text=f"limit ±{float(lim[key]):g}",
                annotation_position="top left",
            )
            fig.add_hline(y=-float(lim[key]), line=dash, row=r, col=1)
    if clear:
        _clearance_panel(fig, clear, lim, len(panels))
    s = prog.summary
    fig.update_layout(
        title={
            "text": f"Program: order {' '.join(str(k) for k in s.get('order', []))}; {fmt(s.get('total_s'), 1)} s in total, "
            f"{fmt(s.get('drilling_s'), 1)} s drilling",
            "font": {"size": 13},
        },
        barmode="overlay",
        height=220 + 250 * (len(panels) - 1),
        margin={"t": 70, "b": 40},
        legend={"orientation": "h", "y": -0.06},
    )
    fig.update_yaxes(showticklabels=False, row=1, col=1)
    fig.update_xaxes(title_text="time (s)", row=len(panels), col=1)
    return fig


CLEARANCE_LINES = {
    "clearance_mm": ("body to anatomy", "#d62728", "clearance"),
    "tool_clearance_mm": ("tool to anatomy (transit)", "#7f7f7f", None),
    "self_clearance_mm": ("self", "#17becf", "self_clearance"),
}
"""The clearance series of program.json: label, colour, and the limit's key in ``limits`` (the tool's is 0)."""


def _clearance_panel(fig: go.Figure, clear: dict[str, Any], lim: dict[str, Any], row: int) -> None:
    """The body, tool and self clearances along time (program.json's ``clearances_along_time``), each with
    its limit as a dotted line of its colour."""
    import plotly.graph_objects as go

    t = np.asarray(clear["t_s"], dtype=float)
    for key, (label, colour, limit_key) in CLEARANCE_LINES.items():
        y = np.array([np.nan if v is None else float(v) for v in clear.get(key) or []], dtype=float)
        if len(y) != len(t) or not np.isfinite(y).any():
            continue
        fig.add_trace(
            go.Scatter(
                name=label,
                mode="lines",
                line={"width": 1.2, "color": colour},
                legendgroup="clearance",
                x=t.tolist(),
                y=[float(v) if math.isfinite(v) else None for v in y],
            ),
            row=row,
            col=1,
        )
        level = 0.0 if limit_key is None else lim.get(limit_key)
        if isinstance(level, (int, float)):
            fig.add_hline(y=float(level), line={"color": colour, "width": 1, "dash": "dot"}, row=row, col=1)


def _operating_points(speed: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Rows that draw the (speed, torque) cloud: one per occupied cell of a GRID x GRID grid over its
    range, and the row of the largest torque."""
    ok = np.flatnonzero(np.isfinite(speed) & np.isfinite(torque))
    if not len(ok):
        return ok
    cells = []
    for v in (speed[ok], torque[ok]):
        span = float(v.max() - v.min()) or 1.0
        cells.append(np.minimum(((v - v.min()) / span * GRID).astype(np.int64), GRID - 1))
    _, first = np.unique(cells[0] * GRID + cells[1], return_index=True)
    return np.unique(np.r_[ok[first], ok[int(np.argmax(torque[ok]))]])


def motors_figure(prog: ProgramFiles) -> go.Figure | None:
    """Per actuator the program's operating points, torque |tau| (N m) against speed |q_dot| (deg/s), as
    on a motor datasheet; the peak (star: the row of the largest |tau|) and the RMS torque over time
    (dashed) of the CSV's torques; program.json's sizing peak (with the lateral force, model §18.2)
    dotted when it has one. None when the CSV has no torque columns."""
    if prog.tau_Nm is None:
        return None
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    motors = prog.motors or {}
    fig = make_subplots(rows=1, cols=len(JOINTS), subplot_titles=list(JOINTS), horizontal_spacing=0.05)
    for j, name in enumerate(JOINTS):
        speed, tau = np.abs(prog.q_dot_deg[:, j]), np.abs(prog.tau_Nm[:, j])
        keep = _operating_points(speed, tau)
        fig.add_trace(
            go.Scattergl(
                name=f"{name} operating points",
                x=speed[keep].tolist(),
                y=tau[keep].tolist(),
                mode="markers",
                showlegend=False,
                marker={"size": 3, "color": JOINT_COLOURS[j], "opacity": 0.5},
                hovertemplate="%{x:.2f} deg/s, %{y:.3f} N·m<extra>" + name + "</extra>",
            ),
            row=1,
            col=j + 1,
        )
        if not len(keep):
            continue
        peak = int(keep[np.argmax(tau[keep])])
        fig.add_trace(
            go.Scatter(
                name=f"{name} peak",
                x=[float(speed[peak])],
                y=[float(tau[peak])],
                mode="markers",
                showlegend=False,
                marker={"symbol": "star", "size": 13, "color": "#d62728"},
                hovertemplate=f"peak |τ| %{{y:.3f}} N·m at t = {prog.t_s[peak]:.2f} s<extra>{name}</extra>",
            ),
            row=1,
            col=j + 1,
        )
        rms = _rms(prog.t_s, prog.tau_Nm[:, j])
        fig.add_hline(
            y=rms,
            line={"color": "#333", "width": 1, "dash": "dash"},
            row=1,
            col=j + 1,
            annotation_text=f"RMS {rms:.3g}",
            annotation_position="bottom right",
        )
        sizing = motors.get(name, {}).get("torque_peak_Nm")
        if isinstance(sizing, (int, float)) and math.isfinite(sizing):
            fig.add_hline(
                y=float(sizing),
                line={"color": "#d62728", "width": 1, "dash": "dot"},
                row=1,
                col=j + 1,
                annotation_text=f"sizing peak {float(sizing):.3g}",
                annotation_position="top right",
            )
        fig.update_xaxes(title_text="speed |q̇| (deg/s)", rangemode="tozero", row=1, col=j + 1)
    fig.update_yaxes(title_text="torque |τ| (N·m)", row=1, col=1)
    fig.update_yaxes(rangemode="tozero")
    fig.update_layout(
        title={
            "text": "Actuator torque against speed along the program (star: peak |τ|; dashed: RMS τ; dotted: program.json's "
            "sizing peak)",
            "font": {"size": 13},
        },
        height=420,
        margin={"t": 80, "b": 50},
    )
    return fig


def _rms(t: np.ndarray, y: np.ndarray) -> float:
    """RMS of ``y`` over time (trapezoid rule over the rows' times; NaN rows left out)."""
    ok = np.isfinite(y)
    if ok.sum() < 2:
        return float(np.sqrt(np.mean(y[ok] ** 2))) if ok.any() else math.nan
    tt, yy = t[ok], y[ok]
    return float(np.sqrt(np.trapezoid(yy**2, tt) / (tt[-1] - tt[0])))


def _table(head: tuple[str, ...], rows: list[tuple[Any, ...]], fail: list[bool] | None = None) -> str:
    out = "<table><tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"
    for k, r in enumerate(rows):
        cls = " class='fail'" if fail and fail[k] else ""
        out += f"<tr{cls}>" + "".join(f"<td>{esc(fmt(c, 3))}</td>" for c in r) + "</tr>"
    return out + "</table>"


def _num(v: Any) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def _largest(per_joint: Any) -> tuple[float | None, str]:
    """(the largest value of a {joint: value} mapping, its joint); (None, "") when there is none."""
    values = {str(k): _num(v) for k, v in per_joint.items()} if isinstance(per_joint, dict) else {}
    finite = {k: v for k, v in values.items() if v is not None}
    if not finite:
        return None, ""
    name = max(finite, key=lambda k: finite[k])
    return finite[name], name


def limits_table(prog: ProgramFiles) -> str:
    """The program's extremes (program.json) against their limits: value, where, limit, margin (< 0: beyond)."""
    s, lim = prog.summary, prog.limits
    speed, accel = s.get("joint_speed_max_deg_s"), s.get("joint_accel_max_deg_s2")
    rows = [  # (quantity, value, where, limit, kind)
        (
            "body to anatomy, smallest (mm)",
            _num(s.get("clearance_min_mm")),
            s.get("clearance_min_at", ""),
            _num(lim.get("clearance")),
            "min",
        ),
        (
            "tool to anatomy in transit, smallest (mm)",
            _num(s.get("tool_clearance_min_mm")),
            s.get("tool_clearance_min_at", ""),
            0.0,
            "min",
        ),
        (
            "self clearance, smallest (mm)",
            _num(s.get("self_clearance_min_mm")),
            s.get("self_clearance_min_at", ""),
            _num(lim.get("self_clearance")),
            "min",
        ),
        ("η_L, largest", _num(s.get("eta_L_max")), s.get("eta_L_max_at", ""), _num(lim.get("kappa_max")), "max"),
        ("joint rate, largest (deg/s)", *_largest(speed), _num(lim.get("max_joint_speed_deg")), "max"),
        ("joint acceleration, largest (deg/s²)", *_largest(accel), _num(lim.get("max_joint_accel_deg")), "max"),
        (
            "tip speed in transit, largest (mm/s)",
            _num(s.get("tip_speed_max_transit_mm_s")),
            "",
            _num(lim.get("max_tip_speed")),
            "max",
        ),
    ]
    out, fail = [], []
    for name, value, where, limit, kind in rows:
        margin = None if value is None or limit is None else (value - limit if kind == "min" else limit - value)
        out.append((name, value, where or "—", limit, margin))
        fail.append(margin is not None and margin < 0.0)
    return _table(("quantity", "value", "where", "limit", "margin"), out, fail)


MOTOR_COLUMNS = (
    ("torque_peak_Nm", "peak |τ| (N·m)"),
    ("torque_rms_Nm", "RMS τ (N·m)"),
    ("speed_peak_deg_s", "peak |q̇| (deg/s)"),
    ("power_peak_W", "peak power (W)"),
    ("energy_J", "energy (J)"),
    ("torque_peak_gravity_Nm", "peak gravity τ (N·m)"),
    ("torque_peak_loads_only_Nm", "peak τ without masses (N·m)"),
)
"""program.json's ``motors`` figures the table shows (the last two when present), with their headers."""


def motors_table(prog: ProgramFiles) -> str:
    """program.json's ``motors`` figures per actuator (model §18.3) and the peak speed in rpm; "" when it has none."""
    motors = prog.motors
    if not motors:
        return ""
    cols = [c for k, c in enumerate(MOTOR_COLUMNS) if k < 5 or any(c[0] in m for m in motors.values())]
    rows = []
    for name, m in motors.items():
        speed = _num(m.get("speed_peak_deg_s"))
        rows.append((name, *(_num(m.get(key)) for key, _ in cols), None if speed is None else speed / 6.0))
    return (
        "<h3>Motor sizing (program.json)</h3><p class='note'>Peak and RMS torques here include each actuator's worst lateral-force "
        "term (model §18.2-18.3); the plot's marks are those of the CSV's torques (gravity, inertia, thrust).</p>"
        + _table(("actuator", *(h for _, h in cols), "peak speed (rpm)"), rows)
    )


def summary_table(prog: ProgramFiles, folder: str | None = None) -> str:
    """The program's summary (program.json) and its per-trajectory and transit times."""
    s = prog.summary
    items = [
        (
            "order",
            " ".join(str(k) for k in s.get("order", [])) + (f" ({s['order_method']})" if s.get("order_method") else ""),
        ),
        (
            "total / drilling / approach / retract / transit (s)",
            " / ".join(
                fmt(_num(s.get(k)), 2) for k in ("total_s", "drilling_s", "approach_s", "retract_s", "transit_s")
            ),
        ),
        ("rows × dt", f"{len(prog.t_s)} × {fmt(_num(s.get('dt_s')), 3)} s"),
        ("working mode", s.get("mode", "—")),
        ("plan", s.get("plan", "—")),
        ("anatomy", s.get("anatomy") or "none"),
        ("folder", str(prog.folder) if folder is None else folder),
    ]
    out = "<table>" + "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in items) + "</table>"
    per = [t for t in s.get("trajectories", []) if isinstance(t, dict)]
    if per:
        keys = (
            "trajectory",
            "level",
            "side",
            "start_s",
            "approach_s",
            "drill_s",
            "retract_s",
            "drilled_mm",
            "standoff_mm",
        )
        out += "<h3>Per trajectory</h3>" + _table(
            keys, [tuple(_num(t.get(k)) if k.endswith(("_s", "_mm")) else t.get(k, "") for k in keys) for t in per]
        )
    tr = [t for t in s.get("transits", []) if isinstance(t, dict)]
    if tr:
        keys = ("from", "to", "start_s", "duration_s", "method", "waypoints")
        out += "<h3>Transits</h3>" + _table(
            keys, [tuple(_num(t.get(k)) if k.endswith("_s") else t.get(k, "") for k in keys) for t in tr]
        )
    return out


def program_section(
    prog: ProgramFiles,
    params: Any = None,
    anatomy_meshes: Any = None,
    c_z: float | None = None,
    include_js: bool = False,
    note: str = "",
    folder: str | None = None,
) -> str:
    """The program's part of a report page (HTML): summary, timeline, limits, motors, and the playback
    for the design ``params`` ``(27,)`` (skipped with a note when None). ``include_js``: put plotly.js inline
    (the page's first figure); ``note``: a line shown above the playback (e.g. why the anatomy is missing);
    ``folder``: how the page names the program's folder (default its path when read)."""
    from arcube.report.program_scene import playback_figure

    parts = [
        "<h2>Drilling program</h2><p class='note'>Read from the program's files (program.csv, program.json; model §17): "
        "the robot runs these rows in its working mode.</p>",
        summary_table(prog, folder),
    ]
    parts += ["<h3>Timeline</h3>", plotly_div(timeline_figure(prog), DIV_IDS["timeline"], include_js)]
    parts += [
        "<h3>Limits along the program</h3>",
        limits_table(prog),
        "<p class='note'>The smallest clearances are over every state the program was checked at (model §17.2, "
        "no part moving more than 0.5 mm between two); the timeline's clearances are at up to 2000 of the rows. "
        "Accelerations in the timeline are central differences of the CSV's rates; the table's are program.json's.</p>",
    ]
    motors = motors_figure(prog)
    if motors is not None:
        parts += ["<h3>Motors</h3>", plotly_div(motors, DIV_IDS["motors"], False), motors_table(prog)]
    elif prog.motors:
        parts += ["<h3>Motors</h3>", motors_table(prog)]
    parts.append("<h3>Playback</h3>")
    if note:
        parts.append(f"<p class='note'>{esc(note)}</p>")
    if params is None:
        parts.append(
            "<p class='note'>No playback: program.json does not record the design; give it (arcube report DIR --design D.json).</p>"
        )
    else:
        play = playback_figure(prog, params, anatomy_meshes, c_z)
        parts.append(
            f"<p class='note'>The robot at {len(play.rows)} of the program's {len(prog.t_s)} rows (every segment's first and last, "
            "the others spread over time and joint motion); patient frame, mm.</p>"
            + plotly_div(play.figure, DIV_IDS["playback"], False)
        )
    return "\n".join(parts)


def write_program_report(
    folder: str | os.PathLike[str], design: Any = None, anatomy: Any = None, anatomy_frame: str = "LPS"
) -> Path:
    """Write ``folder/report.html`` for a program folder (program.csv, program.json); returns its path.

    ``design``: a :class:`~arcube.model.design.Design`, preset name or JSON path for the playback
    (default: :func:`~arcube.report.program_data.find_design`; without one there is no playback).
    ``anatomy``: what ``--anatomy`` takes (``"none"``, ``"default"``, mesh files in ``anatomy_frame``)
    instead of the anatomy program.json names. InputError (one line) when a file is unreadable;
    nothing is written then.
    """
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.model.design import Design
    from arcube.report.program_scene import summary_anatomy

    prog = read_program(folder)
    recorded = prog.summary.get("design")
    if design is None and isinstance(recorded, dict):  # the design that ran the program (as arcube export --program)
        d: Design | None = Design.from_dict(recorded, source=f"{prog.folder / 'program.json'}: design")
    else:  # given, or for a program.json that records none: the design.json the folder belongs to
        spec = design if design is not None else find_design(prog.folder)
        d = Design.coerce(spec) if spec is not None else None
    if anatomy is None:
        anat, note = summary_anatomy(prog.summary)
    else:
        anat, note = resolve_anatomy(anatomy, anatomy_frame, prog.summary.get("plan")), ""
    section = program_section(
        prog, None if d is None else d.to_vector(), None if anat is None else anat.meshes, include_js=True, note=note
    )
    title = f"AR-CUBE drilling program: {prog.summary.get('plan', prog.folder.name)}"
    out = prog.folder / "report.html"
    atomic_write_text(
        out,
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{esc(title)}</title><style>{CSS}</style></head>"
        f"<body><h1>{esc(title)}</h1>{section}</body></html>",
    )
    return out
