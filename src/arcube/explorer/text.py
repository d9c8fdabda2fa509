"""The explorer's figures as text: one table (figure, value, requirement, verdict), in Markdown for the
live panel and in HTML for the static export, and the line under the scene for the point shown."""

from __future__ import annotations

import html
import math
from typing import Any

from arcube.explorer.live import Figures, View

__all__ = ["PASS", "FAIL", "figure_rows", "html_table", "markdown_table", "point_line"]

PASS, FAIL, NA = "pass", "FAIL", "—"
_LABELS = {
    "reach": "reach, whole lines",
    "clearance": "clearance to the anatomy",
    "self_clearance": "self clearance",
    "lateral_error": "lateral error",
    "axis_error": "axis error",
    "torque": "actuator torque",
    "holding_torque": "holding torque (weight)",
    "z_dyad": "z leg closes (model §19.2)",
}


def _num(v: Any, digits: int = 2, unit: str = "") -> str:
    if v is None or not isinstance(v, (int, float)) or math.isnan(v):
        return NA
    if math.isinf(v):
        return "∞"
    return f"{v:.{digits}f}{(' ' + unit) if unit else ''}"


def _digits(unit: str) -> int:
    return {"mm": 2, "deg": 3, "N·m": 2, "%": 1, "failing points": 0}.get(unit, 3)


def figure_rows(fig: Figures) -> list[tuple[str, str, str, str]]:
    """(figure, value, requirement, verdict) rows: the plan's headline figures, then each requirement."""
    s = fig.summary
    eta = s["eta_G"]
    rows = [
        ("reach, drill points", f"{s['reach_pct']:.1f} % ({s['reachable']}/{s['n_points']})", "", ""),
        ("η_G", _num(eta, 4) if math.isfinite(eta) else "— (not every point reachable)", "", ""),
    ]
    if "holding_torque_max_Nm" in s and not any(r["requirement"] == "holding_torque" for r in fig.requirements):
        rows.append(("holding torque", _num(s["holding_torque_max_Nm"], 2, "N·m"), "", ""))
    for r in fig.requirements:
        name, unit = r["requirement"], r["unit"]
        value = _num(r["value"], _digits(unit), unit)
        if name == "reach":
            value = f"{r['value']:.1f} %"
        elif r["part"]:
            value += f" ({r['part']})"
        op = "≥" if r["kind"] == "min" else "≤"
        verdict = NA if r["passed"] is None else PASS if r["passed"] else FAIL
        if r["passed"] is None and name == "clearance":
            value = "no anatomy"
        rows.append((_LABELS.get(name, name), value, f"{op} {r['limit']:g} {unit}", verdict))
    if s["failures"]:
        rows.append(
            (
                "failing points",
                ", ".join(f"{k}: {n}" for k, n in sorted(s["failures"].items(), key=lambda kv: -kv[1])),
                "",
                "",
            )
        )
    return rows


def markdown_table(fig: Figures) -> str:
    """The rows as a Markdown table, with a verdict line on top."""
    verdict = "**Meets every requirement**" if fig.passed else "**Fails a requirement**"
    lines = [
        f"{verdict} · mode {fig.summary['mode']} · kernel {1000.0 * fig.seconds:.0f} ms",
        "",
        "| figure | value | requirement | |",
        "|---|---|---|---|",
    ]
    lines += [f"| {a} | {b} | {c} | {'**FAIL**' if d == FAIL else d} |" for a, b, c, d in figure_rows(fig)]
    return "\n".join(lines)


def html_table(fig: Figures) -> str:
    """The rows as an HTML table (the static export)."""
    esc = html.escape
    head = "<tr><th>figure</th><th>value</th><th>requirement</th><th></th></tr>"
    body = "".join(
        f"<tr><td>{esc(a)}</td><td>{esc(b)}</td><td>{esc(c)}</td><td>{esc(d)}</td></tr>"
        for a, b, c, d in figure_rows(fig)
    )
    verdict = "Meets every requirement" if fig.passed else "Fails a requirement"
    return f"<p><b>{verdict}</b> · mode {esc(fig.summary['mode'])}</p><table>{head}{body}</table>"


def point_line(view: View, fig: Figures) -> str:
    """One line for the point shown: where, dexterity, and both closest pairs."""
    i = view.index
    dex = fig.points["dexterity_pct"][i]
    reach = bool(fig.points["reachable"][i])
    parts = [view.label, f"100/η_L {_num(float(dex), 1)} %" if reach else "unreachable"]
    if view.patient.part:
        parts.append(f"clearance {_num(view.patient.clearance, 1, 'mm')} ({view.patient.part})")
    if view.self_.part:
        parts.append(f"self {_num(view.self_.clearance, 1, 'mm')} ({view.self_.part} – {view.self_.other_part})")
    return " · ".join(parts)
