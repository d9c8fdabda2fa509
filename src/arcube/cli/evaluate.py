"""``arcube evaluate``: one design on drilling trajectories (table, JSON, HTML report)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import typer

from arcube.cli.common import (
    ENVELOPE,
    FORCE,
    PLAN,
    check_new_file,
    file_path,
    masses_given,
    with_help,
    one_plan,
    options_of,
    plan_request,
    request_flags,
)
from arcube.cli.projection import Given, command, option

__all__ = ["register"]

JSON = option("--json", "Print one JSON object (per-point results and summary).", bool, key="as_json")
REPORT = option(
    "--report",
    "Also write a self-contained HTML report (plots, 3D mechanism) here.",
    Path,
    params=("report",),
    parse=file_path("report.html"),
)
FLAGS = [
    *PLAN,
    *ENVELOPE,
    JSON,
    REPORT,
    with_help(FORCE, "Replace the --report file if it exists (it is never replaced without it)."),
    *request_flags("clearances", "body", "loads", "masses"),
]


def evaluate(given: Given) -> None:
    """Evaluate a design on drilling trajectories: reachability, condition numbers, dexterity, and the
    holding torque of model §18.2 with the robot's masses (the mass flags' defaults unless given)."""
    from arcube.api import evaluate as evaluate_api
    from arcube.report import check_report_path, write_report
    from arcube.report.text import print_evaluation

    options = options_of(given)
    if options.mass_model_on(
        True if masses_given(given) else None
    ):  # the holding torque, unless the links are too thin for the default wall and no mass flag asks for it
        options = options.replace(outputs=options.outputs.replace(holding_torque=True))
    report = given.get("report")
    check_new_file(given, "report")
    if report is not None:
        report = check_report_path(report, REPORT.name)  # before the work: a folder that cannot be written, a FIFO
    result = evaluate_api(
        given.get("design", "paper"),
        one_plan(given),
        options=options,
        **{k: given.get(k) for k in ("points", "mode", "engine") if k in given},
        **plan_request(given),
    )
    if report is not None:
        write_report(result, report)
    if given.get("as_json"):
        sys.stdout.write(json.dumps(result.to_json(), allow_nan=False) + "\n")
    else:
        print_evaluation(result)
        if report is not None:
            typer.echo(f"report: {report}")


def register(app: typer.Typer) -> None:
    """Add the ``evaluate`` command to ``app``."""
    command(app, "evaluate", FLAGS, evaluate, help=evaluate.__doc__ or "")
