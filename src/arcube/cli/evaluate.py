"""``arcube evaluate``: one design on drilling trajectories (table, JSON, HTML report)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, ClearanceOpt, DesignOpt, EngineOpt, GuardsOpt, IdsOpt, LevelsOpt,
    LinkRadiusOpt, ModeOpt, EncoderOpt, ThrustOpt, LateralForceOpt, StiffnessOpt, loads, MotorLengthOpt, MotorRadiusOpt, PointsOpt, SelfClearanceOpt, SideOpt, TrajOpt, TransformOpt,
    radii,
)  # fmt: skip
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, given_masses, masses_of

__all__ = ["register"]


def evaluate(
    design: DesignOpt = "paper",
    trajectories: TrajOpt = "reference",
    points: PointsOpt = 30,
    mode: ModeOpt = "+,+,+,+",
    guards: GuardsOpt = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object (per-point results and summary).")] = False,
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    transform: TransformOpt = None,
    engine: EngineOpt = "auto",
    report: Annotated[Path | None, typer.Option("--report", help="Also write a self-contained HTML report (plots, 3D mechanism) here.")] = None,
    anatomy: AnatomyOpt = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    clearance: ClearanceOpt = None,
    self_clearance: SelfClearanceOpt = None,
    link_radius: LinkRadiusOpt = 8.0,
    actuator_radius: ActuatorRadiusOpt = 25.0,
    motor_radius: MotorRadiusOpt = 20.0,
    motor_length: MotorLengthOpt = 120.0,
    encoder_deg: EncoderOpt = "0.01",
    thrust: ThrustOpt = 30.0,
    lateral_force: LateralForceOpt = 10.0,
    actuator_stiffness: StiffnessOpt = "1e4",
    wall: WallOpt = None,
    density: DensityOpt = None,
    m_delta: MDeltaOpt = None,
    m_motor: MMotorOpt = None,
    gravity: GravityOpt = None,
) -> None:
    """Evaluate a design on drilling trajectories: reachability, condition numbers, dexterity, and the
    holding torque of MODEL.md 18.2 with the robot's masses (the mass flags' defaults unless given)."""
    from arcube.api import evaluate as evaluate_api
    from arcube.options import GUARDED_OPTIONS, Masses, Options
    from arcube.report import check_report_path, write_report
    from arcube.report.text import print_evaluation

    given = given_masses(wall, density, m_delta, m_motor, gravity)
    # the default mass model, unless the links are too thin for its wall and no mass flag asks for one
    masses = masses_of(given, link_radius) if given or link_radius > Masses().wall_mm else None
    base = GUARDED_OPTIONS if guards else Options()
    if masses is not None:
        base = base.replace(masses=masses, outputs=base.outputs.replace(holding_torque=True))
    result = evaluate_api(
        design, trajectories, points=points, mode=mode, guards=guards, options=base,
        side=side, levels=levels, ids=ids, transform=transform, engine=engine,
        anatomy=anatomy, anatomy_frame=anatomy_frame, clearance=clearance, self_clearance=self_clearance,
        radii=radii(link_radius, actuator_radius, motor_radius, motor_length),
        **loads(encoder_deg, thrust, lateral_force, actuator_stiffness),
    )  # fmt: skip
    if report is not None:
        write_report(result, check_report_path(report, "--report"))  # the error names the flag
    if as_json:
        sys.stdout.write(json.dumps(result.to_json(), allow_nan=False) + "\n")
    else:
        print_evaluation(result)
        if report is not None:
            typer.echo(f"report: {report}")


def register(app: typer.Typer) -> None:
    """Add the ``evaluate`` command to ``app``."""
    app.command("evaluate")(evaluate)
