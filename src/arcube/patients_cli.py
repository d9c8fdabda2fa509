"""``arcube patients``: write virtual patients (MORPHOMETRY.md section 4) and print their check."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from arcube.errors import InputError

__all__ = ["register", "run_patients"]


def run_patients(mean: bool, seed: int | None, technique: str, count: int, out: Path) -> list[str]:
    """Generate, write and check the patients; return one check text per patient.

    Args:
        mean: the mean patient (every parameter at its published mean).
        seed: seed of patient 0; patient k uses ``seed + k`` so each file can be regenerated
            on its own from the seed stored in its JSON.
        technique: pedicle, roy-camille, magerl or an.
        count: number of patients K (>= 1).
        out: K = 1: the CSV path (an existing folder receives ``patient_000.csv``);
            K > 1: a folder (created) receiving ``patient_000.csv`` ... ``patient_{K-1}.csv``.
            Each CSV gets its drawn parameters beside it as ``<stem>.json``.
    """
    from arcube.patients import TECHNIQUES, check_patient, format_check, generate_patient, write_patient
    from arcube.trajectories import read_csv

    if mean == (seed is not None):
        raise InputError("patients: give exactly one of --mean or --seed S")
    if technique not in TECHNIQUES:
        raise InputError(f"patients: --technique {technique!r}: expected one of {', '.join(TECHNIQUES)}")
    if count < 1:
        raise InputError(f"patients: --count {count}: expected at least 1")
    if mean and count > 1:
        raise InputError("patients: --count > 1 with --mean would write identical patients")
    if seed is not None and seed < 0:
        raise InputError(f"patients: --seed {seed}: expected a non-negative integer")
    width = max(3, len(str(count - 1)))
    if count == 1 and not out.is_dir():
        paths = [out]
    else:
        if out.exists() and not out.is_dir():
            raise InputError(f"patients: --out {out}: exists and is not a folder (needed for --count > 1)")
        paths = [out / f"patient_{k:0{width}d}.csv" for k in range(count)]
    if any(p.suffix.lower() == ".json" for p in paths):
        raise InputError(f"patients: --out {out}: the CSV path must not end in .json (the parameters go there)")
    texts = []
    for k, path in enumerate(paths):
        ts, params = generate_patient(None if mean else seed + k, technique)
        json_path = write_patient(ts, params, path)
        # The check re-reads the written file, so it sees the 3-decimal points a user gets.
        check = format_check(check_patient(read_csv(path), params))
        texts.append(f"# {path} (parameters: {json_path})\n{check}")
    return texts


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
        for text in run_patients(mean, seed, technique, count, out):
            typer.echo(text)
