"""The program's files (MODEL.md 17.3): ``program.csv`` (one row per time step) and ``program.json``.

Numbers are written with ``repr`` (the shortest text that reads back to the same float64), so the
forward kinematics of a row's angles reproduces its pose to rounding (far below 1e-6 mm). Both
files are written atomically (temporary file, then rename); if the second cannot be written the
first is removed again, so a folder never holds half a program.
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.io.files import atomic_write_text

__all__ = ["CSV_COLUMNS", "JOINTS", "TORQUE_COLUMNS", "Program", "prepare_folder", "remove_folder"]

JOINTS = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuators, in q's order."""
CSV_COLUMNS: tuple[str, ...] = (
    "t_s", "segment", "trajectory", "E_x", "E_y", "E_z", "e_x", "e_y", "e_z", *JOINTS, *(f"{j}_dot" for j in JOINTS),
)  # fmt: skip
"""Columns of ``program.csv`` (MODEL.md 17.3): s; patient frame, mm; deg; deg/s."""
TORQUE_COLUMNS: tuple[str, ...] = tuple(f"tau_{j}_Nm" for j in JOINTS)
"""Columns appended to ``program.csv`` when the program has its actuator torques (MODEL.md 18.2), N m."""
CSV_NAME, JSON_NAME = "program.csv", "program.json"


@dataclass(frozen=True, eq=False)
class Program:
    """A timed drilling program: its rows and its summary (MODEL.md 17.3).

    Rows ``(n, ...)``: ``t_s`` time, ``segment`` (approach, drill, retract, transit), ``trajectory``
    (the plan's id, or ``"a->b"`` in a transit), ``E`` tip and ``e`` axis (patient frame, mm),
    ``q_deg`` the five actuator angles and ``q_dot_deg`` their rates (deg, deg/s), in :data:`JOINTS` order;
    ``tau_Nm`` the actuator torques (gravity, inertia, thrust; MODEL.md 18.2) when masses were given.
    """

    t_s: NDArray[np.float64]
    segment: NDArray[np.str_]
    trajectory: NDArray[np.str_]
    E: NDArray[np.float64]
    e: NDArray[np.float64]
    q_deg: NDArray[np.float64]
    q_dot_deg: NDArray[np.float64]
    summary: dict[str, Any]
    path: Path | None = None
    tau_Nm: NDArray[np.float64] | None = None

    @property
    def order(self) -> list[str]:
        """The trajectory ids in the order they are drilled."""
        return list(self.summary["order"])

    @property
    def total_s(self) -> float:
        """The program's duration, s."""
        return float(self.summary["total_s"])

    def to_csv(self) -> str:
        """The text of ``program.csv``."""
        buf = io.StringIO()
        tau = self.tau_Nm
        buf.write(",".join(CSV_COLUMNS + (TORQUE_COLUMNS if tau is not None else ())) + "\n")
        for i in range(len(self.t_s)):
            nums = (*self.E[i], *self.e[i], *self.q_deg[i], *self.q_dot_deg[i], *(tau[i] if tau is not None else ()))
            buf.write(f"{_num(self.t_s[i])},{self.segment[i]},{self.trajectory[i]},{','.join(_num(v) for v in nums)}\n")
        return buf.getvalue()

    def to_json(self) -> dict[str, Any]:
        """The object of ``program.json`` (non-finite numbers as null)."""
        return _clean(self.summary)

    def write(self, out: str | os.PathLike[str]) -> Path:
        """Write both files into the folder ``out`` (created); returns it."""
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        csv_path = folder / CSV_NAME
        atomic_write_text(csv_path, self.to_csv())
        try:
            atomic_write_text(folder / JSON_NAME, json.dumps(self.to_json(), indent=2, allow_nan=False) + "\n")
        except BaseException:
            csv_path.unlink(missing_ok=True)
            raise
        return folder


def _num(v: float) -> str:
    return repr(float(v)) if math.isfinite(v) else ""


def _clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def prepare_folder(out: str | os.PathLike[str]) -> tuple[Path, bool]:
    """Make sure the program can be written into ``out`` before any work: (folder, created_here).

    InputError naming ``out`` when it is a file, cannot be created, or cannot be written.
    """
    folder = Path(out)
    created = False
    try:
        if folder.exists() and not folder.is_dir():
            raise InputError.of("out", f"{folder}: is a file, not a folder")
        created = not folder.exists()
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".program-write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        if created:
            remove_folder(folder)
        raise InputError.of("out", f"{folder}: cannot write ({exc.strerror or exc})") from None
    return folder, created


def remove_folder(folder: Path) -> None:
    """Remove a folder this run created, if it is still empty (a failed run leaves nothing)."""
    try:
        folder.rmdir()
    except OSError:
        pass
