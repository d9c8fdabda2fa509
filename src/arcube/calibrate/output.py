"""The output folder of an identification, written all or nothing.

``DIR/design.json`` (the calibrated design: :mod:`arcube.calibrate.design_file`), ``calibration.json``
(:meth:`arcube.calibrate.result.Calibration.to_json`), ``residuals.csv`` (one row per measurement: its
file row, pose id, fitted or held out, tip and axis residuals before and after), ``covariance.csv`` (the
identified unknowns' covariance, 31 x 31 in mm and deg, what ``arcube breach --calibration`` draws the
calibrated robot's errors from, model §21.4 and 22.2), and the pages a caller
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

import numpy as np

from arcube.calibrate.model import UNKNOWNS
from arcube.calibrate.result import Calibration
from arcube.io.files import write_folder

RESIDUAL_COLUMNS: tuple[str, ...] = ("row", "pose", "set", "E_before_mm", "e_before_deg", "E_after_mm", "e_after_deg")
COVARIANCE_FILE = "covariance.csv"
"""The identified unknowns' covariance: a header ``unknown`` + the 31 names, then one row per unknown (mm, deg)."""

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


def covariance_csv(cov: np.ndarray) -> str:
    """covariance.csv's text (:data:`COVARIANCE_FILE`): every value as the shortest text that reads back exactly."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["unknown", *UNKNOWNS])
    for name, row in zip(UNKNOWNS, np.asarray(cov, dtype=float)):
        w.writerow([name, *(repr(float(v)) for v in row)])
    return buf.getvalue()


def read_covariance(path: str | os.PathLike[str]) -> np.ndarray:
    """The ``(31, 31)`` covariance of a covariance.csv, checked: the unknowns' names in order, finite, symmetric, its
    eigenvalues >= 0 (up to rounding); one-line InputError naming the file and the problem."""
    from arcube.errors import InputError
    from arcube.io.inputs import read_text
    from arcube.io.tables import number, parse_table

    p = Path(path)
    table = parse_table(read_text(p), str(p), required=("unknown", *UNKNOWNS))
    if [row[0] for _, row in table.rows] != list(UNKNOWNS):
        raise InputError(f"{p}: expected one row per unknown, in the order {', '.join(UNKNOWNS[:3])}, ...")
    cov = np.array([[number(row[table.index(c)], table.where(line), c) for c in UNKNOWNS] for line, row in table.rows])
    if not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-15):
        raise InputError(f"{p}: the covariance must be finite and symmetric")
    w = np.linalg.eigvalsh(cov)
    if w.min() < -1e-9 * max(w.max(), 1e-300):
        raise InputError(f"{p}: the covariance is not positive semi-definite (an eigenvalue of {w.min():.3g})")
    return cov


def contents(result: Calibration, pages: Pages | None = None) -> dict[str, bytes]:
    """Every file of the folder: name -> bytes."""
    files = {
        "design.json": (json.dumps(result.design_json(), indent=2) + "\n").encode(),
        "calibration.json": (json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n").encode(),
        "residuals.csv": residuals_csv(result).encode(),
        COVARIANCE_FILE: covariance_csv(result.covariance).encode(),
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
