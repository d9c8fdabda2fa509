"""The public Python API: evaluate a design, optimize one, read a run. The CLI calls exactly these.

```python
import arcube
design = arcube.Design.paper()                       # or arcube.Design.load("best_design.json")
plan = arcube.load_trajectories("reference")         # CSV, Slicer markups, a folder
ev = arcube.evaluate(design, plan, points=30, mode=(1, 1, 1, 1), guarded=False)
ev.summary["eta_G"], ev.points.dexterity_pct
result = arcube.optimize(plan, arcube.RunSettings(population=40, generations=5, seed=1))   # in memory
result.best_design, result.summary["eta_G"], result.history
run = arcube.optimize(plan, arcube.RunSettings(population=40, generations=5, seed=1), out="run")  # a run folder
```

Every function raises :class:`arcube.InputError` with a one-line message that names the argument
or setting as written here (the CLI replaces it with its flag).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np


from arcube.coerce import engine_name, points as checked_points, seeds as checked_seeds
from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.result import Evaluation, evaluate_design
from arcube.io.trajectories import TrajectorySet
from arcube.model.design import Design
from arcube.optimization.settings import RunSettings
from arcube.options import Options, request_options
from arcube.request import Request

from arcube.design_job import DesignResult
from arcube.motion import Planner, Program, ProgramLimits  # noqa: F401 (re-exported by arcube)
from arcube.report.study import write_study_convergence
from arcube.optimization.run_results import OptimizeResult, Study

if TYPE_CHECKING:
    from arcube.accuracy import ToleranceResult, ToleranceSettings
    from arcube.evaluation.envelope import Envelope
    from arcube.evaluation.anatomy import Anatomy
    from arcube.export.joints import JointTrajectory

__all__ = [
    "OptimizeResult",
    "Study",
    "design",
    "evaluate",
    "joints",
    "optimize",
    "program",
    "resume",
    "study",
    "tolerance",
]

PathLike = str | os.PathLike[str]


def evaluate(
    design: Design | PathLike = "paper",
    plan: TrajectorySet | PathLike = "reference",
    *,
    options: Options | None = None,
    points: int = 30,
    mode: str | Sequence[float] | None = None,
    guarded: bool = False,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    transform: PathLike | None = None,
    engine: str = "auto",
    anatomy: Anatomy | Sequence[PathLike] | PathLike | None = None,
    anatomy_frame: str = "LPS",
    segments: str | Sequence[str | int] | None = None,
    envelope: Any = None,
    table_z: float | None = None,
    **changes: Any,
) -> Evaluation:
    """Evaluate one design on a drilling plan (model §8): reachability, seven condition numbers,
    dexterity, clearances (14.3) and the drill-tip metrics (15).

    Args:
        design: a :class:`Design`, a preset name (``"paper"``) or a design JSON path; or an :class:`arcube.Request`
            (the design, plan, selection, anatomy, envelope, mode, points and options in one, for asking the same of
            :func:`joints`, :func:`program` and :func:`arcube.explore` too; the keywords it holds then stay unset).
        plan: a :class:`TrajectorySet` or what :func:`arcube.load_trajectories` reads
            (CSV, Slicer ``.mrk.json`` file or folder, ``"reference"``).
        options: the :class:`arcube.Options` of the evaluation (guards, body, loads, masses); None:
            the paper's model, with the guards of model §8.2 when ``guarded``.
        points: N samples per trajectory (>= 2), both ends included.
        mode: working mode, the signs of TMS x, TMS y, RTS x, RTS y: ``(1, 1, -1, 1)`` or ``"+,+,-,+"``;
            None: the design's own (:attr:`Design.mode`), else ``+,+,+,+``.
        side: keep only some trajectories (``"R"``, ``"C3-C5"`` or ``["C3", "C4"]``, ``"1,3"`` or ``["1", "3"]``).
        levels: see ``side``.
        ids: see ``side``.
        transform: a JSON 4x4 rigid transform from the file's frame to the patient frame (file plans only).
        engine: ``auto`` (compiled kernel when available), ``numba`` or ``numpy`` (the reference).
        anatomy: an :class:`~arcube.evaluation.anatomy.Anatomy`, ``"default"`` (the plan's default
            anatomy, model §14.2), mesh files (STL/OBJ/PLY) in ``anatomy_frame`` (LPS, RAS or
            patient), or None: then no clearance to the anatomy is computed; or a segmentation
            (``.seg.nrrd``, ``.nii``, ``.nii.gz``), of which ``segments`` keeps some (names or label values).
        envelope: the envelope of the whole patient and the table (model §19.5): ``"default"`` (a
            coarse body on the plan's landmarks), skin mesh files, or None / ``"none"``; with one, the clearance to
            it at every point (and its guard, ``envelope_clearance_mm=MM``).
        table_z: see ``envelope``.
        **changes: settings of ``options`` by name or short name (``clearance=5``, ``thrust=25``,
            ``link_radius=6``, ``encoder_deg=0.02``; see :data:`arcube.options.FLAT`).

    Returns:
        An :class:`Evaluation` (``.summary``, ``.points``, ``.to_json()``, ``.to_dataframe()``).
    """
    req = Request.of(locals(), evaluate)
    engine_resolved = engine_name(engine)
    r = _request(req, guarded, changes)
    opts = r.options.replace(outputs=r.options.outputs.replace(clearances=True))
    return evaluate_design(
        r.design, r.plan, r.points, r.signs, opts, engine_resolved, anatomy=r.anatomy, envelope=r.envelope
    )


class _Request(NamedTuple):
    """One request's arguments, coerced and checked: what :func:`evaluate` and :func:`joints` compute with."""

    design: Design
    plan: TrajectorySet
    points: int
    signs: np.ndarray
    options: Options
    anatomy: Anatomy | None
    envelope: Envelope | None


def _request(req: Request, guarded: bool, changes: dict[str, Any]) -> _Request:
    """``req`` resolved (:meth:`Request.resolve`), its points and options checked before the slow anatomy (the options:
    ``req.options``, else the paper's with the guards of model §8.2 when ``guarded``, changed by ``changes``)."""
    from arcube.request import with_design_c_z

    own: dict[str, Any] = {}

    def before_anatomy(_: TrajectorySet) -> None:  # the request's own arguments, checked before the slow anatomy
        own.update(n=checked_points(req.points), opts=request_options(req.options, guarded, **changes))

    r = req.resolve(before_anatomy)
    n, opts = own["n"], with_design_c_z(own["opts"], r.design)
    if opts.guards.clearance_mm is not None and r.anatomy is None:
        raise InputError.of("Guards.clearance_mm", "needs an anatomy (anatomy default or mesh files)")
    if opts.guards.envelope_clearance_mm is not None and r.envelope is None:
        raise InputError.of("Guards.envelope_clearance_mm", "needs an envelope (envelope default or a skin mesh)")
    return _Request(r.design, r.plan, n, r.signs, opts, r.anatomy, r.envelope)


def joints(
    design: Design | PathLike = "paper",
    plan: TrajectorySet | PathLike = "reference",
    *,
    speed: float = 1.0,
    options: Options | None = None,
    points: int = 30,
    mode: str | Sequence[float] | None = None,
    guarded: bool = False,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    transform: PathLike | None = None,
    anatomy: Any = None,
    anatomy_frame: str = "LPS",
    segments: Any = None,
    **changes: Any,
) -> JointTrajectory:
    """Joint angles (deg) and rates (deg/s) for drilling each trajectory of a plan at ``speed`` mm/s
    (``arcube joints``); the other arguments as :func:`evaluate` takes them. With
    ``options.outputs.holding_torque`` also the holding torque of model §18.2 per row.
    ``.write_csv(path)`` writes the CSV."""
    import math

    from arcube.evaluation.task import build_task
    from arcube.export.joints import joint_trajectory

    req = Request.of(locals(), joints)
    from arcube.motion.limits import MAX_SPEED_MM_S

    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (math.isfinite(speed) and speed > 0.0):
        raise InputError.of("speed", f"must be a finite positive number of mm/s, got {speed!r}")
    if speed > MAX_SPEED_MM_S:  # as a program's speeds (ProgramLimits)
        raise InputError.of(
            "speed", f"must be at most {MAX_SPEED_MM_S:g} mm/s (beyond any drilling robot), got {speed:g}"
        )
    r = _request(req, guarded, changes)
    task = build_task(r.plan.entry, r.plan.target, r.points, ids=r.plan.ids)
    return joint_trajectory(
        r.design, task, float(speed), r.signs, r.options, None if r.anatomy is None else r.anatomy.distance
    )


def tolerance(
    design: Design | PathLike = "paper",
    plan: TrajectorySet | PathLike = "reference",
    out: PathLike | None = None,
    *,
    settings: ToleranceSettings | None = None,
    points: int = 30,
    mode: str | Sequence[float] | None = None,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    transform: PathLike | None = None,
    engine: str = "auto",
    **fields: Any,
) -> ToleranceResult:
    """The accuracy budget of a robot built to tolerances (model §20; ``arcube tolerance``): the first-order
    worst case and RMS of the lateral, axial and axis errors at every point of the plan, each error
    source's share, and the Monte Carlo over built robots (p95 of each robot's largest lateral error).

    Args:
        design: as :func:`evaluate` takes them (``mode``
            None: the design's own).
        plan: see ``design``.
        points: see ``design``.
        mode: see ``design``.
        side: see ``design``.
        levels: see ``design``.
        ids: see ``design``.
        transform: see ``design``.
        out: a folder to create (new or empty) with ``tolerance.json``, ``tolerance_points.csv``,
            ``sensitivity.csv`` and the pictures; None writes nothing.
        settings: an :class:`arcube.ToleranceSettings` and changes to it by field name
            (``tolerance_class="f"``, ``tol={"r": 0.02}``, ``samples=300``).
        fields: see ``settings``.
        engine: the first order's: ``numba`` (compiled), ``numpy`` (the reference) or ``auto``.
    """
    from arcube.accuracy import ToleranceSettings as Tolerances
    from arcube.accuracy.budget import budget
    from arcube.evaluation.task import build_task
    from arcube.options import validated

    req = Request.of(locals(), tolerance)
    if settings is not None and not isinstance(settings, Tolerances):
        raise InputError.of("settings", f"must be an arcube.ToleranceSettings, got {type(settings).__name__}")
    s = (
        validated(Tolerances, {**(settings.model_dump() if settings is not None else {}), **fields})
        if fields or settings is None
        else settings
    )
    r = _request(req, False, {})
    task = build_task(r.plan.entry, r.plan.target, r.points, ids=r.plan.ids)
    result = budget(
        r.design, task.E, task.e, r.signs, s, [task.ids[i] for i in task.trajectory], task.k, engine=engine_name(engine)
    )
    if out is not None:
        from arcube.report.accuracy import write_budget

        write_budget(result, out)
    return result


def program(design: Any, plan: Any = "reference", out: PathLike | None = None, **kwargs: Any) -> Program:
    """The drilling program of ``design`` for a plan (model §17): :func:`arcube.motion.program`, and
    with ``out`` its timeline ``program.png`` beside ``program.csv`` and ``program.json`` (the three
    written as one: all or none). Arguments: those of :func:`arcube.motion.program` (``options``,
    ``anatomy``, ``mode``, ``order``, ``limits``, ``masses``, ``feed=1.0``, ...)."""
    from arcube.motion import program as build
    from arcube.report.program import timeline_png_bytes

    return build(design, plan, out, figures=lambda prog: {"program.png": timeline_png_bytes(prog)}, **kwargs)


def _plans(plan: Any) -> list[Any]:
    plans = list(plan) if isinstance(plan, (list, tuple)) else [plan]
    return [p if isinstance(p, TrajectorySet) else os.fspath(p) for p in plans]


def _settings(settings: Any, fields: dict[str, Any], what: str) -> RunSettings:
    from arcube.optimization.config import run_settings

    if settings is not None and not isinstance(settings, RunSettings):
        raise InputError.of(
            "settings",
            f"must be an arcube.RunSettings (give the {what} folder as out=...), got {type(settings).__name__}",
        )
    return run_settings(settings, **fields)


def optimize(
    plan: TrajectorySet | PathLike | Sequence[TrajectorySet | PathLike] = "reference",
    settings: RunSettings | None = None,
    out: PathLike | None = None,
    *,
    progress: Callable[[dict[str, Any]], None] | None = None,
    workers: int = 1,
    dask: str | None = None,
    **fields: Any,
) -> OptimizeResult:
    """Optimize the design (model §12): minimize eta_G subject to every point reachable.

    Args:
        plan: one plan or several (a robust problem over patients); each a :class:`TrajectorySet`
            or what :func:`arcube.load_trajectories` reads.
        settings: a :class:`arcube.RunSettings` (algorithm, budget, seed, free parameters, bounds,
            objectives, limits, docking, options); None: the defaults.
        out: the run folder to create (must be absent or empty); None runs in memory and writes nothing.
        progress: called with each generation's history row and timing.
        workers: evaluate each population over local processes or a dask.distributed scheduler.
        dask: see ``workers``.
        **fields: changes to ``settings`` by field name (``population=40``, ``free=["all", "L"]``);
            the options' short names ``clearance``, ``thrust``, ``link_radius``, ... are accepted.

    Returns:
        The finished run, an :class:`OptimizeResult`: in memory, or reading its folder (``.path``).
    """
    from arcube.optimization import run as runmod
    from arcube.optimization.build import stl_roundtrip
    from arcube.optimization.config import build_config

    s = _settings(settings, fields, "run")
    specs = _plans(plan)
    cfg = build_config(specs, s, workers=workers, dask=dask)
    if out is None:
        # per entry of the config (a patient, or one of its dockings: model §19), its plan's anatomy
        by_plan = (
            [resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec, segments=s.segments) for spec in specs]
            if s.anatomy
            else []
        )
        anatomies = tuple(by_plan[p.get("plan_index", i)] for i, p in enumerate(cfg.patients)) if by_plan else ()
        if anatomies:
            cfg = cfg.with_patients([{**cfg.patient(i), "anatomy_source": a.source} for i, a in enumerate(anatomies)])
        grids = {id(a): stl_roundtrip(a) for a in by_plan}
        return runmod.run_in_memory(cfg, tuple(grids[id(a)] for a in anatomies), progress)
    run_dir = Path(out)
    runmod.check_new_folder(run_dir)
    runmod.start(run_dir, cfg, on_generation=progress)
    return OptimizeResult(run_dir)


def resume(
    path: PathLike,
    *,
    progress: Callable[[dict[str, Any]], None] | None = None,
    workers: int | None = None,
    dask: str | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> OptimizeResult | Study | DesignResult:
    """Continue an interrupted run from its checkpoint, or finish an interrupted study or design job
    (the same result as an uninterrupted one); returns the :class:`OptimizeResult`, the :class:`Study`
    or the :class:`~arcube.design_job.DesignResult` (a design job tells ``on_stage`` its stages after the search)."""
    from arcube.design_job import STUDY, finish_design, is_design, read_design
    from arcube.optimization import run as runmod
    from arcube.optimization import study as studymod

    run_dir = Path(path)
    if is_design(run_dir):
        read_design(run_dir)
        if not (run_dir / STUDY / "summary.json").exists():
            studymod.resume_study(run_dir / STUDY, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
            write_study_convergence(run_dir / STUDY)
        return finish_design(run_dir, on_stage, workers or 1, dask)
    if studymod.is_study(run_dir):
        studymod.resume_study(run_dir, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
        write_study_convergence(run_dir)
        return Study(run_dir)
    cfg, raw = runmod.read_config(run_dir)
    runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
    runmod.resume(
        run_dir, workers=workers if workers is not None else (1 if dask else None), dask=dask, on_generation=progress
    )
    return OptimizeResult(run_dir)


def study(
    plan: TrajectorySet | PathLike | Sequence[TrajectorySet | PathLike] = "reference",
    out: PathLike | None = None,
    *,
    seeds: str | Sequence[int] = "1-5",
    workers: int = 1,
    dask: str | None = None,
    best_known: float | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    settings: RunSettings | None = None,
    **fields: Any,
) -> Study:
    """Run the same optimization once per seed and compare: how much does the optimum depend on luck?

    Args:
        plan: as :func:`optimize` takes them (every setting but ``seed``).
        settings: see ``plan``.
        fields: see ``plan``.
        out: the study folder to create (must be absent or empty).
        seeds: ``"1-5"``, ``"1,3,7"``, ``"1-3,10"`` or a sequence of integers.
        workers: run that many seeds at once in local processes, or each seed as a task on a
            dask.distributed scheduler (its workers must see ``out``); each seed's run itself uses one process.
        dask: see ``workers``.
        best_known: an eta_G to draw on the convergence figure.
        progress: each generation's history row, when the seeds run one after another in this process.
        on_seed: called with (seed, the run's summary) as each seed finishes.

    Returns:
        The finished :class:`Study` (``summary["best"]``, ``["median"]``, ``["worst"]``, ``best_design``).
    """
    from arcube.optimization import study as studymod
    from arcube.optimization.config import build_config

    if out is None:
        raise InputError.of("out", "is required (the study folder)")
    if "seed" in fields or (settings is not None and getattr(settings, "seed", None) is not None):
        raise InputError("a study sets each run's seed from seeds=...; drop seed=", param="seed")
    seed_list = checked_seeds(seeds)
    s = _settings(settings, fields, "study")
    base = build_config(_plans(plan), s.replace(seed=seed_list[0]))
    studymod.start_study(
        Path(out),
        base,
        seed_list,
        workers=workers,
        dask=dask,
        best_known=best_known,
        on_seed=on_seed,
        on_generation=progress,
    )
    write_study_convergence(Path(out))
    return Study(Path(out))


def design(
    plan: TrajectorySet | PathLike | Sequence[TrajectorySet | PathLike] | None = None,
    out: PathLike | None = None,
    *,
    cohort: PathLike | None = None,
    validate: PathLike | None = None,
    seeds: str | Sequence[int] = "1-3",
    minima: dict[str, float] | Sequence[str] | None = None,
    maxima: dict[str, float] | Sequence[str] | None = None,
    drop: Sequence[str] = (),
    settings: RunSettings | None = None,
    workers: int = 1,
    dask: str | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
    **fields: Any,
) -> DesignResult:
    """Find one robot that meets every requirement at every docking (``arcube design``; model §16-17, 19).

    Args:
        plan: one plan or several (None: the bundled reference patient); each patient's R and L trajectories
            are docked apart (``dockings="per-side"``, the default) or together (``dockings="per-patient"``).
        out: the design folder to create (must be absent or empty).
        cohort: a cohort file instead of ``plan`` (:mod:`arcube.design_job.cohort`): the patients, each with its own
            plan, anatomy and envelope (paths relative to the file).
        seeds: one optimization per seed (``"1-3"`` or a sequence).
        minima: change a requirement's limit (``{"clearance": 8}``, ``{"torque": 15}``, or
            ``["torque=15"]`` as the command line gives them: each name once);
            the defaults are clearance >= 5 mm, self_clearance >= 2 mm, lateral_error <= 0.5 mm,
            axis_error <= 0.25 deg, torque <= 20 N m.
        maxima: see ``minima``.
        drop: requirements to drop (``["torque"]``).
        settings: the optimization's budget, engine, anatomy, objectives, standoff (as
            :func:`optimize` takes them); the free parameters, working mode, guards and limits are
            the design job's.
        fields: see ``settings``.
        progress: told each generation's history row, each finished seed's summary
            and each stage after the search (``"building the drilling program ..."``).
        on_seed: see ``progress``.
        on_stage: see ``progress``.
        validate: a held-out cohort file, docked by the robot chosen into ``validation/`` (coverage: model §19.6).

    Returns:
        A :class:`~arcube.design_job.DesignResult` (``met``, ``summary``, ``rows``, ``design``).
    """
    from arcube.design_job import DESIGN_GENERATIONS, design_settings, start_design
    from arcube.design_job.requirements import requirements_from

    if out is None:
        raise InputError.of("out", "is required (the design folder)")
    reqs = requirements_from(minima, maxima, drop)
    if settings is None and "generations" not in fields:
        fields = {**fields, "generations": DESIGN_GENERATIONS}  # the design job's budget, as the CLI's
    if cohort is not None and plan is not None:
        raise InputError.of("cohort", "replaces the plans: give a cohort file or trajectories, not both")
    if cohort is not None and settings is None and "anatomy" not in fields:
        fields = {
            **fields,
            "anatomy": "default",
        }  # each patient's own anatomy (default: its plan's) comes from the cohort
    s = design_settings(reqs, _settings(settings, fields, "design"))
    from arcube.design_job.cohort import read_cohort

    plans = (
        read_cohort(cohort, side=s.side, levels=s.levels, ids=s.ids, transform=s.transform)
        if cohort is not None
        else _plans("reference" if plan is None else plan)
    )
    return start_design(
        Path(out),
        plans,
        s,
        reqs,
        checked_seeds(seeds),
        workers=workers,
        dask=dask,
        on_seed=on_seed,
        on_generation=progress,
        on_stage=on_stage,
        validate=validate,
    )
