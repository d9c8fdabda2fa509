"""``arcube program``: the drilling program of a design for a plan (MODEL.md 17), as program.csv and program.json."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.cli.common import (
    ActuatorRadiusOpt, AnatomyFrameOpt, AnatomyOpt, DesignOpt, IdsOpt, LateralForceOpt, LevelsOpt, LinkRadiusOpt, ModeOpt, MotorLengthOpt,
    MotorRadiusOpt, SideOpt, ThrustOpt, TrajOpt, TransformOpt,
)  # fmt: skip
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, flag_message, given_masses, masses_of
from arcube.errors import InputError

__all__ = ["register"]

def _flagged(exc: InputError) -> InputError:
    """The error as the command line prints it (the flag in place of the setting), for in-process callers too."""
    return InputError(flag_message(exc))


def _num(v: Any, unit: str = "") -> str:
    return f"{v:.4g}{unit}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def program(
    out: Annotated[Path | None, typer.Option("--out", help="Folder for program.csv and program.json (created).")] = None,
    design: DesignOpt = "",
    trajectories: TrajOpt = "",
    anatomy: AnatomyOpt = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    mode: ModeOpt = "+,+,+,+",
    order: Annotated[str, typer.Option("--order", help="Trajectory order: shortest (least total time) or given (the plan's).")] = "shortest",
    side: SideOpt = None,
    levels: LevelsOpt = None,
    ids: IdsOpt = None,
    transform: TransformOpt = None,
    standoff: Annotated[float, typer.Option("--standoff", help="The tip waits this far outside the anatomy along its axis (MODEL.md 17.1), mm.")] = 20.0,
    approach_speed: Annotated[float, typer.Option("--approach-speed", help="Standoff -> entry, mm/s.")] = 10.0,
    feed: Annotated[float, typer.Option("--feed", help="Drilling feed, entry -> target, mm/s.")] = 1.5,
    retract_speed: Annotated[float, typer.Option("--retract-speed", help="Target -> standoff, mm/s.")] = 10.0,
    max_joint_speed: Annotated[float, typer.Option("--max-joint-speed", help="Largest actuator rate, deg/s.")] = 30.0,
    max_joint_accel: Annotated[float, typer.Option("--max-joint-accel", help="Largest actuator acceleration, deg/s^2.")] = 120.0,
    max_tip_speed: Annotated[float, typer.Option("--max-tip-speed", help="Largest tip speed in transit, mm/s.")] = 50.0,
    tool_radius: Annotated[float, typer.Option("--tool-radius", help="Radius of the tool E -> H, which clears the anatomy in transit, mm.")] = 1.5,
    dt: Annotated[float, typer.Option("--dt", help="Time step of the rows, s.")] = 0.01,
    clearance: Annotated[float, typer.Option("--clearance", help="Body to anatomy everywhere, mm (with an anatomy).")] = 5.0,
    self_clearance: Annotated[float, typer.Option("--self-clearance", help="Between the body's own parts everywhere, mm.")] = 2.0,
    kappa_max: Annotated[float, typer.Option("--kappa-max", help="Largest eta_L everywhere.")] = 100.0,
    seed: Annotated[int, typer.Option("--seed", help="Random seed of the transit planner (OMPL).")] = 1,
    plan_time: Annotated[float, typer.Option("--plan-time", help="Time budget of one blocked transit's planner, s.")] = 10.0,
    link_radius: LinkRadiusOpt = 8.0,
    actuator_radius: ActuatorRadiusOpt = 25.0,
    motor_radius: MotorRadiusOpt = 20.0,
    motor_length: MotorLengthOpt = 120.0,
    thrust: ThrustOpt = 30.0,
    lateral_force: LateralForceOpt = 10.0,
    wall: WallOpt = None,
    density: DensityOpt = None,
    m_delta: MDeltaOpt = None,
    m_motor: MMotorOpt = None,
    gravity: GravityOpt = None,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress lines (one per transit) on stderr.")] = False,
) -> None:
    """A timed, collision-free joint program that drills every trajectory (MODEL.md 17): program.csv and program.json."""
    from arcube.options import Body, Loads
    from arcube.program import Planner, ProgramLimits
    from arcube.program import program as program_api
    from arcube.program.motors import motor_table_text

    for flag, value in (("--design", design), ("--trajectories", trajectories), ("--out", out)):
        if not value:
            raise InputError(f"{flag} is required" + (" (the program folder)" if flag == "--out" else ""))
    try:
        limits = ProgramLimits(
            standoff_mm=standoff, approach_speed=approach_speed, feed=feed, retract_speed=retract_speed,
            max_joint_speed_deg=max_joint_speed, max_joint_accel_deg=max_joint_accel, max_tip_speed=max_tip_speed,
            tool_radius=tool_radius, dt=dt, clearance=clearance, self_clearance=self_clearance, kappa_max=kappa_max,
        )  # fmt: skip
        body = Body(link_radius=link_radius, actuator_radius=actuator_radius, motor_radius=motor_radius, motor_length=motor_length)
        loads = Loads(thrust_N=thrust, lateral_force_N=lateral_force)
        given = given_masses(wall, density, m_delta, m_motor, gravity)
        masses = masses_of(given, link_radius) if given else None  # None: the program's default masses (MODEL.md 18.1)
        log = None if quiet else (lambda line: sys.stderr.write(line + "\n"))
        prog = program_api(design, trajectories, out, anatomy=anatomy, anatomy_frame=anatomy_frame, mode=mode, order=order, side=side,
                           levels=levels, ids=ids, transform=transform, limits=limits, body=body, planner=Planner(seed=seed, time_s=plan_time),
                           log=log, masses=masses, loads=loads)  # fmt: skip
    except InputError as exc:
        raise _flagged(exc) from None
    s = prog.summary
    sys.stdout.write(
        f"program: order {' '.join(s['order'])}; total {_num(s['total_s'], ' s')} (drilling {_num(s['drilling_s'], ' s')}, "
        f"transit {_num(s['transit_s'], ' s')}); clearance min {_num(s['clearance_min_mm'], ' mm')}, tool {_num(s['tool_clearance_min_mm'], ' mm')}, "
        f"self {_num(s['self_clearance_min_mm'], ' mm')}; eta_L max {_num(s['eta_L_max'])}; "
        f"joint rate max {_num(max(s['joint_speed_max_deg_s'].values()), ' deg/s')}\n{motor_table_text(s)}{prog.path}\n"
    )  # fmt: skip


def register(app: typer.Typer) -> None:
    """Add the ``program`` command to ``app``."""
    app.command("program")(program)
