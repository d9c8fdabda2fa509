"""``arcube dock``: a built robot docked on every patient side of a plan or a cohort, and its coverage (model §19.6).

One folder holds the job, written whole or not at all (it is made beside ``out`` and renamed into place at the end;
a killed job leaves no ``out``, and the next job removes what it left)::

    summary.json       the robot (22 parameters, mode), every side's docking (patient, side, met, what was missed,
                       the requirement that binds and its margin, m_x ... mount_rz), the coverage with its 95 % Wilson
                       interval (coverage, coverage_low, coverage_high), sides, met, and the settings
    coverage.csv       one row per side: the same, for a spreadsheet
    report.html        the coverage table and a picture of which sides are served and what binds on the others
    dockings/<patient>_<side>/
                       design.json (the robot unchanged at that docking), requirements.csv, program/ (when the
                       requirements are met at the plan's points), report.html (with the accuracy as built)

Each side is :func:`arcube.design_job.dock.solve_docking`'s problem, independent of the others (model §19.3): they run
one after another, over ``workers`` local processes, or as tasks on a dask.distributed cluster (whose workers must
see the output's parent folder); the result does not depend on which.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arcube.design_job.summaries import DockSummary
from arcube.design_job.dock import DOCK_EVALUATIONS, DockingJob, DockingOutcome, solve_docking
from arcube.design_job.dockings import PLACEMENT, Docking
from arcube.design_job.requirements import (
    REQUIREMENTS,
    Requirement,
    normalized_shortfall,
    write_requirements_csv,
)
from arcube.model.robot import BuiltRobot, read_robot, write_docking
from arcube.errors import InputError
from arcube.io.files import as_mkdir, atomic_write_text
from arcube.io.json_values import finite
from arcube.optimization.config import PatientPlan
from arcube.optimization.settings import RunSettings

__all__ = [
    "COVERAGE_COLUMNS",
    "DOCK_FORMAT",
    "DockResult",
    "binding_row",
    "dock",
    "dock_patients",
    "docking_jobs",
    "row_violation",
    "run_jobs",
    "solve_only",
    "wilson",
]

DOCK_FORMAT = "arcube-dock"
DOCKINGS = "dockings"
COVERAGE_COLUMNS = (
    "patient",
    "side",
    "met",
    "binding",
    "margin",
    "unit",
    "missed",
    "eta_G",
    *PLACEMENT,
    "binding_violation",
)
"""The columns of coverage.csv, one row per side (``binding_violation``: the normalized violation of model §16 by which
the binding requirement was chosen, :func:`binding_row`)."""
Z95 = 1.959963984540054
"""The normal quantile of a two-sided 95 % interval."""


@dataclass(frozen=True)
class DockResult:
    """What ``arcube dock`` found: whether every side is met, the summary written to summary.json, its folder."""

    path: Path
    met: bool
    summary: DockSummary

    def __post_init__(self) -> None:
        object.__setattr__(self, "summary", DockSummary(self.summary))

    @property
    def coverage(self) -> float:
        """The fraction of the sides met."""
        return float(self.summary["coverage"])

    @property
    def missed(self) -> list[dict[str, Any]]:
        """The dockings (summary entries) that are not met."""
        return [d for d in self.summary["dockings"] if not d["meets_requirements"]]


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float, float]:
    """(k/n, low, high): the estimate of a proportion from k successes in n trials and its Wilson score interval."""
    if n <= 0:
        return math.nan, math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # at k = 0 (k = n) the interval reaches 0 (1) exactly; computed, it would miss by a rounding error
    return p, 0.0 if k == 0 else max(0.0, centre - half), 1.0 if k == n else min(1.0, centre + half)


def binding_row(rows: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """The requirement that binds at a docking. Of the failed rows, the one with the largest normalized violation of
    model §16 (:func:`row_violation`, one scale for every unit): a point not reached first (the reach row with its
    V_reach > 0, or the z dyad's row: §16's V_reach outranks every fit shortfall), then the largest term of G (a guard's or
    a clearance's mean over the points of min(s / S, 1), a limit's normalized shortfall), a row not measured last; ties
    in the rows' order. Without a failed row, of the named requirements (:data:`REQUIREMENTS`: clearance, torque, ...;
    not the pass/fail rows of reach, the guards and the program) the tightest relative to its limit."""

    def rel(r: dict[str, Any]) -> float:
        m = r["margin"]
        if not isinstance(m, (int, float)) or not math.isfinite(m):
            return -math.inf
        return m / abs(r["limit"]) if r["limit"] else m

    def rank(r: dict[str, Any]) -> tuple[int, float]:
        v = row_violation(r)
        if r["requirement"] in _NOT_REACHED and v != 0.0:  # V_reach > 0, or a z dyad open (NaN: no figure)
            return 0, -v if math.isfinite(v) else math.inf
        return (1, -v) if math.isfinite(v) else (2, 0.0)

    failed = [r for r in rows if not r["passed"]]
    if failed:
        return min(failed, key=rank)
    limits = [
        r
        for r in rows
        if r["requirement"] in REQUIREMENTS
        and r.get("limit")
        and isinstance(r.get("margin"), (int, float))
        and math.isfinite(r["margin"])
    ]
    return min(limits, key=rel) if limits else None


_NOT_REACHED = ("reach", "z_dyad")
"""The rows of model §16's V_reach: the points the inverse kinematics does not solve, the z dyad's among them (its
amendment)."""


def row_violation(row: dict[str, Any]) -> float:
    """A requirement row's normalized violation (model §16): its ``violation``
    (:func:`~arcube.design_job.requirements.assess`, :func:`~arcube.design_job.requirements.judge`), else the normalized
    shortfall of its limit from its margin (the program's and the breach's rows); NaN when it has none (not measured)."""
    v = row.get("violation")
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v)
    kind = row.get("kind") or REQUIREMENTS.get(row["requirement"], ("max",))[0]
    return normalized_shortfall(kind, float(row.get("limit") or 0.0), row.get("margin"))  # type: ignore[arg-type]


def docking_jobs(
    robot: BuiltRobot,
    patients: Sequence[PatientPlan],
    settings: RunSettings,
    reqs: Sequence[Requirement],
    *,
    seed: int,
    starts: int,
    evaluations: int,
    folder: Path,
) -> list[DockingJob]:
    """One job per patient side (``settings.dockings`` per-side, the default: each side present in the plan; per-patient:
    the whole plan), each writing into ``folder/dockings/<patient>_<side>``."""
    from arcube.io import load_trajectories, select

    jobs = []
    for p in patients:
        plan = load_trajectories(p.plan, settings.transform)
        plan = select(plan, side=settings.side, levels=settings.levels, ids=settings.ids)
        if not len(plan.ids):
            raise InputError.of(
                "plan", f"patient {p.name}: no trajectories left after the selection of side, levels and ids"
            )
        sides: list[str | None] = (
            [sd for sd in ("R", "L") if sd in plan.sides] if settings.dockings != "per-patient" else [None]
        )
        for side in sides:
            job = DockingJob(robot, p, side, settings, tuple(reqs), int(seed), int(starts), int(evaluations), "")
            jobs.append(DockingJob(**{**job.__dict__, "folder": str(folder / DOCKINGS / job.label)}))
    return jobs


def _dock_and_write(job: DockingJob) -> DockingOutcome:
    """Solve one docking and write its folder (design.json, requirements.csv, report.html): one process's or worker's task."""
    outcome, docking, s = solve_docking(job)
    write_docking_folder(Path(job.folder), outcome, docking, s, job.seed)
    return outcome


def write_docking_folder(folder: Path, outcome: DockingOutcome, d: Docking, s: RunSettings, seed: int) -> None:
    """The docking's own files: its design (the robot unchanged, at the docking), its requirement rows and its report
    (the verdict, the requirements, the accuracy as built to the job's tolerance class, the program when built)."""
    from arcube.design_job.outputs import (
        PROGRAM,
        accuracy_budget,
        breach_check,
        breach_risk,
        docking_evaluation,
        trajectory_verdict,
    )
    from arcube.report import write_report
    from arcube.report.design_job import design_preface

    folder.mkdir(parents=True, exist_ok=True)
    write_docking(outcome.design, folder / "design.json", outcome.patient, outcome.side, d.plan)
    write_requirements_csv(folder / "requirements.csv", [{**r, "docking": outcome.label} for r in outcome.rows])
    ev = docking_evaluation(d, s)  # the robot's c_z is always set (read_robot): the z dyad is closed with it
    perfect = next((r["value"] for r in outcome.rows if r["requirement"] == "lateral_error"), None)
    accuracy = {**accuracy_budget(folder, d.design, d.plan, str(d.design.mode), s, perfect), "docking": outcome.label}
    outcome.extra["accuracy_p95_mm"] = accuracy.get("lateral_error_p95_mm")
    breach, _ = breach_check(folder, d, s, (), trajectory_verdict(ev))
    outcome.extra["breach_probability"] = breach.get("breach_probability")
    program = folder / PROGRAM if (folder / PROGRAM / "program.json").exists() else None
    mine = {
        "meets_requirements": outcome.met,
        "seed": seed,
        "mode": d.design.mode,
        "eta_G": outcome.eta_G,
        "accuracy": accuracy,
        "breach": breach,
    }
    write_report(
        ev,
        folder / "report.html",
        program=program,
        preface=design_preface(mine, outcome.rows, d.design, c_z=d.design.c_z, folder=folder),
        title=f"AR-CUBE docking: patient {outcome.patient}, side {outcome.side}",
        risk=breach_risk(breach),
    )


def solve_only(job: DockingJob) -> DockingOutcome:
    """Solve one docking (its program into ``job.folder``); nothing else written: a process's or worker's task."""
    return solve_docking(job)[0]


def run_jobs(
    jobs: Sequence[DockingJob],
    workers: int,
    dask: str | None,
    on_docking: Callable[[DockingOutcome], None] | None,
    task: Callable[[DockingJob], DockingOutcome] = _dock_and_write,
) -> list[DockingOutcome]:
    """Every job's outcome (``task(job)``: solve and write its folder, by default), in the jobs' order: here, over
    ``workers`` processes, or on the dask scheduler ``dask``."""
    done: dict[int, DockingOutcome] = {}

    def record(i: int, outcome: DockingOutcome) -> None:
        done[i] = outcome
        if on_docking is not None:
            on_docking(outcome)

    if dask:
        from arcube.optimization.executors import connect_dask

        client = connect_dask(dask)
        try:
            futures = [client.submit(task, job, pure=False) for job in jobs]
            for i, fut in enumerate(futures):
                record(i, fut.result())
        finally:
            client.close()
    elif workers > 1 and len(jobs) > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        ctx = multiprocessing.get_context("spawn")  # no fork under threads (the progress line)
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=ctx) as pool:
            futures = {pool.submit(task, job): i for i, job in enumerate(jobs)}
            try:
                for fut in as_completed(futures):
                    record(futures[fut], fut.result())
            except BaseException:
                pool.shutdown(wait=True, cancel_futures=True)
                raise
    else:
        for i, job in enumerate(jobs):
            record(i, task(job))
    return [done[i] for i in range(len(jobs))]


def docking_verdict(label: str, patient: str, side: str, rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The first fields of a docking's line of summary.json (a design job's or ``arcube dock``'s): who, whether its
    requirement rows are all met, and which are missed."""
    met = bool(rows) and all(r["passed"] for r in rows)
    missed = [r["requirement"] for r in rows if not r["passed"]]
    return {"label": label, "patient": patient, "side": side, "meets_requirements": met, "missed": missed}


def binding_fields(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The fields of a docking's line of summary.json naming the requirement that binds there (:func:`binding_row`)."""
    bind = binding_row(rows)
    return {
        "binding": None if bind is None else bind["requirement"],
        "binding_margin": None if bind is None else bind["margin"],
        "binding_unit": None if bind is None else bind.get("unit"),
        "binding_where": None if bind is None else (bind.get("part") or None),
        "binding_violation": None if bind is None else row_violation(bind),
    }


def _entry(outcome: DockingOutcome) -> dict[str, Any]:
    """One side's line of summary.json."""
    values = outcome.design.to_dict()
    return {
        **docking_verdict(outcome.label, outcome.patient, outcome.side, outcome.rows),
        **binding_fields(outcome.rows),
        **{n: values[n] for n in PLACEMENT},
        "eta_G": outcome.eta_G,
        "violation": outcome.violation,
        "found_by": outcome.found_by,
        "evaluations": outcome.evaluations,
        "placements_checked": outcome.tried,
        "seconds": round(outcome.seconds, 2),
        "folder": f"{DOCKINGS}/{outcome.label}",
        **outcome.extra,
    }


def coverage_summary(robot: BuiltRobot, outcomes: Sequence[DockingOutcome]) -> dict[str, Any]:
    """The robot, every side's entry and the coverage (its Wilson interval) of summary.json."""
    met = sum(o.met for o in outcomes)
    p, lo, hi = wilson(met, len(outcomes))
    return {
        "robot": robot.values,
        "mode": robot.design.mode,
        "zdyad_elbow": int(robot.design.zdyad_elbow),
        "c_z_assumed": robot.c_z_assumed,
        "dockings": [_entry(o) for o in outcomes],
        "coverage": p,
        "coverage_low": lo,
        "coverage_high": hi,
        "sides": len(outcomes),
        "met": met,
    }


def coverage_csv(entries: Sequence[dict[str, Any]]) -> str:
    """coverage.csv's text: :data:`COVERAGE_COLUMNS`, one row per side (quoted where a field needs it)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COVERAGE_COLUMNS)
    for e in entries:
        w.writerow(
            [
                e["patient"],
                e["side"],
                "yes" if e["meets_requirements"] else "no",
                e["binding"] or "",
                ""
                if e["binding_margin"] is None or not math.isfinite(e["binding_margin"])
                else f"{e['binding_margin']:.6g}",
                e["binding_unit"] or "",
                ";".join(e["missed"]),
                "" if e["eta_G"] is None else f"{e['eta_G']:.6g}",
                *(f"{e[n]:.6f}" for n in PLACEMENT),
                _number(e.get("binding_violation")),
            ]
        )
    return buf.getvalue()


def _number(v: Any) -> str:
    """A figure of coverage.csv: 6 significant digits, empty when missing or not finite."""
    return f"{v:.6g}" if isinstance(v, (int, float)) and math.isfinite(v) else ""


def _stage(out: Path) -> Path:
    """A new folder beside ``out`` to build the job in; stale ones of jobs that were killed are removed first."""
    import tempfile

    out.parent.mkdir(parents=True, exist_ok=True)
    for old in out.parent.glob(f".{out.name}.dock-*.tmp"):
        try:
            pid = int(old.name.rsplit(".dock-", 1)[1].split("-", 1)[0])
            os.kill(pid, 0)
        except ProcessLookupError:
            shutil.rmtree(old, ignore_errors=True)  # its job is gone
        except (ValueError, IndexError, PermissionError):
            pass
    # mkdtemp makes it 0700; the folder it becomes is read by others (dask workers, a team): as mkdir would make it
    return as_mkdir(Path(tempfile.mkdtemp(prefix=f".{out.name}.dock-{os.getpid()}-", suffix=".tmp", dir=out.parent)))


def dock_patients(
    robot: str | os.PathLike[str] | BuiltRobot,
    patients: Sequence[PatientPlan],
    out: str | os.PathLike[str],
    settings: RunSettings,
    reqs: Sequence[Requirement],
    *,
    seed: int = 1,
    starts: int = 8,
    evaluations: int = DOCK_EVALUATIONS,
    workers: int = 1,
    dask: str | None = None,
    on_docking: Callable[[DockingOutcome], None] | None = None,
    extra: dict[str, Any] | None = None,
) -> DockResult:
    """Dock ``robot`` (a robot file or a :class:`BuiltRobot`) on every side of ``patients`` into the new folder ``out``
    (module docstring); ``settings``: the design job's (:func:`~arcube.design_job.job.design_settings`); ``on_docking`` is
    told each side's outcome as it is found; ``extra`` goes into summary.json beside the settings."""
    from arcube.optimization import run as runmod

    out = Path(out)
    runmod.check_new_folder(out)
    for name, value, least in (("starts", starts, 1), ("evaluations", evaluations, 100), ("workers", workers, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise InputError.of(name, f"must be an integer >= {least}, got {value!r}")
    if dask and workers > 1:
        raise InputError.of("workers", "and dask exclude each other (the Dask cluster has its own workers)")
    if dask:
        from arcube.optimization.executors import check_dask_address

        check_dask_address(dask)
    built = robot if isinstance(robot, BuiltRobot) else read_robot(robot)
    names = [p.name for p in patients]
    if len(set(names)) != len(names):
        raise InputError.of(
            "plan", f"two patients are named {next(n for n in names if names.count(n) > 1)!r}: each needs its own name"
        )
    started = time.perf_counter()
    stage = _stage(out)
    try:
        jobs = docking_jobs(
            built, patients, settings, reqs, seed=seed, starts=starts, evaluations=evaluations, folder=stage
        )
        outcomes = run_jobs(jobs, workers, dask, on_docking)
        summary = {
            "format": DOCK_FORMAT,
            "format_version": 1,
            "robot_file": built.source,
            **coverage_summary(built, outcomes),
            "settings": {
                "seed": int(seed),
                "starts": int(starts),
                "evaluations": int(evaluations),
                "requirements": [[r.name, r.kind, r.limit] for r in reqs],
                "tolerance_class": settings.tolerance_class,
                "points": settings.points,
                "standoff_mm": settings.standoff,
                "envelope": list(settings.envelope),
            },
            "wall_s": round(time.perf_counter() - started, 1),
            **(extra or {}),
        }
        atomic_write_text(stage / "coverage.csv", coverage_csv(summary["dockings"]))
        atomic_write_text(stage / "summary.json", json.dumps(finite(summary), indent=2, allow_nan=False) + "\n")
        from arcube.report.coverage import write_coverage_report

        write_coverage_report(stage / "report.html", summary)
        if out.is_dir():
            out.rmdir()  # empty (checked above)
        os.replace(stage, out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return DockResult(out, summary["met"] == summary["sides"], summary)


def dock(
    robot: str | os.PathLike[str],
    plan: Any = None,
    out: str | os.PathLike[str] | None = None,
    *,
    cohort: str | os.PathLike[str] | None = None,
    seed: int = 1,
    starts: int = 8,
    evaluations: int = DOCK_EVALUATIONS,
    minima: Any = None,
    maxima: Any = None,
    drop: Sequence[str] = (),
    settings: RunSettings | None = None,
    workers: int = 1,
    dask: str | None = None,
    on_docking: Callable[[DockingOutcome], None] | None = None,
    **fields: Any,
) -> DockResult:
    """Dock a built robot on every side of a plan or a cohort (``arcube dock``, model §19.6); the robot is not changed.

    Args:
        robot: a design.json of ``arcube design`` (the robot and its dockings) or any docking's design file; its
            parameters, working mode and z-dyad elbow are used as they are, its dockings as warm starts.
        plan: one plan (None: the bundled reference patient), each of its sides a docking; or ``cohort``.
        out: the folder to create (absent or empty); see the module docstring for what it holds.
        cohort: a cohort file (:mod:`arcube.design_job.cohort`) instead of ``plan``.
        seed: the searches' seed (each side's search is seeded by it and the side's label).
        starts: CMA-ES runs per side (>= 1); evaluations: each side's search budget.
        minima: the requirements, as :func:`arcube.design` takes them (the same defaults).
        maxima: see ``minima``.
        drop: see ``minima``.
        settings: the design job's other settings (anatomy, envelope, standoff, points, side, class, ...).
        fields: see ``settings``.
        workers: the sides over local processes, or as tasks of a dask.distributed scheduler.
        dask: see ``workers``.
        on_docking: told each side's :class:`~arcube.design_job.dock.DockingOutcome` as it is found.

    Returns:
        A :class:`DockResult` (``met``: every side; ``coverage``; ``summary``; ``path``).
    """
    from arcube.design_job.cohort import plans_as_cohort, read_cohort
    from arcube.io import TrajectorySet
    from arcube.optimization.config import run_settings
    from arcube.design_job.requirements import design_settings, requirements_from

    if out is None:
        raise InputError.of("out", "is required (the folder of the dockings)")
    reqs = requirements_from(minima, maxima, drop)
    if cohort is not None and plan is not None:
        raise InputError.of("cohort", "replaces the plans: give a cohort file or trajectories, not both")
    if settings is None and "anatomy" not in fields:
        fields = {**fields, "anatomy": "default"}  # each patient's default anatomy, as arcube design with a cohort
    if settings is not None and not isinstance(settings, RunSettings):
        raise InputError.of("settings", f"must be an arcube.RunSettings, got {type(settings).__name__}")
    s = design_settings(reqs, run_settings(settings, **fields))
    if cohort is not None:
        patients = read_cohort(cohort, side=s.side, levels=s.levels, ids=s.ids, transform=s.transform)
    else:
        plans = list(plan) if isinstance(plan, (list, tuple)) else ["reference" if plan is None else plan]
        patients = plans_as_cohort([p if isinstance(p, TrajectorySet) else os.fspath(p) for p in plans]) or []
    return dock_patients(
        robot,
        patients,
        out,
        s,
        reqs,
        seed=seed,
        starts=starts,
        evaluations=evaluations,
        workers=workers,
        dask=dask,
        on_docking=on_docking,
    )
