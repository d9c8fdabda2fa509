"""The report page of a calibration (model §21.4): one self-contained HTML file (plotly.js inline).

* the residuals per measurement, before (nominal model) and after (identified), fitted and held out,
  beside the tracker's noise level (div ``fig-residuals``);
* each unknown's identified deviation with its sigma bar, in units of its typical size, the
  non-identifiable ones marked with what they are confounded with (div ``fig-deviations``), and the table;
* the calibrated robot's accuracy budget along its points: first-order RMS and Monte Carlo p95 of the
  lateral error (div ``fig-budget``).

:func:`page_bytes` renders it; :func:`arcube.calibrate.output.write_calibration` writes the whole output
folder with it. This module takes the calibration as it is (:class:`arcube.calibrate.result.Calibration`),
without importing the calibration package, which sits above the report.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from arcube.model.mechanism import format_mode
from arcube.report.page import CSS, esc, fmt, plotly_div

PAGE = "calibration.html"
DIV_IDS = {"residuals": "fig-residuals", "deviations": "fig-deviations", "budget": "fig-budget"}


def residuals_figure(result: Any) -> Any:
    """Tip (mm) and axis (deg) residual of every measurement, before and after, fitted and held out."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    m, r = result.measurements, result.residuals
    labels = [m.pose[i] if m.pose is not None else str(m.rows[i] if m.rows else i + 1) for i in range(len(m))]
    x = np.arange(len(m))
    fig = make_subplots(
        rows=2,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.08,
        subplot_titles=("tip residual |E_meas − E_model| (mm)", "axis residual ∠(e_meas, e_model) (deg)"),
    )
    noise = result.residual_rms()["noise"]
    for row, (before, after, level) in enumerate(
        ((r.E_before_mm, r.E_after_mm, noise["E_rms_mm"]), (r.e_before_deg, r.e_after_deg, noise["e_rms_deg"])), start=1
    ):
        show = row == 1
        fig.add_trace(
            go.Scatter(
                x=x,
                y=before,
                mode="markers",
                name="before (nominal)",
                marker={"color": "#999", "symbol": "circle-open"},
                text=labels,
                legendgroup="b",
                showlegend=show,
            ),
            row=row,
            col=1,
        )
        for mask, name, color in (
            (result.fitted, "after, fitted", "#1f77b4"),
            (~result.fitted, "after, held out", "#ff7f0e"),
        ):
            fig.add_trace(
                go.Scatter(
                    x=x[mask],
                    y=after[mask],
                    mode="markers",
                    name=name,
                    marker={"color": color},
                    text=[labels[i] for i in np.flatnonzero(mask)],
                    legendgroup=name,
                    showlegend=show,
                ),
                row=row,
                col=1,
            )
        fig.add_hline(y=level, line={"color": "#2ca02c", "dash": "dash"}, row=row, col=1)
    fig.update_yaxes(type="log", row=1, col=1)
    fig.update_yaxes(type="log", row=2, col=1)
    fig.update_xaxes(title_text="measurement (file order); green: RMS at the tracker's noise level", row=2, col=1)
    fig.update_layout(height=620, margin={"t": 40})
    return fig


def deviations_figure(result: Any) -> Any:
    """Identified deviation / typical size, with +-sigma bars; the non-identifiable unknowns at 0, marked x."""
    import plotly.graph_objects as go

    rows = result.unknown_rows()
    names = [u["name"] for u in rows]
    dev = np.array([u["deviation"] / u["scale"] for u in rows])
    sig = np.array([(u["sigma"] or 0.0) / u["scale"] for u in rows])
    ok = np.array([u["identifiable"] for u in rows])
    hover = [
        f"{u['name']}: {u['deviation']:+.4g} ± {fmt(u['sigma'], 4)} {u['unit']} (typical size {u['scale']:.3g} {u['unit']})"
        for u in rows
    ]
    fig = go.Figure()
    fig.add_trace(
        go.Scatter(
            x=[n for n, k in zip(names, ok) if k],
            y=dev[ok],
            mode="markers",
            name="identified",
            error_y={"type": "data", "array": sig[ok], "visible": True},
            marker={"color": "#1f77b4"},
            hovertext=[h for h, k in zip(hover, ok) if k],
            hoverinfo="text",
        )
    )
    if (~ok).any():
        text = [
            f"{u['name']}: not identifiable, confounded with "
            + (
                ", ".join(f"{c['name']} ({c['coefficient']:+.3g})" for c in u["confounded_with"])
                or "nothing (moves nothing here)"
            )
            for u in rows
            if not u["identifiable"]
        ]
        fig.add_trace(
            go.Scatter(
                x=[n for n, k in zip(names, ok) if not k],
                y=np.zeros(int((~ok).sum())),
                mode="markers",
                name="not identifiable (kept nominal)",
                marker={"color": "#d62728", "symbol": "x", "size": 10},
                hovertext=text,
                hoverinfo="text",
            )
        )
    fig.update_yaxes(title_text="identified − nominal, in typical sizes (±σ)")
    fig.update_layout(height=420, margin={"t": 30})
    return fig


def budget_figure(result: Any) -> Any:
    """Lateral error of the calibrated robot along its points: first-order RMS and Monte Carlo p50, p95."""
    import plotly.graph_objects as go

    b = result.budget
    x = np.arange(len(b.labels))
    text = [f"{lab} #{int(k)}" for lab, k in zip(b.labels, b.point)]
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=x, y=b.lateral_mm[:, 1], name="Monte Carlo p95", line={"color": "#d62728"}, text=text))
    fig.add_trace(go.Scatter(x=x, y=b.lateral_mm[:, 0], name="Monte Carlo p50", line={"color": "#1f77b4"}, text=text))
    fig.add_trace(
        go.Scatter(x=x, y=b.lateral_rms_mm, name="first-order RMS", line={"color": "#2ca02c", "dash": "dot"}, text=text)
    )
    where = "the plan's points, trajectory after trajectory" if b.where == "plan" else "the measured poses"
    fig.update_xaxes(title_text=f"point ({where})")
    fig.update_yaxes(title_text="lateral error (mm)", rangemode="tozero")
    fig.update_layout(height=420, margin={"t": 30})
    return fig


def _table(rows: list[list[Any]], head: list[str]) -> str:
    th = "".join(f"<th>{esc(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{esc(fmt(v, 4))}</td>" for v in row) + "</tr>" for row in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def page_html(result: Any) -> str:
    """The whole page's HTML text."""
    data = result.to_json()
    res = data["residuals"]
    m = result.measurements
    figs = [("residuals", residuals_figure(result)), ("deviations", deviations_figure(result))]
    if result.budget is not None:
        figs.append(("budget", budget_figure(result)))
    divs = {key: plotly_div(fig, DIV_IDS[key], include_js=k == 0) for k, (key, fig) in enumerate(figs)}
    title = f"AR-CUBE calibration: {m.source}"
    resid_rows = [
        [
            name,
            res[name]["rows"],
            res[name]["E_rms_mm_before"],
            res[name]["E_rms_mm"],
            res[name]["e_rms_deg_before"],
            res[name]["e_rms_deg"],
        ]
        for name in ("fitted", "held_out")
    ]
    resid_rows.append(["tracker noise level", "", "", res["noise"]["E_rms_mm"], "", res["noise"]["e_rms_deg"]])
    unknowns = [
        [
            u["name"],
            u["kind"],
            u["unit"],
            u["nominal"],
            u["identified"],
            u["deviation"],
            u["sigma"],
            "yes" if u["identifiable"] else "no",
            ", ".join(f"{c['name']} ({c['coefficient']:+.3g})" for c in u["confounded_with"]),
        ]
        for u in data["unknowns"]
    ]
    overview = [
        ["working mode", format_mode(result.mode)],
        ["measurements (fitted / held out)", f"{int(result.fitted.sum())} / {int((~result.fitted).sum())}"],
        ["identifiable unknowns", f"{data['identifiable_count']} of 31"],
        ["O1 (Borm and Menq)", result.o1],
        ["condition number", result.condition_number],
        ["σ̂ (1: residuals at the noise level)", result.sigma_hat],
        ["solver", result.solver["message"]],
    ]
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(title)}</h1>",
        _table(overview, ["", ""]),
        (
            "<h2>Residuals</h2><p class='note'>RMS over the rows of the tip residual (mm, 3-D) and the axis residual (deg), "
            "with the nominal model (before) and the identified one (after). At the tracker's noise level they are √3 σ_E and √2 σ_e.</p>"
        ),
        _table(
            resid_rows, ["rows", "count", "tip before (mm)", "tip after (mm)", "axis before (deg)", "axis after (deg)"]
        ),
        divs["residuals"],
        (
            "<h2>Identified deviations</h2><p class='note'>Identified minus nominal value of each unknown, in units of its typical "
            "size (ISO 2768-1 class m tolerance; docking 10 mm, 5°; zero offsets 0.1°), with ±σ bars. An unknown that cannot be told "
            "apart from others is kept nominal; a deviation of it looks like the listed ones times their coefficients.</p>"
        ),
        divs["deviations"],
        _table(
            unknowns,
            ["unknown", "kind", "unit", "nominal", "identified", "deviation", "σ", "identifiable", "confounded with"],
        ),
    ]
    if result.budget is not None:
        s = result.budget.summary
        where = "the plan's points" if result.budget.where == "plan" else "the measured poses"
        parts += [
            (
                f"<h2>Accuracy of the calibrated robot</h2><p class='note'>On {esc(where)}: the parameters' and zero offsets' errors are "
                "the identification's (normal, its covariance); encoders and lost motion as model §20.1. First-order RMS (maximum over "
                f"the points) and the Monte Carlo's 95th percentile over {result.budget.robot_lateral_max_mm.size} robots of each robot's "
                "largest error.</p>"
            ),
            _table([[k, v] for k, v in s.items()], ["figure", "value"]),
            divs["budget"],
        ]
    else:
        parts.append(
            "<h2>Accuracy of the calibrated robot</h2><p class='fail'>The calibrated design reaches none of the points: no budget.</p>"
        )
    parts.append("</body></html>")
    return "\n".join(parts)


def page_bytes(result: Any) -> bytes:
    return page_html(result).encode("utf-8")
