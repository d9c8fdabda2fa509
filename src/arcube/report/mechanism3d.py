"""The robot's body and the anatomy as plotly 3D traces, shared by the evaluation report's scene
(:func:`arcube.report.html.scene_figure`) and the program's playback
(:func:`arcube.report.program_scene.playback_figure`).

The body is drawn from :func:`arcube.model.body.mechanism_points` as lines (frame, cranks, four-bars,
z dyad, platform, spherical links as great-circle arcs, drill): :data:`SCENE_TRACES` in order, each
with its :data:`STYLE`; :func:`mechanism_traces` gives their coordinates at one pose.

Both figures animate the body the same way: :func:`add_body` draws it at the first pose,
:func:`body_frames` gives a plotly frame and a slider step per pose, :func:`scene_layout` the fixed
axes, camera and title, :func:`animation_controls` the slider and the play / pause buttons, and
:func:`note_annotations` the figure's note.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.model.body import MechanismPoints

__all__ = [
    "SCENE_TRACES",
    "STYLE",
    "add_body",
    "animation_controls",
    "body_frames",
    "mechanism_traces",
    "mesh_trace",
    "note_annotations",
    "scene_layout",
    "xyz",
]

SCENE_TRACES = (
    "frame",
    "cranks",
    "four-bar x",
    "four-bar y",
    "z dyad",
    "z dyad (open)",
    "platform",
    "spherical x",
    "spherical y",
    "drill",
    "drill tip",
)
"""The body's traces, in the order :func:`mechanism_traces` returns them."""

STYLE: dict[str, dict[str, Any]] = {
    "frame": {"mode": "lines+markers", "line": {"color": "black", "width": 8}, "marker": {"size": 4, "color": "black"}},
    "cranks": {
        "mode": "lines+markers",
        "line": {"color": "#1f77b4", "width": 7},
        "marker": {"size": 4, "color": "#1f77b4"},
    },
    "four-bar x": {"mode": "lines+markers", "line": {"color": "#ff7f0e", "width": 5}, "marker": {"size": 3}},
    "four-bar y": {"mode": "lines+markers", "line": {"color": "#2ca02c", "width": 5}, "marker": {"size": 3}},
    "z dyad": {"mode": "lines+markers", "line": {"color": "#9467bd", "width": 5}, "marker": {"size": 3}},
    "z dyad (open)": {"mode": "lines", "line": {"color": "#9467bd", "width": 3, "dash": "dash"}},
    "platform": {"mode": "lines", "line": {"color": "#7f7f7f", "width": 3}},
    "spherical x": {"mode": "lines", "line": {"color": "#b35806", "width": 6}},
    "spherical y": {"mode": "lines", "line": {"color": "#1b7837", "width": 6}},
    "drill": {
        "mode": "lines+markers",
        "line": {"color": "#d62728", "width": 9},
        "marker": {"size": 4, "color": "#d62728"},
    },
    "drill tip": {"mode": "markers", "marker": {"size": 5, "color": "black", "symbol": "diamond"}},
}
"""Plotly line/marker style of each of :data:`SCENE_TRACES`."""


def xyz(polylines: Sequence[NDArray[np.float64]]) -> dict[str, list[float | None]]:
    """x, y, z lists of polylines ``(n_i, 3)`` separated by None (plotly gaps); NaN -> None."""
    out: dict[str, list[float | None]] = {"x": [], "y": [], "z": []}
    for k, line in enumerate(polylines):
        if k:
            for c in out.values():
                c.append(None)
        for j, c in enumerate(out.values()):
            # Full precision (no rounding): the tests check closure on the drawn data to 1e-9 mm.
            c.extend(None if not math.isfinite(v) else float(v) for v in line[:, j])
    return out


def mechanism_traces(mp: MechanismPoints, i: int) -> list[dict[str, Any]]:
    """The data (coordinates only) of the :data:`SCENE_TRACES` at point ``i`` of 1-D ``mp``."""
    O, P, D, Q, K, T = mp.O[i], mp.P[i], mp.D[i], mp.Q[i], mp.K[i], mp.T[i]
    closes = bool(mp.z_closes[i])
    arcs = [np.concatenate([mp.arc_alpha[i, u], mp.arc_beta[i, u, 1:]]) for u in range(2)]
    empty = [np.full((1, 3), np.nan)]
    return [
        xyz([np.stack([O, P[u]]) for u in range(3)]),
        xyz([np.stack([P[u], D[u]]) for u in range(3)]),
        *(xyz([np.stack([D[u], K[u], T[u], Q[u]])]) for u in range(2)),
        xyz([np.stack([D[2], mp.J_z[i], Q[2]])] if closes else empty),
        xyz(empty if closes else [np.stack([D[2], Q[2]])]),
        xyz([np.stack([mp.C[i], Q[u]]) for u in range(3)]),
        *(xyz([arcs[u], np.stack([mp.C[i], mp.B[i, u]])]) for u in range(2)),
        xyz([np.stack([mp.E[i], mp.drill_end[i]]), np.stack([mp.H[i], mp.H[i]])]),
        xyz([mp.E[i][None]]),
    ]


def mechanism_extent(mp: MechanismPoints, rows: NDArray[np.intp]) -> NDArray[np.float64]:
    """Every drawn joint position of ``mp`` at ``rows``, ``(n, 3)`` (NaN where there is none): for fixed axis ranges."""
    parts = (mp.P, mp.D, mp.Q, mp.K, mp.T, mp.arc_alpha, mp.arc_beta, mp.drill_end, mp.O, mp.J_z)
    return np.concatenate([a[rows].reshape(-1, 3) for a in parts])


def add_body(fig: Any, traces: Sequence[dict[str, Any]]) -> None:
    """Add the :data:`SCENE_TRACES` to ``fig``, each with its :data:`STYLE` and coordinates ``traces`` (as
    :func:`mechanism_traces` gives them): the traces the frames of :func:`body_frames` move."""
    import plotly.graph_objects as go

    for name, data in zip(SCENE_TRACES, traces):
        fig.add_trace(go.Scatter3d(name=name, hoverinfo="name", **STYLE[name], **data))


def body_frames(
    mp: MechanismPoints, poses: Iterable[tuple[int, str, str, str]], first: int
) -> tuple[list[Any], list[dict[str, Any]]]:
    """(plotly frames, slider steps), one of each per pose ``(i, name, title, label)``: the frame ``name`` draws
    the body at point ``i`` of 1-D ``mp`` into the figure's traces ``first`` on (those of :func:`add_body`) and
    shows ``title``; its step, labelled ``label``, jumps to it."""
    import plotly.graph_objects as go

    dyn = list(range(first, first + len(SCENE_TRACES)))
    frames, steps = [], []
    for i, name, title, label in poses:
        frames.append(
            go.Frame(
                name=name,
                traces=dyn,
                data=[go.Scatter3d(**d) for d in mechanism_traces(mp, i)],
                layout={"title": {"text": title}},
            )
        )
        steps.append(
            {
                "label": label,
                "method": "animate",
                "args": [
                    [name],
                    {"mode": "immediate", "frame": {"duration": 0, "redraw": True}, "transition": {"duration": 0}},
                ],
            }
        )
    return frames, steps


def scene_layout(title: str, points: NDArray[np.float64]) -> dict[str, Any]:
    """Layout of an animated 3D scene titled ``title``: axis ranges (mm) fixed to everything ever drawn,
    ``points`` ``(n, 3)`` (NaN ignored), so that the view does not jump between frames."""
    lo, hi = np.nanmin(points, axis=0), np.nanmax(points, axis=0)
    pad = 0.05 * float(np.max(hi - lo)) + 1.0
    axes = {
        f"{a}axis": {"range": [float(lo[j] - pad), float(hi[j] + pad)], "title": f"{a} (mm)"}
        for j, a in enumerate("xyz")
    }
    return {
        "title": {"text": title, "font": {"size": 13}},
        "scene": {
            "aspectmode": "data",
            **axes,
            "camera": {"up": {"x": 0, "y": 0, "z": 1}, "eye": {"x": 1.4, "y": -1.6, "z": 0.9}},
        },
        "height": 760,
        "margin": {"l": 0, "r": 0, "t": 50, "b": 0},
        "legend": {"x": 0.0, "y": 0.95},
    }


def animation_controls(steps: list[dict[str, Any]], frame_ms: int, prefix: str) -> dict[str, Any]:
    """Layout of the play / pause buttons (``frame_ms`` per frame when playing) and the slider of ``steps``,
    whose current value is shown after ``prefix``."""
    play = {
        "label": "▶ play",
        "method": "animate",
        "args": [
            None,
            {"frame": {"duration": frame_ms, "redraw": True}, "fromcurrent": True, "transition": {"duration": 0}},
        ],
    }
    pause = {
        "label": "❚❚ pause",
        "method": "animate",
        "args": [[None], {"frame": {"duration": 0, "redraw": False}, "mode": "immediate"}],
    }
    return {
        "updatemenus": [
            {"type": "buttons", "buttons": [play, pause], "x": 0.0, "y": 0.06, "xanchor": "left", "direction": "left"}
        ],
        "sliders": [
            {
                "active": 0,
                "steps": steps,
                "x": 0.15,
                "len": 0.83,
                "y": 0.06,
                "font": {"color": "rgba(0,0,0,0)", "size": 6},
                "currentvalue": {"prefix": prefix, "font": {"size": 12, "color": "#333"}},
                "ticklen": 2,
            }
        ],
    }


def note_annotations(note: str, color: str) -> list[dict[str, Any]]:
    """The figure's ``note`` in ``color`` at its top right corner; none when ``note`` is empty."""
    if not note:
        return []
    return [
        {
            "text": note,
            "showarrow": False,
            "xref": "paper",
            "yref": "paper",
            "x": 1.0,
            "y": 1.0,
            "xanchor": "right",
            "yanchor": "top",
            "font": {"color": color},
        }
    ]


ENVELOPE_COLOR = "#8fa8c8"
"""The envelope of the whole patient and the table (model §19.5), drawn faint and blue-grey behind the anatomy."""


def envelope_trace(envelope: Any) -> Any:
    """A faint plotly ``Mesh3d`` of the envelope's regions (rounded boxes, skin, table), one trace; None without one."""
    if envelope is None:
        return None
    from arcube.evaluation.envelope_drawing import envelope_meshes

    return mesh_trace(
        [m for _, m in envelope_meshes(envelope)],
        name="envelope (" + ", ".join(envelope.names) + ")",
        color=ENVELOPE_COLOR,
        opacity=0.12,
    )


def mesh_trace(meshes: Sequence[Any], name: str = "anatomy", color: str = "#e8d8b0", opacity: float = 0.35) -> Any:
    """A translucent plotly ``Mesh3d`` of triangle meshes (objects with ``vertices`` ``(V, 3)`` mm and
    ``faces`` ``(F, 3)``, e.g. an :class:`~arcube.evaluation.anatomy.Anatomy`'s), as one trace."""
    import plotly.graph_objects as go

    verts, faces, offset = [], [], 0
    for m in meshes:
        verts.append(np.asarray(m.vertices, float))
        faces.append(np.asarray(m.faces, np.int64) + offset)
        offset += len(m.vertices)
    V, F = np.concatenate(verts), np.concatenate(faces)
    return go.Mesh3d(
        x=V[:, 0].tolist(),
        y=V[:, 1].tolist(),
        z=V[:, 2].tolist(),
        i=F[:, 0].tolist(),
        j=F[:, 1].tolist(),
        k=F[:, 2].tolist(),
        color=color,
        opacity=opacity,
        name=name,
        hoverinfo="name",
        showlegend=True,
    )
