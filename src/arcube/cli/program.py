"""``arcube program``: the drilling program of a design for a plan (model §17), as program.csv and program.json."""

from __future__ import annotations

import math
import sys
from typing import Any

import typer

from arcube.cli.common import (
    DESIGN,
    MODE,
    OUT,
    PATIENT,
    QUIET,
    SELECTION,
    TRAJECTORIES,
    TRANSFORM,
    one_plan,
    options_of,
    plan_request,
    masses_given,
    request_flags,
    with_help,
)
from arcube.cli.projection import Given, command, model_flags, option
from arcube.motion.limits import Planner, ProgramLimits


__all__ = ["register"]

FOLDER = with_help(
    OUT,
    "Folder for program.csv, program.json and program.png (created; one that holds an older program is refused).",
    required=True,
)
ORDER = option(
    "--order",
    "Trajectory order: shortest (least total time) or given (the plan's). [default: shortest]",
    params=("order",),
)
FLAGS = [
    FOLDER,
    with_help(DESIGN, DESIGN.help.split(" [")[0], required=True),
    with_help(TRAJECTORIES, TRAJECTORIES.help.split(" [")[0], required=True),
    *PATIENT,
    MODE,
    ORDER,
    *SELECTION,
    TRANSFORM,
    *model_flags(ProgramLimits, "limits"),
    *model_flags(Planner, "planner"),
    *request_flags("body"),
    *[f for f in request_flags("loads") if f.key in ("options.loads.thrust_N", "options.loads.lateral_force_N")],
    *request_flags("masses"),
    with_help(QUIET, "No progress lines (one per transit) on stderr."),
]


def _num(v: Any, unit: str = "") -> str:
    return f"{v:.4g}{unit}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def program(given: Given) -> None:
    """A timed, collision-free joint program that drills every trajectory (model §17): program.csv and program.json."""
    from arcube.api import program as program_api
    from arcube.motion.motors import motor_table_text

    limits = ProgramLimits().merged(given.tree("limits"))
    planner = Planner().merged(given.tree("planner"))
    options = options_of(given, guarded=False)
    log = None if given.get("quiet") else (lambda line: sys.stderr.write(line + "\n"))
    kw = {k: given.get(k) for k in ("mode", "order") if k in given}
    prog = program_api(
        given.get("design"),
        one_plan(given),
        given.get("out"),
        options=options,
        limits=limits,
        planner=planner,
        log=log,
        masses=True if masses_given(given) else None,
        **kw,
        **plan_request(given),
    )
    s = prog.summary
    sys.stdout.write(
        f"program: order {' '.join(s['order'])}; total {_num(s['total_s'], ' s')} (drilling {_num(s['drilling_s'], ' s')}, "
        f"transit {_num(s['transit_s'], ' s')}); clearance min {_num(s['clearance_min_mm'], ' mm')}, tool {_num(s['tool_clearance_min_mm'], ' mm')}, "
        f"self {_num(s['self_clearance_min_mm'], ' mm')}; eta_L max {_num(s['eta_L_max'])}; "
        f"joint rate max {_num(max(s['joint_speed_max_deg_s'].values()), ' deg/s')}\n{motor_table_text(s)}{prog.path}\n"
    )


def register(app: typer.Typer) -> None:
    """Add the ``program`` command to ``app``."""
    command(app, "program", FLAGS, program, help=program.__doc__ or "")
