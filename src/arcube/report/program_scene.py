"""The drilling program's 3D playback: the robot's body with the anatomy at a subsample of the
program's rows, as plotly animation frames with a slider and a play button.

The body at a row is the design's inverse kinematics of the row's pose (E, e) in the program's
working mode (program.json ``mode``), drawn by :mod:`arcube.report.mechanism3d` as the evaluation
report's scene draws it. program.json records neither the design nor the body's radii, so the
design comes from the caller (the report of the design, or ``arcube report --design``); the row's
joint angles are compared with that design's IK, and a design that does not reproduce them is named
in the figure's note.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.errors import InputError
from arcube.model.body import mechanism_points
from arcube.model.mechanism import inverse_kinematics, parse_mode
from arcube.report.mechanism3d import (
    add_body,
    animation_controls,
    body_frames,
    mechanism_extent,
    mechanism_traces,
    mesh_trace,
    note_annotations,
    scene_layout,
    xyz,
)
from arcube.report.program_data import JOINTS, ProgramFiles

if TYPE_CHECKING:
    pass

__all__ = ["ANGLE_TOL_DEG", "FRAMES", "Playback", "playback_figure", "playback_rows", "summary_anatomy"]

FRAMES = 150
"""About this many animation frames (rows) in a playback."""
ANGLE_TOL_DEG = 1e-3
"""A design reproduces a program when its IK gives every frame's joint angles within this, deg."""
PATH_POINTS = 3000
"""At most about this many points of the tip's path are drawn."""
N_STATIC = 2
"""Static traces before the animated :data:`SCENE_TRACES`: the tip's path and the drilled lines."""


def playback_rows(prog: ProgramFiles, n_frames: int = FRAMES) -> NDArray[np.intp]:
    """The rows shown as frames, increasing: the first and last row of every span (segment), and the
    others spread evenly over a progress that is half time, half joint motion (so a transit of a
    second gets as many frames as its motion deserves), ``n_frames`` or a few more in all (every row
    when there are fewer)."""
    n = len(prog.t_s)
    ends = [r for s in prog.spans() for r in (s.first, s.last)]
    if n <= n_frames:
        return np.arange(n)
    dq = np.linalg.norm(np.nan_to_num(np.diff(prog.q_deg, axis=0)), axis=1)
    dt = np.diff(prog.t_s)
    progress = np.r_[0.0, np.cumsum(dt / max(float(dt.sum()), 1e-12) + (dq / float(dq.sum()) if dq.sum() > 0 else 0.0))]
    rows = np.unique(ends)
    for m in range(max(n_frames - len(rows), 2), n + 1):  # more even rows until the union has n_frames
        even = np.searchsorted(progress, np.linspace(0.0, progress[-1], m))
        rows = np.unique(np.clip(np.r_[ends, even], 0, n - 1).astype(np.intp))
        if len(rows) >= n_frames:
            break
    return rows


class Playback(NamedTuple):
    """The playback figure, its frames' rows ``(F,)``, and a note ("" when the design reproduces the program)."""

    figure: Any
    rows: NDArray[np.intp]
    note: str


def _angle_gap(prog: ProgramFiles, rows: NDArray[np.intp], sol: Any) -> tuple[float, int]:
    """(largest |IK - CSV| joint angle over the frames that have an IK solution, deg; frames without one)."""
    ik = np.degrees(np.concatenate([np.asarray(sol.rho), np.asarray(sol.delta)], axis=-1))
    gap = np.abs((ik - prog.q_deg[rows] + 180.0) % 360.0 - 180.0)
    ok = np.isfinite(gap).all(axis=1)
    return (float(gap[ok].max()) if ok.any() else float("nan")), int((~ok).sum())


def _title(prog: ProgramFiles, k: int) -> str:
    q = ", ".join(f"{v:.1f}" for v in prog.q_deg[k])
    return f"t = {prog.t_s[k]:.2f} s · {prog.segment[k]} {prog.trajectory[k]} · q = ({q}) deg ({', '.join(JOINTS)})"


def playback_figure(
    prog: ProgramFiles, params: ArrayLike, anatomy_meshes: Any = None, c_z: float | None = None, n_frames: int = FRAMES
) -> Playback:
    """The 3D playback of ``prog`` for the design ``params`` ``(27,)`` (mm, deg): one plotly frame per
    row of :func:`playback_rows`, named ``r<row>``, with a slider (labelled by time) and play / pause
    buttons; the tip's path and the drilled lines (static); the anatomy (triangle meshes) if given.
    ``c_z``: the z dyad's second link (mm; None: c_z = d_z), as the evaluation's scene draws it."""
    import plotly.graph_objects as go

    mode_text = str(prog.summary.get("mode", DEFAULT_MODE_TEXT))
    try:
        mode = parse_mode(mode_text)
    except ValueError as exc:
        raise InputError(f"{prog.folder / 'program.json'}: mode: {exc}") from None
    rows = playback_rows(prog, n_frames)
    p = np.asarray(params, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(p, prog.E[rows], prog.e[rows], mode)
        mp = mechanism_points(p, prog.E[rows], prog.e[rows], mode, c_z=c_z, sol=sol)
    gap, unreached = _angle_gap(prog, rows, sol)
    note = ""
    if unreached or not gap <= ANGLE_TOL_DEG:
        note = (
            f"The design does not reproduce this program in mode {mode_text}: "
            + (f"{unreached} of {len(rows)} frames have no IK solution; " if unreached else "")
            + (f"joint angles differ by up to {gap:.3g} deg. " if np.isfinite(gap) else "")
            + "Is it the program's design?"
        )
    fig = go.Figure()
    step = max(1, int(np.ceil(len(prog.t_s) / PATH_POINTS)))
    path_rows = np.unique(np.r_[np.arange(0, len(prog.t_s), step), len(prog.t_s) - 1])
    drills = [prog.E[[s.first, s.last]] for s in prog.spans() if s.segment == "drill"]
    for name, color, width, lines in (
        ("tip path", "#17becf", 2, [prog.E[path_rows]]),
        ("drilled", "#8c1c13", 6, drills or [np.full((1, 3), np.nan)]),
    ):
        fig.add_trace(
            go.Scatter3d(name=name, mode="lines", line={"color": color, "width": width}, hoverinfo="skip", **xyz(lines))
        )
    add_body(fig, mechanism_traces(mp, 0))
    poses = ((i, f"r{int(k)}", _title(prog, int(k)), f"{prog.t_s[k]:.2f}") for i, k in enumerate(rows))
    fig.frames, steps = body_frames(mp, poses, N_STATIC)
    if anatomy_meshes:
        fig.add_trace(mesh_trace(anatomy_meshes))  # after the animated traces: frames address those by index
    allp = np.concatenate([prog.E, mechanism_extent(mp, np.arange(len(rows)))])
    fig.update_layout(
        **scene_layout(_title(prog, int(rows[0])), allp),
        **animation_controls(steps, 120, "t (s) = "),
        annotations=note_annotations(note, "#d62728"),
    )
    return Playback(fig, rows, note)


def summary_anatomy(summary: dict[str, Any]) -> tuple[Any, str]:
    """The anatomy program.json's ``anatomy`` names (its ``Anatomy.source``), loaded again: (an
    :class:`~arcube.evaluation.anatomy.Anatomy` or None, a note saying why there is none, or "")."""
    from arcube.evaluation.anatomy import Anatomy, load_anatomy
    from arcube.io.meshes import read_meshes

    source = summary.get("anatomy")
    if not source:
        return None, ""
    text = str(source)
    try:
        if text == "default (reference patient)":
            return load_anatomy(["default"], "LPS", "reference"), ""
        found = re.fullmatch(r"default \((.+)\)", text)
        if found:
            return Anatomy.from_meshes(read_meshes([found.group(1)], "patient"), text), ""
        found = re.fullmatch(r"(.+) \((LPS|RAS|patient)\)", text)
        if found:
            return load_anatomy(found.group(1).split(", "), found.group(2)), ""
    except (InputError, OSError, ValueError) as exc:
        return None, f"the program's anatomy ({text}) is not drawn: {exc}; give it with --anatomy"
    return None, f"the program's anatomy ({text}) is not drawn: give it with --anatomy"
