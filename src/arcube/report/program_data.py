"""A drilling program (MODEL.md 17.3) as the report reads it back from its files, ``program.csv`` and
``program.json``, so that a report never recomputes the program (and never imports :mod:`arcube.motion`).

``program.csv``: columns ``t_s, segment, trajectory, E_x, E_y, E_z, e_x, e_y, e_z`` (s; patient frame,
mm), the five actuator angles ``rho_x ... delta_y`` (deg) and rates ``rho_x_dot ... delta_y_dot``
(deg/s); optionally the actuator torques ``tau_rho_x_Nm ... tau_delta_y_Nm`` (N m, MODEL.md 18.2).
Empty cells (non-finite values) read as NaN. ``program.json``: the summary (times, order, smallest
clearances, limits, and, with 18.3, ``motors``). Anything unreadable is a one-line
:class:`~arcube.errors.InputError` naming the file.
"""

from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.evaluation.performance import ACTUATOR_NAMES as JOINTS  # q's order in a program (arcube.motion.output.JOINTS)

__all__ = ["CSV_NAME", "JOINTS", "JSON_NAME", "TORQUE_COLUMNS", "ProgramFiles", "Span", "envelope", "find_design", "is_program_folder",
           "read_program"]  # fmt: skip

CSV_NAME, JSON_NAME = "program.csv", "program.json"
POSE_COLUMNS = ("E_x", "E_y", "E_z", "e_x", "e_y", "e_z")
NUMERIC_COLUMNS: tuple[str, ...] = (*POSE_COLUMNS, *JOINTS, *(f"{j}_dot" for j in JOINTS))
"""The numeric columns every program.csv has, after ``t_s, segment, trajectory``."""
TORQUE_COLUMNS: tuple[str, ...] = tuple(f"tau_{j}_Nm" for j in JOINTS)
"""The optional actuator torque columns (N m), in :data:`JOINTS` order."""


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
    """A program folder's contents: ``n`` rows and the summary of program.json."""

    folder: Path
    t_s: NDArray[np.float64]  # (n,) s
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
        """program.json's ``motors``: per actuator name its sizing figures (MODEL.md 18.3), or None."""
        m = self.summary.get("motors")
        return {str(k): v for k, v in m.items() if isinstance(v, dict)} if isinstance(m, dict) and m else None

    def spans(self) -> list[Span]:
        """The runs of equal (segment, trajectory) rows, in time order."""
        out: list[Span] = []
        n, start = len(self.t_s), 0
        for i in range(1, n + 1):
            if i == n or self.segment[i] != self.segment[start] or self.trajectory[i] != self.trajectory[start]:
                end_t = self.t_s[i] if i < n else self.t_s[n - 1]
                out.append(Span(start, i - 1, str(self.segment[start]), str(self.trajectory[start]), float(self.t_s[start]), float(end_t)))
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
    return p.is_dir() and ((p / CSV_NAME).is_file() or (p / JSON_NAME).is_file())


def _read_summary(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: missing (a program folder holds program.csv and program.json)") from None
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise InputError(f"{path}: not a readable program summary ({type(exc).__name__}: {' '.join(str(exc).split())[:160]})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: not a program summary (expected a JSON object, got {type(data).__name__})")
    return data


def _number(text: str, path: Path, line: int, column: str) -> float:
    if text == "":
        return math.nan  # the program writes non-finite values as empty cells
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{path}: line {line}, column {column}: not a number ({text[:40]!r})") from None


def read_program(folder: str | os.PathLike[str]) -> ProgramFiles:
    """Read ``folder/program.csv`` and ``folder/program.json``; InputError (one line, naming the file) if
    either is missing or malformed: a missing column, a short row, a cell that is not a number, no rows,
    or times that do not increase."""
    root = Path(folder)
    csv_path = root / CSV_NAME
    try:
        with csv_path.open(encoding="utf-8", newline="") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise InputError(f"{csv_path}: missing (a program folder holds program.csv and program.json)") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{csv_path}: unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:160]})") from None
    summary = _read_summary(root / JSON_NAME)
    if not rows:
        raise InputError(f"{csv_path}: empty (no header)")
    header = [h.strip() for h in rows[0]]
    col = {h: i for i, h in enumerate(header)}
    missing = [c for c in ("t_s", "segment", "trajectory", *NUMERIC_COLUMNS) if c not in col]
    if missing:
        raise InputError(f"{csv_path}: not a program (missing column(s) {', '.join(missing)})")
    torques = all(c in col for c in TORQUE_COLUMNS)
    numeric = ["t_s", *NUMERIC_COLUMNS, *(TORQUE_COLUMNS if torques else ())]
    body = [(k + 2, r) for k, r in enumerate(rows[1:]) if any(c.strip() for c in r)]
    if not body:
        raise InputError(f"{csv_path}: no rows")
    data = np.empty((len(body), len(numeric)))
    segment, trajectory = [], []
    for k, (line, r) in enumerate(body):
        if len(r) != len(header):
            raise InputError(f"{csv_path}: line {line}: {len(r)} cells, the header has {len(header)}")
        data[k] = [_number(r[col[c]].strip(), csv_path, line, c) for c in numeric]
        segment.append(r[col["segment"]].strip())
        trajectory.append(r[col["trajectory"]].strip())
    t = data[:, 0]
    bad = np.flatnonzero(~np.isfinite(t) | np.r_[False, np.diff(t) <= 0.0])
    if len(bad):
        raise InputError(f"{csv_path}: line {body[int(bad[0])][0]}: t_s must be finite and increase, got {t[bad[0]]!r}")
    at = {c: j for j, c in enumerate(numeric)}
    cols = lambda names: data[:, [at[c] for c in names]]  # noqa: E731
    return ProgramFiles(
        folder=root, t_s=t.copy(), segment=np.array(segment), trajectory=np.array(trajectory), E=cols(POSE_COLUMNS[:3]),
        e=cols(POSE_COLUMNS[3:]), q_deg=cols(JOINTS), q_dot_deg=cols([f"{j}_dot" for j in JOINTS]),
        tau_Nm=cols(TORQUE_COLUMNS) if torques else None, summary=summary,
    )  # fmt: skip


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
