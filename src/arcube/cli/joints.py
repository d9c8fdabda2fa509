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
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, given_masses, masses_of
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
    wall: WallOpt = None,
    density: DensityOpt = None,
    m_delta: MDeltaOpt = None,
    m_motor: MMotorOpt = None,
    gravity: GravityOpt = None,
) -> None:
    """Joint angles (deg) and rates (deg/s) for drilling each trajectory at --speed mm/s, as CSV. With any
    mass flag (e.g. --gravity 0,0,-9.81 for the defaults) also the holding torque of MODEL.md 18.2 per row."""
    from arcube.options import GUARDED_OPTIONS, Options
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
    body = radii(link_radius, actuator_radius, motor_radius, motor_length)
    changes = {"clearance_mm": clearance, "self_clearance_mm": self_clearance}
    opts = (GUARDED_OPTIONS if guards else Options()).replace(
        thrust_N=thrust, lateral_force_N=lateral_force, link_radius=body.link, actuator_radius=body.actuator, motor_radius=body.motor,
        motor_length=body.motor_length, **{k: v for k, v in changes.items() if v is not None},
    )  # fmt: skip
    given = given_masses(wall, density, m_delta, m_motor, gravity)
    if given:  # the columns of MODEL.md 18.2 (arcube.export.joints.MASS_COLUMNS)
        opts = opts.replace(masses=masses_of(given, link_radius), outputs=opts.outputs.replace(holding_torque=True))
    anat = resolve_anatomy(anatomy, anatomy_frame, trajectories) if anatomy else None
    if opts.guards.clearance_mm is not None and anat is None:
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
