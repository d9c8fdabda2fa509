"""``arcube tolerance``: the accuracy budget of a robot built to tolerances (model §20), into a folder."""

from __future__ import annotations

import typer

from arcube.accuracy.settings import ToleranceSettings
from arcube.cli.common import (
    DESIGN,
    MODE,
    OUT,
    POINTS,
    SELECTION,
    TRAJECTORIES,
    check_class_counts,
    one_plan,
    plan_request,
    with_help,
)
from arcube.cli.projection import Given, command, model_flags

__all__ = ["register"]

FLAGS = [
    with_help(DESIGN, DESIGN.help.split(" [")[0], required=True),
    with_help(TRAJECTORIES, TRAJECTORIES.help.split(" [")[0], required=True),
    *SELECTION,
    POINTS,
    MODE,
    *model_flags(ToleranceSettings, "tolerances"),
    with_help(
        OUT,
        "Folder for tolerance.json, tolerance_points.csv, sensitivity.csv and the pictures (created; new or empty).",
        required=True,
    ),
]


def tolerance(given: Given) -> None:
    """The accuracy budget of the design built to tolerances (model §20): the worst case and RMS of the first
    order and the Monte Carlo over built robots, each error source's share, and the pictures a manufacturer reads."""
    from arcube.api import tolerance as tolerance_api

    settings = ToleranceSettings().merged(given.tree("tolerances"))
    check_class_counts(given, "tolerances.tolerance_class", "tolerances.tol", settings.tol)
    result = tolerance_api(
        given.get("design"),
        one_plan(given),
        given.get("out"),
        settings=settings,
        **{k: given.get(k) for k in ("points", "mode") if k in given},
        **plan_request(given),
    )
    s, mc = result.summary, result.monte_carlo_summary()
    typer.echo(
        f"built to ISO 2768-{settings.tolerance_class} ({settings.distribution}; {mc['robots']} robots): lateral error p95 "
        f"{s['lateral_error_p95_mm']:.3g} mm (the largest over the plan's points of 95 % of the robots), first-order worst case "
        f"{s['lateral_error_wc_mm']:.3g} mm, RMS {s['lateral_error_rms_mm']:.3g} mm; axis error p95 {s['axis_error_p95_deg']:.3g} deg, "
        f"worst case {s['axis_error_wc_deg']:.3g} deg"
    )
    top = ", ".join(f"{name} {share:.0%} (T {tol:g} {unit})" for name, tol, unit, share in result.ranked_sources()[:3])
    typer.echo(f"tighten first: {top}")
    typer.echo(f"results in {given.get('out')}")


def register(app: typer.Typer) -> None:
    """Add the ``tolerance`` command to ``app``."""
    command(app, "tolerance", FLAGS, tolerance, help=tolerance.__doc__ or "")
