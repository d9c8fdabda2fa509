"""The output folder of an identification, written all or nothing.

``DIR/design.json`` (the calibrated design: :mod:`arcube.calibrate.design_file`), ``calibration.json``
(:meth:`arcube.calibrate.result.Calibration.to_json`), ``residuals.csv`` (one row per measurement: its
file row, pose id, fitted or held out, tip and axis residuals before and after), and the pages a caller
hands in (``pages``: :func:`write_calibration` passes the HTML page that
:func:`arcube.report.calibration.page_bytes` draws). Everything goes into a temporary folder beside DIR,
then is renamed to DIR: a reader, or a failure, never sees half a calibration. DIR must be new or empty.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path

from arcube.calibrate.result import Calibration
from arcube.io.files import write_folder

RESIDUAL_COLUMNS: tuple[str, ...] = ("row", "pose", "set", "E_before_mm", "e_before_deg", "E_after_mm", "e_after_deg")

Pages = Mapping[str, Callable[[Calibration], bytes]]
"""File name -> a function rendering that file (bytes) of a calibration."""


def residuals_csv(result: Calibration) -> str:
    """``residuals.csv``'s text: per measurement, its row, pose id, ``fitted`` or ``held_out``, residuals (mm, deg)."""
    m, r = result.measurements, result.residuals
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(RESIDUAL_COLUMNS)
    for i in range(len(m)):
        row = m.rows[i] if m.rows is not None else i + 1
        pose = m.pose[i] if m.pose is not None else ""
        values = (r.E_before_mm[i], r.e_before_deg[i], r.E_after_mm[i], r.e_after_deg[i])
        w.writerow([row, pose, "fitted" if result.fitted[i] else "held_out", *(repr(float(v)) for v in values)])
    return buf.getvalue()


def contents(result: Calibration, pages: Pages | None = None) -> dict[str, bytes]:
    """Every file of the folder: name -> bytes."""
    files = {
        "design.json": (json.dumps(result.design_json(), indent=2) + "\n").encode(),
        "calibration.json": (json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n").encode(),
        "residuals.csv": residuals_csv(result).encode(),
    }
    files.update({name: render(result) for name, render in (pages or {}).items()})
    return files


def write(result: Calibration, out_dir: str | os.PathLike[str], pages: Pages | None = None) -> Path:
    """Write the calibration's folder (module doc) with the pages ``pages`` renders; returns its path."""
    return write_folder(contents(result, pages), out_dir)


def write_calibration(result: Calibration, out_dir: str | os.PathLike[str]) -> Path:
    """The calibration's folder (design.json, calibration.json, residuals.csv, calibration.html), all or nothing."""
    from arcube.report.calibration import PAGE, page_bytes

    return write(result, out_dir, {PAGE: page_bytes})
