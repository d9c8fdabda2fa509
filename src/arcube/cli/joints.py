"""``arcube joints``: joint angles and rates along the trajectories, as CSV (:mod:`arcube.export.joints`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, ClearanceOpt, DesignOpt, GuardsOpt, IdsOpt, LateralForceOpt, LevelsOpt,
    LinkRadiusOpt, ModeOpt, MotorLengthOpt, MotorRadiusOpt, PointsOpt, SelfClearanceOpt, SideOpt, ThrustOpt, TrajOpt, TransformOpt,
    radii,
)  # fmt: skip
from arcube.errors import InputError

__all__ = ["register"]


def joints(
    out: Annotated[Path, typer.Option("--out", help="Output CSV file (written atomically).")],
    design: DesignOpt = "paper",
    trajectories: TrajOpt = "reference",
    speed: Annotated[float, typer.Option("--speed", help="Drilling speed along each trajectory, mm/s.")] = 1.0,
    points: PointsOpt = 30,
    mode: ModeOpt = "+,+,+,+",
    guards: GuardsOpt = False,
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    transform: TransformOpt = None,
    thrust: ThrustOpt = 30.0,
    lateral_force: LateralForceOpt = 10.0,
    anatomy: AnatomyOpt = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    clearance: ClearanceOpt = None,
    self_clearance: SelfClearanceOpt = None,
    link_radius: LinkRadiusOpt = 8.0,
    actuator_radius: ActuatorRadiusOpt = 25.0,
    motor_radius: MotorRadiusOpt = 20.0,
    motor_length: MotorLengthOpt = 120.0,
) -> None:
    """Joint angles (deg) and rates (deg/s) for drilling each trajectory at --speed mm/s, as CSV."""
    from arcube.evaluation.reference import GUARDED_OPTIONS, Options
    from arcube.evaluation.result import load_task, parse_mode_option
    from arcube.export.joints import joint_trajectory
    from arcube.model.design import Design

    if not (math.isfinite(speed) and speed > 0.0):
        raise InputError(f"--speed must be a finite positive number of mm/s, got {speed}")
    if out.exists() and out.is_dir():
        raise InputError(f"--out {out}: is a folder; give a CSV file path")
    signs = parse_mode_option(mode)
    d = Design.load(design)
    _, task = load_task(trajectories, points, side, levels, ids, transform)
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.evaluation.reference import with_body, with_loads

    opts = with_loads(GUARDED_OPTIONS if guards else Options(), thrust=thrust, lateral_force=lateral_force)
    opts = with_body(opts, clearance=clearance, self_clearance=self_clearance,
                     radii=radii(link_radius, actuator_radius, motor_radius, motor_length))  # fmt: skip
    anat = resolve_anatomy(anatomy, anatomy_frame, trajectories) if anatomy else None
    if opts.clearance_mm is not None and anat is None:
        raise InputError("--clearance needs an anatomy (--anatomy default or mesh files)")
    jt = joint_trajectory(d, task, speed, signs, opts, None if anat is None else anat.distance)
    try:
        path = jt.write_csv(out)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    n_bad = int((~jt.reachable).sum())
    sys.stdout.write(f"{path}\n")
    if n_bad:
        sys.stderr.write(f"note: {n_bad} of {len(jt.reachable)} points are unreachable (empty cells, reachable=false)\n")


def register(app: typer.Typer) -> None:
    """Add the ``joints`` command to ``app``."""
    app.command("joints")(joints)
