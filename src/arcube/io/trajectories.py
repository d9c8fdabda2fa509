"""Drilling-trajectory sets: CSV input/output, subsets and the optional rigid transform.

A trajectory is an entry point and a target point in the patient frame (x = patient's right,
y = superior, z = posterior; mm). A :class:`TrajectorySet` holds T of them in file order.

CSV layout (one trajectory per row, header required, extra columns ignored; every row has as many
fields as the header, each column is named once: :mod:`arcube.io.tables`)::

    trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z

``level`` and ``side`` may be missing or empty (unknown); each column may appear once. Four optional
columns describe each screw's pedicle (model §22.1; an empty cell: the level's mean, or the default,
applies): ``pedicle_width_mm``, ``pedicle_height_mm`` (the isthmus, outer cortex to outer cortex),
``isthmus_depth_mm`` (from the entry along the drill) and ``screw_diameter_mm``. A column whose name is a
near miss of a known one (``pedicle_widht_mm``) is refused, naming the one it resembles: a misspelt
column is not silently ignored.
Coordinates are plain decimal numbers (``-12.5``, ``1e3``; not ``1_000``) within ±1e5 mm
(:mod:`arcube.io.inputs`, which also sets the size, file-type and encoding limits of every
reader). Row numbers in error messages are line numbers in the file, the header being row 1.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from collections.abc import Sequence
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.io.inputs import coordinate_problem, load_json, read_text, short_repr
from arcube.io.tables import number, parse_table

__all__ = [
    "CSV_COLUMNS",
    "PEDICLE_COLUMNS",
    "LEVEL_ORDER",
    "TrajectorySet",
    "apply_transform",
    "atomic_write",
    "read_csv",
    "read_transform",
    "select",
    "validate_points",
    "write_csv",
]

CSV_COLUMNS = (
    "trajectory",
    "level",
    "side",
    "entry_x",
    "entry_y",
    "entry_z",
    "target_x",
    "target_y",
    "target_z",
)
PEDICLE_COLUMNS = ("pedicle_width_mm", "pedicle_height_mm", "isthmus_depth_mm", "screw_diameter_mm")
"""The optional columns of a plan CSV that describe each screw's pedicle (model §22.1), mm."""
PEDICLE_LIMITS = {
    "pedicle_width_mm": 30.0,
    "pedicle_height_mm": 30.0,
    "isthmus_depth_mm": 200.0,
    "screw_diameter_mm": 20.0,
}
"""Each pedicle column's values lie in (0, limit) mm (a screw of 20 mm or more is no pedicle screw)."""
_COORD_COLUMNS = CSV_COLUMNS[3:]
# level and side may be absent: a plan exported from elsewhere often has neither.
_REQUIRED_COLUMNS = ("trajectory",) + _COORD_COLUMNS
LEVEL_ORDER = ("C1", "C2", "C3", "C4", "C5", "C6", "C7")
_SIDES = ("R", "L", "")
# Below this an entry and a target are the same point: no drill axis can be defined.
_MIN_LENGTH_MM = 1e-9
# The shortest trajectory a plan may hold, mm: no screw or wire is shorter (cervical pedicle screws are 14-30 mm);
# a plan written in metres has trajectories of some hundredths.
SHORTEST_TRAJECTORY_MM = 1.0
_RIGID_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class TrajectorySet:
    """T drilling trajectories in the patient frame.

    Attributes:
        ids: trajectory identifiers, kept as strings, in file order.
        levels: vertebral level per trajectory (e.g. ``"C3"``), ``""`` when unknown.
        sides: ``"R"``, ``"L"`` or ``""`` when unknown.
        entry: (T, 3) float array, mm, patient frame; read-only.
        target: (T, 3) float array, mm, patient frame; read-only.
        source: the path the set came from, ``"reference"``, or a generator tag.
        pedicle: (T, 4) float array, mm, the :data:`PEDICLE_COLUMNS` of each trajectory, NaN where not
            given; None when the plan has none of them. Read-only.
    """

    ids: tuple[str, ...]
    levels: tuple[str, ...]
    sides: tuple[str, ...]
    entry: np.ndarray
    target: np.ndarray
    source: str
    pedicle: np.ndarray | None = None

    def __post_init__(self) -> None:
        # Copy and freeze the arrays so a frozen set cannot be mutated through them.
        entry = np.array(self.entry, dtype=float).reshape(-1, 3)
        target = np.array(self.target, dtype=float).reshape(-1, 3)
        entry.setflags(write=False)
        target.setflags(write=False)
        object.__setattr__(self, "entry", entry)
        object.__setattr__(self, "target", target)
        for name in ("ids", "levels", "sides"):
            object.__setattr__(self, name, tuple(str(v) for v in getattr(self, name)))
        if self.pedicle is not None:
            pedicle = np.array(self.pedicle, dtype=float).reshape(-1, len(PEDICLE_COLUMNS))
            if pedicle.shape[0] != entry.shape[0]:
                raise ValueError(
                    f"TrajectorySet: pedicle has {pedicle.shape[0]} rows for {entry.shape[0]} trajectories"
                )
            pedicle.setflags(write=False)
            object.__setattr__(self, "pedicle", pedicle)
        n = len(self.ids)
        if not (len(self.levels) == len(self.sides) == entry.shape[0] == target.shape[0] == n):
            raise ValueError(
                f"TrajectorySet: inconsistent sizes (ids {n}, levels {len(self.levels)}, "
                f"sides {len(self.sides)}, entry {entry.shape[0]}, target {target.shape[0]})"
            )

    def __len__(self) -> int:
        return len(self.ids)

    def __eq__(self, other: object) -> bool:
        """Exact equality of every field (arrays compared element-wise)."""
        if not isinstance(other, TrajectorySet):
            return NotImplemented
        return (
            self.ids == other.ids
            and self.levels == other.levels
            and self.sides == other.sides
            and self.source == other.source
            and np.array_equal(self.entry, other.entry)
            and np.array_equal(self.target, other.target)
            and (self.pedicle is None) == (other.pedicle is None)
            and (self.pedicle is None or np.array_equal(self.pedicle, other.pedicle, equal_nan=True))
        )

    __hash__ = None  # type: ignore[assignment]  # equality is by value over arrays

    @property
    def lengths(self) -> np.ndarray:
        """(T,) drilling lengths |target − entry|, mm."""
        return np.linalg.norm(self.target - self.entry, axis=1)


def atomic_write(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` atomically (temporary file in the same folder + os.replace).

    Raises InputError naming the path when the file system refuses.
    """
    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise InputError(f"{os.fspath(path)}: cannot write ({exc.strerror or exc})") from exc


def validate_points(labels: Sequence[str], ids: Sequence[str], entry: np.ndarray, target: np.ndarray) -> None:
    """Check what every reader must guarantee; raise InputError at the first problem.

    Args:
        labels: per trajectory, where it came from (``"plan.csv row 4"``), for messages.
        ids: trajectory ids; must be non-empty and unique.
        entry: (T, 3) arrays, mm; must be finite, within ±1e5 mm
            (:data:`arcube.io.inputs.COORDINATE_LIMIT_MM`) and at least :data:`SHORTEST_TRAJECTORY_MM` apart per row.
        target: see ``entry``.
    """
    seen: dict[str, str] = {}
    for i, tid in enumerate(ids):
        if tid == "":
            raise InputError(f"{labels[i]}: empty trajectory id")
        if tid in seen:
            raise InputError(f"{labels[i]}: duplicate trajectory id {short_repr(tid)} (also at {seen[tid]})")
        seen[tid] = labels[i]
        if not (np.all(np.isfinite(entry[i])) and np.all(np.isfinite(target[i]))):
            raise InputError(f"{labels[i]}: coordinates are not finite numbers")
        for role, point in (("entry", entry[i]), ("target", target[i])):
            problem = coordinate_problem(point)
            if problem:
                raise InputError(f"{labels[i]}: {role} {problem} (a unit mistake?)")
        length = float(np.linalg.norm(target[i] - entry[i]))
        if length < _MIN_LENGTH_MM:
            raise InputError(f"{labels[i]}: zero-length trajectory (entry == target)")
        if length < SHORTEST_TRAJECTORY_MM:
            raise InputError(
                f"{labels[i]}: the trajectory is {length:.3g} mm long, shorter than any screw "
                f"({SHORTEST_TRAJECTORY_MM:g} mm): coordinates are in mm (a plan in metres?)"
            )


def _parse_csv_text(text: str, name: str, source: str) -> TrajectorySet:
    """Parse CSV ``text`` (:func:`arcube.io.tables.parse_table`); ``name`` labels error messages, ``source`` goes into the set."""
    table = parse_table(text, name, required=_REQUIRED_COLUMNS, key=lambda h: h.strip().lower())
    _refuse_near_misses(table.header, name)
    col = {c: table.index(c) for c in (*CSV_COLUMNS, *PEDICLE_COLUMNS) if c in table.header}
    pedicle_cols = [c for c in PEDICLE_COLUMNS if c in col]
    pedicle: list[list[float]] = []
    ids: list[str] = []
    levels: list[str] = []
    sides: list[str] = []
    labels: list[str] = []
    points: list[list[float]] = []
    for line, row in table.rows:
        where = table.where(line)
        points.append([number(row[col[c]], where, c) for c in _COORD_COLUMNS])
        ids.append(row[col["trajectory"]])
        levels.append(row[col["level"]].upper() if "level" in col else "")
        side = row[col["side"]].upper() if "side" in col else ""
        if side not in _SIDES:
            raise InputError(f"{where}: side must be R, L or empty ({short_repr(side)})")
        sides.append(side)
        labels.append(where)
        if pedicle_cols:
            pedicle.append([_pedicle_value(row[col[c]], where, c) if c in col else np.nan for c in PEDICLE_COLUMNS])
    if not ids:
        raise InputError(f"{name}: no trajectories (header only)")
    pts = np.array(points, dtype=float)
    validate_points(labels, ids, pts[:, :3], pts[:, 3:])
    ped = np.array(pedicle, dtype=float) if pedicle_cols else None
    if ped is not None:
        length = np.linalg.norm(pts[:, 3:] - pts[:, :3], axis=1)
        bad = np.flatnonzero(ped[:, 2] >= length)
        if bad.size:
            k = int(bad[0])
            raise InputError(
                f"{labels[k]}: isthmus_depth_mm {ped[k, 2]:g} is not inside the trajectory ({length[k]:.3g} mm from entry to target)"
            )
    return TrajectorySet(tuple(ids), tuple(levels), tuple(sides), pts[:, :3], pts[:, 3:], source, ped)


def _pedicle_value(text: str, where: str, column: str) -> float:
    """One pedicle cell: NaN when empty (the default applies), else a number in (0, limit) mm."""
    if not text.strip():
        return float("nan")
    v = number(text, where, column)
    limit = PEDICLE_LIMITS[column]
    if not (math.isfinite(v) and 0.0 < v < limit):
        raise InputError(f"{where}: {column} must be a number of mm in (0, {limit:g}), got {short_repr(text)}")
    return v


def _refuse_near_misses(header: Sequence[str], name: str) -> None:
    """InputError for a column that is not one of the plan's but nearly is (a misspelt optional column is read as none)."""
    import difflib

    known = (*CSV_COLUMNS, *PEDICLE_COLUMNS)
    for h in header:
        if h and h not in known:
            close = difflib.get_close_matches(h, known, n=1, cutoff=0.8)
            if close:
                raise InputError(
                    f"{name}: unknown column {short_repr(h)}: did you mean {close[0]}? (other columns are ignored, a "
                    "misspelt one is not)"
                )


def read_csv(path: str | os.PathLike[str]) -> TrajectorySet:
    """Read a trajectory CSV (see module docstring). Raises InputError on any problem."""
    p = Path(path)
    text = read_text(p)
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # universal newlines, as open() in text mode
    return _parse_csv_text(text, str(p), str(p))


def read_reference() -> TrajectorySet:
    text = resources.files("arcube").joinpath("data", "reference_patient.csv").read_text("utf-8")
    return _parse_csv_text(text, "reference_patient.csv (bundled)", "reference")


def read_transform(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a rigid 4×4 homogeneous transform (file frame → patient frame, mm) from JSON.

    Accepted: ``{"matrix": [[4 numbers] × 4]}`` or the bare 4×4 list. The rotation must be
    orthonormal with determinant +1 and the last row 0 0 0 1, each within 1e-6.

    Returns:
        (4, 4) float array.
    """
    p = Path(path)

    def bad(reason: str) -> InputError:
        return InputError(f"{p}: unreadable transform ({reason})")

    data: Any = load_json(p, fail=bad)
    if isinstance(data, dict):
        if "matrix" not in data:
            raise bad("expected a 4x4 list or an object with a 'matrix' key")
        data = data["matrix"]
    if not (
        isinstance(data, list)
        and len(data) == 4
        and all(isinstance(r, list) and len(r) == 4 for r in data)
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for r in data for v in r)
    ):
        raise bad("expected 4 rows of 4 numbers")
    m = np.array(data, dtype=float)
    if not np.all(np.isfinite(m)):
        raise bad("non-finite entries")
    if np.max(np.abs(m[3] - [0.0, 0.0, 0.0, 1.0])) > _RIGID_TOL:
        raise bad("last row is not 0 0 0 1")
    rot = m[:3, :3]
    with np.errstate(all="ignore"):  # entries such as 1e300 overflow here; they fail the test all the same
        if not np.max(np.abs(rot @ rot.T - np.eye(3))) <= _RIGID_TOL:
            raise bad("rotation part is not orthonormal: not a rigid transform")
    if abs(np.linalg.det(rot) - 1.0) > _RIGID_TOL:
        raise bad("rotation determinant is not +1: a reflection, not a rigid transform")
    problem = coordinate_problem(m[:3, 3])
    if problem:
        raise bad(f"translation {problem}")
    return m


def apply_transform(ts: TrajectorySet, matrix: np.ndarray) -> TrajectorySet:
    """Map entry and target points by the (4, 4) homogeneous ``matrix``: p' = R p + t."""
    rot, t = matrix[:3, :3], matrix[:3, 3]
    return TrajectorySet(
        ts.ids, ts.levels, ts.sides, ts.entry @ rot.T + t, ts.target @ rot.T + t, ts.source, ts.pedicle
    )


def _expand_levels(spec: str) -> set[str]:
    """``"C3-C5,C7"`` → {"C3", "C4", "C5", "C7"}; ranges follow C1..C7 order."""
    wanted: set[str] = set()
    for token in (t.strip().upper() for t in spec.split(",")):
        if not token:
            raise InputError.of("levels", f"{spec!r}: empty item")
        m = re.fullmatch(r"(\w+)\s*-\s*(\w+)", token)
        if m is None:
            wanted.add(token)
            continue
        lo, hi = m.groups()
        if lo not in LEVEL_ORDER or hi not in LEVEL_ORDER:
            raise InputError.of("levels", f"{spec!r}: range {token!r} must use levels C1..C7")
        i, j = LEVEL_ORDER.index(lo), LEVEL_ORDER.index(hi)
        if i > j:
            raise InputError.of("levels", f"{spec!r}: range {token!r} runs backwards")
        wanted.update(LEVEL_ORDER[i : j + 1])
    return wanted


def select(
    ts: TrajectorySet,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[Any] | None = None,
) -> TrajectorySet:
    """Subset of ``ts`` matching every given filter (AND), in the set's own order.

    Args:
        side: ``"R"`` or ``"L"`` (case-insensitive).
        levels: ``"C3-C5"``, ``"C3,C5"`` or mixtures such as ``"C3,C5-C7"``; or a sequence of such items.
        ids: comma-separated ids, e.g. ``"1,3,5"``, or a sequence of ids; an id absent from the set is an error.

    Raises:
        InputError: bad filter syntax, unknown id, or nothing left.
    """
    levels = levels if levels is None or isinstance(levels, str) else ",".join(str(v) for v in levels)
    ids = ids if ids is None or isinstance(ids, str) else ",".join(str(v) for v in ids)
    keep = np.ones(len(ts), dtype=bool)
    if side is not None:
        s = side.strip().upper()
        if s not in ("R", "L"):
            raise InputError.of("side", f"{side!r}: expected R or L")
        keep &= np.array([v == s for v in ts.sides], dtype=bool)
    if levels is not None:
        wanted = _expand_levels(levels)
        keep &= np.array([v in wanted for v in ts.levels], dtype=bool)
    if ids is not None:
        wanted_ids = [t.strip() for t in ids.split(",")]
        if any(t == "" for t in wanted_ids):
            raise InputError.of("ids", f"{ids!r}: empty item")
        unknown = [t for t in wanted_ids if t not in ts.ids]
        if unknown:
            raise InputError.of("ids", f"{ids!r}: unknown trajectory id(s) {', '.join(unknown)} in {ts.source}")
        keep &= np.array([v in wanted_ids for v in ts.ids], dtype=bool)
    if not keep.any():
        given = ", ".join(f"{k}={v}" for k, v in (("side", side), ("levels", levels), ("ids", ids)) if v is not None)
        raise InputError(f"no trajectory of {ts.source} matches {given}")
    idx = np.flatnonzero(keep)
    return TrajectorySet(
        tuple(ts.ids[i] for i in idx),
        tuple(ts.levels[i] for i in idx),
        tuple(ts.sides[i] for i in idx),
        ts.entry[idx],
        ts.target[idx],
        ts.source,
        None if ts.pedicle is None else ts.pedicle[idx],
    )


def _fmt(value: float, decimals: int | None) -> str:
    value = float(value) + 0.0  # turns -0.0 into 0.0
    if decimals is None:
        return repr(value)  # shortest text that reads back to the same float
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def write_csv(ts: TrajectorySet, path: str | os.PathLike[str], decimals: int | None = None) -> None:
    """Write ``ts`` as CSV (columns of :data:`CSV_COLUMNS`, then :data:`PEDICLE_COLUMNS` when the set has them;
    an empty cell where a row has none), atomically.

    Args:
        decimals: fixed decimals for coordinates (mm); None writes the shortest text that
            reads back to the identical float, so a round trip is exact.
    """
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS + (PEDICLE_COLUMNS if ts.pedicle is not None else ()))
    for i in range(len(ts)):
        coords = [_fmt(v, decimals) for v in (*ts.entry[i], *ts.target[i])]
        ped = [] if ts.pedicle is None else ["" if math.isnan(v) else _fmt(v, decimals) for v in ts.pedicle[i]]
        writer.writerow([ts.ids[i], ts.levels[i], ts.sides[i], *coords, *ped])
    atomic_write(path, buf.getvalue())
