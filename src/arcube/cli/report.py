"""``arcube report DIR``: the HTML report of an optimization run (DIR/report.html + PNGs), or of a
drilling program folder (program.csv, program.json: DIR/report.html)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import AnatomyFrameOpt

__all__ = ["register"]


def report(
    run_dir: Annotated[Path, typer.Argument(help="An optimization run folder (config.toml, best_design.json, history.csv), or a program folder (program.csv, program.json).")],
    anatomy: Annotated[list[str] | None, typer.Option("--anatomy", help="Anatomy to draw and measure instead of the run's own (copied into the run folder) or the program's: none, default or mesh files.")] = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    best_known: Annotated[float | None, typer.Option("--best-known", help="An eta_G to draw as a reference line on the convergence plot (e.g. the best design known).")] = None,
    design: Annotated[str | None, typer.Option("--design", help="For a program folder: the design that runs it (JSON or preset), for the 3D playback. Default: design.json in the folder or in the design job around it.")] = None,
) -> None:
    """Write the HTML report of an optimization run or a drilling program (RUN_DIR/report.html) and print its path."""
    from arcube.errors import InputError
    from arcube.report.program_data import is_program_folder

    if is_program_folder(run_dir) and not (run_dir / "config.toml").exists():
        from arcube.report.program_html import write_program_report

        if best_known is not None:
            raise InputError("--best-known: a program folder has no convergence plot")
        sys.stdout.write(f"{write_program_report(run_dir, design=design, anatomy=anatomy, anatomy_frame=anatomy_frame)}\n")
        return
    if design is not None:
        raise InputError(f"--design: only for a program folder (program.csv, program.json); {run_dir} is not one")
    from arcube.api import Run

    sys.stdout.write(f"{Run.load(run_dir).write_report(anatomy=anatomy, anatomy_frame=anatomy_frame, best_known=best_known)}\n")


def register(app: typer.Typer) -> None:
    """Add the ``report`` command to ``app``."""
    app.command("report")(report)
