"""The ``optimize`` command; :func:`register` adds it to a Typer app.

``arcube optimize``'s options are :class:`arcube.RunSettings` (every field but pymoo's ``period``)
and the options groups of :class:`arcube.Options`, generated from the models (:mod:`arcube.cli.projection`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import typer

from arcube.cli.common import (
    DASK,
    OUT,
    QUIET,
    TRAJECTORIES,
    WORKERS,
    RichBar,
    check_class_counts,
    masses_given,
    request_flags,
    with_help,
)
from arcube.cli.projection import Flag, Given, command, model_flags
from arcube.errors import InputError
from arcube.optimization.settings import RunSettings

__all__ = ["PLANS", "RUN_FLAGS", "Progress", "print_summary", "register", "run_settings"]

PLANS = with_help(
    TRAJECTORIES,
    "Trajectory sets (CSV, .mrk.json, folder or 'reference'); several make a robust problem over patients.",
    required=True,
)
RUN_FLAGS: list[Flag] = [
    replace(f, spread=True) if f.dest in ("anatomy", "envelope") else f
    for f in model_flags(RunSettings, "run", skip=("period", "options"))
] + [replace(f, key="run." + f.key) for f in request_flags("guards", "body", "loads", "masses")]
"""The flags of :class:`arcube.RunSettings` (its options groups included), keyed under ``run``."""


def run_settings(given: Given, **fields: Any) -> RunSettings:
    """The :class:`arcube.RunSettings` of the flags given (``fields`` on top), the mass flags checked."""
    settings = RunSettings(**{**given.tree("run"), **fields})
    chosen = given.get("run.algorithm")
    if isinstance(chosen, str) and chosen.strip().lower() != settings.algorithm:  # objectives pick the algorithm
        objectives = given.get("run.objectives")
        shown = ",".join(objectives) if isinstance(objectives, (list, tuple)) else objectives
        raise InputError(
            f"{given.flag('run.algorithm')} {chosen} and {given.flag('run.objectives')} {shown}: "
            f"{len(settings.run_objectives)} objectives are searched by {settings.algorithm} (model §15.5); leave "
            f"{given.flag('run.algorithm')} out"
        )
    from arcube.optimization.settings import MULTI_OBJECTIVE_ALGORITHMS

    if "run.compactness" in given and settings.objectives:
        raise InputError(
            f"{given.flag('run.compactness')} and {given.flag('run.objectives')}: the objectives are given, so the "
            f"shorthand would be ignored; name the compactness among {given.flag('run.objectives')} instead"
        )
    if "run.compactness" in given and settings.algorithm not in MULTI_OBJECTIVE_ALGORITHMS:
        raise InputError(
            f"{given.flag('run.compactness')}: the second objective of nsga2 and nsga3; {settings.algorithm} would "
            f"ignore it: leave it out, or give {given.flag('run.algorithm')} nsga2"
        )
    if given.get("run.eliminate_duplicates") and settings.algorithm != "ga":
        raise InputError(
            f"{given.flag('run.eliminate_duplicates')}: drops ga's duplicate offspring; {settings.algorithm} would "
            f"ignore it: leave it out, or give {given.flag('run.algorithm')} ga"
        )
    _check_ignored(given, settings)
    fixed = [n for n in settings.bounds if n not in settings.free] if "run.bounds" in given else []
    if fixed:  # a parameter the search does not move keeps its start value: its bound would be ignored
        raise InputError(
            f"{given.flag('run.bounds')} {fixed[0]}: not free, so its bound would be ignored; add it to "
            f"{given.flag('run.free')} or leave its bound out"
        )
    if masses_given(given) or given.tree("run.options.masses"):
        settings.options.check_masses()
    return settings


def _check_ignored(given: Given, settings: RunSettings) -> None:
    """InputError naming a flag this run would take and ignore: ``--class`` / ``--tol`` with no objective or limit on
    the robot as built (model §20.3), ``--class`` under tolerances that set every length and angle, ``--aggregate`` /
    ``--placement`` with one trajectory set and no dockings (nothing to combine)."""
    from arcube.optimization.objectives import needs

    if not needs("robust", settings.run_objectives, settings.limits):
        for key in ("run.tolerance_class", "run.tol"):
            if key in given:
                shown = given.get(key)
                shown = ",".join(map(str, shown)) if isinstance(shown, (list, tuple)) else shown
                raise InputError(
                    f"{given.flag(key)} {shown}: the tolerances of lateral_error_wc and lateral_error_rms (model §20.3); no "
                    f"objective or limit uses them, so it would be ignored: leave it out, or add "
                    f"{given.flag('run.maxima')} lateral_error_rms=0.5"
                )
    check_class_counts(given, "run.tolerance_class", "run.tol", settings.tol)
    if len(given.get("plan") or []) <= 1 and settings.dockings is None:
        for key in ("run.aggregate", "run.placement"):
            if key in given:
                raise InputError(
                    f"{given.flag(key)} {given.get(key)}: how several trajectory sets are combined; with one it would "
                    f"be ignored: leave it out, or give several sets after {given.flag('plan')}"
                )


class Progress(RichBar):
    """Rich progress bar on stderr: design evaluations out of the budget, best eta_G, feasible fraction, evaluations/s, ETA."""

    def __init__(self, total: int, enabled: bool) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn, TimeRemainingColumn

        columns = (
            "evaluations",
            TextColumn("best η_G {task.fields[best]}"),
            TextColumn("feasible {task.fields[feas]}"),
            TextColumn("{task.fields[eps]} eval/s"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
        )
        super().__init__(enabled, columns, total=total, best="-", feas="-", eps="-")
        self.first_evals: int | None = None

    def __call__(self, row: dict[str, Any]) -> None:
        if not self.enabled:
            return
        if self.first_evals is None:
            self.first_evals = row["evaluations"]
        eps = (row["evaluations"] - self.first_evals) / row["session_s"] if row["session_s"] > 0 else 0.0
        best = row["best_eta_G"]
        self.progress.update(
            self.task,
            completed=row["evaluations"],
            best=f"{best:.4f}" if math.isfinite(best) else "none feasible",
            feas=f"{row['feasible_fraction']:.0%}",
            eps=f"{eps:,.0f}",
        )


def print_summary(run_dir: Path, summary: dict[str, Any]) -> None:
    eta = summary["eta_G"]
    dex = summary["dexterity_pct"]
    head = "feasible" if summary["feasible"] else "NOT feasible"
    eta_text = f"eta_G {eta:.6g}" if eta is not None else "eta_G inf"
    typer.echo(
        f"{head}: {eta_text} (dexterity min/mean/max {dex['min']:.2f}/{dex['mean']:.2f}/{dex['max']:.2f} %), mode {summary['mode']}"
    )
    typer.echo(
        f"{summary['generations']} generations, {summary['evaluations']} evaluations, {summary['wall_s']:.1f} s "
        f"(evaluation {summary['eval_s']:.1f} s), stopped by {summary['stopped_by']}, seed {summary['seed']}"
    )
    if "front_size" in summary:
        typer.echo(f"Pareto front: {summary['front_size']} designs in {run_dir / 'pareto.csv'}")
    typer.echo(f"results in {run_dir}")


RUN_OUT = with_help(OUT, "Run folder (created; must be new or empty).", required=True)
FLAGS = [PLANS, RUN_OUT, *RUN_FLAGS, WORKERS, DASK, QUIET]


def optimize(given: Given) -> None:
    """Optimize the design (model §12): minimize eta_G with every task point reachable."""
    from arcube.api import optimize as optimize_api

    settings = run_settings(given)
    with Progress(settings.population * settings.generations, enabled=not given.get("quiet")) as bar:
        run = optimize_api(
            given.get("plan"),
            settings,
            out=given.get("out"),
            progress=bar,
            **{k: given.get(k) for k in ("workers", "dask") if k in given},
        )
    print_summary(run.path, run.summary)


def register(app: typer.Typer) -> None:
    """Add the ``optimize`` command to ``app``."""
    command(app, "optimize", FLAGS, optimize, help=optimize.__doc__ or "")
