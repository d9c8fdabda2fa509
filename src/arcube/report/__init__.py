"""Reporting layer: mechanism drawings, figures and the self-contained HTML report.

* :mod:`arcube.report.text`: the terminal tables of an evaluation;
* :mod:`arcube.report.figures`: matplotlib PNGs (the paper's Fig 4, optimizer convergence);
* :mod:`arcube.report.html`: one self-contained HTML file (plotly, with plotly.js embedded);
* :mod:`arcube.report.run_report`: the report of an optimization run folder.

Submodules are imported lazily so that ``import arcube.report`` stays cheap (plotly and
matplotlib load only when a report is written).
"""

from __future__ import annotations

from typing import Any

__all__ = ["mechanism_points", "write_evaluation_report", "write_run_report"]


def __getattr__(name: str) -> Any:
    if name == "mechanism_points":
        from arcube.model.body import mechanism_points

        return mechanism_points
    if name == "write_evaluation_report":
        from arcube.report.html import write_evaluation_report

        return write_evaluation_report
    if name == "write_run_report":
        from arcube.report.run_report import write_run_report

        return write_run_report
    raise AttributeError(f"module 'arcube.report' has no attribute {name!r}")
