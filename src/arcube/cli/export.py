"""``arcube export``: a simulation model of a design, assembled at one task point (:mod:`arcube.export.mjcf`),
or at the first row of a drilling program with the program's replay (:mod:`arcube.export.replay`)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from arcube.cli.common import (
    C_Z,
    PATIENT,
    SELECTION,
    DESIGN,
    FORCE,
    check_replace,
    file_out,
    MODE,
    OUT,
    POINTS,
    TRAJECTORIES,
    masses_given,
    one_plan,
    options_of,
    request_flags,
    with_given_c_z,
)
from arcube.cli.projection import Given, command, option
from arcube.errors import InputError

__all__ = ["register"]

FORMATS = ("mjcf",)
MODEL_OUT = file_out(OUT, "Output file, e.g. robot.xml (written atomically).", "robot.xml", required=True)
FORMAT = option("--format", "Model format: mjcf (MuJoCo XML). [default: mjcf]", key="fmt")
AT = option(
    "--at",
    "Task point to assemble at, ID:K (trajectory id, sample index k); default the first point the design reaches.",
    params=("at",),
)
PROGRAM = option(
    "--program",
    "Program folder (arcube program): assemble at its first row and write its replay beside --out "
    "(robot.xml -> robot.replay.csv); design: --design, else the folder's.",
    Path,
    params=("program",),
)
PLAN_FLAGS = [TRAJECTORIES, AT, POINTS, MODE, *SELECTION]
"""Flags that pick the task point; a program fixes its own (its first row, its working mode)."""
FLAGS = [
    MODEL_OUT,
    FORCE,
    DESIGN,
    FORMAT,
    *PLAN_FLAGS,
    C_Z,
    *PATIENT,
    *request_flags("body", "masses"),
    PROGRAM,
]


def export(given: Given) -> None:
    """Write the mechanism as a simulation model (MuJoCo MJCF) assembled at one task point or a program's first row."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.export.mjcf import export_mjcf
    from arcube.io.files import atomic_write_text

    fmt = str(given.get("fmt", "mjcf"))
    if fmt.strip().lower() not in FORMATS:
        raise InputError(f"{FORMAT.name} {fmt!r}: unknown format (known: {', '.join(FORMATS)})")
    out: Path = given.get("out")
    if out.exists() and out.is_dir():
        raise InputError(f"{MODEL_OUT.name} {out}: is a folder; give a file path such as robot.xml")
    blocker = next((p for p in out.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        raise InputError(f"{MODEL_OUT.name} {out}: cannot write ({blocker} is a file, not a folder)")
    if "program" in given:  # first: a folder where the replay goes is named, whatever --force says
        _check_targets(out)
    check_replace(given)
    options = options_of(given)
    asked = True if masses_given(given) else None  # a mass flag asks for the mass model, even at its default values
    if not options.mass_model_on(
        asked
    ):  # links too thin for the default wall and no mass flag: a model without the masses
        sys.stderr.write(
            f"note: {request_flags('body')[0].name} {options.body.link_radius:g} mm is not above the default "
            f"{options.masses.wall_mm:g} mm wall: exported without the masses of model §18.1 "
            f"(give {request_flags('masses')[0].name} to have them)\n"
        )
    if "program" in given:
        _export_program(given, out, options, asked)
        return
    plan = one_plan(given)
    # called without an anatomy too: --segments alone is refused there, not ignored
    anat = resolve_anatomy(
        given.get("anatomy"), given.get("anatomy_frame", "LPS"), plan, segments=given.get("segments")
    )
    kw = {k: given.get(k) for k in ("at", "points", "mode") if k in given}
    from arcube.io.load import load_plan

    full = load_plan(plan)
    ts = load_plan(full, side=given.get("side"), levels=given.get("levels"), ids=given.get("ids"))
    from arcube.evaluation.envelope import resolve_envelope

    env = resolve_envelope(
        given.get("envelope"), full, anat, given.get("table_z"), given.get("anatomy_frame", "LPS")
    )  # drawn (model §19.5)
    from arcube.model.robot import design_at_side

    text = export_mjcf(
        with_given_c_z(given, design_at_side(given.get("design", "paper"), given.get("side"), placed=True)),
        ts,
        options=options,
        anatomy=anat,
        masses=asked,
        envelope=env,
        **kw,
    )
    try:
        atomic_write_text(out, text)
    except OSError as exc:
        raise InputError(f"{MODEL_OUT.name} {out}: cannot write ({exc.strerror or exc})") from None
    sys.stdout.write(f"{out}\n")


def _check_targets(out: Path) -> None:
    """InputError naming the file when the model or its replay (``robot.replay.csv``) would go where a folder or a
    FIFO stands (before the work, and before an existing model's --force is asked for)."""
    from arcube.export.replay import replay_path
    from arcube.io.files import check_targets

    try:
        check_targets([out, replay_path(out)])
    except OSError as exc:
        raise InputError(f"{MODEL_OUT.name} {out}: cannot write {exc.filename} ({exc.strerror})") from None


def _export_program(given: Given, out: Path, options: object, masses: bool | None) -> None:
    """``--program``: the model at the program's first row and its replay (written atomically, both or none)."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.export.replay import export_program, read_program, recorded_design, replay_path, write_program_export

    clash = [f.name for f in PLAN_FLAGS if f.key in given]
    if clash:
        raise InputError(
            f"{', '.join(clash)}: not with {PROGRAM.name} (the model is assembled at the program's first row, in its working mode)"
        )
    rows = read_program(given.get("program"))
    anat = (
        resolve_anatomy(
            given.get("anatomy"),
            given.get("anatomy_frame", "LPS"),
            rows.summary.get("plan"),
            segments=given.get("segments"),
        )
        if given.get("anatomy")
        else None
    )
    check_replace(given, replay_path(out))
    design = given.get("design")
    if given.get("c_z") is not None:  # --c-z sets the c_z of the design the program runs (its own, else recorded)
        design = design or recorded_design(rows)
        design = None if design is None else with_given_c_z(given, design)
    result = export_program(rows, design, options=options, anatomy=anat, masses=masses)  # type: ignore[arg-type]
    try:
        xml_path, csv_path = write_program_export(result, out)
    except OSError as exc:
        raise InputError(
            f"{MODEL_OUT.name} {out}: cannot write {exc.filename or out} ({exc.strerror or exc}); nothing was written"
        ) from None
    sys.stdout.write(f"{xml_path}\n{csv_path}\n")


def register(app: typer.Typer) -> None:
    """Add the ``export`` command to ``app``."""
    command(app, "export", FLAGS, export, help=export.__doc__ or "")
