"""One self-contained HTML report of an evaluation (and of an optimization run).

:func:`write_evaluation_report` writes a single HTML file that opens with no network (plotly.js
is embedded once, ``include_plotlyjs=True``) holding:

* the design table (as the paper's Table 2: rows m, f, p, d, c, t, r, o, alpha, beta; columns
  x, y, z), the summary and the per-trajectory table;
* the paper's Fig 4 (local inverted dexterity along all task points), div ``fig-dexterity``;
* for a run, convergence per generation from ``history.csv``, div ``fig-convergence``;
* a 3D scene, div ``fig-scene``: the mechanism drawn from :mod:`arcube.model.body` (frame,
  cranks, four-bars, z dyad, spherical links as arcs, drill) and the trajectories, with a
  slider and a play button that move it along the reachable task points (plotly frames).

With ``program`` (a program folder of the design) it adds the drilling program's section
(:mod:`arcube.report.program_html`). Beside the HTML it writes ``<stem>_dexterity.png`` and, for a run, ``<stem>_convergence.png``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.model.design import UNITS
from arcube.io.files import atomic_write_text
from arcube.evaluation.indices import JACOBIAN_NAMES
from arcube.model.mechanism import parse_mode
from arcube.report.figures import (
    JACOBIAN_COLORS,
    UNREACHABLE_COLOR,
    History,
    ParetoFront,
    convergence_png,
    dexterity_png,
    dexterity_series,
    pareto_png,
    read_history,
    read_pareto,
)
from arcube.model.body import PART_NAMES, MechanismPoints, mechanism_points
from arcube.report.mechanism3d import (
    SCENE_TRACES,
    add_body,
    animation_controls,
    body_frames,
    mechanism_extent,
    mechanism_traces as _mechanism_traces,
    note_annotations,
    scene_layout,
    xyz as _xyz,
)
from arcube.report.page import CSS as _CSS, esc as _esc, fmt as _fmt, plotly_div
from arcube.report.mechanism3d import envelope_trace
from arcube.report.tip import anatomy_trace, tip_figure

if TYPE_CHECKING:
    import plotly.graph_objects as go

    from arcube.evaluation.result import Evaluation

DIV_IDS = {
    "dexterity": "fig-dexterity",
    "convergence": "fig-convergence",
    "pareto": "fig-pareto",
    "tip": "fig-tip",
    "scene": "fig-scene",
}
TITLES = {
    "dexterity": "Local inverted dexterity along the drilling trajectories (paper Fig. 4)",
    "convergence": "Optimization convergence per generation",
    "scene": "AR-CUBE mechanism along the trajectories",
}
_N_STATIC = 2
"""Static traces of the 3D scene (the trajectories and their entry points), before the animated :data:`SCENE_TRACES`."""


def _frame_title(report: Evaluation, i: int, mp: MechanismPoints, series: Any) -> str:
    t = int(report.task.trajectory[i])
    lim = int(series.limiting[i])
    text = f"{TITLES['scene']}: trajectory {series.labels[t]}, k = {int(report.task.k[i])}, 100/η_L = {series.dexterity[i]:.1f} %"
    text += f" ({JACOBIAN_NAMES[lim]})" if lim >= 0 else ""
    pts = report.results.points
    if np.isfinite(pts.clearance_mm[i]):
        c, part = float(pts.clearance_mm[i]), PART_NAMES[int(pts.clearance_part[i])]
        text += (
            f" · clearance {c:.1f} mm ({part})" if c >= 0.0 else f" · COLLISION: {part} {-c:.1f} mm inside the anatomy"
        )
    if np.isfinite(pts.self_clearance_mm[i]) and pts.self_clearance_mm[i] < 0.0:
        text += f" · parts overlap by {-float(pts.self_clearance_mm[i]):.1f} mm"
    return text + ("" if mp.z_closes[i] else " · z dyad open (dashed)")


def _risk_traces(ts: Any, risk: dict[str, float]) -> list[Any]:
    """One line per screw coloured by its P(breach) (green 0 to red 1, grey where it has none), named with it, the
    worst first, and a colour bar."""
    import plotly.graph_objects as go
    from matplotlib import colormaps

    cmap = colormaps["RdYlGn_r"]
    order = sorted(range(len(ts.ids)), key=lambda j: -np.nan_to_num(risk.get(ts.ids[j], np.nan), nan=-1.0))
    out = []
    for rank, j in enumerate(order):
        p = risk.get(ts.ids[j], np.nan)
        known = p is not None and np.isfinite(p)
        rgba = cmap(float(p)) if known else (0.6, 0.6, 0.6, 1.0)
        colour = "rgb({:.0f},{:.0f},{:.0f})".format(*(255 * c for c in rgba[:3]))
        what = f"P(breach) {100 * p:.1f} %" if known else "not reached: no P(breach)"
        name = f"screw {ts.ids[j]} ({ts.levels[j]} {ts.sides[j]}): {what}" + (" (worst)" if rank == 0 and known else "")
        seg = np.stack([ts.entry[j], ts.target[j]])
        out.append(
            go.Scatter3d(
                name=name, mode="lines", line={"color": colour, "width": 6}, hovertext=[name] * 2, **_xyz([seg])
            )
        )
    out.append(
        go.Scatter3d(
            name="P(breach)",
            mode="markers",
            x=[None],
            y=[None],
            z=[None],
            showlegend=False,
            marker={
                "color": [0.0],
                "cmin": 0.0,
                "cmax": 1.0,
                "colorscale": "RdYlGn",
                "reversescale": True,
                "colorbar": {"title": "P(breach)", "tickformat": ".0%", "len": 0.5},
            },
        )
    )
    return out


def scene_figure(report: Evaluation, risk: dict[str, float] | None = None) -> go.Figure:
    """3D scene with one plotly frame per reachable task point, a slider and a play button. ``risk``: screw id ->
    P(breach) (model §22): each screw's line coloured by it, named with it, the worst first."""
    import plotly.graph_objects as go

    task, ts = report.task, report.trajectories
    series = dexterity_series(report)
    mp = mechanism_points(
        report.design.to_vector(), task.E, task.e, parse_mode(report.mode), c_z=report.options.guards.c_z
    )
    shown = np.flatnonzero(series.reachable & np.isfinite(mp.D).all(axis=(-2, -1)))
    fig = go.Figure()
    seg = [np.stack([a, b]) for a, b in zip(ts.entry, ts.target)]
    if risk is None:
        fig.add_trace(
            go.Scatter3d(
                name="trajectories", mode="lines", line={"color": "#17becf", "width": 4}, hoverinfo="skip", **_xyz(seg)
            )
        )
    else:
        for trace in _risk_traces(ts, risk):
            fig.add_trace(trace)
    labels = [f"entry {lab}" for lab in series.labels]
    fig.add_trace(
        go.Scatter3d(
            name="entry points",
            mode="markers",
            marker={"size": 3, "color": "#17becf"},
            hovertext=labels,
            hoverinfo="text",
            **_xyz([np.asarray(ts.entry)]),
        )
    )
    first = (
        _mechanism_traces(mp, int(shown[0])) if len(shown) else [_xyz([np.full((1, 3), np.nan)])] * len(SCENE_TRACES)
    )
    add_body(fig, first)
    poses = (
        (
            int(i),
            f"p{int(i)}",
            _frame_title(report, int(i), mp, series),
            f"{task.ids[int(task.trajectory[i])]}:{int(task.k[i])}",
        )
        for i in shown
    )
    fig.frames, steps = body_frames(mp, poses, _N_STATIC)
    anatomy = anatomy_trace(report)
    if anatomy is not None:  # after the animated traces: frames address those by index
        fig.add_trace(anatomy)
    envelope = envelope_trace(report.envelope)
    if envelope is not None:
        fig.add_trace(envelope)
    pts = [np.asarray(ts.entry), np.asarray(ts.target)]
    if len(shown):
        pts.append(mechanism_extent(mp, shown))
    n_skip = len(task) - len(shown)
    note = (f"{n_skip} of {len(task)} points are unreachable: they have no slider step." if n_skip else "") + (
        " No reachable point: only the trajectories are drawn." if not len(shown) else ""
    )
    title = _frame_title(report, int(shown[0]), mp, series) if len(shown) else TITLES["scene"]
    fig.update_layout(**scene_layout(title, np.concatenate(pts)), annotations=note_annotations(note, UNREACHABLE_COLOR))
    if steps:
        fig.update_layout(**animation_controls(steps, 150, "trajectory:k = "))
    return fig


def dexterity_figure(report: Evaluation) -> go.Figure:
    """Plotly version of Fig 4: 100/eta_L per point, coloured by the limiting Jacobian."""
    import plotly.graph_objects as go

    s = dexterity_series(report)
    task = report.task
    hover = [f"traj {s.labels[int(t)]}, k={int(k)}" for t, k in zip(task.trajectory, task.k)]
    fig = go.Figure()
    fig.add_trace(
        go.Scatter(
            x=s.index.tolist(),
            y=s.dexterity.tolist(),
            mode="lines",
            line={"color": "#bbbbbb", "width": 1},
            name="100/η_L",
            hoverinfo="skip",
        )
    )
    for j, name in enumerate(JACOBIAN_NAMES):
        sel = np.flatnonzero(s.limiting == j)
        if len(sel):
            fig.add_trace(
                go.Scatter(
                    x=sel.tolist(),
                    y=s.dexterity[sel].round(3).tolist(),
                    mode="markers",
                    name=f"limited by {name}",
                    marker={"color": JACOBIAN_COLORS[name], "size": 6},
                    text=[hover[i] for i in sel],
                    hovertemplate="%{text}<br>100/η_L = %{y:.2f} %<extra>" + name + "</extra>",
                )
            )
    bad = np.flatnonzero(~s.reachable)
    if len(bad):
        fig.add_trace(
            go.Scatter(
                x=bad.tolist(),
                y=[0.0] * len(bad),
                mode="markers",
                name="unreachable",
                marker={"color": UNREACHABLE_COLOR, "symbol": "x", "size": 7},
                text=[f"{hover[i]}: {s.failure[i]}" for i in bad],
                hovertemplate="%{text}<extra>unreachable</extra>",
            )
        )
    top = max(float(np.max(s.dexterity, initial=0.0)), 1.0) * 1.15
    fig.update_layout(
        title={"text": TITLES["dexterity"]},
        height=430,
        margin={"t": 60, "b": 50},
        xaxis={"title": "point index along the trajectories", "range": [-1, len(s.index)]},
        yaxis={"title": "local inverted dexterity 100/η_L (%)", "range": [-3, top]},
        shapes=[
            {
                "type": "line",
                "x0": b,
                "x1": b,
                "xref": "x",
                "yref": "paper",
                "y0": 0,
                "y1": 1,
                "line": {"color": "#666", "width": 1, "dash": "dash"},
            }
            for b in s.boundaries
        ],
        annotations=[
            {
                "x": c,
                "y": 1.0,
                "xref": "x",
                "yref": "paper",
                "text": lab,
                "showarrow": False,
                "yanchor": "top",
                "font": {"size": 10},
                "textangle": -90 if len(s.labels) > 12 else 0,
            }
            for c, lab in zip(s.centres, s.labels)
        ],
    )
    return fig


def convergence_figure(history: History, best_known: float | None = None) -> go.Figure:
    """best / mean eta_G (left axis) and feasible fraction in % (right axis) per generation; ``best_known``: a reference line."""
    from plotly.subplots import make_subplots

    g = history.generation.tolist()
    nan_to_none = lambda a: [None if not math.isfinite(v) else float(v) for v in a]  # noqa: E731
    fig = make_subplots(specs=[[{"secondary_y": True}]])
    fig.add_scatter(
        x=g, y=nan_to_none(history.best_eta_G), name="best η_G", mode="lines", line={"color": "#1f77b4", "width": 2}
    )
    fig.add_scatter(
        x=g,
        y=nan_to_none(history.mean_eta_G),
        name="mean η_G (feasible)",
        mode="lines",
        line={"color": "#1f77b4", "dash": "dash"},
    )
    fig.add_scatter(
        x=g,
        y=nan_to_none(100.0 * history.feasible_fraction),
        name="feasible %",
        mode="lines",
        line={"color": "#2ca02c"},
        secondary_y=True,
    )
    if best_known is not None and math.isfinite(best_known) and best_known > 0.0:
        fig.add_scatter(
            x=[g[0], g[-1]] if g else [],
            y=[best_known, best_known],
            name=f"best known {best_known:g}",
            mode="lines",
            line={"color": "#d62728", "dash": "dot", "width": 1},
        )
    fig.update_layout(title={"text": TITLES["convergence"]}, height=380, margin={"t": 60})
    fig.update_xaxes(title_text="generation")
    # eta_G falls from tens to about 1.3: a log axis shows the last percent, where runs differ
    fig.update_yaxes(title_text="η_G (log scale)", type="log", secondary_y=False)
    fig.update_yaxes(title_text="feasible designs (%)", range=[-2, 102], dtick=20, secondary_y=True)
    return fig


def design_table(report: Evaluation) -> str:
    """HTML table like the paper's Table 2 (rows m..beta, columns x, y, z; NA where none)."""
    vals = report.design.to_dict()
    rows = []
    for stem in ("m", "f", "p", "d", "c", "t", "r", "o", "alpha", "beta"):
        if stem == "r":
            cells = f'<td colspan="3" style="text-align:center">{vals["r"]:.4f}</td>'
        else:
            cells = "".join(
                f"<td>{vals[f'{stem}_{a}']:.4f}</td>" if f"{stem}_{a}" in vals else "<td>NA</td>" for a in "xyz"
            )
        unit = UNITS["r" if stem == "r" else f"{stem}_x"]
        sym = {"alpha": "α", "beta": "β"}.get(stem, stem)
        rows.append(f"<tr><th>{sym}</th>{cells}<td>{unit}</td></tr>")
    return "<table><tr><th></th><th>x</th><th>y</th><th>z</th><th>unit</th></tr>" + "".join(rows) + "</table>"


def summary_html(report: Evaluation) -> str:
    """Summary list, the per-trajectory table and the diagnosis lines."""
    s = report.summary
    dex = s["dexterity_pct"]
    guards = {k: v for k, v in report.options.guards.model_dump().items() if v not in (None, False)}
    items = [
        ("trajectories", f"{report.trajectories.source}: {len(report.task.ids)} × {report.task.n_points} points"),
        ("working mode", report.mode),
        ("guards", ", ".join(f"{k}={v}" for k, v in guards.items()) or "none (paper)"),
        ("w_G", int(s["w_G"])),
        ("reachable", f"{100 * s['reachable_fraction']:.1f} % of {s['n_points']} points"),
        ("η_G", _fmt(s["eta_G"])),
        ("100/η_G", _fmt(s["inverted_eta_G_pct"], 2) + " %"),
        (
            "inverted dexterity min / mean / max",
            f"{dex['min']:.2f} / {dex['mean']:.2f} / {dex['max']:.2f} % (0 at unreachable points)",
        ),
        ("failures", ", ".join(f"{k}: {n}" for k, n in s["failures"].items()) or "none"),
        ("engine", report.engine),
    ]
    out = "<table>" + "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in items) + "</table>"
    head = ("traj", "level", "side", "reachable", "dex min %", "dex mean %", "dex max %", "limiting", "first failure")
    out += "<h3>Per trajectory</h3><table><tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr>"
    for r in report.per_trajectory():
        cells = (
            r.id,
            r.level,
            r.side,
            f"{100 * r.reachable_fraction:.0f} %",
            f"{r.dexterity_min:.2f}",
            f"{r.dexterity_mean:.2f}",
            f"{r.dexterity_max:.2f}",
            r.limiting_jacobian or "—",
            r.first_failure or "—",
        )
        out += "<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in cells) + "</tr>"
    out += "</table>"
    segments = None if report.anatomy is None else report.anatomy.segments
    if segments:  # an anatomy read from a segmentation: which segments, how big, where (model §14.2)
        out += "<h3>Anatomy segments</h3><table><tr><th>segment</th><th>label</th><th>layer</th><th>voxels</th><th>bounds min (mm)</th><th>bounds max (mm)</th><th>file</th></tr>"
        for seg in segments:
            cells = (
                seg.name,
                seg.label,
                seg.layer,
                f"{seg.voxels:,}",
                ", ".join(f"{v:.1f}" for v in seg.lo),
                ", ".join(f"{v:.1f}" for v in seg.hi),
                Path(seg.file).name,
            )
            out += "<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in cells) + "</tr>"
        out += "</table>"
    diag = report.diagnosis()
    if diag:
        out += "<h3>Why points fail</h3><ul>" + "".join(f"<li>{_esc(line)}</li>" for line in diag) + "</ul>"
    return out


def _bbox_marker(front: ParetoFront, size: int) -> dict[str, Any]:
    """The front's markers, coloured by the bounding-box volume (L) on a Viridis scale with its colour bar."""
    return {
        "size": size,
        "color": front.bbox_volume_L.tolist(),
        "colorscale": "Viridis",
        "showscale": True,
        "colorbar": {"title": "bbox (L)"},
    }


def pareto_figure(front: ParetoFront) -> go.Figure:
    """eta_G against the sum of link lengths, colored by the bounding-box volume (an NSGA-II run's front);
    with the run's objectives: the front in each pair of them, the chosen design (best_design.json) marked."""
    import plotly.graph_objects as go

    if front.objectives:
        names = list(front.objectives)
        c = front.chosen
        if len(names) == 2:
            a, b = names
            fig = go.Figure(
                go.Scatter(
                    x=front.objectives[b].tolist(),
                    y=front.objectives[a].tolist(),
                    mode="markers",
                    name="front",
                    marker=_bbox_marker(front, 7),
                )
            )
            fig.add_trace(
                go.Scatter(
                    x=[float(front.objectives[b][c])],
                    y=[float(front.objectives[a][c])],
                    mode="markers",
                    name="best_design.json",
                    marker={"symbol": "star", "size": 16, "color": "#d62728"},
                )
            )
            fig.update_xaxes(title_text=b)
            fig.update_yaxes(title_text=a)
        else:
            dims = [{"label": n, "values": v.tolist()} for n, v in front.objectives.items()]
            colors = ["#d62728" if i == c else "#1f77b4" for i in range(len(front.eta_G))]
            fig = go.Figure(
                go.Splom(dimensions=dims, marker={"size": 5, "color": colors}, showupperhalf=False, name="front")
            )
        fig.update_layout(
            title={
                "text": "Pareto front of the run's objectives (star: best_design.json, the lowest " + names[0] + ")"
            },
            height=420 if len(names) == 2 else 700,
            margin={"t": 60},
        )
        return fig

    fig = go.Figure(
        go.Scatter(
            x=front.links_sum_mm.tolist(),
            y=front.eta_G.tolist(),
            mode="markers+lines",
            name="front",
            marker=_bbox_marker(front, 8),
            line={"color": "#bbb", "width": 1},
            hovertemplate="links %{x:.0f} mm<br>η_G %{y:.4f}<br>bbox %{marker.color:.1f} L<extra></extra>",
        )
    )
    fig.update_layout(
        title={"text": "Pareto front: dexterity (η_G, lower is better) against size"}, height=420, margin={"t": 60}
    )
    fig.update_xaxes(title_text="sum of link lengths (mm)")
    fig.update_yaxes(title_text="η_G")
    return fig


def write_evaluation_report(
    report: Evaluation,
    path: str | os.PathLike[str],
    history_csv: str | os.PathLike[str] | None = None,
    run_info: dict[str, Any] | None = None,
    pareto_csv: str | os.PathLike[str] | None = None,
    limits: dict[str, float] | None = None,
    best_known: float | None = None,
    program: str | os.PathLike[str] | None = None,
    preface: str | None = None,
    title: str | None = None,
    risk: dict[str, float] | None = None,
) -> Path:
    """Write the self-contained HTML report of ``report`` to ``path`` (and the PNGs beside it).

    ``history_csv``: a run's ``history.csv`` (adds the convergence plot and PNG).
    ``run_info``: key -> value rows shown at the top (e.g. a run's settings and summary).
    ``pareto_csv``: an NSGA-II run's ``pareto.csv`` (adds the front plot and PNG).
    ``limits``: requirement lines of the drill-tip plots, e.g. ``{"lateral_error": 0.2}``.
    ``best_known``: an eta_G drawn as a reference line on the convergence plots.
    ``program``: a program folder of this design (program.csv, program.json; ``arcube design``'s
    ``program/``): adds the program's section (:mod:`arcube.report.program_html`), read before any file is written.
    ``preface``: an HTML fragment put right under the title (a design job's verdict and requirements); ``title``: the
    page's title (default "AR-CUBE report: " and the plan's source; a docking's names its patient and side).
    ``risk``: screw id -> P(breach): the 3D scene colours each screw by it (a docking's report).
    Returns the HTML path. Every file is written atomically.
    """
    out = Path(path)
    prog = None
    if program is not None:
        from arcube.report.program_data import read_program

        prog = read_program(program)
    stem = out.with_suffix("")
    dexterity_png(report, f"{stem}_dexterity.png")
    figs: list[tuple[str, go.Figure]] = [("dexterity", dexterity_figure(report))]
    if history_csv is not None:
        history = read_history(history_csv)
        convergence_png(history, f"{stem}_convergence.png", best_known=best_known)
        figs.append(("convergence", convergence_figure(history, best_known)))
    if pareto_csv is not None:
        front = read_pareto(pareto_csv)
        pareto_png(front, f"{stem}_pareto.png")
        figs.append(("pareto", pareto_figure(front)))
    figs.append(("tip", tip_figure(report, limits)))
    figs.append(("scene", scene_figure(report, risk)))
    divs = {}
    for k, (key, fig) in enumerate(figs):
        # plotly.js goes inline once, with the first figure; the others reuse it.
        divs[key] = plotly_div(fig, DIV_IDS[key], include_js=k == 0)
    title = title or f"AR-CUBE report: {report.trajectories.source}"
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{_esc(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_esc(title)}</h1>",
    ]
    if preface:
        parts.append(preface)
    if run_info:
        parts.append(
            "<h2>Optimization run</h2><table>"
            + "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(_fmt(v))}</td></tr>" for k, v in run_info.items())
            + "</table>"
        )
    parts += [
        "<h2>Design (Table 2 layout)</h2>",
        design_table(report),
        "<h2>Summary</h2>",
        summary_html(report),
        "<h2>Dexterity</h2>",
        divs["dexterity"],
    ]
    if "convergence" in divs:
        parts += ["<h2>Convergence</h2>", divs["convergence"]]
    if "pareto" in divs:
        parts += ["<h2>Pareto front</h2>", divs["pareto"]]
    parts += [
        "<h2>At the drill tip</h2><p class='note'>Worst-case tip and axis errors for the encoder resolution, the largest "
        "actuator torque and the lateral deflection under the drilling loads (model §15), and the clearance of the robot's "
        "body to the anatomy (model §14) when an anatomy is given; unreachable points are gaps.</p>",
        divs["tip"],
    ]
    parts += [
        "<h2>Mechanism</h2><p class='note'>Patient frame R_w (x right, y superior, z posterior). Spherical links are drawn as "
        "great-circle arcs on the sphere of radius r around the drill tip E; a dashed z dyad means (d_z, c_z) cannot span "
        "D_z–Q_z at that point (model §6, not checked by the paper).</p>",
        divs["scene"],
    ]
    if prog is not None:
        from arcube.report.program_html import program_section

        parts.append(
            program_section(
                prog,
                report.design.to_vector(),
                None if report.anatomy is None else report.anatomy.meshes,
                report.options.guards.c_z,
                # as seen from the page: a folder written in a staging folder and moved keeps its place beside the page
                folder=os.path.relpath(Path(prog.folder).resolve(), Path(out).resolve().parent),
            )
        )
    parts += [
        f"<p class='note'>Figures also saved as {_esc(Path(f'{stem}_dexterity.png').name)}"
        + (f" and {_esc(Path(f'{stem}_convergence.png').name)}" if "convergence" in divs else "")
        + ".</p></body></html>",
    ]
    atomic_write_text(out, "\n".join(parts))
    return out
