"""``arcube calibrate poses | simulate | identify``: the built robot's real dimensions from tracker
measurements (model §21), one subcommand per step: choose the poses to measure, rehearse with a
simulated robot, identify the real dimensions and zero offsets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from arcube.calibrate.settings import IdentifySettings, PoseSettings, SimulateSettings
from arcube.cli.common import (
    SELECTION,
    ANATOMY,
    ANATOMY_FRAME,
    DESIGN,
    FORCE,
    check_replace,
    MODE,
    OUT,
    SEGMENTS,
    SIDE,
    TRAJECTORIES,
    one_plan,
    file_out,
    with_help,
)
from arcube.cli.projection import Given, command, model_flags, option
from arcube.model.robot import design_at_side

__all__ = ["register"]

_DESIGN = with_help(DESIGN, "The nominal design: a design JSON (plain or calibrated) or a preset.", required=True)
MEASUREMENTS = option(
    "--measurements",
    "Measurement CSV: rho_x, rho_y, rho_z, delta_x, delta_y (deg, as the encoders read them), "
    "E_x, E_y, E_z (mm) and e_x, e_y, e_z (patient frame), one row per measured pose.",
    Path,
    params=("measurements",),
    required=True,
)
POSES = option(
    "--poses",
    "Poses CSV (arcube calibrate poses), the joint angles to drive the simulated robot to.",
    Path,
    params=("poses",),
    required=True,
)
POSE_FLAGS = [
    _DESIGN,
    with_help(TRAJECTORIES, "The plan whose points and approach lines the poses are chosen around.", required=True),
    *SELECTION,
    MODE,
    ANATOMY,
    ANATOMY_FRAME,
    SEGMENTS,
    *model_flags(PoseSettings, "poses"),
    file_out(
        OUT, "Poses CSV to write (the measurement file's columns with E and e nominal).", "poses.csv", required=True
    ),
    FORCE,
]
SIMULATE_FLAGS = [
    _DESIGN,
    with_help(SIDE, "With a robot's design.json (robot and dockings): the side whose docking was measured."),
    POSES,
    *model_flags(SimulateSettings, "simulate"),
    file_out(
        OUT,
        "Measurement CSV to write (the simulated tracker's readings), and beside it <stem>.truth.json, the "
        "simulated robot's true design.",
        "measurements.csv",
        required=True,
    ),
    FORCE,
]
IDENTIFY_FLAGS = [
    _DESIGN,
    MEASUREMENTS,
    MODE,
    *model_flags(IdentifySettings, "identify"),
    with_help(
        TRAJECTORIES,
        "Optional plan: the calibrated robot's accuracy budget on its points (default: the measured poses).",
    ),
    with_help(SIDE, "Keep the plan's trajectories of one side, R or L; with a robot's design.json, its docking there."),
    with_help(
        OUT,
        "Folder for design.json, calibration.json, residuals.csv and calibration.html (created; new or empty).",
        required=True,
    ),
]


def _plan(given: Given) -> object | None:
    from arcube.io.load import load_plan

    if "plan" not in given:
        return None
    return load_plan(one_plan(given), side=given.get("side"), levels=given.get("levels"), ids=given.get("ids"))


def poses(given: Given) -> None:
    """Choose the poses to measure (model §21.3): greedy D-optimal among the plan's points, its approach lines
    and random poses around them; prints O1 and the condition number against a random choice of the same count."""
    from arcube.calibrate import poses as poses_api
    from arcube.evaluation.anatomy import resolve_anatomy

    check_replace(given)
    plan = _plan(given)
    # called without an anatomy too: --segments alone is refused there, not ignored
    anatomy = resolve_anatomy(
        given.get("anatomy"), given.get("anatomy_frame", "LPS"), one_plan(given), segments=given.get("segments")
    )
    sel = poses_api(
        design_at_side(given.get("design"), given.get("side"), placed=True),
        plan,
        given.get("mode"),
        PoseSettings().merged(given.tree("poses")),
        anatomy=anatomy,
        out=given.get("out"),
    )
    s = sel.summary()
    typer.echo(
        f"{s['poses']} poses chosen of {s['candidates']} candidates (mode {s['mode']}): O1 {s['O1']:.3g}, condition number "
        f"{s['condition_number']:.4g}; {s['poses']} random poses: O1 {s['O1_random']:.3g}, condition number "
        f"{s['condition_number_random']:.4g}"
    )
    for name, others in s["not_identifiable"].items():
        typer.echo(f"  not identifiable: {name} (confounded with {', '.join(others) or 'nothing measured'})")
    typer.echo(f"poses in {given.get('out')}")


def simulate(given: Given) -> None:
    """Build a robot to a tolerance class and measure it at the poses with tracker noise (a rehearsal of a calibration)."""
    from arcube.calibrate import simulate as simulate_api

    from arcube.calibrate.simulate import truth_path

    check_replace(given, truth_path(given.get("out")))
    sim = simulate_api(
        design_at_side(given.get("design"), given.get("side"), alone=True, placed=True),
        given.get("poses"),
        SimulateSettings().merged(given.tree("simulate")),
        out=given.get("out"),
    )
    typer.echo(
        f"{len(sim.measurements)} measurements of a robot built to ISO 2768-{sim.settings.tolerance_class} (seed {sim.settings.seed}) "
        f"in {given.get('out')}; the robot's true design in {truth_path(given.get('out'))}"
    )


def identify(given: Given) -> None:
    """Identify the robot's real dimensions, docking and joint zero offsets from the measurements (model §21.2):
    design.json (the calibrated design), calibration.json, residuals and the report page."""
    from arcube.calibrate import identify as identify_api

    from dataclasses import replace

    from arcube.calibrate.design_file import load_design
    from arcube.model.robot import docking_labels

    plan = _plan(given)
    start = load_design(design_at_side(given.get("design"), given.get("side"), alone=plan is None, placed=True))
    if not start.labels:  # a robot's design.json and a side: that docking (design.json records where it was measured)
        start = replace(start, labels=docking_labels(given.get("design"), given.get("side")))
    cal = identify_api(
        start,
        given.get("measurements"),
        given.get("mode"),
        IdentifySettings().merged(given.tree("identify")),
        trajectories=plan,
        out=given.get("out"),
    )
    rms = cal.residual_rms()
    fit, held = rms["fitted"], rms["held_out"]
    typer.echo(
        f"fitted {fit['rows']} measurements: tip residual RMS {fit['E_rms_mm_before']:.3g} -> {fit['E_rms_mm']:.3g} mm, axis "
        f"{fit['e_rms_deg_before']:.3g} -> {fit['e_rms_deg']:.3g} deg (the tracker's noise: {rms['noise']['E_rms_mm']:.3g} mm, "
        f"{rms['noise']['e_rms_deg']:.3g} deg)"
    )
    if held["rows"]:
        typer.echo(f"held out {held['rows']}: tip {held['E_rms_mm']:.3g} mm, axis {held['e_rms_deg']:.3g} deg")
    if (
        cal.budget is not None
    ):  # the robot's accuracy before (its tip off by what the residuals say) and after calibration
        b = cal.budget.summary
        robots = cal.budget.robot_lateral_max_mm
        apart = int(np.sum(~np.isfinite(robots)))  # drawn robots that do not assemble at every point: error infinite
        typer.echo(
            f"accuracy: the tip was {fit['E_rms_mm_before']:.3g} mm RMS from where the nominal model put it; calibrated, the lateral "
            f"error is {b['lateral_error_p95_mm']:.3g} mm (p95 over {robots.size} robots drawn from the "
            f"identification, on the {cal.budget.where}'s points), RMS {b['lateral_error_rms_mm']:.3g} mm"
            + (
                f"; {apart} of the {robots.size} robots do not assemble at every point: the identification is that "
                "uncertain (measure more poses: calibrate poses --count)"
                if apart
                else ""
            )
        )
    hidden = [u["name"] for u in cal.unknown_rows() if not u["identifiable"]]
    typer.echo(
        f"not identifiable from these poses (kept at their nominal values): {', '.join(hidden) if hidden else 'none'}"
    )
    typer.echo(f"calibrated design in {Path(given.get('out')) / 'design.json'}")


def register(app: typer.Typer) -> None:
    """Add the ``calibrate`` command group to ``app``."""
    group = typer.Typer(
        name="calibrate",
        help=__doc__.split("\n\n")[0].replace("\n", " "),
        no_args_is_help=True,
        add_completion=False,
        rich_markup_mode=None,
    )
    command(group, "poses", POSE_FLAGS, poses, help=poses.__doc__ or "", registry_name="calibrate poses")
    command(
        group, "simulate", SIMULATE_FLAGS, simulate, help=simulate.__doc__ or "", registry_name="calibrate simulate"
    )
    command(
        group, "identify", IDENTIFY_FLAGS, identify, help=identify.__doc__ or "", registry_name="calibrate identify"
    )
    app.add_typer(group)
