"""``arcube breach``: how likely each screw is to leave its pedicle, and what decides it (the model, section 22)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import typer

from arcube.accuracy.settings import ToleranceSettings
from arcube.cli.common import (
    SELECTION,
    DESIGN,
    MODE,
    OUT,
    PATIENT,
    TRAJECTORIES,
    check_class_counts,
    file_path,
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
MARKUPS = option(
    "--markups",
    "Also write the screws as a 3D Slicer line markups file (FILE.mrk.json, new): each screw a line, its target "
    "point's description its P(breach), status, deciding source and docking.",
    Path,
    params=("markups",),
    parse=file_path("screws.mrk.json"),
)
DOCK_EVALUATIONS = option(
    "--dock-evaluations",
    "The search budget of a side the robot file has no docking of, docked first as arcube dock docks it (its "
    "--evaluations). [default: 6000]",
    int,
    params=("dock_evaluations",),
)
FLAGS = [
    with_help(
        DESIGN,
        "The robot: a design job's design.json (each side drilled from its docking of this plan, or docked first as "
        "arcube dock docks it), a docking's design file (refused on another patient's plan), or a design file.",
    ),
    CALIBRATION,
    with_help(TRAJECTORIES, TRAJECTORIES.help.split(" [")[0], required=True),
    *SELECTION,
    MODE,
    *[
        with_help(
            f,
            f.help.replace("[default: none]", "[default: default, as arcube dock]")
            + (
                " Default: the plan's default anatomy where it has one (as arcube dock), else none."
                if f.name == "--anatomy"
                else ""
            ),
        )
        for f in PATIENT
    ],
    *model_flags(
        ToleranceSettings, "tolerances", skip=("samples", "seed", "docking_mm", "docking_deg", "distribution")
    ),
    *model_flags(BreachSettings, "breach"),
    *[f for f in request_flags("loads") if f.key in ("options.loads.thrust_N", "options.loads.actuator_stiffness")],
    with_help(
        OUT,
        "Folder for breach.csv, what_it_takes.csv, summary.json and the pictures (created; new or empty).",
        required=True,
    ),
    MARKUPS,
    DOCK_EVALUATIONS,
]


def _check_markups(path: Path | None) -> None:
    """A markups file must be a new ``.mrk.json`` in an existing folder: refused before any work is done."""
    if path is None:
        return
    if not path.name.lower().endswith(".mrk.json"):
        raise InputError(f"{MARKUPS.name} {path}: name a .mrk.json file (3D Slicer's markups)")
    if os.path.lexists(path) and not (path.is_fifo() or path.is_char_device()):
        raise InputError(f"{MARKUPS.name} {path}: exists; name a new file")
    if not path.parent.is_dir():
        raise InputError(f"{MARKUPS.name} {path}: no folder {path.parent}")


def _pct(v: Any) -> str:
    return f"{100 * v:.1f} %" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def breach(given: Given) -> None:
    """The probability that each screw of the plan breaches its pedicle, with the robot as built (or calibrated), the
    registration and the deflection under thrust; which of them decides each screw (the model, section 22)."""
    import sys

    from arcube.design_job.at_patient import breach as breach_api
    from arcube.pedicles.first_order import REGISTRATION_MAX
    from arcube.options import Loads

    if given.get("design") is None and given.get("calibration") is None:
        raise InputError(f"{DESIGN.name} or {CALIBRATION.name} is required")
    _check_markups(given.get("markups"))
    told = [given.flag(k) for k in given.values if k.startswith("tolerances.")]
    if told and given.get("calibration") is not None:
        raise InputError(
            f"{CALIBRATION.name} and {', '.join(told)}: the calibration's covariance gives the robot's errors "
            f"({CALIBRATION.name} is instead of {' and '.join(told)}); give one"
        )
    tolerances = ToleranceSettings().merged(given.tree("tolerances")) if told else None
    check_class_counts(given, "tolerances.tolerance_class", "tolerances.tol", tolerances and tolerances.tol)
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
        say=lambda text: print(f"note: {text}", file=sys.stderr, flush=True),
        **({"dock_evaluations": given.get("dock_evaluations")} if given.get("dock_evaluations") is not None else {}),
        **plan_request(given),
    )
    rows, s = result.rows(), result.summary()
    notes = result.settings.get("dockings") or {}
    judged = next((n.get("judged_with") for n in notes.values() if n.get("judged_with")), None)
    if judged:
        typer.echo(f"reached: each screw's trajectory judged as a docking's report does ({judged})")
    for name, note in notes.items():
        typer.echo(f"side {name}: {note['how']}" if name in ("R", "L") else f"{note['how']}")
    typer.echo(
        f"{'screw':<8} {'level':<5} {'side':<4} {'room':>6} {'P(breach)':>10} {'95 % interval':>16} {'major':>7} {'robot':>7} "
        f"{'regist.':>8} {'deflect.':>8}  {'decides':<12}"
    )
    for r in rows:
        if r["status"] == "not_reached":
            note = notes.get(r["docking"], {})
            why = (note.get("not_reached") or {}).get(r["trajectory"]) or "no inverse kinematics at its isthmus"
            typer.echo(
                f"{r['trajectory']:<8} {r['level']:<5} {r['side']:<4} {r['room_mm']:>5.2f}  not reached by the robot at "
                f"docking {note.get('docking', r['docking'])}{f' ({why})' if why else ''}: no P(breach)"
            )
            continue
        interval = f"{_pct(r['p_breach_low'])}-{_pct(r['p_breach_high'])}"
        typer.echo(
            f"{r['trajectory']:<8} {r['level']:<5} {r['side']:<4} {r['room_mm']:>5.2f}  {_pct(r['p_breach']):>10} {interval:>16} "
            f"{_pct(r['p_major']):>7} {_pct(r['p_robot_alone']):>7} {_pct(r['p_registration_alone']):>8} {_pct(r['p_deflection_alone']):>8}"
            + (
                "  screw too wide: P = 1 by geometry"
                if r["status"] == "screw_too_wide"
                else f"  {r['deciding_source']:<12}"
            )
        )
    worst = s["worst_screw"]
    robot = (
        "calibrated"
        if given.get("calibration")
        else f"built to ISO 2768-{(tolerances or ToleranceSettings()).tolerance_class}"
    )
    settings_text = (
        f"the robot {robot}, registration {settings.registration_mm:g} mm / {settings.registration_deg:g} deg RMS, thrust "
        f"{loads.thrust_N:g} N, {settings.samples} samples"
    )
    if worst is None:
        typer.echo(f"{settings_text}: no screw is reached, no P(breach)")
    else:
        decided = (
            f"decided by the {s['deciding_source']}"
            if s["deciding_source"]
            else "too wide for its pedicle: by geometry"
        )
        typer.echo(
            f"{settings_text}: over the {s['reached']} reached screws of {s['screws']}, the largest P(breach) is "
            f"{_pct(s['breach_probability'])} (screw {worst}, {decided}); expected breached screws "
            f"{s['expected_breaches']:.2f} of {s['reached']}"
        )
    if s["too_wide"]:
        typer.echo(f"  too wide for their pedicle (P = 1 by geometry, whatever the errors): {', '.join(s['too_wide'])}")
    takes = s["what_it_takes"]
    if takes:
        typer.echo(
            f"what it takes to bring P(breach) to {_pct(settings.target)} (first order, model section 22): per level, "
            "its worst screw"
        )
        typer.echo(
            f"  {'level':<6} {'screw':<8} {'P(breach)':>10} {'registration needed':>20} {'screw max':>10}  as built"
        )
        for t in takes:
            reg = (
                "-"
                if t["registration_needed"] is None
                else f">= {REGISTRATION_MAX:g} mm / deg"
                if t["registration_needed"] >= REGISTRATION_MAX
                else f"{t['registration_needed']:.3g} mm / deg"
            )
            screw = "-" if t["screw_max_mm"] is None else f"{t['screw_max_mm']:.2f} mm"
            nothing = "not even the calibration" if given.get("calibration") else "none of the ISO 2768 classes"
            built = {"none": nothing, "calibration": "the calibration"}.get(t["as_built"], f"class {t['as_built']}")
            typer.echo(
                f"  {t['level']:<6} {t['worst_trajectory']:<8} {_pct(t['p_breach']):>10} {reg:>20} {screw:>10}  {built}"
            )
    typer.echo(f"results in {given.get('out')}")
    if given.get("markups") is not None:
        from arcube.io.files import atomic_write_text
        from arcube.pedicles.output import breach_markups

        atomic_write_text(given.get("markups"), breach_markups(result))
        typer.echo(f"the screws as 3D Slicer markups in {given.get('markups')}")
    if s["not_reached"]:
        typer.echo(
            f"not reached by the robot at its docking (the design job's verdict, guards included): screws "
            f"{', '.join(s['not_reached'])}; they have no P(breach)",
            err=True,
        )
        raise typer.Exit(3)


def register(app: typer.Typer) -> None:
    """Add the ``breach`` command to ``app``."""
    command(app, "breach", FLAGS, breach, help=breach.__doc__ or "")
