"""``arcube report RUN_DIR``: the HTML report of an optimization run (RUN_DIR/report.html + PNGs)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def report(run_dir: Annotated[Path, typer.Argument(help="An optimization run folder (config.toml, best_design.json, history.csv).")]) -> None:
    """Write the HTML report of an optimization run (RUN_DIR/report.html) and print its path."""
    from arcube.api import Run

    sys.stdout.write(f"{Run.load(run_dir).write_report()}\n")


def register(app: typer.Typer) -> None:
    """Add the ``report`` command to ``app``."""
    app.command("report")(report)
