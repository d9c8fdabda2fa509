"""``arcube export``: a simulation model of a design, assembled at one task point (:mod:`arcube.export.mjcf`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, DesignOpt, IdsOpt, LevelsOpt, LinkRadiusOpt, ModeOpt,
    MotorLengthOpt, MotorRadiusOpt, PointsOpt, SideOpt, TrajOpt, radii,
)  # fmt: skip
from arcube.errors import InputError

__all__ = ["register"]

FORMATS = ("mjcf",)


def export(
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
) -> None:
    """Write the mechanism as a simulation model (MuJoCo MJCF) assembled at one task point."""
    from arcube.api import resolve_anatomy
    from arcube.evaluation.result import load_trajectory_set, parse_mode_option
    from arcube.export.mjcf import export_mjcf
    from arcube.io.files import atomic_write_text
    from arcube.model.design import Design

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
    signs = parse_mode_option(mode)
    d = Design.load(design)
    ts = load_trajectory_set(trajectories, points, side, levels, ids)
    anat = resolve_anatomy(anatomy, anatomy_frame, trajectories) if anatomy else None
    text = export_mjcf(d, ts, at=at, points=points, mode=signs, c_z=c_z, radii=body, anatomy=anat)
    try:
        atomic_write_text(out, text)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    sys.stdout.write(f"{out}\n")


def register(app: typer.Typer) -> None:
    """Add the ``export`` command to ``app``."""
    app.command("export")(export)
