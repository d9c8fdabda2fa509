"""A drilling program's folder (model §17.3) read back from its files: the one reader under
``arcube report``, ``arcube export --program`` and the MuJoCo replay.

``program.csv``: columns ``t_s, segment, trajectory, E_x, E_y, E_z, e_x, e_y, e_z`` (s; patient
frame, mm; unit axis), the five actuator angles ``rho_x ... delta_y`` (deg) and rates
``rho_x_dot ... delta_y_dot`` (deg/s); optionally the actuator torques ``tau_rho_x_Nm ...
tau_delta_y_Nm`` (N m, model §18.2); other columns are ignored. An empty cell (the writer's
non-finite value) reads as NaN, except in ``t_s``. ``program.json``: the summary (times, order,
smallest clearances, limits, motors, design, ...).

Both files are read within the limits of every reader (:mod:`arcube.io.inputs`,
:mod:`arcube.io.tables`: regular files only (no device, no FIFO), size, encoding, JSON depth and integer
digits, field length, rows as wide as the header, each column once, numbers in decimal notation)
and within the program's own: at most :data:`MAX_PROGRAM_ROWS` rows, times finite and increasing,
segments one of :data:`SEGMENTS`, tips within the coordinate range, unit axes, angles, rates and
torques within :data:`MAX_JOINT_VALUE`; the summary's fields that the report and the export use
have the types the writer gives them (``order`` a list of ids, ``transits`` a list of objects,
times numbers or null, ...). Any breach is one :class:`~arcube.errors.InputError` naming the file
(and the row or field) and the problem.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.io.inputs import COORDINATE_LIMIT_MM, load_json, read_text, short_repr
from arcube.io.tables import parse_table

__all__ = [
    "CSV_COLUMNS",
    "CSV_NAME",
    "JOINTS",
    "JSON_NAME",
    "MAX_JOINT_VALUE",
    "MAX_PROGRAM_BYTES",
    "MAX_PROGRAM_ROWS",
    "PNG_NAME",
    "POSE_COLUMNS",
    "PROGRAM_FILES",
    "SEGMENTS",
    "TORQUE_COLUMNS",
    "ProgramFiles",
    "Span",
    "is_program_folder",
    "read_program_files",
    "read_summary",
]

CSV_NAME, JSON_NAME, PNG_NAME = "program.csv", "program.json", "program.png"
PROGRAM_FILES = (CSV_NAME, JSON_NAME, PNG_NAME)
"""The files ``arcube program`` writes into its folder (the PNG is the timeline figure)."""
JOINTS = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuators, in q's order."""
POSE_COLUMNS = ("E_x", "E_y", "E_z", "e_x", "e_y", "e_z")
CSV_COLUMNS: tuple[str, ...] = ("t_s", "segment", "trajectory", *POSE_COLUMNS, *JOINTS, *(f"{j}_dot" for j in JOINTS))
"""Columns of ``program.csv`` (model §17.3): s; patient frame, mm; deg; deg/s."""
TORQUE_COLUMNS: tuple[str, ...] = tuple(f"tau_{j}_Nm" for j in JOINTS)
"""The optional actuator torque columns (N m), in :data:`JOINTS` order."""
SEGMENTS = ("approach", "drill", "retract", "transit")
"""What a row of a program does (model §17.1)."""
MAX_PROGRAM_ROWS = 500_000
"""Most rows a program may have (83 minutes at the default 0.01 s step): what ``arcube program``
writes and what the readers take, so that every program written can be read back."""
MAX_PROGRAM_BYTES = 256 * 2**20
"""Largest ``program.csv`` read, bytes (:data:`MAX_PROGRAM_ROWS` rows of 24 numbers fit)."""
MAX_JOINT_VALUE = 1.0e6
"""Largest |angle| (deg), |rate| (deg/s) and |torque| (N m) in a program row: beyond it a value is
damage, and would overflow the accelerations the report draws."""
MAX_SUMMARY_NUMBER = 1.0e12
"""Largest |number| in the summary (times, clearances, limits, motor figures)."""
_UNIT_TOL = 1e-6


class Span(NamedTuple):
    """A run of rows with the same segment and trajectory: rows ``first..last`` (inclusive), from
    ``t0`` (its first row) to ``t1`` (the next span's first row; the last row for the last span), s."""

    first: int
    last: int
    segment: str
    trajectory: str
    t0: float
    t1: float


@dataclass(frozen=True, eq=False)
class ProgramFiles:
    """A program folder's contents: ``n`` rows and the summary of program.json (checked)."""

    folder: Path
    t_s: NDArray[np.float64]  # (n,) s, finite, increasing
    segment: NDArray[np.str_]  # (n,) approach, drill, retract, transit
    trajectory: NDArray[np.str_]  # (n,) the plan's id, "a->b" in a transit
    E: NDArray[np.float64]  # (n, 3) tip, patient frame, mm
    e: NDArray[np.float64]  # (n, 3) unit drill axis
    q_deg: NDArray[np.float64]  # (n, 5) actuator angles, deg
    q_dot_deg: NDArray[np.float64]  # (n, 5) actuator rates, deg/s
    tau_Nm: NDArray[np.float64] | None  # (n, 5) actuator torques, N m (None: the CSV has no torque columns)
    summary: dict[str, Any]

    @property
    def limits(self) -> dict[str, Any]:
        """program.json's ``limits`` (ProgramLimits: max_joint_speed_deg, max_joint_accel_deg, clearance ...); {} if absent."""
        lim = self.summary.get("limits")
        return lim if isinstance(lim, dict) else {}

    @property
    def motors(self) -> dict[str, dict[str, Any]] | None:
        """program.json's ``motors``: per actuator name its sizing figures (model §18.3), or None."""
        m = self.summary.get("motors")
        return {str(k): v for k, v in m.items() if isinstance(v, dict)} if isinstance(m, dict) and m else None

    def spans(self) -> list[Span]:
        """The runs of equal (segment, trajectory) rows, in time order."""
        out: list[Span] = []
        n, start = len(self.t_s), 0
        for i in range(1, n + 1):
            if i == n or self.segment[i] != self.segment[start] or self.trajectory[i] != self.trajectory[start]:
                end_t = self.t_s[i] if i < n else self.t_s[n - 1]
                out.append(
                    Span(
                        start,
                        i - 1,
                        str(self.segment[start]),
                        str(self.trajectory[start]),
                        float(self.t_s[start]),
                        float(end_t),
                    )
                )
                start = i
        return out

    def accel_deg_s2(self) -> NDArray[np.float64]:
        """Actuator accelerations ``(n, 5)``, deg/s^2: central differences of the rates,
        (r[k+1] - r[k-1]) / (t[k+1] - t[k-1]); one-sided at the first and last row; zeros for one row."""
        r, t = self.q_dot_deg, self.t_s
        if len(t) < 2:
            return np.zeros_like(r)
        out = np.empty_like(r)
        out[1:-1] = (r[2:] - r[:-2]) / (t[2:] - t[:-2])[:, None]
        out[0], out[-1] = (r[1] - r[0]) / (t[1] - t[0]), (r[-1] - r[-2]) / (t[-1] - t[-2])
        return out


def is_program_folder(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a folder holding program.csv or program.json (then it is read as a program)."""
    p = Path(path)
    return p.is_dir() and ((p / CSV_NAME).exists() or (p / JSON_NAME).exists())


def _missing(path: Path) -> InputError:
    return InputError(
        f"{path}: missing (a program folder holds {CSV_NAME} and {JSON_NAME}, as 'arcube program' writes them)"
    )


# ----------------------------------------------------------------------------- program.json

_NUMBERS = (
    "total_s",
    "drilling_s",
    "approach_s",
    "retract_s",
    "transit_s",
    "dt_s",
    "clearance_min_mm",
    "tool_clearance_min_mm",
    "self_clearance_min_mm",
    "eta_L_max",
    "tip_speed_max_transit_mm_s",
    "rows",
    "checked_states",
    "resolution_mm",
)
_TEXTS = (
    "order_method",
    "mode",
    "plan",
    "anatomy",
    "check_engine",
    "timing",
    "clearance_min_at",
    "tool_clearance_min_at",
    "self_clearance_min_at",
    "eta_L_max_at",
)
_NUMBER_MAPS = ("joint_speed_max_deg_s", "joint_accel_max_deg_s2", "limits", "design", "body", "loads")
_OBJECT_LISTS = ("trajectories", "transits")


def _kind(value: Any) -> str:
    """A JSON value's type in words, and the value itself when short (``a number (5)``, ``null``)."""
    if value is None:
        return "null"
    words = _type_words(value)
    return words if isinstance(value, (list, dict)) else f"{words} ({short_repr(value, 40)})"


def _type_words(value: Any) -> str:
    return (
        "null"
        if value is None
        else {
            bool: "a boolean",
            int: "a number",
            float: "a number",
            str: "text",
            list: "a list",
            dict: "an object",
        }.get(type(value), type(value).__name__)
    )


def _check_number(value: Any, where: str, fail: Any, nullable: bool = True) -> None:
    if value is None and nullable:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(f"{where} must be a number{' or null' if nullable else ''}, got {_kind(value)}")
    if not (math.isfinite(value) and abs(value) <= MAX_SUMMARY_NUMBER):
        raise fail(f"{where} must be a finite number within ±{MAX_SUMMARY_NUMBER:g}, got {short_repr(value, 30)}")


def _check_summary(data: Any, fail: Any) -> dict[str, Any]:
    """InputError (through ``fail``) unless the fields the readers use have the writer's types."""
    if not isinstance(data, dict):
        raise fail(f"not a program summary (expected a JSON object, got {_kind(data)})")
    for key in _NUMBERS:
        if key in data:
            _check_number(data[key], key, fail)
    for key in _TEXTS:
        if key in data and data[key] is not None and not isinstance(data[key], str):
            raise fail(f"{key} must be text or null, got {_kind(data[key])}")
    if "order" in data:
        order = data["order"]
        if not isinstance(order, list) or not all(isinstance(k, str) for k in order):
            raise fail(f"order must be a list of trajectory ids (text), got {_kind(order)}")
    for key in _OBJECT_LISTS:
        if key in data and not (isinstance(data[key], list) and all(isinstance(v, dict) for v in data[key])):
            raise fail(f"{key} must be a list of objects, got {_kind(data[key])}")
    for key in _NUMBER_MAPS:
        if key in data:
            table = data[key]
            if not isinstance(table, dict):
                raise fail(f"{key} must be an object of numbers, got {_kind(table)}")
            for name, v in table.items():
                if (
                    key == "design" and name == "mode" and isinstance(v, str)
                ):  # a design's working mode ("+,+,-,+"), checked by Design
                    continue
                _check_number(v, f"{key}.{name}", fail, nullable=key != "design")
    motors = data.get("motors")
    if motors is not None:
        if not isinstance(motors, dict) or not all(isinstance(m, dict) for m in motors.values()):
            raise fail(f"motors must be an object of objects (one per actuator) or null, got {_kind(motors)}")
        for name, figures in motors.items():
            for k, v in figures.items():
                _check_number(v, f"motors.{name}.{k}", fail)
    along = data.get("clearances_along_time")
    if along is not None:
        if not (isinstance(along, dict) and all(isinstance(v, list) for v in along.values())):
            raise fail(f"clearances_along_time must be an object of lists, got {_kind(along)}")
        if len({len(v) for v in along.values()}) > 1:
            raise fail("clearances_along_time: its lists differ in length")
        for k, values in along.items():
            for i, v in enumerate(values):
                _check_number(v, f"clearances_along_time.{k}[{i}]", fail)
    return data


def read_summary(path: str | os.PathLike[str]) -> dict[str, Any]:
    """``program.json`` as a dict, checked (module docstring); InputError naming the file."""
    p = Path(path)
    if not p.exists() and not p.is_symlink():
        raise _missing(p)
    fail = lambda problem: InputError(f"{p}: {problem}")  # noqa: E731
    data = _check_summary(load_json(p, fail=fail, pipes=False), fail)
    where = _not_finite(data)
    if where is not None:  # what the writer never writes (it writes null): damage, in a field the readers use or not
        raise fail(f"{where}: a number beyond the float range (an integer of more than 300 digits, or 1e400)")
    return data


def _not_finite(data: Any) -> str | None:
    """Where the first number that is not finite lies in parsed JSON (``transits[0].s``), None if none does (the
    reader reads an integer of more than 300 digits as a float: inf)."""
    stack: list[tuple[Any, str]] = [(data, "")]
    while stack:
        value, where = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            return where or "the summary"
        if isinstance(value, dict):
            stack.extend((v, f"{where}.{k}" if where else str(k)) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, f"{where}[{i}]") for i, v in enumerate(value))
    return None


# ----------------------------------------------------------------------------- program.csv


def _rows(path: Path) -> tuple[Any, bool]:
    """The parsed table of program.csv and whether it has the torque columns."""
    if not path.exists() and not path.is_symlink():
        raise _missing(path)
    table = parse_table(read_text(path, MAX_PROGRAM_BYTES, pipes=False), os.fspath(path), required=CSV_COLUMNS)
    if not table.rows:
        raise InputError(f"{path}: no rows")
    if len(table.rows) > MAX_PROGRAM_ROWS:
        raise InputError(f"{path}: {len(table.rows)} rows, more than a program may have ({MAX_PROGRAM_ROWS})")
    return table, all(c in table.header for c in TORQUE_COLUMNS)


def _bounded(table: Any, names: tuple[str, ...], limit: float, what: str) -> NDArray[np.float64]:
    values = table.numbers(names, empty=math.nan)
    with np.errstate(invalid="ignore"):
        bad = np.argwhere(np.abs(values) > limit)
    if len(bad):
        i, j = bad[0]
        raise InputError(
            f"{table.where(table.rows[i][0])}: {names[j]} = {values[i, j]:.6g} is beyond ±{limit:g} ({what})"
        )
    return values


def read_program_files(folder: str | os.PathLike[str]) -> ProgramFiles:
    """Read ``folder/program.csv`` and ``folder/program.json`` (module docstring); one InputError
    naming the file, row or field for anything missing, malformed or out of range."""
    root = Path(folder)
    csv_path = root / CSV_NAME
    table, torques = _rows(csv_path)
    summary = read_summary(root / JSON_NAME)
    t = table.column("t_s")
    bad = np.flatnonzero(np.r_[False, np.diff(t) <= 0.0] | (np.abs(t) > 1e9))
    if len(bad):
        raise InputError(
            f"{table.where(table.rows[int(bad[0])][0])}: t_s must increase and stay within ±1e9 s, got {float(t[bad[0]])!r}"
        )
    if summary.get("rows") is not None and summary["rows"] != len(t):
        raise InputError(
            f"{root / JSON_NAME}: rows is {summary['rows']!r}, but {CSV_NAME} has {len(t)}: the two files are not of one "
            "program"
        )
    segment = [cells[table.index("segment")] for _, cells in table.rows]
    odd = next((k for k, s in enumerate(segment) if s not in SEGMENTS), None)
    if odd is not None:
        raise InputError(
            f"{table.where(table.rows[odd][0])}: segment {short_repr(segment[odd], 40)} is not one of {', '.join(SEGMENTS)}"
        )
    E = _bounded(table, POSE_COLUMNS[:3], COORDINATE_LIMIT_MM, "mm: a tip beyond the coordinate range")
    e = _bounded(table, POSE_COLUMNS[3:], 1.0 + _UNIT_TOL, "a unit axis")
    with np.errstate(invalid="ignore"):
        off = np.flatnonzero(np.abs(np.linalg.norm(e, axis=1) - 1.0) > _UNIT_TOL)
    if len(off):
        raise InputError(f"{table.where(table.rows[int(off[0])][0])}: the axis (e_x, e_y, e_z) is not a unit vector")
    q = _bounded(table, JOINTS, MAX_JOINT_VALUE, "deg")
    qd = _bounded(table, tuple(f"{j}_dot" for j in JOINTS), MAX_JOINT_VALUE, "deg/s")
    tau = _bounded(table, TORQUE_COLUMNS, MAX_JOINT_VALUE, "N m") if torques else None
    return ProgramFiles(
        folder=root,
        t_s=t,
        segment=np.array(segment),
        trajectory=np.array([cells[table.index("trajectory")] for _, cells in table.rows]),
        E=E,
        e=e,
        q_deg=q,
        q_dot_deg=qd,
        tau_Nm=tau,
        summary=summary,
    )
