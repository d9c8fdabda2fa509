"""The program's files (model §17.3): ``program.csv`` (one row per time step) and ``program.json``
(and, through :func:`arcube.program`, the timeline ``program.png``).

Numbers are written with ``repr`` (the shortest text that reads back to the same float64), so the
forward kinematics of a row's angles reproduces its pose to rounding (far below 1e-6 mm). The files
are written as one (:func:`arcube.io.files.atomic_write_files`): all or none, so a folder never
holds half a program.

The folder (:func:`prepare_folder`, before any work): created if missing; a file there, a folder
that cannot be written, or one that holds an older program (any of :data:`~arcube.io.program_files.PROGRAM_FILES`)
is refused. Replacing an older program silently would lose it; a program folder is like a run
folder, new or without a program, and the message says which file to delete. While a program is
built its folder holds the lock ``.running`` (:mod:`arcube.optimization.lock`): a second
``arcube program`` into the same folder is refused instead of racing the first.
"""

from __future__ import annotations

import io
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube import interrupts
from arcube.errors import InputError
from arcube.io.files import atomic_write_files
from arcube.io.inputs import file_kind, what_is
from arcube.io.program_files import CSV_COLUMNS, CSV_NAME, JOINTS, JSON_NAME, PROGRAM_FILES, TORQUE_COLUMNS
from arcube.optimization.lock import acquire, release

__all__ = ["CSV_COLUMNS", "JOINTS", "TORQUE_COLUMNS", "Program", "prepare_folder", "remove_folder"]


@dataclass(frozen=True, eq=False)
class Program:
    """A timed drilling program: its rows ``(n, ...)`` and its summary (model §17.3)."""

    t_s: NDArray[np.float64]
    """``(n,)`` time of each row, s."""
    segment: NDArray[np.str_]
    """``(n,)`` the piece a row belongs to: approach, drill, retract or transit."""
    trajectory: NDArray[np.str_]
    """``(n,)`` the plan's trajectory id, or ``"a->b"`` in a transit."""
    E: NDArray[np.float64]
    """``(n, 3)`` drill tip, mm, patient frame."""
    e: NDArray[np.float64]
    """``(n, 3)`` unit drill axis, patient frame."""
    q_deg: NDArray[np.float64]
    """``(n, 5)`` the commanded (encoder) actuator angles, deg, in :data:`JOINTS` order (a calibrated design's zero
    offsets not added)."""
    q_dot_deg: NDArray[np.float64]
    """``(n, 5)`` their rates, deg/s."""
    summary: dict[str, Any]
    """program.json's object: the drilling order, the durations, the clearances and joint rates it keeps, its limits
    and what it was built from."""
    path: Path | None = None
    """The folder it was written to or read from (None: only in memory)."""
    tau_Nm: NDArray[np.float64] | None = None
    """``(n, 5)`` actuator torques (gravity, inertia, thrust; model §18.2), N m, when masses were given."""

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

    def write(self, out: str | os.PathLike[str], extra: Mapping[str, bytes] | None = None) -> Path:
        """Write program.csv, program.json and the ``extra`` files (name -> bytes, e.g. the timeline
        PNG) into the folder ``out`` (created), all or none; returns it. OSError names the file at fault."""
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        files = {
            folder / CSV_NAME: self.to_csv().encode("utf-8"),
            folder / JSON_NAME: (json.dumps(self.to_json(), indent=2, allow_nan=False) + "\n").encode("utf-8"),
        }
        files.update({folder / name: data for name, data in (extra or {}).items()})
        atomic_write_files(files)
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


def prepare_folder(out: str | os.PathLike[str]) -> tuple[Path, bool, Path]:
    """Make sure the program can be written into ``out`` before any work (module docstring):
    (folder, created_here, lock). Release the lock with :func:`remove_folder`.

    InputError naming ``out`` when it is a file, cannot be created or written, holds an older
    program, or another process is writing a program into it.
    """
    folder = Path(out)
    created, lock = False, None
    try:
        if folder.exists() and not folder.is_dir():
            raise InputError.of("out", f"{folder}: is {what_is(folder)}, not a folder")
        with interrupts.deferred():  # a folder made and its lock written, or neither
            created = not folder.exists()
            folder.mkdir(parents=True, exist_ok=True)
            lock = acquire(folder)
        older = [name for name in PROGRAM_FILES if os.path.lexists(folder / name)]
        if older:
            shown = [
                name if (folder / name).is_file() else f"{name} ({file_kind(os.lstat(folder / name).st_mode)})"
                for name in older
            ]
            raise InputError.of(
                "out",
                f"{folder}: holds an older program ({', '.join(shown)}); give a new or empty folder, "
                f"or delete {' and '.join(older)} first",
            )
    except BaseException as exc:
        remove_folder(folder, lock, created)
        if isinstance(exc, OSError):
            raise InputError.of("out", f"{folder}: cannot write ({exc.strerror or exc})") from None
        if isinstance(exc, InputError) and exc.param != "out":  # the lock's: another process writes here
            raise InputError.of("out", str(exc)) from None
        raise
    return folder, created, lock


def remove_folder(folder: Path, lock: Path | None = None, created: bool = True) -> None:
    """Release the folder's ``lock`` (if given); remove a folder this run ``created``, if it is then empty (a failed run leaves nothing)."""
    if lock is not None:
        release(lock)
    if created:
        try:
            folder.rmdir()
        except OSError:
            pass
