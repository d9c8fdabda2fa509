"""The opening of an ``arcube design`` job's report: the verdict, the requirements, the whole design, and
what the robot drills as built (model §20), before the evaluation's plots.

:func:`design_preface` returns an HTML fragment that :func:`arcube.report.write_report` puts right under
the title. Its requirement rows are the ones the terminal prints and requirements.csv holds (the same
list), so the three never disagree.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from arcube.model.design import PARAM_NAMES, UNITS, Design
from arcube.report.page import esc, fmt

__all__ = ["design_preface", "requirement_where"]


def requirement_where(row: Mapping[str, Any]) -> str:
    """Where a requirement is tightest, as the terminal says it (patient, trajectory, segment, point; part or actuator)."""
    w = row.get("where") or {}
    where = f"patient {w['patient']}, trajectory {w['trajectory']} ({w['segment']}, point {w['point']})" if w else ""
    part = row.get("part") or ""
    if row["requirement"] == "program":
        return str(part)
    return ", ".join(p for p in (where, str(part)) if p)


def _num(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else "—"


def _requirements_table(rows: Sequence[Mapping[str, Any]]) -> str:
    head = (
        "<tr><th>requirement</th><th>limit</th><th>value</th><th>margin</th><th>unit</th><th></th><th>where</th></tr>"
    )
    body = []
    for r in rows:
        sign = "≥" if r["kind"] == "min" else "≤"
        verdict = "ok" if r["passed"] else "<span class='fail'>FAIL</span>"
        body.append(
            f"<tr><th>{esc(r['requirement'])}</th><td>{sign} {_num(r['limit'])}</td><td>{_num(r['value'])}</td>"
            f"<td>{_num(r['margin'])}</td><td>{esc(r.get('unit', ''))}</td><td>{verdict}</td>"
            f"<td style='text-align:left'>{esc(requirement_where(r))}</td></tr>"
        )
    return "<table>" + head + "".join(body) + "</table>"


def _parameters_table(design: Design, mode: str, c_z: float | None) -> str:
    vals = design.to_dict()
    cells = [(name, vals[name], UNITS.get(name, "")) for name in PARAM_NAMES]
    cells.append(("c_z", c_z if c_z is not None else vals["d_z"], "mm" + ("" if c_z is not None else " (= d_z)")))
    rows = [cells[i : i + 4] for i in range(0, len(cells), 4)]
    html = "<table>" + "".join(
        "<tr>" + "".join(f"<th>{esc(n)}</th><td>{fmt(float(v))} {esc(u)}</td>" for n, v, u in row) + "</tr>"
        for row in rows
    )
    return html + f"<tr><th>working mode</th><td colspan='7' style='text-align:left'>{esc(mode)}</td></tr></table>"


def _image(path: Path, alt: str) -> str:
    if not path.is_file():
        return ""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f"<img alt='{esc(alt)}' style='max-width:48%' src='data:image/png;base64,{data}'>"


def _accuracy(accuracy: Mapping[str, Any] | None, folder: Path | None) -> str:
    if not accuracy:
        return ""
    cls = accuracy.get("tolerance_class", "m")
    if "not_computed" in accuracy:
        return f"<h2>Accuracy as built (ISO 2768-{esc(cls)})</h2><p>Not computed: {esc(accuracy['not_computed'])}</p>"
    top = ", ".join(
        f"{t['source']} {100 * t['share']:.0f} % (T {t['tolerance']:g} {t['unit']})"
        for t in accuracy.get("tighten_first", [])
    )
    items = [
        (
            "perfect robot: largest lateral error (encoders only, model §15.2)",
            f"{_num(accuracy.get('perfect_robot_lateral_error_mm'))} mm",
        ),
        (
            f"built to ISO 2768-{cls}: lateral error p95 over {accuracy.get('robots')} robots",
            f"{_num(accuracy.get('lateral_error_p95_mm'))} mm",
        ),
        (
            "first-order worst case / RMS lateral error",
            f"{_num(accuracy.get('lateral_error_wc_mm'))} / {_num(accuracy.get('lateral_error_rms_mm'))} mm",
        ),
        (
            "axis error p95 / worst case",
            f"{_num(accuracy.get('axis_error_p95_deg'))} / {_num(accuracy.get('axis_error_wc_deg'))} deg",
        ),
        ("tighten first", top or "—"),
    ]
    html = (
        f"<h2>Accuracy as built (ISO 2768-{esc(cls)})</h2><p class='note'>What robots machined to these tolerances drill "
        "(model §20: the first order's exact worst case over the tolerance box, and a Monte Carlo of built robots "
        "commanded by the nominal model). A calibration (arcube calibrate) removes the part it can identify. Files: accuracy/.</p><table>"
    )
    html += (
        "".join(f"<tr><th style='text-align:left'>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in items) + "</table>"
    )
    if folder is not None:
        html += _image(folder / "lateral_histogram.png", "lateral error of each built robot") + _image(
            folder / "sources.png", "error sources ranked"
        )
    return html


def _breach(figures: Mapping[str, Any] | None, folder: Path | None) -> str:
    """The breach section (model §22): per screw P(breach), its interval, the major ones, each source alone."""
    if not figures:
        return ""
    if "not_computed" in figures:
        return f"<h2>Breach probability</h2><p>Not computed: {esc(figures['not_computed'])}</p>"

    def pct(v: Any) -> str:
        return "—" if v is None or (isinstance(v, float) and v != v) else f"{100 * v:.1f} %"

    head = (
        "<h2>Breach probability (model §22)</h2><p class='note'>How likely each screw is to leave its pedicle with this robot as "
        "built (the accuracy section's tolerances), a registration of 0.5 mm / 0.5° RMS and the drilling thrust, and what decides it: "
        f"each source alone. Largest: {pct(figures.get('breach_probability'))} (screw {esc(figures.get('worst_screw'))}); expected "
        f"breached screws {_num(figures.get('expected_breaches'))}. Files: breach/.</p>"
    )
    table = [
        "<table><tr><th>screw</th><th>level</th><th>side</th><th>room (mm)</th><th>P(breach)</th><th>95 % interval</th><th>major</th>"
        "<th>robot alone</th><th>registration alone</th><th>deflection alone</th></tr>"
    ]
    for r in figures.get("screws", []):
        cls = " class='fail'" if r["too_wide"] else ""
        table.append(
            f"<tr{cls}><td>{esc(r['trajectory'])}</td><td>{esc(r['level'])}</td><td>{esc(r['side'])}</td><td>{r['room_mm']:.2f}</td>"
            f"<td>{pct(r['p_breach'])}</td><td>{pct(r['p_breach_low'])} – {pct(r['p_breach_high'])}</td><td>{pct(r['p_major'])}</td>"
            f"<td>{pct(r['p_robot_alone'])}</td><td>{pct(r['p_registration_alone'])}</td><td>{pct(r['p_deflection_alone'])}</td></tr>"
        )
    html = head + "".join(table) + "</table>"
    if folder is not None:
        html += _image(folder / "breach_by_screw.png", "P(breach) per screw and each source alone") + _image(
            folder / "worst_screw.png", "the worst screw's isthmus"
        )
    return html


def _as_built(accuracy: Mapping[str, Any] | None, breach: Mapping[str, Any] | None) -> str:
    """The verdict's second line: the lateral error requirement speaks of a perfect robot; beside it, what the robot
    drills as built to its class (and the breach probability of its worst screw), so that neither stands alone."""
    if not accuracy or "lateral_error_p95_mm" not in accuracy:
        return ""
    text = (
        f"Lateral error: {_num(accuracy.get('perfect_robot_lateral_error_mm'))} mm for a perfect robot (the requirement above), "
        f"<b>{_num(accuracy['lateral_error_p95_mm'])} mm</b> (p95) for the robot as built to ISO 2768-{esc(accuracy.get('tolerance_class', 'm'))}"
    )
    if breach and isinstance(breach.get("breach_probability"), float):
        text += f"; the worst screw breaches its pedicle with P = {100 * breach['breach_probability']:.0f} % as built (section below)"
    return f"<p class='note'>{text}. A calibration (arcube calibrate) brings the robot close to the perfect one.</p>"


def design_preface(
    summary: Mapping[str, Any],
    rows: Sequence[Mapping[str, Any]],
    design: Design,
    c_z: float | None = None,
    folder: str | Path | None = None,
) -> str:
    """The HTML that opens a design job's report: verdict, requirements table (``rows``, as requirements.csv),
    the 27 parameters with c_z and the working mode, the accuracy budget as built (``summary["accuracy"]``,
    its pictures from ``folder``/accuracy when given), and the program's line."""
    met = bool(summary.get("meets_requirements"))
    missed = [r for r in rows if not r["passed"]]
    verdict = (
        "meets every requirement"
        if met
        else f"does NOT meet every requirement ({len(missed)} missed: "
        + ", ".join(str(r["requirement"]) for r in missed)
        + ")"
    )
    head = (
        f"<h2>Verdict</h2><p><b{'' if met else ' class=fail'}>The design {esc(verdict)}</b>: seed {esc(summary.get('seed'))}, "
        f"mode {esc(summary.get('mode'))}, η_G {_num(summary.get('eta_G'))}; {len(rows) - len(missed)} of {len(rows)} requirements met, "
        "checked by the NumPy reference.</p>" + _as_built(summary.get("accuracy"), summary.get("breach"))
    )
    program = next((r for r in rows if r["requirement"] == "program"), None)
    prog = ""
    if program is not None:
        prog = (
            f"<p>Drilling program: {'built, ' + esc(program.get('part', '')) if program['passed'] else '<span class=fail>blocked</span>: ' + esc(program.get('part', ''))}"
            " (its section is at the end of this page; files: program/).</p>"
        )
    base = None if folder is None else Path(folder) / "accuracy"
    return (
        head
        + prog
        + "<h2>Requirements</h2>"
        + _requirements_table(rows)
        + "<p class=note>Each requirement is checked at the plan's points and, for the clearances, along the approach "
        "lines too (from the standoff to the entry point, model §17.1): a figure here can be smaller than "
        "<code>arcube evaluate</code>'s, which checks the plan's points only.</p>"
        + "<h2>The design: every parameter</h2>"
        + _parameters_table(design, str(summary.get("mode", "")), c_z)
        + _accuracy(summary.get("accuracy"), base)
        + _breach(summary.get("breach"), None if folder is None else Path(folder) / "breach")
    )
