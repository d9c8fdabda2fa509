"""``arcube report DIR``: the HTML report of an optimization run (DIR/report.html + PNGs), or of a
drilling program folder (program.csv, program.json: DIR/report.html)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from arcube.cli.common import ANATOMY, ANATOMY_FRAME, DESIGN, with_help
from arcube.cli.projection import Given, argument, command
from arcube.cli.study import BEST_KNOWN

__all__ = ["register"]

FLAGS = [
    with_help(
        ANATOMY,
        "Anatomy to draw and measure instead of the run's own (copied into the run folder) or the program's: none, default or mesh files.",
    ),
    ANATOMY_FRAME,
    with_help(BEST_KNOWN, "An eta_G to draw as a reference line on the convergence plot (e.g. the best design known)."),
    with_help(
        DESIGN,
        "For a program folder: the design that runs it (JSON or preset), for the 3D playback. Default: design.json in the folder "
        "or in the design job around it.",
    ),
]
RUN_DIR = argument(
    "run_dir",
    "An optimization run folder (config.toml, best_design.json, history.csv), or a program folder (program.csv, program.json).",
)


def report(given: Given) -> None:
    """Write the HTML report of an optimization run or a drilling program (RUN_DIR/report.html) and print its path."""
    from arcube.errors import InputError
    from arcube.report.program_data import is_program_folder

    run_dir: Path = given.get("run_dir")
    anatomy, frame, best_known, design = (
        given.get("anatomy"),
        given.get("anatomy_frame", "LPS"),
        given.get("best_known"),
        given.get("design"),
    )
    if run_dir.is_dir():  # before the work: never into a FIFO or a folder named report.html, nor its PNGs beside one
        from arcube.report import check_report_path

        check_report_path(run_dir / "report.html", "RUN_DIR")
    if is_program_folder(run_dir) and not (run_dir / "config.toml").exists():
        from arcube.report.program_html import write_program_report

        if best_known is not None:
            raise InputError(f"{BEST_KNOWN.name}: a program folder has no convergence plot")
        sys.stdout.write(f"{write_program_report(run_dir, design=design, anatomy=anatomy, anatomy_frame=frame)}\n")
        return
    if design is not None:
        raise InputError(f"{DESIGN.name}: only for a program folder (program.csv, program.json); {run_dir} is not one")
    from arcube.report.run_report import write_run_report

    sys.stdout.write(f"{write_run_report(run_dir, anatomy=anatomy, anatomy_frame=frame, best_known=best_known)}\n")


def register(app: typer.Typer) -> None:
    """Add the ``report`` command to ``app``."""
    command(app, "report", FLAGS, report, help=report.__doc__ or "", arguments=[RUN_DIR])
