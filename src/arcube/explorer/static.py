"""``arcube explore --html FILE``: the explorer's scene as one standalone HTML file (no server).

The same solids, colours, closest pairs and figures as the live app, at one point of the lines, drawn
with plotly; plotly.js is embedded (``include_plotlyjs=True``), so the file opens with no network.
Below the scene: the figures table and the per-point plot along the lines.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube import interrupts
from arcube.explorer import text
from arcube.explorer.live import Figures, LiveModel, View
from arcube.explorer.scene import CLASSES, COLOURS, cylinder_frames
from arcube.io.files import atomic_write_text

__all__ = ["DIV_SCENE", "DIV_POINTS", "scene_figure", "write_static"]

DIV_SCENE, DIV_POINTS = "explore-scene", "explore-points"


def _rotation(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices ``(N, 3, 3)`` of unit quaternions wxyz ``(N, 4)``."""
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def _instances(
    base: Any, pos: NDArray[np.float64], rot: NDArray[np.float64], scale: NDArray[np.float64], rgb: NDArray[np.uint8]
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.uint8]]:
    """One mesh of every instance of ``base`` (vertices, faces, a colour per face)."""
    v = np.asarray(base.vertices, float)
    f = np.asarray(base.faces, np.int64)
    V = np.einsum("nij,nvj->nvi", rot, v[None] * scale[:, None, :]) + pos[:, None, :]
    F = f[None] + (np.arange(len(pos)) * len(v))[:, None, None]
    return V.reshape(-1, 3), F.reshape(-1, 3), np.repeat(rgb, len(f), axis=0)


def _body_mesh(view: View) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.uint8]]:
    import trimesh

    interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost

    s = view.solids
    pos, quat, length = cylinder_frames(s.cylinders)
    cyl = _instances(
        trimesh.creation.cylinder(radius=1.0, height=1.0, sections=16),
        pos,
        _rotation(quat),
        np.stack([s.cylinder_radius, s.cylinder_radius, length], 1),
        view.part_rgb[s.cylinder_part],
    )
    n = len(s.spheres)
    ball = _instances(
        trimesh.creation.icosphere(subdivisions=1, radius=1.0),
        s.spheres,
        np.tile(np.eye(3), (n, 1, 1)),
        np.repeat(s.sphere_radius[:, None], 3, 1),
        view.part_rgb[s.sphere_part],
    )
    return (
        np.concatenate([cyl[0], ball[0]]),
        np.concatenate([cyl[1], ball[1] + len(cyl[0])]),
        np.concatenate([cyl[2], ball[2]]),
    )


def _lines(segments: NDArray[np.float64]) -> dict[str, list[float | None]]:
    out: dict[str, list[float | None]] = {"x": [], "y": [], "z": []}
    for a, b in segments:
        for j, key in enumerate("xyz"):
            out[key] += [float(a[j]), float(b[j]), None]
    return out


def _mesh(V: NDArray[np.float64], F: NDArray[np.int64], **style: Any) -> Any:
    """A plotly ``Mesh3d`` of vertices ``V`` ``(n, 3)`` (mm) and triangles ``F`` ``(m, 3)``, styled by ``style``."""
    import plotly.graph_objects as go

    return go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2], **style)


def _line_trace(name: str, color: str, width: float, segments: NDArray[np.float64]) -> Any:
    """A plotly ``Scatter3d`` of the line segments ``(n, 2, 3)`` (mm), hovered by its name."""
    import plotly.graph_objects as go

    return go.Scatter3d(
        mode="lines", name=name, line={"color": color, "width": width}, hoverinfo="name", **_lines(segments)
    )


def scene_figure(model: LiveModel, view: View) -> Any:
    """The plotly 3D scene of ``view``: body solids coloured by clearance, anatomy, plan, closest pairs."""
    import plotly.graph_objects as go

    fig = go.Figure()
    if model.anatomy is not None:
        V, F = model.anatomy.vertices_faces()
        fig.add_trace(_mesh(V, F, color="#e8d6aa", opacity=0.45, name="anatomy", hoverinfo="name", showlegend=True))
    if model.envelope is not None:
        from arcube.report.mechanism3d import envelope_trace

        fig.add_trace(envelope_trace(model.envelope))
    plan = model.plan
    standoff = model.E_app.reshape(len(plan.ids), model.points, 3)[:, 0]
    fig.add_trace(_line_trace("drill lines", "#00aac8", 5, np.stack([plan.entry, plan.target], 1)))
    fig.add_trace(_line_trace("approach lines", "#96c8d7", 3, np.stack([standoff, plan.entry], 1)))
    if np.all(np.isfinite(view.solids.cylinders)):
        V, F, rgb = _body_mesh(view)
        fig.add_trace(
            _mesh(
                V,
                F,
                name="robot (colour: clearance)",
                facecolor=[f"rgb({r},{g},{b})" for r, g, b in rgb],
                flatshading=False,
                hoverinfo="name",
                showlegend=True,
            )
        )
        fig.add_trace(_line_trace("tool E–H", "#3c3c46", 6, np.stack([view.E, view.mp.H])[None]))
        for pair, colour, name in (
            (view.patient, "#dc143c", "closest to the anatomy"),
            (view.self_, "#a028c8", "closest parts"),
        ):
            if np.isfinite(pair.clearance):
                fig.add_trace(
                    go.Scatter3d(
                        mode="lines+markers",
                        name=f"{name}: {pair.clearance:.1f} mm ({pair.part}–{pair.other_part})",
                        line={"color": colour, "width": 6},
                        marker={"size": 4, "color": colour},
                        **_lines(np.stack([pair.robot, pair.other])[None]),
                    )
                )
    fig.add_trace(
        go.Scatter3d(
            mode="markers",
            name="drill tip E",
            x=[view.E[0]],
            y=[view.E[1]],
            z=[view.E[2]],
            marker={"size": 4, "color": "black", "symbol": "diamond"},
        )
    )
    fig.update_layout(
        title={"text": view.label, "font": {"size": 13}},
        height=760,
        margin={"l": 0, "r": 0, "t": 40, "b": 0},
        legend={"x": 0.0, "y": 0.98},
        scene={
            "aspectmode": "data",
            "xaxis": {"title": "x (mm)"},
            "yaxis": {"title": "y (mm)"},
            "zaxis": {"title": "z (mm)"},
            "camera": {"up": {"x": 0, "y": 0, "z": 1}, "eye": {"x": 1.3, "y": -1.6, "z": 1.0}},
        },
    )
    return fig


def points_figure(model: LiveModel, fig: Figures, index: int) -> Any:
    """Dexterity and both clearances along the lines (gaps where there is no value), the point shown marked."""
    from plotly.subplots import make_subplots

    x = np.arange(len(model)).tolist()
    none = lambda a: [None if not np.isfinite(v) else float(v) for v in a]  # noqa: E731
    out = make_subplots(specs=[[{"secondary_y": True}]])
    out.add_scatter(x=x, y=none(fig.points["dexterity_pct"]), name="100/η_L (%)", line={"color": "#1f77b4"})
    out.add_scatter(
        x=x, y=none(fig.points["clearance_mm"]), name="clearance (mm)", line={"color": "#d62728"}, secondary_y=True
    )
    out.add_scatter(
        x=x,
        y=none(fig.points["self_clearance_mm"]),
        name="self clearance (mm)",
        line={"color": "#9467bd"},
        secondary_y=True,
    )
    out.add_vline(x=index, line={"color": "#444", "dash": "dot"})
    out.update_layout(
        title={"text": "Along the lines (per trajectory: approach, then drill)"}, height=360, margin={"t": 50}
    )
    out.update_xaxes(title_text="point")
    out.update_yaxes(title_text="100/η_L (%)", secondary_y=False)
    out.update_yaxes(title_text="mm", secondary_y=True)
    return out


_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;padding:2px 8px;text-align:left}
th{background:#f3f3f3}.key span{display:inline-block;padding:0 .6em;margin-right:.4em;border-radius:3px}"""


def write_static(model: LiveModel, path: str | os.PathLike[str], index: int | None = None, title: str = "") -> Path:
    """Write the standalone scene of ``model`` at point ``index`` of the lines (default: the first
    drill point) with its figures to ``path``, atomically; returns the path."""
    import plotly.io as pio

    out = Path(path)
    i = model.points if index is None else int(index)
    fig = model.evaluate()
    view = model.view(i)
    scene_div, points_div = (
        pio.to_html(
            figure,
            full_html=False,
            include_plotlyjs=first,  # plotly.js once, in the first div
            div_id=div_id,
            config={"displaylogo": False, "responsive": True},
        )
        for figure, first, div_id in (
            (scene_figure(model, view), True, DIV_SCENE),
            (points_figure(model, fig, view.index), False, DIV_POINTS),
        )
    )
    key = "".join(f"<span style='background:rgb{COLOURS[c]}'>{c}</span>" for c in CLASSES)
    esc = html.escape
    page = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>AR-CUBE explorer: {esc(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>AR-CUBE explorer</h1><p>{esc(title)}</p>",
        text.html_table(fig),
        f"<p>{esc(text.point_line(view, fig))}</p>",
        f"<p class='key'>Part colours (clearance against the requirement): {key}</p>",
        scene_div,
        points_div,
        "</body></html>",
    ]
    atomic_write_text(out, "\n".join(page))
    return out
