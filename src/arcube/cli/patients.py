"""``arcube patients``: write virtual patients (MORPHOMETRY.md section 4) and print their check."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from arcube.patients.cohort import write_patients

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add the ``patients`` command to ``app``."""

    @app.command("patients")
    def patients(
        out: Annotated[Path, typer.Option("--out", help="CSV path (K = 1) or folder (K > 1).")],
        mean: Annotated[bool, typer.Option("--mean", help="The mean patient (all parameters at their means).")] = False,
        seed: Annotated[int | None, typer.Option("--seed", help="Random seed S; patient k uses S + k.")] = None,
        technique: Annotated[str, typer.Option("--technique", help="pedicle, roy-camille, magerl or an.")] = "pedicle",
        count: Annotated[int, typer.Option("--count", help="Number of patients K.")] = 1,
    ) -> None:
        """Write virtual patients (bilateral C3-C7 trajectories, CSV + parameters JSON) and print their check."""
        for text in write_patients(mean, seed, technique, count, out):
            typer.echo(text)
