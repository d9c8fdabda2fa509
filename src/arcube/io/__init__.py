"""Reading and writing what arcube exchanges with the outside world.

* :mod:`arcube.io.trajectories`: trajectory sets (CSV), subsets, rigid transforms;
* :mod:`arcube.io.slicer`: 3D Slicer markups (``.mrk.json``);
* :mod:`arcube.io.load`: :func:`load_trajectories`, one entry point for every format, and
  :func:`load_plan`, a plan as every command takes it (a set or a file, kept to a side, levels, ids);
* :mod:`arcube.io.files`: atomic writes (temporary file, then rename; special files written in place);
* :mod:`arcube.io.inputs`: the layer under every reader (regular files and pipes only, size,
  encoding, JSON nesting and number limits, the coordinate range);
* :mod:`arcube.io.tables`: the strict layer under every CSV (rows as wide as the header, each column
  once, numbers in plain decimal notation);
* :mod:`arcube.io.program_files`: a drilling program's folder read back (report, export, replay).
"""

from __future__ import annotations

from arcube.io.files import atomic_write_bytes, atomic_write_text
from arcube.io.load import load_plan, load_trajectories
from arcube.io.slicer import read_markups, write_markups
from arcube.io.trajectories import (
    CSV_COLUMNS,
    TrajectorySet,
    apply_transform,
    atomic_write,
    read_csv,
    read_transform,
    select,
    validate_points,
    write_csv,
)

__all__ = [
    "CSV_COLUMNS",
    "TrajectorySet",
    "apply_transform",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "load_plan",
    "load_trajectories",
    "read_csv",
    "read_markups",
    "read_transform",
    "select",
    "validate_points",
    "write_csv",
    "write_markups",
]
