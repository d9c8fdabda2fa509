"""The report of a robot's coverage (``arcube dock``'s ``report.html``, and a design job's with held-out patients;
model §19.6): which patient sides the built robot serves, what binds on the others, with a picture of it.

One self-contained page: the verdict and the coverage with its 95 % Wilson interval (training and held-out side by side
when both are given), a map of the sides (a cell per patient and side: served in green, not in red, labelled with the
requirement that binds and its margin) drawn as an inline SVG, and the table of the sides, each linking to its
docking's own report. This layer reads the summary dictionaries only.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from arcube.io.files import atomic_write_text
from arcube.report.page import CSS, esc, fmt

__all__ = ["coverage_map_svg", "coverage_section", "coverage_table", "write_coverage_report"]

_SIDES = ("R", "L", "both")


def _pct(v: Any) -> str:
    return f"{100.0 * v:.0f} %" if isinstance(v, (int, float)) and math.isfinite(v) else "—"


def _bind(d: Mapping[str, Any]) -> str:
    if not d.get("binding"):
        return ""
    m = d.get("binding_margin")
    margin = (
        f" {m:+.3g} {d.get('binding_unit') or ''}".rstrip() if isinstance(m, (int, float)) and math.isfinite(m) else ""
    )
    return f"{d['binding']}{margin}"


def coverage_map_svg(dockings: Sequence[Mapping[str, Any]], title: str = "") -> str:
    """An SVG grid: a row per patient, a column per side, each cell green (met) or red (not met) with the requirement
    that binds there and its margin."""
    patients = list(dict.fromkeys(d["patient"] for d in dockings))
    sides = [s for s in _SIDES if any(d["side"] == s for d in dockings)]
    by = {(d["patient"], d["side"]): d for d in dockings}
    name_w, cell_w, cell_h, top = 150, 230, 26, 44
    width, height = name_w + cell_w * len(sides) + 10, top + cell_h * len(patients) + 10
    out = [
        f"<svg xmlns='http://www.w3.org/2000/svg' width='{width}' height='{height}' role='img' aria-label='{esc(title or 'coverage map')}' "
        "style='font:12px system-ui,sans-serif;max-width:100%'>"
    ]
    if title:
        out.append(f"<text x='4' y='14' font-weight='bold'>{esc(title)}</text>")
    for j, side in enumerate(sides):
        out.append(
            f"<text x='{name_w + j * cell_w + cell_w / 2}' y='{top - 8}' text-anchor='middle'>side {esc(side)}</text>"
        )
    for i, patient in enumerate(patients):
        y = top + i * cell_h
        out.append(f"<text x='{name_w - 6}' y='{y + 17}' text-anchor='end'>{esc(patient)}</text>")
        for j, side in enumerate(sides):
            d = by.get((patient, side))
            x = name_w + j * cell_w
            if d is None:
                out.append(f"<rect x='{x}' y='{y}' width='{cell_w - 2}' height='{cell_h - 2}' fill='#eee'/>")
                continue
            fill, label = ("#cdeccd", "served") if d["meets_requirements"] else ("#f6c9c9", "not served")
            text = f"{label}: {_bind(d)}" if _bind(d) else label
            # the whole text, never cut: squeezed into the cell when longer than it holds at 12 px (about 6.5 px a character)
            room = cell_w - 12
            fit = f" textLength='{room}' lengthAdjust='spacingAndGlyphs'" if 6.5 * len(text) > room else ""
            out.append(
                f"<rect x='{x}' y='{y}' width='{cell_w - 2}' height='{cell_h - 2}' fill='{fill}' stroke='#999'>"
                f"<title>{esc(d['label'])}: {esc(text)}</title></rect>"
                f"<text x='{x + 6}' y='{y + 17}'{fit}>{esc(text)}</text>"
            )
    out.append("</svg>")
    return "".join(out)


def coverage_table(dockings: Sequence[Mapping[str, Any]], link: str | None = "") -> str:
    """The sides as an HTML table: patient, side, met, what binds and by how much, what was missed, eta_G, the placement;
    ``link``: the folder prefix of the dockings' reports (None: no links)."""
    rows = [
        "<div style='overflow-x:auto'><table><tr><th>patient</th><th>side</th><th>met</th><th>binds</th><th>missed</th>"
        "<th>η_G</th><th>m (mm)</th><th>mount (deg)</th><th>report</th></tr>"
    ]
    for d in dockings:
        cls = "" if d["meets_requirements"] else " class='fail'"
        report = "" if link is None else f"<a href='{esc(link + d['folder'])}/report.html'>{esc(d['label'])}</a>"
        m = ", ".join(f"{d[k]:.1f}" for k in ("m_x", "m_y", "m_z"))
        mount = ", ".join(f"{d[k]:.1f}" for k in ("mount_rx", "mount_ry", "mount_rz"))
        rows.append(
            f"<tr{cls}><td>{esc(d['patient'])}</td><td>{esc(d['side'])}</td><td>{'yes' if d['meets_requirements'] else 'no'}</td>"
            f"<td>{esc(_bind(d))}</td><td>{esc(', '.join(d['missed']))}</td><td>{esc(fmt(d.get('eta_G'), 3))}</td>"
            f"<td>{esc(m)}</td><td>{esc(mount)}</td><td>{report}</td></tr>"
        )
    rows.append("</table></div>")
    return "".join(rows)


def _line(name: str, s: Mapping[str, Any]) -> str:
    return (
        f"<tr><td>{esc(name)}</td><td>{s['met']} of {s['sides']}</td><td>{_pct(s['coverage'])}</td>"
        f"<td>{_pct(s['coverage_low'])} – {_pct(s['coverage_high'])}</td></tr>"
    )


def coverage_section(
    summary: Mapping[str, Any], held_out: Mapping[str, Any] | None = None, held_out_link: str = "validation/"
) -> str:
    """The coverage as an HTML fragment: the table (training and held-out side by side when both), the maps of the sides,
    and the table of the held-out sides linking to their reports under ``held_out_link``."""
    which = "training" if held_out is not None else "these patients"
    parts = [
        "<h2>Coverage (the model, 19.6)</h2><table><tr><th>patients</th><th>sides met</th><th>coverage</th><th>95 % Wilson interval</th></tr>",
        _line(which, summary),
    ]
    if held_out is not None:
        parts.append(_line("held out (never seen by the search)", held_out))
    parts.append("</table><h3>Sides served, and what binds</h3>")
    parts.append(coverage_map_svg(summary["dockings"], which))
    if held_out is not None:
        parts.append("<br>" + coverage_map_svg(held_out["dockings"], "held out"))
        parts.append("<h3>The held-out sides</h3>" + coverage_table(held_out["dockings"], held_out_link))
    return "".join(parts)


def write_coverage_report(
    path: str | os.PathLike[str],
    summary: Mapping[str, Any],
    held_out: Mapping[str, Any] | None = None,
    held_out_link: str = "validation/",
) -> Path:
    """Write the page (module docstring) for ``summary`` (summary.json of ``arcube dock``); with ``held_out`` (the
    held-out cohort's, linked under ``held_out_link``), the two coverages side by side and both maps."""
    out = Path(path)
    robot = summary.get("robot") or {}
    served = summary["met"] == summary["sides"]
    verdict = (
        f"serves every one of its {summary['sides']} patient sides"
        if served
        else f"serves {summary['met']} of {summary['sides']} patient sides"
    )
    which = "training" if held_out is not None else "these patients"
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>AR-CUBE: coverage of one robot</title><style>{CSS}</style></head><body>",
        "<h1>Which patients does the robot serve?</h1>",
        f"<p>The robot (mode {esc(summary.get('mode'))}, c_z {fmt(robot.get('c_z'), 1)} mm, L {fmt(robot.get('L'), 1)} mm) "
        f"<b{'' if served else ' class=fail'}>{esc(verdict)}</b>{' (training)' if held_out is not None else ''}. A side is served "
        "when a docking of the robot as it is built meets every requirement of the design job, re-checked by the NumPy reference, "
        "with its drilling program built (the docking problem: docs, the model, 19.6).</p>",
        coverage_section(summary, held_out, held_out_link),
        f"<h2>The sides ({esc(which)})</h2>" + coverage_table(summary["dockings"], ""),
        "<p class='note'>binds: the requirement with the least margin at that side (a missed one first), and its margin. "
        "Each docking's own report has its requirement table, its accuracy as built and its program.</p></body></html>",
    ]
    atomic_write_text(out, "".join(parts))
    return out
