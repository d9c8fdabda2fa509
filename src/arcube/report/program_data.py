"""A drilling program (model §17.3) as the report reads it back from its files, ``program.csv`` and
``program.json``, so that a report never recomputes the program (and never imports :mod:`arcube.motion`).

The reading itself is :mod:`arcube.io.program_files`, the one reader of program folders (shared with
``arcube export --program`` and the MuJoCo replay): its limits, its checks and its one-line
:class:`~arcube.errors.InputError` naming the file. This module adds what only the report needs:
where the program's design is (:func:`find_design`) and the rows that draw a long curve (:func:`envelope`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from arcube.io.program_files import (
    CSV_NAME,
    JOINTS,
    JSON_NAME,
    POSE_COLUMNS,
    TORQUE_COLUMNS,
    ProgramFiles,
    Span,
    is_program_folder,
)
from arcube.io.program_files import read_program_files as read_program

__all__ = [
    "CSV_NAME",
    "JOINTS",
    "JSON_NAME",
    "TORQUE_COLUMNS",
    "ProgramFiles",
    "Span",
    "envelope",
    "find_design",
    "is_program_folder",
    "read_program",
]

NUMERIC_COLUMNS: tuple[str, ...] = (*POSE_COLUMNS, *JOINTS, *(f"{j}_dot" for j in JOINTS))
"""The numeric columns every program.csv has, after ``t_s, segment, trajectory``."""


def find_design(folder: str | os.PathLike[str]) -> Path | None:
    """The design a program folder belongs to, when it says so by its place: ``folder/design.json``, or
    ``design.json`` of the ``arcube design`` job the folder is the ``program/`` of; else None. The
    report asks only when program.json records no design (it prefers the one that ran the program)."""
    root = Path(folder)
    if (root / "design.json").is_file():
        return root / "design.json"
    if (root.parent / "design.toml").is_file() and (root.parent / "design.json").is_file():
        return root.parent / "design.json"
    return None


def envelope(y: NDArray[np.float64], max_points: int) -> NDArray[np.intp]:
    """Row indices that draw ``y`` ``(n,)`` with at most about ``max_points`` points and the same
    envelope: all rows when n <= max_points, else in each of max_points/2 equal buckets its smallest
    and its largest value (so every peak is drawn exactly). NaN rows are skipped in a bucket."""
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    edges = np.linspace(0, n, max(max_points // 2, 1) + 1).astype(int)
    keep = [0, n - 1]
    filled = np.where(np.isfinite(y), y, np.nan)
    for a, b in zip(edges[:-1], edges[1:]):
        chunk = filled[a:b]
        if b > a and np.isfinite(chunk).any():
            keep += [a + int(np.nanargmin(chunk)), a + int(np.nanargmax(chunk))]
    return np.unique(np.asarray(keep, dtype=np.intp))
