"""``arcube report RUN_DIR``: the HTML report of an optimization run (RUN_DIR/report.html + PNGs)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from arcube.cli.common import AnatomyFrameOpt

__all__ = ["register"]


def report(
    run_dir: Annotated[Path, typer.Argument(help="An optimization run folder (config.toml, best_design.json, history.csv).")],
    anatomy: Annotated[list[str] | None, typer.Option("--anatomy", help="Anatomy to draw and measure instead of the run's own (copied into the run folder): none, default or mesh files.")] = None,
    anatomy_frame: AnatomyFrameOpt = "LPS",
    best_known: Annotated[float | None, typer.Option("--best-known", help="An eta_G to draw as a reference line on the convergence plot (e.g. the best design known).")] = None,
) -> None:
    """Write the HTML report of an optimization run (RUN_DIR/report.html) and print its path."""
    from arcube.api import Run

    sys.stdout.write(f"{Run.load(run_dir).write_report(anatomy=anatomy, anatomy_frame=anatomy_frame, best_known=best_known)}\n")


def register(app: typer.Typer) -> None:
    """Add the ``report`` command to ``app``."""
    app.command("report")(report)
