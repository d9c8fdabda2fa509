"""The report of one robot at several dockings (``arcube design``'s ``report.html``, model §19.4).

One self-contained page: the verdict, the robot's 22 parameters and working mode, each requirement at the
docking where it is tightest, a table of the dockings (patient, side, placement, the figures that bind), and
every docking's mechanism side by side with its patient's plan and anatomy (the scene of
:func:`arcube.report.html.scene_figure` at the plan's first reachable point; each docking's own report,
with the animation and its program, is linked). The dockings are duck-typed: ``label``, ``name``, ``side``,
``met``, ``rows``, ``design`` (:class:`arcube.design_job.dockings.Docking`), so this layer imports no job.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from arcube.io.files import atomic_write_text
from arcube.metrics import METRICS
from arcube.report.page import CSS, esc, fmt, plotly_div

__all__ = ["write_dockings_report"]

_FIGURES = (*(m.name for m in METRICS if m.requirement and m.default_limit is not None), "program")
"""The columns of the dockings table: the default requirements (:mod:`arcube.metrics`), then the program."""


def _value(rows: Sequence[dict[str, Any]], name: str) -> str:
    r = next((r for r in rows if r["requirement"] == name), None)
    if r is None:
        return "—"
    v = r["value"]
    text = (
        "yes"
        if name == "program" and r["passed"]
        else ("no" if name == "program" else (f"{v:.3g}" if math.isfinite(v) else "—"))
    )
    return f"<span class='fail'>{esc(text)}</span>" if not r["passed"] else esc(text)


def _accuracy(dockings: Sequence[Any], accuracies: Sequence[dict[str, Any]]) -> str:
    """Per docking, what the robot drills as built (model §20) and how likely its worst screw breaches (22)."""
    if not accuracies:
        return ""
    rows = [
        "<h2>What the robot drills as built</h2><p class='note'>The lateral error requirement speaks of a perfect robot; as built "
        "to its tolerance class the same robot drills farther from the plan (the Monte Carlo of built robots, p95), and each screw "
        "may leave its pedicle (the breach probability of the docking's worst screw). Each docking's report has the details.</p>"
        "<table><tr><th>docking</th><th>lateral error, perfect robot (mm)</th><th>as built, p95 (mm)</th><th>class</th>"
        "<th>worst case, first order (mm)</th><th>largest P(breach)</th></tr>"
    ]
    for d, a in zip(dockings, accuracies):
        p = (getattr(d, "breach", {}) or {}).get("breach_probability")
        rows.append(
            f"<tr><td>{esc(d.label)}</td><td>{esc(fmt(a.get('perfect_robot_lateral_error_mm'), 3))}</td>"
            f"<td>{esc(fmt(a.get('lateral_error_p95_mm'), 3))}</td><td>{esc(a.get('tolerance_class', ''))}</td>"
            f"<td>{esc(fmt(a.get('lateral_error_wc_mm'), 3))}</td><td>{'—' if p is None else f'{100 * p:.0f} %'}</td></tr>"
        )
    return "".join(rows) + "</table>"


def write_dockings_report(
    path: str | os.PathLike[str],
    dockings: Sequence[Any],
    evaluations: Sequence[Any],
    rows: Sequence[dict[str, Any]],
    met: bool,
    extra: str = "",
    accuracies: Sequence[dict[str, Any]] = (),
) -> Path:
    """Write the page (module docstring) to ``path``; ``evaluations``: each docking's
    :class:`~arcube.evaluation.result.Evaluation` (its scene), ``rows``: the requirements at their tightest docking;
    ``extra``: an HTML fragment after the verdict (the coverage, :func:`arcube.report.coverage.coverage_section`)."""
    from arcube.report.html import scene_figure

    out = Path(path)
    first = dockings[0].design
    values = {**first.to_dict(), "c_z": first.c_z_mm}
    robot = [n for n in values if n not in ("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz")]
    verdict = "meets every requirement at every docking" if met else "does NOT meet every requirement"
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>AR-CUBE: one robot, {len(dockings)} dockings</title>"
        f"<style>{CSS}.grid{{display:grid;grid-template-columns:minmax(0,1fr);gap:1em}}.grid>div{{min-width:0}}"
        "td,th{white-space:normal}</style></head><body>",
        f"<h1>One robot, {len(dockings)} docking{'s' if len(dockings) > 1 else ''}</h1>",
        f"<p>The robot {esc(verdict)}; working mode {esc(first.mode or '+,+,+,+')}.</p>",
        extra,
        "<h2>The robot (model §19.1)</h2><table><tr>",
    ]
    # the robot's 22 values in rows of 8 name / value pairs: one row of 22 columns ran off a 1400 px screen (L and c_z hidden)
    for i in range(0, len(robot), 8):
        names = robot[i : i + 8]
        parts.append(
            ("</tr><tr>" if i else "")
            + "".join(f"<th>{esc(n)}</th>" for n in names)
            + "</tr><tr>"
            + "".join(f"<td>{values[n]:.2f}</td>" for n in names)
        )
    parts.append("</tr></table>")
    parts.append(
        "<h2>Requirements, where each is tightest (model §19.4)</h2><table><tr><th>requirement</th><th>limit</th><th>value</th>"
        "<th>margin</th><th>docking</th><th>where</th></tr>"
    )
    for r in rows:
        w = r.get("where") or {}
        where = f"trajectory {w['trajectory']} ({w['segment']}, point {w['point']})" if w else ""
        sign = ">=" if r["kind"] == "min" else "<="
        cls = "" if r["passed"] else " class='fail'"
        parts.append(
            f"<tr{cls}><td>{esc(r['requirement'])}</td><td>{sign} {r['limit']:.4g}</td><td>{esc(fmt(r['value'], 3))}</td>"
            f"<td>{esc(fmt(r['margin'], 3))}</td><td>{esc(r.get('docking', ''))}</td><td>{esc(where + (' ' + r['part'] if r.get('part') else ''))}</td></tr>"
        )
    parts.append(
        "</table><h2>Dockings</h2><table><tr><th>docking (its report)</th><th>met</th><th>m (mm)</th>"
        "<th>mount (deg)</th><th>η_G</th>" + "".join(f"<th>{esc(n.replace('_', ' '))}</th>" for n in _FIGURES) + "</tr>"
    )
    for d, ev in zip(dockings, evaluations):
        v = d.design.to_dict()
        eta = ev.summary.get("eta_G")
        parts.append(
            f"<tr><td><a href='dockings/{esc(d.label)}/report.html'>{esc(d.name)}, side {esc(d.side)}</a></td>"
            f"<td>{'yes' if d.met else '<span class=fail>no</span>'}</td>"
            f"<td>{v['m_x']:.1f}, {v['m_y']:.1f}, {v['m_z']:.1f}</td><td>{v['mount_rx']:.1f}, {v['mount_ry']:.1f}, {v['mount_rz']:.1f}</td>"
            f"<td>{esc(fmt(eta))}</td>" + "".join(f"<td>{_value(d.rows, n)}</td>" for n in _FIGURES) + "</tr>"
        )
    parts.append("</table>" + _accuracy(dockings, accuracies))
    parts.append(
        "<h2>Every docking, side by side</h2><p class='note'>Each docking's mechanism at the first reachable point of "
        "its plan, with its patient's anatomy and envelope (patient frame R_w: x right, y superior, z posterior). Its own "
        "report animates it along every point and plays its drilling program.</p><div class='grid'>"
    )
    for k, (d, ev) in enumerate(zip(dockings, evaluations)):
        fig = scene_figure(ev)
        fig.frames = ()
        fig.update_layout(
            sliders=[],
            updatemenus=[],
            height=560,
            autosize=True,
            width=None,
            title={"text": f"{d.name}, side {d.side}", "font": {"size": 14}},
        )
        parts.append(f"<div><h3>{esc(d.label)}</h3>{plotly_div(fig, f'fig-docking-{k}', include_js=k == 0)}</div>")
    parts.append("</div></body></html>")
    atomic_write_text(out, "\n".join(parts))
    return out
