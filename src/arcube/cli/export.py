"""``arcube export``: a simulation model of a design, assembled at one task point (:mod:`arcube.export.mjcf`),
or at the first row of a drilling program with the program's replay (:mod:`arcube.export.replay`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, DesignOpt, IdsOpt, LevelsOpt, LinkRadiusOpt, ModeOpt,
    MotorLengthOpt, MotorRadiusOpt, PointsOpt, SideOpt, TrajOpt, radii,
)  # fmt: skip
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, given_masses, masses_of
from arcube.errors import InputError

if TYPE_CHECKING:
    from arcube.model.body import BodyRadii
    from arcube.options import Options

__all__ = ["register"]

FORMATS = ("mjcf",)
PLAN_OPTIONS = ("trajectories", "at", "points", "mode", "side", "levels", "ids")
"""Options that pick the task point; a program fixes its own (its first row, its working mode)."""


def export(
    ctx: typer.Context,
    out: Annotated[Path, typer.Option("--out", help="Output file, e.g. robot.xml (written atomically).")],
    design: DesignOpt = "paper",
    fmt_name: Annotated[str, typer.Option("--format", help="Model format: mjcf (MuJoCo XML).")] = "mjcf",
    trajectories: TrajOpt = "reference",
    at: Annotated[str | None, typer.Option("--at", help="Task point to assemble at, ID:K (trajectory id, sample index k); default the first point the design reaches.")] = None,
    c_z: Annotated[float | None, typer.Option("--c-z", help="Second link of the z-leg dyad, mm (default d_z; MODEL.md 6).")] = None,
    points: PointsOpt = 30,
    mode: ModeOpt = "+,+,+,+",
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    anatomy: AnatomyOpt = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    link_radius: LinkRadiusOpt = 8.0,
    actuator_radius: ActuatorRadiusOpt = 25.0,
    motor_radius: MotorRadiusOpt = 20.0,
    motor_length: MotorLengthOpt = 120.0,
    wall: WallOpt = None,
    density: DensityOpt = None,
    m_delta: MDeltaOpt = None,
    m_motor: MMotorOpt = None,
    gravity: GravityOpt = None,
    program: Annotated[Path | None, typer.Option("--program", help="Program folder (arcube program): assemble at its first row and write its replay beside --out (robot.xml -> robot.replay.csv); design: --design, else the folder's.")] = None,
) -> None:
    """Write the mechanism as a simulation model (MuJoCo MJCF) assembled at one task point or a program's first row."""
    from arcube.api import resolve_anatomy
    from arcube.evaluation.result import load_trajectory_set, parse_mode_option
    from arcube.export.mjcf import export_mjcf
    from arcube.io.files import atomic_write_text
    from arcube.model.design import Design
    from arcube.evaluation.bodies import MassModel
    from arcube.options import Masses, Options

    if fmt_name.strip().lower() not in FORMATS:
        raise InputError(f"--format {fmt_name!r}: unknown format (known: {', '.join(FORMATS)})")
    if out.exists() and out.is_dir():
        raise InputError(f"--out {out}: is a folder; give a file path such as robot.xml")
    blocker = next((p for p in out.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        raise InputError(f"--out {out}: cannot write ({blocker} is a file, not a folder)")
    if c_z is not None and not (math.isfinite(c_z) and c_z > 0.0):
        raise InputError(f"--c-z must be a finite number of mm > 0, got {c_z}")
    body = radii(link_radius, actuator_radius, motor_radius, motor_length)
    given = given_masses(wall, density, m_delta, m_motor, gravity)
    if given or link_radius > Masses().wall_mm:
        masses: Any = Options(masses=masses_of(given, link_radius))  # MODEL.md 18.1
    else:  # links too thin for the default wall and no mass flag: a model without the masses (as arcube evaluate)
        masses = MassModel(link_radius_mm=link_radius, wall_mm=link_radius / 2, density_kg_m3=0.0, m_delta_kg=0.0, m_motor_kg=0.0)
        sys.stderr.write(f"note: --link-radius {link_radius:g} mm is not above the default {Masses().wall_mm:g} mm wall: "
                         "exported without the masses of MODEL.md 18.1 (give --wall to have them)\n")
    if program is not None:
        _export_program(ctx, program, out, design, c_z, body, anatomy, anatomy_frame, masses)
        return
    signs = parse_mode_option(mode)
    d = Design.load(design)
    ts = load_trajectory_set(trajectories, points, side, levels, ids)
    anat = resolve_anatomy(anatomy, anatomy_frame, trajectories) if anatomy else None
    text = export_mjcf(d, ts, at=at, points=points, mode=signs, c_z=c_z, radii=body, anatomy=anat, masses=masses)
    try:
        atomic_write_text(out, text)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    sys.stdout.write(f"{out}\n")


def _explicit(ctx: typer.Context, name: str) -> bool:
    """Whether the option of parameter ``name`` was given (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def _export_program(ctx: typer.Context, folder: Path, out: Path, design: str, c_z: float | None, body: BodyRadii, anatomy: list[str] | None,
                    anatomy_frame: str, masses: Options) -> None:  # fmt: skip
    """``--program``: the model at the program's first row and its replay (written atomically, both or none)."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.export.replay import export_program, read_program, write_program_export

    given = [f"--{n.replace('_', '-')}" for n in PLAN_OPTIONS if _explicit(ctx, n)]
    if given:
        raise InputError(f"{', '.join(given)}: not with --program (the model is assembled at the program's first row, in its working mode)")
    try:
        rows = read_program(folder)
        anat = resolve_anatomy(anatomy, anatomy_frame, rows.summary.get("plan")) if anatomy else None
        result = export_program(rows, design if _explicit(ctx, "design") else None, c_z=c_z, radii=body, anatomy=anat, masses=masses)
    except InputError as exc:
        if exc.param in ("program", "design"):
            raise InputError(f"--{exc.param}{str(exc)[len(exc.param):]}") from None
        raise
    try:
        xml_path, csv_path = write_program_export(result, out)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    sys.stdout.write(f"{xml_path}\n{csv_path}\n")


def register(app: typer.Typer) -> None:
    """Add the ``export`` command to ``app``."""
    app.command("export")(export)
