"""The output folder of an accuracy budget, written all or nothing.

``DIR/tolerance.json`` (settings, design, mode, the summaries of model §20.3-20.4, the Monte Carlo's
percentiles, the sources ranked), ``tolerance_points.csv`` (one row per plan point, plan order),
``sensitivity.csv`` (one row per error source, by decreasing share), and the pictures a caller hands in
(``figures``: :data:`arcube.report.accuracy.FIGURES`, which :func:`arcube.report.accuracy.write_budget`
passes; this layer computes and writes data, and never draws). Everything is written into a temporary
folder beside DIR, then renamed to DIR: a reader, or a failure, never sees half a budget. DIR must be
new or empty.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from arcube.accuracy.budget import POINT_COLUMNS, ToleranceResult
from arcube.io.files import write_folder

FILES: tuple[str, ...] = ("tolerance.json", "tolerance_points.csv", "sensitivity.csv")
SENSITIVITY_COLUMNS: tuple[str, ...] = ("source", "tolerance", "unit", "share")


def _cell(value: Any) -> str:
    """A CSV cell: numbers in full precision, NaN (no value: the point is not reached) empty, infinity ``inf``."""
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    return str(value)


def _csv(columns: tuple[str, ...], rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in rows:
        w.writerow([_cell(row[c]) for c in columns])
    return buf.getvalue()


def points_csv(result: ToleranceResult) -> str:
    """``tolerance_points.csv``'s text."""
    return _csv(POINT_COLUMNS, result.point_rows())


def sensitivity_csv(result: ToleranceResult) -> str:
    """``sensitivity.csv``'s text: source, tolerance (mm or deg), unit, share (of the lateral variance, plan mean)."""
    rows = [dict(zip(SENSITIVITY_COLUMNS, r)) for r in result.ranked_sources()]
    return _csv(SENSITIVITY_COLUMNS, rows)


Figures = Mapping[str, Callable[[ToleranceResult], bytes]]
"""File name -> a function drawing that picture (PNG bytes) of a budget."""


def contents(result: ToleranceResult, figures: Figures | None = None) -> dict[str, bytes]:
    """Every file of the folder: name -> bytes (the pictures drawn by ``figures``)."""
    files = {
        "tolerance.json": (json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n").encode(),
        "tolerance_points.csv": points_csv(result).encode(),
        "sensitivity.csv": sensitivity_csv(result).encode(),
    }
    files.update({name: draw(result) for name, draw in (figures or {}).items()})
    return files


def write(result: ToleranceResult, out_dir: str | os.PathLike[str], figures: Figures | None = None) -> Path:
    """Write the budget's folder ``out_dir`` (new or empty) all or nothing, with the pictures ``figures`` draws
    (none by default; :func:`arcube.report.accuracy.write_budget` gives them all); returns its path.

    Raises:
        InputError: ``out_dir`` is a file or a folder that is not empty (named ``out``).
        OSError: the file system refuses (nothing is left behind).
    """
    return write_folder(contents(result, figures), out_dir)  # the pictures drawn before anything touches the disk
