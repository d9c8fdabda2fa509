"""``arcube patients``: write virtual patients (MORPHOMETRY.md section 4) and print their check."""

from __future__ import annotations

import sys

import typer

from arcube.cli.common import FORCE, OUT, SEED, check_replace, with_help
from arcube.cli.projection import Given, command, model_flags, option
from arcube.patients.cohort import narrow_summary, patient_files, patient_paths, write_patients
from arcube.patients.settings import PatientAnatomyFormat

__all__ = ["register"]

FLAGS = [
    with_help(
        OUT,
        "A CSV path (*.csv, one patient), or a folder (created) that receives patient_000.csv ... and cohort.toml.",
        required=True,
    ),
    option("--mean", "The mean patient (all parameters at their means).", bool, params=("mean",)),
    with_help(SEED, "Random seed S; patient k uses S + k."),
    option("--technique", "pedicle, roy-camille, magerl or an. [default: pedicle]", params=("technique",)),
    option("--count", "Number of patients K. [default: 1]", int, params=("count",)),
    *model_flags(PatientAnatomyFormat, "format"),
    with_help(FORCE, "Replace files of the same names (patients are never written over a file without it)."),
]


def patients(given: Given) -> None:
    """Write virtual patients (bilateral C3-C7 trajectories, CSV + parameters JSON) and print their check.

    A pedicle drawn no wider (or taller) than the default screw is named in one warning line on stderr (the exit code
    stays 0); a folder's cohort.toml records how many there are."""
    from arcube.evaluation.envelope_drawing import plan_envelope_path, write_plan_envelope

    fmt = PatientAnatomyFormat().merged(given.tree("format"))
    out, count = given.get("out"), given.get("count", 1)
    check_replace(
        given, *patient_files(out, count, fmt.anatomy_format), *map(plan_envelope_path, patient_paths(out, count))
    )
    written = write_patients(
        bool(given.get("mean")),
        given.get("seed"),
        given.get("technique", "pedicle"),
        count,
        out,
        anatomy_format=fmt.anatomy_format,
        anatomy_spacing_mm=fmt.anatomy_spacing_mm,
        beside=write_plan_envelope,
    )
    for text in written:
        typer.echo(text)
    if (
        written.narrow
    ):  # drawn from the published spread (MORPHOMETRY.md section 6): a fact of the patient, not an error
        its = "its screw" if len(written.narrow) == 1 else "their screws"
        sys.stderr.write(f"warning: {narrow_summary(written.narrow)}; arcube breach marks {its} too_wide\n")


def register(app: typer.Typer) -> None:
    """Add the ``patients`` command to ``app``."""
    command(app, "patients", FLAGS, patients, help=patients.__doc__ or "")
