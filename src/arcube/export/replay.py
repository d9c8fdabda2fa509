"""A drilling program (model §17) as a MuJoCo model and a replay of its joint targets.

:func:`export_program` reads a program (the folder that ``arcube program`` writes, or a
:class:`~arcube.motion.Program`) and returns

* the MJCF of :mod:`arcube.export.mjcf` for the program's design, **assembled at the program's
  first row** (its keyframe ``assembled`` is that state, ctrl included), with the masses of model
  §18.1 (:mod:`arcube.export.inertia`);
* the **replay**, a CSV with one row per row of ``program.csv`` (:data:`REPLAY_COLUMNS`):

  - ``t_s``, ``segment``, ``trajectory``: as in ``program.csv`` (s; approach, drill, retract, transit);
  - ``E_x_mm`` .. ``E_z_mm``, ``e_x`` .. ``e_z``: the program's drill tip E (mm) and axis e in the
    patient frame, which is MuJoCo's world frame;
  - ``ctrl_rho_x`` .. ``ctrl_delta_y``: the targets of the five position actuators, in the model's
    actuator order (rad): the program's angles, deg -> rad;
  - ``qvel_rho_x`` .. ``qvel_delta_y``: their rates (rad/s);
  - ``qpos_rho_x`` .. ``qpos_tau_y``: every hinge (rad, :data:`~arcube.export.mjcf.JOINT_NAMES`,
    MuJoCo's ``qpos`` order): the actuated ones as ``ctrl_*``, the passive ones from the IK,
    continuous along the rows from the keyframe's.

  A controller sets ``data.ctrl`` to the row's targets at ``t_s``; a viewer may set ``data.qpos`` to the
  row's ``qpos_*`` (kinematic replay). ``examples/mujoco_replay.py`` adds the torque that the motion
  needs (MuJoCo's inverse dynamics projected through the loops) as a feed-forward and interpolates
  between rows.

The program's angles are the IK's up to whole turns of delta (a program keeps delta continuous), so
the model's actuated hinges take the program's first-row angles as their reference: a target never
asks for a spurious turn. Before writing, the design is checked against the program: at every row its
IK at (E, e), in the program's working mode, must give the program's five angles (mod 2 pi) within
:data:`ANGLE_TOL_RAD`; else :class:`InputError` (another design's program). The z dyad must close with
c_z at every row (as at every plan point in :func:`~arcube.export.mjcf.export_mjcf`).

The design: the caller's, else the one the program folder records: a ``design`` object in
``program.json`` (name -> value), a ``design.json`` in the folder, or, for the ``program/`` folder of
an ``arcube design`` job (``design.toml`` beside it, or its ``summary.json`` lists the folder under
``files.program``), the job's ``design.json``; ``arcube report`` prefers the recorded design the same way.
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT, parse_mode
from arcube.errors import InputError
from arcube.export.angles import ACTUATED, JOINT_NAMES, joint_values
from arcube.export.mjcf import check_z_dyad, checked_inputs, model_xml, with_c_z
from arcube.io.files import atomic_write_files
from arcube.io.inputs import load_json
from arcube.io.program_files import CSV_NAME, JSON_NAME, read_program_files
from arcube.model.design import Design
from arcube.model.mechanism import format_mode, inverse_kinematics
from arcube.options import Options, request_options
from arcube.motion.output import Program

__all__ = [
    "ANGLE_TOL_RAD",
    "REPLAY_COLUMNS",
    "ProgramExport",
    "export_program",
    "read_program",
    "recorded_design",
    "replay_path",
    "write_program_export",
]

REPLAY_COLUMNS: tuple[str, ...] = (
    "t_s",
    "segment",
    "trajectory",
    "E_x_mm",
    "E_y_mm",
    "E_z_mm",
    "e_x",
    "e_y",
    "e_z",
    *(f"ctrl_{n}" for n in ACTUATED),
    *(f"qvel_{n}" for n in ACTUATED),
    *(f"qpos_{n}" for n in JOINT_NAMES),
)
"""Columns of the replay CSV (module docstring): s, mm, unit vector, rad, rad/s, rad."""
ANGLE_TOL_RAD = 1.0e-6
"""Largest difference (rad, mod 2 pi) between the design's IK and a program row's angle: the rows are
written with ``repr`` and reproduce their pose to rounding, so any real mismatch is far larger."""


@dataclass(frozen=True)
class ProgramExport:
    """What :func:`export_program` returns: the MJCF text, the replay CSV text, and the design used."""

    xml: str
    replay_csv: str
    design: Design
    rows: int


def read_program(folder: str | os.PathLike[str]) -> Program:
    """The program in ``folder``, read by :func:`arcube.io.program_files.read_program_files` (the one
    reader of program folders: its limits and checks); columns beyond model §17.3's, such as
    ``tau_*_Nm``, are ignored. InputError naming ``program`` and the file for a missing, unreadable or
    damaged file, or a cell the replay cannot use (empty or not finite)."""
    path = Path(folder)
    if not path.is_dir():
        raise InputError.of(
            "program",
            f"{path}: {'no such folder' if not path.exists() else 'not a folder'} (give the folder that 'arcube program' wrote)",
        )
    try:
        files = read_program_files(path)
    except InputError as exc:
        raise InputError.of("program", str(exc)) from None
    table = np.column_stack([files.t_s, files.E, files.e, files.q_deg, files.q_dot_deg])
    bad = np.flatnonzero(~np.all(np.isfinite(table), axis=1))
    if len(bad):
        raise InputError.of(
            "program",
            f"{path / CSV_NAME}: data row {int(bad[0]) + 1} has an empty or non-finite pose, angle or rate (the replay needs every one)",
        )
    kept = ("t_s", "segment", "trajectory", "E", "e", "q_deg", "q_dot_deg", "summary")  # not tau_Nm
    return Program(**{name: getattr(files, name) for name in kept}, path=path)


def _rows_of(program: Any) -> Program:
    if isinstance(program, Program):
        return program
    if isinstance(program, (str, os.PathLike)):
        return read_program(program)
    raise InputError.of(
        "program", f"must be a program folder or an arcube.motion.Program, got {type(program).__name__}"
    )


def recorded_design(rows: Program) -> Design | None:
    """The design a program records (module docstring), or None."""
    recorded = rows.summary.get("design")
    if isinstance(recorded, dict):
        return Design.from_dict(recorded, source="program.json design")
    if rows.path is None:
        return None
    folder = rows.path.resolve()
    if (folder / "design.json").is_file():
        return Design.from_json(folder / "design.json")
    job = folder.parent
    if not (job / "design.json").is_file():
        return None
    try:
        summary = load_json(job / "summary.json")
    except InputError:  # no job summary, or an unreadable one: design.toml alone decides
        summary = {}
    files = summary.get("files", {}) if isinstance(summary, dict) else {}
    if (job / "design.toml").is_file() or (isinstance(files, dict) and files.get("program") == folder.name):
        return Design.from_json(job / "design.json")
    return None


def _check_angles(
    params: NDArray[np.float64], rows: Program, signs: NDArray[np.float64], q0_deg: NDArray[np.float64]
) -> None:
    """InputError unless the design's IK at every row, less a calibrated design's zero offsets ``q0_deg``
    ``(5,)`` (model §21.4: what the controller commands), gives the row's five angles (mod 2 pi)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, rows.E, rows.e, signs)
    ik = np.concatenate([sol.rho, sol.delta], axis=-1) - np.radians(q0_deg)  # (n, 5) rad
    diff = np.abs(np.remainder(ik - np.radians(rows.q_deg) + np.pi, 2.0 * np.pi) - np.pi)
    bad = ~(diff <= ANGLE_TOL_RAD)  # NaN (no IK) counts as bad
    if not bad.any():
        return
    i, j = np.argwhere(bad)[0]
    at = f"row {i} (t = {rows.t_s[i]:.6g} s, {rows.segment[i]} {rows.trajectory[i]})"
    if not np.isfinite(ik[i, j]):
        problem = f"has no IK solution at {at} in mode {format_mode(signs)}"
    else:
        problem = f"gives {ACTUATED[j]} = {math.degrees(ik[i, j]):.6g} deg at {at} where the program has {rows.q_deg[i, j]:.6g} deg"
    raise InputError.of("design", f"does not run this program: it {problem}; give the program's own design")


def export_program(
    program: Any,
    design: Design | Any = None,
    *,
    c_z: float | None = None,
    options: Options | None = None,
    anatomy: Any = None,
    masses: bool | None = None,
    **changes: Any,
) -> ProgramExport:
    """The MJCF of a program's design assembled at its first row, and the replay CSV (module docstring).

    Parameters
    ----------
    program : a program folder (``program.csv``, ``program.json``) or a :class:`~arcube.motion.Program`.
    design : a :class:`Design`, preset name, design JSON path or vector; None: the one the program
        records (:func:`recorded_design`), else InputError naming ``design``.
    c_z, options, anatomy, masses, changes : as in :func:`~arcube.export.mjcf.export_mjcf` (``c_z`` deprecated: the
        design's own).

    Raises :class:`InputError` for an unreadable program, no design, a design whose IK does not give
    the program's angles, or a z dyad that cannot close with c_z at every row.
    """
    opts = request_options(options, **changes)
    rows = _rows_of(program)
    if len(rows.t_s) == 0:
        raise InputError.of("program", "has no rows")
    if design is None:
        design = recorded_design(rows)
        if design is None:
            raise InputError.of(
                "design",
                "is required: the program records no design (none in program.json, no design.json in the folder or in an 'arcube design' job around it)",
            )
    d = Design.coerce(with_c_z(design, c_z, "export_program"))
    mode = rows.summary.get("mode")
    mode = DEFAULT_MODE_TEXT if mode is None else mode
    try:  # the program's own mode: a bad one is the program's fault, not a flag's
        if not isinstance(mode, str):
            raise ValueError(f"must be text like '+,+,-,+', got {type(mode).__name__}")
        parse_mode(mode)
    except ValueError as exc:
        source = "the program's summary" if rows.path is None else rows.path / JSON_NAME
        raise InputError.of("program", f"{source}: mode: {exc}") from None
    robot = checked_inputs(d, mode)
    params, signs, cz = robot
    _check_angles(params, rows, signs, d.q0)
    check_z_dyad(params, rows.E, rows.e, signs, cz, "rows of the program")
    real_deg = rows.q_deg + d.q0  # the joints' real angles: the commanded ones plus a calibrated design's zero offsets
    q0 = np.radians(real_deg[0])
    source = "the program" if rows.path is None else f"the program {rows.path}"
    where = f"row 0 of {source} (t = {rows.t_s[0]:.6g} s, {rows.segment[0]} {rows.trajectory[0]})"
    note = f"Replay: CSV beside this file (<name>.replay.csv), {len(rows.t_s)} rows: ctrl_* targets (rad) at t_s."
    xml = model_xml(
        robot,
        rows.E[0],
        rows.e[0],
        anatomy,
        where,
        options=opts,
        masses=masses,
        actuated={n: float(q0[i]) for i, n in enumerate(ACTUATED)},
        note=note,
    )
    qpos = joint_values(params, rows.E, rows.e, signs, c_z=cz)
    passive = {n: np.unwrap(qpos[n]) for n in JOINT_NAMES if n not in ACTUATED}  # continuous along the rows
    full = np.stack(
        [passive[n] if n in passive else np.radians(real_deg[:, ACTUATED.index(n)]) for n in JOINT_NAMES], axis=1
    )
    return ProgramExport(xml, _replay_csv(rows, full, real_deg), d, len(rows.t_s))


def _num(v: float) -> str:
    return repr(float(v) + 0.0)


def _replay_csv(rows: Program, qpos: NDArray[np.float64], real_deg: NDArray[np.float64]) -> str:
    """The replay's text: per row, the targets (the joints' real angles ``real_deg`` ``(n, 5)``), rates and every hinge."""
    buf = io.StringIO()
    buf.write(",".join(REPLAY_COLUMNS) + "\n")
    q, qd = np.radians(real_deg), np.radians(rows.q_dot_deg)
    for i in range(len(rows.t_s)):
        nums = (*rows.E[i], *rows.e[i], *q[i], *qd[i], *qpos[i])
        buf.write(f"{_num(rows.t_s[i])},{rows.segment[i]},{rows.trajectory[i]},{','.join(_num(v) for v in nums)}\n")
    return buf.getvalue()


def replay_path(model_path: str | os.PathLike[str]) -> Path:
    """Where the replay of a model file goes: ``robot.xml`` -> ``robot.replay.csv`` (same folder)."""
    p = Path(model_path)
    return p.with_name(p.stem + ".replay.csv")


def write_program_export(export: ProgramExport, model_path: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write the model to ``model_path`` and the replay beside it (:func:`replay_path`) as one output
    (:func:`arcube.io.files.atomic_write_files`): both or none, the existing files kept if either cannot
    be written. Returns both paths; OSError naming the file at fault (e.g. a folder where the replay goes)."""
    xml_path, csv_path = Path(model_path), replay_path(model_path)
    atomic_write_files({xml_path: export.xml.encode("utf-8"), csv_path: export.replay_csv.encode("utf-8")})
    return xml_path, csv_path
