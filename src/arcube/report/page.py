"""Pieces every HTML page of the report shares: its style sheet, escaping, number formatting, and a
plotly figure as an HTML fragment (plotly.js inline with the page's first figure, so the page opens
with no network)."""

from __future__ import annotations

import html as _html
import math
from typing import Any

__all__ = ["CSS", "esc", "fmt", "plotly_div", "png_bytes"]

CSS = """body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;padding:2px 8px;text-align:right}
th{background:#f3f3f3}h2{margin-top:1.4em;border-bottom:1px solid #ddd}.note{color:#555;font-size:90%}
.fail{color:#c00;font-weight:bold}"""
"""The report pages' style sheet (``.note``: explanatory text; ``.fail``: a value beyond its limit)."""


def esc(v: Any) -> str:
    """``str(v)`` escaped for HTML text and attributes."""
    return _html.escape(str(v))


def fmt(v: Any, digits: int = 4) -> str:
    """A table cell's text: floats with ``digits`` decimals, None and NaN as a dash, +inf as ∞."""
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.{digits}f}" if math.isfinite(v) else ("∞" if v > 0 else "—")
    return str(v)


def plotly_div(fig: Any, div_id: str, include_js: bool) -> str:
    """The plotly figure ``fig`` as an HTML ``<div id=div_id>`` with its script; ``include_js`` puts
    plotly.js inline (once per page, with the first figure)."""
    import plotly.io as pio

    return pio.to_html(
        fig,
        full_html=False,
        include_plotlyjs=include_js,
        auto_play=False,
        div_id=div_id,
        config={"displaylogo": False, "responsive": True},
    )


def png_bytes(fig: Any, dpi: int = 120) -> bytes:
    """A bare :class:`matplotlib.figure.Figure` (no pyplot, no global backend state) as PNG bytes."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
