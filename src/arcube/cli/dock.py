"""The ``dock`` command: a built robot, docked on every side of a plan or a cohort, and its coverage (model §19.6).

Exit codes: 0 when every side is served; 3 when some are not (the input was fine: the output names those sides and
what binds there); 2 for bad input, 130 on Ctrl-C.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import typer

from arcube.cli.common import (
    DASK,
    OUT,
    QUIET,
    SEED,
    WORKERS,
    RichBar,
    check_class_counts,
    request_flags,
    with_help,
)
from arcube.cli.design import RUN_FIELDS, COHORT, DROPS, MAXIMA, MINIMA, SEARCH_FIELDS, run_flags
from arcube.cli.optimize import PLANS
from arcube.cli.projection import Given, command, option
from arcube.design_job.requirements import DEFAULTS
from arcube.errors import InputError

__all__ = ["print_dock", "register"]

_FIELDS = tuple(name for name in RUN_FIELDS if name not in SEARCH_FIELDS)
"""The design job's settings that a docking takes from the command line (the robot's own are in its file)."""
ROBOT = option(
    "--robot",
    "The built robot: a design.json of arcube design, or any docking's design file (its parameters, mode and "
    "z-dyad elbow are used as they are; its dockings only as warm starts).",
    Path,
    required=True,
    params=("robot",),
)
STARTS = option(
    "--starts",
    "Search runs per side: the best warm starts (the robot's own dockings carried onto the plan) and random "
    "placements within the bounds. [default: 8]",
    int,
    params=("starts",),
)
EVALUATIONS = option(
    "--evaluations", "Evaluations of each side's search. [default: 6000]", int, params=("evaluations",)
)


def _num(v: Any, digits: str = ".4g") -> str:
    return format(v, digits) if isinstance(v, (int, float)) and math.isfinite(v) else "-"


class DockProgress(RichBar):
    """Rich progress over the sides on stderr: the sides served so far and the last one's verdict."""

    def __init__(self, enabled: bool) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn

        super().__init__(
            enabled, ("sides", TextColumn("{task.fields[last]}"), TimeElapsedColumn()), total=None, last=""
        )
        self.met = self.done = 0

    def __call__(self, outcome: Any) -> None:
        self.done += 1
        self.met += outcome.met
        if self.enabled:
            self.progress.advance(self.task)
            self.progress.update(
                self.task,
                last=f"{self.met} of {self.done} served; {outcome.label}: {'served' if outcome.met else 'not served'}",
            )


def print_dock(result: Any) -> None:
    """The sides (served or not, what binds and by how much, the placement), the coverage and what binds where not served."""
    s = result.summary
    typer.echo(f"{'side':<20} {'served':<6} {'binds':<22} {'margin':>10} {'eta_G':>7}  m (mm); mount (deg)")
    for d in s["dockings"]:
        typer.echo(
            f"{d['label']:<20} {'yes' if d['meets_requirements'] else 'NO':<6} {d['binding'] or '-':<22} "
            f"{_num(d['binding_margin']):>10} {_num(d['eta_G'], '.4f'):>7}  {d['m_x']:.1f}, {d['m_y']:.1f}, {d['m_z']:.1f}; "
            f"{d['mount_rx']:.1f}, {d['mount_ry']:.1f}, {d['mount_rz']:.1f}"
        )
    low, high = 100 * s["coverage_low"], 100 * s["coverage_high"]
    typer.echo(
        f"the robot serves {s['met']} of {s['sides']} sides: coverage {100 * s['coverage']:.0f} % (95 % Wilson interval "
        f"{low:.0f}-{high:.0f} %); results in {result.path}"
    )
    if s.get("c_z_assumed"):
        typer.echo(
            "  note: the robot file has no c_z: the z dyad's second link was taken equal to d_z (the model, section 6)"
        )
    for d in s["dockings"]:
        if not d["meets_requirements"]:
            where = f": {d['binding_where']}" if d.get("binding_where") else ""
            typer.echo(
                f"  not served: {d['label']}: {', '.join(d['missed'])} (binds: {d['binding']} {_num(d['binding_margin'])} "
                f"{d['binding_unit'] or ''}{where}); see {result.path / d['folder'] / 'report.html'}"
            )


def dock(given: Given) -> None:
    """Dock a built robot on every patient side of a plan or a cohort, the robot unchanged: which sides it serves (model §19.6)."""
    from arcube.design_job.coverage import dock as dock_api
    from arcube.optimization.settings import RunSettings

    run = given.tree("run")
    run.setdefault("anatomy", "default")  # each patient's default anatomy, as arcube design with a cohort
    masses = given.tree("options")
    settings = RunSettings(**run, options=masses) if masses else RunSettings(**run)
    if given.tree("options.masses"):
        settings.options.check_masses()
    check_class_counts(given, "run.tolerance_class", "run.tol", settings.tol)
    plans, cohort = given.get("plan"), given.get("cohort")
    if plans is not None and cohort is not None:
        raise InputError(f"{COHORT.name} replaces {PLANS.name}: give one of them")
    if plans is None and cohort is None:
        raise InputError(f"{PLANS.name} or {COHORT.name} is required")
    drop = [name for name in DEFAULTS if given.get(f"drop.{name}")]
    with DockProgress(enabled=not given.get("quiet")) as bar:
        result = dock_api(
            given.get("robot"),
            plans,
            given.get("out"),
            cohort=cohort,
            seed=given.get("seed", 1),
            starts=given.get("starts", 8),
            minima=given.get("minima"),
            maxima=given.get("maxima"),
            drop=drop,
            settings=settings,
            on_docking=bar,
            **{k: given.get(k) for k in ("evaluations", "workers", "dask") if k in given},
        )
    print_dock(result)
    if not result.met:
        raise typer.Exit(3)


def register(app: typer.Typer) -> None:
    """Add the ``dock`` command to ``app``."""
    out = with_help(OUT, "Folder of the dockings (created; must be new or empty).", required=True)
    plans = with_help(
        PLANS,
        "Trajectory sets (CSV, .mrk.json, folder or 'reference'): one patient each, each side a docking; or --cohort.",
        required=False,
    )
    seed = with_help(SEED, "Seed of the searches (each side's is drawn from it and the side's name). [default: 1]")
    workers = with_help(WORKERS, "Sides docked at once, each in its own process. [default: 1]")
    dask = with_help(
        DASK,
        "Address of a dask.distributed scheduler: each side is one task (its workers must see the output's folder).",
    )
    masses = [*request_flags("masses"), *[f for f in request_flags("loads") if f.key == "options.loads.encoder_deg"]]
    flags = [
        ROBOT,
        plans,
        COHORT,
        out,
        seed,
        STARTS,
        EVALUATIONS,
        MINIMA,
        MAXIMA,
        *DROPS,
        *masses,
        *run_flags(_FIELDS),
        workers,
        dask,
        QUIET,
    ]
    command(app, "dock", flags, dock, help=dock.__doc__ or "")
