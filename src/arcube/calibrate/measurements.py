"""The measurement file of a calibration (model §21.1): joint readings and the tracker's tool poses.

CSV, one measurement per row, a header naming the columns (case matters: ``E_x`` is the tip, ``e_x``
the axis), in any order:

* ``rho_x, rho_y, rho_z, delta_x, delta_y``: the joint angles as the encoders read them, deg;
* ``E_x, E_y, E_z``: the drill tip the tracker measured, mm, in the patient frame;
* ``e_x, e_y, e_z``: the drill axis the tracker measured, unit or not (normalised on reading).

Two optional columns, which :func:`arcube.calibrate.poses` writes and a tracker's plain CSV may omit:

* ``pose``: an id of the pose (text), so that a report's residual per measurement can be traced back
  to the pose file row the robot was driven to;
* ``design``: the digest (:func:`arcube.calibrate.design_file.design_digest`) of the design the poses
  were chosen for, the same in every row; :func:`arcube.calibrate.simulate` refuses a poses file made
  for another design. :func:`arcube.calibrate.identify` reads and ignores it.

Any other column is refused (a misspelt column is a mistake, not data). The reader is strict: a
one-line :class:`~arcube.errors.InputError` names the file, the row (line number, the header is row 1)
and the problem (an empty file, a missing, unknown or repeated column, a row with more or fewer fields
than the header, text in a number cell, NaN or infinity, an axis of length 0, a row repeating another's numbers).
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.io.inputs import coordinate_problem, read_text, short_repr
from arcube.io.tables import number, parse_table

JOINT_COLUMNS: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
POSE_COLUMNS: tuple[str, ...] = ("E_x", "E_y", "E_z", "e_x", "e_y", "e_z")
NUMBER_COLUMNS: tuple[str, ...] = (*JOINT_COLUMNS, *POSE_COLUMNS)
"""The 11 required columns, in the order the writer puts them (after ``pose``)."""
OPTIONAL_COLUMNS: tuple[str, ...] = ("pose", "design")
MAX_JOINT_DEG = 360.0
"""Largest |joint reading| accepted, deg (beyond it a value is in the wrong unit)."""


@dataclass(frozen=True)
class Measurements:
    """N measurements: joint readings and measured tool poses (or, in a poses file, nominal poses)."""

    q_deg: NDArray[np.float64]  # (N, 5) joint readings rho_x, rho_y, rho_z, delta_x, delta_y, deg
    E: NDArray[np.float64]  # (N, 3) drill tip, patient frame, mm
    e: NDArray[np.float64]  # (N, 3) unit drill axis, patient frame
    pose: tuple[str, ...] | None = None  # (N,) pose ids, or None (no pose column)
    design: str | None = None  # digest of the design the poses were chosen for, or None
    source: str = "measurements"  # the file (or what made them), for messages
    rows: tuple[int, ...] | None = None  # (N,) line number of each row in its file (header = 1)

    def __len__(self) -> int:
        return int(self.q_deg.shape[0])

    def where(self, i: int) -> str:
        """``"FILE row R"`` of measurement i (its line), or ``"SOURCE measurement i+1"``."""
        if self.rows is not None:
            return f"{self.source} row {self.rows[i]}"
        return f"{self.source} measurement {i + 1}"

    def take(self, index: NDArray[np.intp]) -> Measurements:
        """The measurements at ``index`` (in that order)."""
        idx = np.asarray(index, dtype=np.intp)
        return Measurements(
            self.q_deg[idx],
            self.E[idx],
            self.e[idx],
            None if self.pose is None else tuple(self.pose[i] for i in idx),
            self.design,
            self.source,
            None if self.rows is None else tuple(self.rows[i] for i in idx),
        )


def _cell(text: str, where: str, column: str) -> float:
    return number(text, where, column)


def _header(cells: list[str], name: str) -> dict[str, int]:
    header = [c.strip() for c in cells]
    for i, c in enumerate(header):
        if header.index(c) != i:
            raise InputError(
                f"{name}: column {c or '(empty name)'} appears more than once (columns {header.index(c) + 1} and {i + 1})"
            )
        if c not in NUMBER_COLUMNS and c not in OPTIONAL_COLUMNS:
            hint = (
                " (column names are case-sensitive: E_ is the tip, e_ the axis)"
                if c.lower() in {n.lower() for n in NUMBER_COLUMNS}
                else ""
            )
            raise InputError(
                f"{name}: unknown column {short_repr(c)}{hint}; a measurement file has "
                f"{', '.join(NUMBER_COLUMNS)}, and optionally pose and design"
            )
    missing = [c for c in NUMBER_COLUMNS if c not in header]
    if missing:
        raise InputError(f"{name}: missing column(s) {', '.join(missing)}")
    return {c: i for i, c in enumerate(header)}


def parse_measurements(text: str, name: str) -> Measurements:
    """Parse the CSV ``text`` of a measurement (or poses) file; ``name`` labels every message."""
    table = parse_table(text, name)  # rows as wide as the header, each column once (arcube.io.tables)
    col = _header(list(table.header), name)
    values: list[list[float]] = []
    poses: list[str] = []
    digests: set[str] = set()
    lines: list[int] = []
    seen: dict[tuple[float, ...], int] = {}
    for line, row in table.rows:
        where = table.where(line)
        nums = [_cell(row[col[c]], where, c) for c in NUMBER_COLUMNS]
        q, E, e = nums[:5], nums[5:8], nums[8:]
        bad = next((c for c, v in zip(JOINT_COLUMNS, q) if abs(v) > MAX_JOINT_DEG), None)
        if bad is not None:
            raise InputError(
                f"{where}: {bad} = {q[JOINT_COLUMNS.index(bad)]:g} deg is beyond +-{MAX_JOINT_DEG:g} deg (joint angles in degrees)"
            )
        problem = coordinate_problem(E)
        if problem:
            raise InputError(f"{where}: {problem}")
        if not math.hypot(*e) > 0.0:
            raise InputError(f"{where}: the axis (e_x, e_y, e_z) is (0, 0, 0): a drill axis needs a direction")
        first = seen.setdefault(tuple(nums), line)
        if first != line:
            raise InputError(
                f"{where}: the same 11 numbers as row {first}: one measurement counted twice (a tracker never reads a "
                "pose twice to the last digit; a repeated pose is measured again)"
            )
        values.append(nums)
        lines.append(line)
        if "pose" in col:
            poses.append(row[col["pose"]])
        if "design" in col:
            digests.add(row[col["design"]])
    if not values:
        raise InputError(f"{name}: no measurements (header only)")
    if len(digests) > 1:
        raise InputError(
            f"{name}: the design column holds {len(digests)} different digests (a file mixes poses of several designs)"
        )
    a = np.array(values, dtype=float)
    e_a = a[:, 8:11]
    with np.errstate(over="ignore", invalid="ignore"):
        e_a = e_a / np.linalg.norm(e_a, axis=1, keepdims=True)
    if not np.all(np.isfinite(e_a)):  # a length that overflows or underflows in the norm
        i = int(np.flatnonzero(~np.all(np.isfinite(e_a), axis=1))[0])
        raise InputError(f"{name} row {lines[i]}: the axis (e_x, e_y, e_z) cannot be normalised")
    return Measurements(
        q_deg=a[:, :5],
        E=a[:, 5:8],
        e=e_a,
        pose=tuple(poses) if "pose" in col else None,
        design=(next(iter(digests)) or None) if digests else None,
        source=name,
        rows=tuple(lines),
    )


def read_measurements(path: str | os.PathLike[str]) -> Measurements:
    """Read a measurement (or poses) CSV (module doc). Raises InputError naming the file and row."""
    p = Path(path)
    return parse_measurements(read_text(p), str(p))


def _fmt(v: float) -> str:
    return repr(float(v) + 0.0)


def measurements_csv(m: Measurements) -> str:
    """The CSV text of ``m``: ``pose`` (when there are ids), the 11 columns, ``design`` (when there is one)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = (["pose"] if m.pose is not None else []) + list(NUMBER_COLUMNS) + (["design"] if m.design else [])
    w.writerow(head)
    for i in range(len(m)):
        row = [_fmt(v) for v in (*m.q_deg[i], *m.E[i], *m.e[i])]
        w.writerow(([m.pose[i]] if m.pose is not None else []) + row + ([m.design] if m.design else []))
    return buf.getvalue()


def write_measurements(path: str | os.PathLike[str], m: Measurements) -> None:
    """Write ``m`` as CSV atomically (temporary file, then rename); numbers in full precision."""
    atomic_write_text(path, measurements_csv(m))


__all__ = [
    "JOINT_COLUMNS",
    "NUMBER_COLUMNS",
    "OPTIONAL_COLUMNS",
    "POSE_COLUMNS",
    "Measurements",
    "measurements_csv",
    "parse_measurements",
    "read_measurements",
    "write_measurements",
]
