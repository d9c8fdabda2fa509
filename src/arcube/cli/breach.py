"""``arcube breach``: how likely each screw is to leave its pedicle, and what decides it (the model, section 22)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import typer

from arcube.accuracy.settings import ToleranceSettings
from arcube.cli.common import (
    SELECTION,
    DESIGN,
    MODE,
    OUT,
    TRAJECTORIES,
    one_plan,
    plan_request,
    request_flags,
    with_help,
)
from arcube.cli.projection import Given, command, model_flags, option
from arcube.errors import InputError
from arcube.pedicles.settings import BreachSettings

__all__ = ["register"]

CALIBRATION = option(
    "--calibration",
    "The folder of arcube calibrate identify: its calibrated design, the robot's errors drawn from the "
    "identification's covariance (instead of --class, --tol and the other tolerance flags).",
    Path,
    params=("calibration",),
)
FLAGS = [
    with_help(DESIGN, "The robot: a design file, or a design job's design.json (each side drilled from its docking)."),
    CALIBRATION,
    with_help(TRAJECTORIES, TRAJECTORIES.help.split(" [")[0], required=True),
    *SELECTION,
    MODE,
    *model_flags(
        ToleranceSettings, "tolerances", skip=("samples", "seed", "docking_mm", "docking_deg", "distribution")
    ),
    *model_flags(BreachSettings, "breach"),
    *[f for f in request_flags("loads") if f.key in ("options.loads.thrust_N", "options.loads.actuator_stiffness")],
    with_help(OUT, "Folder for breach.csv, summary.json and the pictures (created; new or empty).", required=True),
]


def _pct(v: Any) -> str:
    return f"{100 * v:.1f} %" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def breach(given: Given) -> None:
    """The probability that each screw of the plan breaches its pedicle, with the robot as built (or calibrated), the
    registration and the deflection under thrust; which of them decides each screw (the model, section 22)."""
    from arcube.options import Loads
    from arcube.pedicles.run import breach as breach_api

    if given.get("design") is None and given.get("calibration") is None:
        raise InputError(f"{DESIGN.name} or {CALIBRATION.name} is required")
    told = [given.flag(k) for k in given.values if k.startswith("tolerances.")]
    if told and given.get("calibration") is not None:
        raise InputError(
            f"{CALIBRATION.name} and {', '.join(told)}: the calibration's covariance gives the robot's errors "
            f"({CALIBRATION.name} is instead of {' and '.join(told)}); give one"
        )
    tolerances = ToleranceSettings().merged(given.tree("tolerances")) if told else None
    settings = BreachSettings().merged(given.tree("breach"))
    loads = Loads().merged(given.tree("options.loads"))
    result = breach_api(
        given.get("design"),
        one_plan(given),
        given.get("out"),
        calibration=given.get("calibration"),
        mode=given.get("mode"),
        tolerances=tolerances,
        settings=settings,
        loads=loads,
        **plan_request(given),
    )
    rows, s = result.rows(), result.summary()
    typer.echo(
        f"{'screw':<8} {'level':<5} {'side':<4} {'room':>6} {'P(breach)':>10} {'95 % interval':>16} {'major':>7} {'robot':>7} "
        f"{'regist.':>8} {'deflect.':>8}"
    )
    for r in rows:
        interval = f"{_pct(r['p_breach_low'])}-{_pct(r['p_breach_high'])}"
        typer.echo(
            f"{r['trajectory']:<8} {r['level']:<5} {r['side']:<4} {r['room_mm']:>5.2f}  {_pct(r['p_breach']):>10} {interval:>16} "
            f"{_pct(r['p_major']):>7} {_pct(r['p_robot_alone']):>7} {_pct(r['p_registration_alone']):>8} {_pct(r['p_deflection_alone']):>8}"
            + ("  too wide" if r["too_wide"] else "")
        )
    worst = s["worst_screw"]
    robot = (
        "calibrated"
        if given.get("calibration")
        else f"built to ISO 2768-{(tolerances or ToleranceSettings()).tolerance_class}"
    )
    typer.echo(
        f"the robot {robot}, registration {settings.registration_mm:g} mm / {settings.registration_deg:g} deg RMS, thrust "
        f"{loads.thrust_N:g} N, {settings.samples} samples: the largest P(breach) is {_pct(s['breach_probability'])} (screw {worst}); "
        f"expected breached screws {s['expected_breaches']:.2f} of {len(rows)}"
    )
    if s["too_wide"]:
        typer.echo(f"  too wide for their pedicle (P = 1 whatever the errors): {', '.join(s['too_wide'])}")
    typer.echo(f"results in {given.get('out')}")


def register(app: typer.Typer) -> None:
    """Add the ``breach`` command to ``app``."""
    command(app, "breach", FLAGS, breach, help=breach.__doc__ or "")
