"""The ``design`` command: the main job for a new patient, a robot that meets every requirement.

Exit codes: 0 when the chosen design meets every requirement; 3 when none found does (the input
was fine: the output names the requirement(s) missed and what relaxing each would take); 2 for
bad input, 130 on Ctrl-C.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import typer

from arcube.cli.common import OUT, QUIET, check_class_counts, request_flags, with_help
from arcube.cli.optimize import PLANS, RUN_FLAGS
from arcube.cli.projection import Flag, Given, command, option
from arcube.cli.study import SEED_DASK, SEED_WORKERS, SEEDS
from arcube.design_job.requirements import DEFAULTS, PROGRAM_FIGURES
from arcube.errors import InputError
from arcube.metrics import requirements_help

__all__ = ["COHORT", "DROPS", "MAXIMA", "MINIMA", "missed_line", "print_design", "register", "run_flags"]

RUN_FIELDS = (
    "anatomy",
    "anatomy_frame",
    "segments",
    "envelope",
    "table_z",
    "dockings",
    "aggregate",
    "objectives",
    "standoff",
    "points",
    "side",
    "levels",
    "ids",
    "setups",
    "population",
    "generations",
    "ftol",
    "algorithm",
    "engine",
    "tolerance_class",
    "tol",
)
"""The optimization settings a design job takes from the command line (the rest are the job's own)."""
SEARCH_FIELDS = ("aggregate", "objectives", "setups", "population", "generations", "ftol", "algorithm")
"""Those of :data:`RUN_FIELDS` that only the search of a robot takes (``arcube dock`` places a built robot)."""
_HELPS = {
    "objectives": "What to minimize among the designs that meet the requirements: eta_G, or another objective name. [default: eta_G]",
    "standoff": "The drill waits this far outside the anatomy (model §17.1), mm. [default: 20]",
    "envelope": "The envelope of the whole patient and the table (model §19.5): default (a coarse body placed on the plan's landmarks), none, or skin mesh files. [default: default]",
    "side": "Keep trajectories of one side: R or L (the robot is docked once per side, as in the paper).",
    "setups": "1, or 2: one placement m per side, the mounting shared (before model §19; dockings gives each docking its own). [default: 1]",
    "dockings": "One robot, docked anew per patient and side (model §19): per-side (each patient's R trajectories one docking, its L ones "
    "another) or per-patient. [default: per-side]",
    "aggregate": "What the robot minimizes over its dockings: max (the worst docking's eta_G) or mean. [default: max]",
    "generations": "Generations (the budget is population x generations evaluations per seed). [default: 100]",
    "ftol": "Stop a seed when its best feasible eta_G moves less than this (see arcube optimize); 0 runs the whole budget. [default: 1e-05]",
    "algorithm": "The optimizer. [default: mscmaes]",
    "engine": "Evaluation engine of the optimizer: auto, numba or numpy (the check is always the NumPy reference). [default: auto]",
    "tolerance_class": "ISO 2768-1 class (f, m, c, v) of the robot as built: the accuracy budget reported (accuracy/) and the "
    "lateral_error_wc / lateral_error_rms requirements (model §20). [default: m]",
}
MINIMA, MAXIMA = (
    option(f"--{kind}", requirements_help(kind), key=f"{kind}ima", multiple=True, params=(f"requirements.{kind}",))
    for kind in ("min", "max")
)
DROPS: list[Flag] = [
    option(
        f"--no-{name.replace('_', '-')}", f"Drop the {name.replace('_', '-')} requirement.", bool, key=f"drop.{name}"
    )
    for name in DEFAULTS
]
"""``--no-<requirement>`` for each default requirement."""
_OBJECTIVE = {"objectives": "--objective"}
COHORT = option(
    "--cohort",
    "A cohort file (TOML): [[patient]] tables with name, plan, anatomy, anatomy_frame (and segments, envelope, "
    "table_z), paths relative to the file; one robot for all of them (model §19).",
    Path,
    params=("cohort",),
)

VALIDATE = option(
    "--validate",
    "A held-out cohort file (as --cohort; no patient named as a training one): the robot chosen is docked on "
    "it as arcube dock does, and the job reports the training and held-out coverage side by side "
    "(validation/, coverage.html).",
    Path,
    params=("validate",),
)


def run_flags(fields: tuple[str, ...] = RUN_FIELDS) -> list[Flag]:
    """The flags of these RunSettings ``fields``, with the design job's help texts (and ``--objective``)."""
    by_field = {f.key.removeprefix("run."): f for f in RUN_FLAGS}
    out = []
    for name in fields:
        f = by_field[name]
        out.append(replace(f, help=_HELPS.get(name, f.help), name=_OBJECTIVE.get(name, f.name)))
    return out


def print_design(result: Any) -> None:
    """The requirements table (each at the docking where it is tightest), the dockings, the verdict and, for each
    requirement missed, what relaxing it would take (a command line the tool accepts)."""
    from arcube.report.design_job import requirement_where

    typer.echo(f"{'requirement':<22} {'limit':>9} {'value':>10} {'margin':>10}  {'':4}  {'docking':<16} where")
    for r in result.rows:
        sign = ">=" if r["kind"] == "min" else "<="
        typer.echo(
            f"{r['requirement']:<22} {sign}{r['limit']:>7.4g} {_num(r['value']):>10} {_num(r['margin']):>10}  "
            f"{'ok' if r['passed'] else 'FAIL':4}  {r.get('docking') or '':<16} {requirement_where(r)}".rstrip()
        )
    s = result.summary
    dockings = s.get("dockings") or []
    if len(dockings) > 1:
        typer.echo(
            f"\n{'docking':<16} {'met':<4} {'clearance':>9} {'self':>6} {'envelope':>8} {'lateral':>8} {'holding':>8}  m (mm); mount (deg)"
        )
        for d in dockings:
            typer.echo(
                f"{d['label']:<16} {'yes' if d['meets_requirements'] else 'NO':<4} {_num(d['clearance_mm']):>9} {_num(d['self_clearance_mm']):>6} "
                f"{_num(d['envelope_clearance_mm']):>8} {_num(d['lateral_error_mm']):>8} {_num(d['holding_torque_Nm']):>8}  "
                f"{d['m_x']:.1f}, {d['m_y']:.1f}, {d['m_z']:.1f}; {d['mount_rx']:.1f}, {d['mount_ry']:.1f}, {d['mount_rz']:.1f}"
            )
    head = (
        "meets every requirement" + (f" at all {len(dockings)} dockings" if len(dockings) > 1 else "")
        if result.met
        else "does NOT meet every requirement"
    )
    met = len(result.rows) - len(result.missed)
    robot = s.get("robot") or {}
    c_z = f", c_z {robot['c_z']:.1f} mm" if robot.get("c_z") is not None else ""
    typer.echo(
        f"design {head} ({met} of {len(result.rows)} requirements met): seed {s['seed']}, mode {s['mode']}, "
        f"eta_G {_num(s.get('eta_G'))}{c_z}; results in {result.path}"
    )
    acc = s.get("accuracy") or {}
    if "lateral_error_p95_mm" in acc:
        top = ", ".join(f"{t['source']} {t['share']:.0%}" for t in acc.get("tighten_first", []))
        folder = (
            result.path / "dockings" / acc["docking"] if acc.get("docking") else result.path
        )  # several dockings: the worst one's
        at = f" at docking {acc['docking']}" if acc.get("docking") else ""
        typer.echo(
            f"  as built to ISO 2768-{acc['tolerance_class']}{at}: lateral error p95 {_num(acc['lateral_error_p95_mm'])} mm over "
            f"{acc['robots']} robots, worst case {_num(acc['lateral_error_wc_mm'])} mm (a perfect robot: "
            f"{_num(acc.get('perfect_robot_lateral_error_mm'))} mm); tighten first: {top}; see {folder / 'accuracy'}"
        )
    elif acc:
        typer.echo(f"  accuracy as built: not computed ({acc.get('not_computed')})")
    for r in result.missed:
        typer.echo("  " + missed_line(r))
    _print_coverage(s)


def _print_coverage(s: dict[str, Any]) -> None:
    """The training coverage (several dockings) and the held-out one (with --validate), and the sides not served."""
    for key, name in (("training", "training"), ("held_out", "held-out")):
        c = s.get(key)
        if c is None or (key == "training" and c["sides"] < 2):
            continue
        typer.echo(
            f"  {name} coverage: {c['met']} of {c['sides']} sides ({100 * c['coverage']:.0f} %, 95 % Wilson interval "
            f"{100 * c['coverage_low']:.0f}-{100 * c['coverage_high']:.0f} %)"
            + ("; see validation/ and coverage.html" if key == "held_out" else "")
        )
    agree = s.get("search_verdict_agreement")
    if agree is not None and len(s.get("seeds_served") or {}) > 0:
        served = ", ".join(f"seed {k}: {v}" for k, v in s["seeds_served"].items())
        typer.echo(
            f"  search and re-check agree on {100 * agree:.0f} % of the dockings the search called feasible; "
            f"dockings served per seed, docked anew where needed: {served}"
        )
    for d in s.get("dockings", []):
        if not d["meets_requirements"] and len(s.get("dockings", [])) > 1:
            typer.echo(
                f"  not served: {d['label']} (binds: {d.get('binding')} {_num(d.get('binding_margin'))} {d.get('binding_unit') or ''})".rstrip()
            )


def missed_line(r: dict[str, Any]) -> str:
    """What one missed requirement row says: by how much, at which docking, and what relaxing it would take."""
    at = f" at docking {r['docking']}" if r.get("docking") else ""
    name, value = r["requirement"], r["value"]
    if not math.isfinite(value) and name in PROGRAM_FIGURES:
        return f"missed: {name}{at} (not measured: no drilling program)"
    if not math.isfinite(value):
        return f"missed: {name}{at} (not measured: the design reaches none of the points where it holds)"
    if name == "program":
        return f"missed: program{at}: {r['part']}"
    if name in ("reach", "rho_max", "transmission", "kappa_max", "single_assembly_mode", "z_dyad"):
        return f"missed: {name}{at} ({_num(value)} {r['unit']}); a larger budget (--generations) or more seeds (--seeds) may find a design"
    need = f"<= {value:.4g}" if r["kind"] == "max" else f">= {value:.4g}"  # the limit the design found would meet
    return (
        f"missed: {name}{at} by {_num(-r['margin'])} {r['unit']}; the best design found meets a limit {need}"
        + _relax(r)
    )


def _relax(row: dict[str, Any]) -> str:
    """What to add to the command to accept the best design found: the limit it meets (a value the flag
    accepts: a maximum > 0, a minimum >= 0), and/or the flag that drops the requirement."""
    name, value = row["requirement"], float(row["value"])
    flag = (MINIMA if row["kind"] == "min" else MAXIMA).name
    drop = next((f.name for f in DROPS if f.key == f"drop.{name}"), None)
    # rounded away from the limit so that the printed value is met by the design (4 significant digits)
    digits = 3 - math.floor(math.log10(abs(value))) if value != 0.0 else 0
    scale = 10.0**digits
    shown = math.ceil(value * scale) / scale if row["kind"] == "max" else math.floor(value * scale) / scale
    options = [f"{flag} {name}={shown:g}"] if (shown > 0.0 if row["kind"] == "max" else shown >= 0.0) else []
    options += [drop] if drop else []
    return f" ({' or '.join(options)})" if options else ""


def _num(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def design(given: Given) -> None:
    """Find a robot that meets every requirement for a plan and its anatomy (model §16-17), checked by the NumPy reference."""
    from arcube.api import design as design_api
    from arcube.cli.design_progress import DesignProgress
    from arcube.coerce import seeds as checked_seeds
    from arcube.design_job import DESIGN_GENERATIONS, STUDY
    from arcube.optimization.settings import RunSettings

    run = given.tree("run")
    run.setdefault("generations", DESIGN_GENERATIONS)
    if given.get("cohort") is not None:
        run.setdefault("anatomy", "default")  # each patient's own (default: its plan's) comes from the cohort file
    masses = given.tree("options")
    settings = RunSettings(**run, options=masses) if masses else RunSettings(**run)
    if given.tree("options.masses"):
        settings.options.check_masses()
    drop = [name for name in DEFAULTS if given.get(f"drop.{name}")]
    seeds = given.get("seeds", "1-3")
    plans, cohort = given.get("plan"), given.get("cohort")
    if plans is None and cohort is None:
        raise InputError(f"{PLANS.name} or {COHORT.name} is required")
    if plans is not None and cohort is not None:
        raise InputError(f"{COHORT.name} replaces {PLANS.name}: give one of them")
    from arcube.design_job.cohort import docking_count

    n = docking_count(
        plans if isinstance(plans, (list, tuple)) or plans is None else [plans],
        cohort,
        run.get("side"),
        str(run.get("dockings", "per-side")) == "per-patient",
    )
    check_class_counts(given, "run.tolerance_class", "run.tol", settings.tol)
    if n == 1 and "run.aggregate" in given:
        raise InputError(
            f"{given.flag('run.aggregate')} {given.get('run.aggregate')}: how the robot's dockings are combined; with one "
            "docking it would be ignored: leave it out, or give both sides or several patients"
        )
    with DesignProgress(
        checked_seeds(seeds), settings.population * settings.generations, enabled=not given.get("quiet"), dockings=n
    ) as bar:
        bar.watch(
            Path(given.get("out")) / STUDY
        )  # seeds in other processes (--workers, --dask) report through their history
        result = design_api(
            plans,
            given.get("out"),
            cohort=cohort,
            seeds=seeds,
            minima=given.get("minima"),
            maxima=given.get("maxima"),
            drop=drop,
            on_seed=bar.seed,
            progress=bar.generation,
            on_stage=bar.stage,
            settings=settings,
            validate=given.get("validate"),
            **{k: given.get(k) for k in ("workers", "dask") if k in given},
        )
    print_design(result)
    if not result.met:
        raise typer.Exit(3)


def register(app: typer.Typer) -> None:
    """Add the ``design`` command to ``app``."""
    out = with_help(OUT, "Design folder (created; must be new or empty).", required=True)
    seeds = with_help(SEEDS, "Seeds, one optimization each: 1-3, 1,3,7. [default: 1-3]")
    masses = [*request_flags("masses"), *[f for f in request_flags("loads") if f.key == "options.loads.encoder_deg"]]
    plans = with_help(
        PLANS,
        "Trajectory sets (CSV, .mrk.json, folder or 'reference'): one patient each, each with its default anatomy "
        "(--anatomy default); or --cohort.",
        required=False,
    )
    flags = [
        plans,
        COHORT,
        VALIDATE,
        out,
        seeds,
        MINIMA,
        MAXIMA,
        *DROPS,
        *masses,
        *run_flags(),
        SEED_WORKERS,
        SEED_DASK,
        QUIET,
    ]
    command(app, "design", flags, design, help=design.__doc__ or "")
