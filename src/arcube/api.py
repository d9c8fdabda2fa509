"""The public Python API: evaluate a design, optimize one, read a run. The CLI calls exactly these.

```python
import arcube
design = arcube.Design.paper()                       # or arcube.Design.load("best_design.json")
plan = arcube.load_trajectories("reference")         # CSV, Slicer markups, a folder
ev = arcube.evaluate(design, plan, points=30, mode=(1, 1, 1, 1), guards=False)
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
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.engine import resolve
from arcube.evaluation.result import Evaluation, evaluate_design, load_trajectory_set
from arcube.io.trajectories import TrajectorySet, select, validate_points
from arcube.model.body import BodyRadii
from arcube.model.design import Design
from arcube.model.mechanism import format_mode, parse_mode
from arcube.optimization.settings import RunSettings
from arcube.options import GUARDED_OPTIONS, Options

from arcube.design_job import DesignResult
from arcube.program import Planner, Program, ProgramLimits, program  # noqa: F401 (re-exported by arcube)
from arcube.report.study import write_study_convergence
from arcube.results import OptimizeResult, Run, Study

if TYPE_CHECKING:
    from arcube.evaluation.anatomy import Anatomy

__all__ = ["OptimizeResult", "Run", "Study", "design", "evaluate", "optimize", "resume", "study"]

PathLike = str | os.PathLike[str]


def _design(design: Design | PathLike | Sequence[float]) -> Design:
    return Design.coerce(design)


def _signs(mode: str | Sequence[float]) -> np.ndarray:
    """A working mode as text (``"+,+,-,+"``) or four signs (``(1, 1, -1, 1)``) -> signs ``(4,)``."""
    try:
        return parse_mode(mode if isinstance(mode, str) else format_mode(mode) if len(list(mode)) == 4 else repr(mode))
    except (TypeError, ValueError) as exc:
        raise InputError(f"mode: {exc}", param="mode") from None


def _points(points: Any) -> int:
    from arcube.evaluation.task import MAX_POINTS

    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or not 2 <= points <= MAX_POINTS:
        raise InputError.of("points", f"must be an integer in [2, {MAX_POINTS}] (both ends of a trajectory included), got {points!r}")
    return int(points)


def evaluate(
    design: Design | PathLike = "paper",
    plan: TrajectorySet | PathLike = "reference",
    *,
    points: int = 30,
    mode: str | Sequence[float] = "+,+,+,+",
    guards: bool = False,
    options: Options | None = None,
    side: str | None = None,
    levels: str | Sequence[str] | None = None,
    ids: str | Sequence[str] | None = None,
    transform: PathLike | None = None,
    engine: str = "auto",
    anatomy: Anatomy | Sequence[PathLike] | PathLike | None = None,
    anatomy_frame: str = "LPS",
    clearance: float | None = None,
    self_clearance: float | None = None,
    radii: BodyRadii | None = None,
    encoder_deg: float | Sequence[float] | None = None,
    thrust: float | None = None,
    lateral_force: float | None = None,
    actuator_stiffness: float | Sequence[float] | None = None,
) -> Evaluation:
    """Evaluate one design on a drilling plan (MODEL.md 8): reachability, seven condition numbers, dexterity.

    Args:
        design: a :class:`Design`, a preset name (``"paper"``) or a design JSON path.
        plan: a :class:`TrajectorySet` or what :func:`arcube.load_trajectories` reads
            (CSV, Slicer ``.mrk.json`` file or folder, ``"reference"``).
        points: N samples per trajectory (>= 2), both ends included.
        mode: working mode, the signs of TMS x, TMS y, RTS x, RTS y: ``(1, 1, -1, 1)`` or ``"+,+,-,+"``.
        guards: turn on the guards of MODEL.md 8.2 (all but the z dyad); ignored when ``options`` is given.
        options: explicit :class:`arcube.Options` (guards, body, loads); the keywords below change it.
        side, levels, ids: keep only some trajectories (``"R"``, ``"C3-C5"`` or ``["C3", "C4"]``, ``"1,3"`` or ``["1", "3"]``).
        transform: a JSON 4x4 rigid transform from the file's frame to the patient frame (file plans only).
        engine: ``auto`` (compiled kernel when available), ``numba`` or ``numpy`` (the reference).
        anatomy: an :class:`~arcube.evaluation.anatomy.Anatomy`, ``"default"`` (the plan's default
            anatomy, MODEL.md 14.2), mesh files (STL/OBJ/PLY) in ``anatomy_frame`` (LPS, RAS or
            patient), or None: then no clearance to the anatomy is computed.
        clearance, self_clearance: the guards ``clearance >= MM`` (``collision/patient``) and
            ``self_clearance >= MM`` (``collision/self``) of MODEL.md 14.3 (``Guards.clearance_mm``, ...).
        radii: the body radii of MODEL.md 14.1 (default 8 / 25 / 20 mm, motor 120 mm long).
        encoder_deg, thrust, lateral_force, actuator_stiffness: the parameters of the tip metrics of MODEL.md 15
            (deg, N, N, N·m/rad; encoder and stiffness one value or five); None keeps ``options``'s
            (defaults 0.01 deg, 30 N, 10 N, 1e4 N·m/rad).

    Returns:
        An :class:`Evaluation` (``.summary``, ``.points``, ``.to_json()``, ``.to_dataframe()``).
    """
    signs = _signs(mode)
    try:
        engine_name = resolve(engine)
    except ValueError as exc:
        raise InputError.of("engine", str(exc)) from None
    n = _points(points)
    d = _design(design)
    levels_text = levels if levels is None or isinstance(levels, str) else ",".join(levels)
    ids_text = ids if ids is None or isinstance(ids, str) else ",".join(str(i) for i in ids)
    if isinstance(plan, TrajectorySet):
        validate_points([f"{plan.source} trajectory {i}" for i in plan.ids], plan.ids, np.asarray(plan.entry), np.asarray(plan.target))
        ts = select(plan, side=side, levels=levels_text, ids=ids_text) if (side or levels_text or ids_text) else plan
    else:
        ts = load_trajectory_set(os.fspath(plan), n, side, levels_text, ids_text, None if transform is None else Path(transform))
    base = options if options is not None else (GUARDED_OPTIONS if guards else Options())
    changes: dict[str, Any] = {"clearance_mm": clearance, "self_clearance_mm": self_clearance, "encoder_deg": encoder_deg,
                               "thrust_N": thrust, "lateral_force_N": lateral_force, "actuator_stiffness": actuator_stiffness}  # fmt: skip
    if radii is not None:
        changes.update(link_radius=radii.link, actuator_radius=radii.actuator, motor_radius=radii.motor, motor_length=radii.motor_length)
    opts = base.replace(**{k: v for k, v in changes.items() if v is not None})
    opts = opts.replace(outputs=opts.outputs.replace(clearances=True))
    anat = resolve_anatomy(anatomy, anatomy_frame, plan)
    if opts.guards.clearance_mm is not None and anat is None:
        raise InputError.of("Guards.clearance_mm", "needs an anatomy (anatomy default or mesh files)")
    return evaluate_design(d, ts, n, signs, opts, engine_name, anatomy=anat)


def _plans(plan: Any) -> list[Any]:
    plans = list(plan) if isinstance(plan, (list, tuple)) else [plan]
    return [p if isinstance(p, TrajectorySet) else os.fspath(p) for p in plans]


def _settings(settings: Any, fields: dict[str, Any], what: str) -> RunSettings:
    from arcube.optimization.config import run_settings

    if settings is not None and not isinstance(settings, RunSettings):
        raise InputError.of("settings", f"must be an arcube.RunSettings (give the {what} folder as out=...), got {type(settings).__name__}")
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
) -> Any:
    """Optimize the design (MODEL.md 12): minimize eta_G subject to every point reachable.

    Args:
        plan: one plan or several (a robust problem over patients); each a :class:`TrajectorySet`
            or what :func:`arcube.load_trajectories` reads.
        settings: a :class:`arcube.RunSettings` (algorithm, budget, seed, free parameters, bounds,
            objectives, limits, docking, options); None: the defaults.
        out: the run folder to create (must be absent or empty); None runs in memory and writes nothing.
        progress: called with each generation's history row.
        workers, dask: evaluate each population over local processes or a dask.distributed scheduler.
        **fields: changes to ``settings`` by field name (``population=40``, ``free=["all", "L"]``);
            the flat option names ``clearance``, ``thrust``, ``link_radius``, ... are accepted.

    Returns:
        The finished :class:`Run` (with ``out``) or an :class:`OptimizeResult` (in memory).
    """
    from arcube.optimization import run as runmod
    from arcube.optimization.config import build_config

    s = _settings(settings, fields, "run")
    specs = _plans(plan)
    cfg = build_config(specs, s, workers=workers, dask=dask)
    if out is None:
        return _optimize_in_memory(cfg, specs, progress)
    run_dir = Path(out)
    runmod.check_new_folder(run_dir)
    runmod.start(run_dir, cfg, on_generation=progress)
    return Run(run_dir)


def _optimize_in_memory(cfg: dict[str, Any], specs: list[Any], progress: Callable[[dict[str, Any]], None] | None) -> OptimizeResult:
    """Run ``cfg`` with nothing written: the same designs and summary as a run folder's."""
    import time

    from arcube.optimization.algorithms import stop_reason
    from arcube.optimization.loop import HISTORY_COLUMNS, describe, run_algorithm
    from arcube.optimization.build import build_model, stl_roundtrip
    from arcube.optimization.executors import make_executor

    s = RunSettings.from_table(cfg["settings"])
    anatomies = tuple(stl_roundtrip(resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec)) for spec in specs) if s.anatomy else ()
    for p, spec in zip(cfg["patients"], specs):
        if s.anatomy:
            p["anatomy_source"] = resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec).source
    model = build_model(cfg, anatomies=anatomies)
    ex = cfg["executor"]
    executor = make_executor(model, int(ex.get("workers", 1)), ex.get("dask") or None)
    rows: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    eval_s = 0.0

    def batch(X: np.ndarray) -> dict[str, np.ndarray]:
        nonlocal eval_s
        t = time.perf_counter()
        try:
            return executor(X)
        finally:
            eval_s += time.perf_counter() - t

    def generation(loop: Any, row: dict[str, Any]) -> None:
        rows.append({**row, "seconds": time.perf_counter() - t0})
        if progress is not None:
            progress({**rows[-1], "total": s.generations, "total_evaluations": s.population * s.generations, "eval_s": eval_s,
                      "optimizer_s": loop.algorithm_s - eval_s, "session_s": time.perf_counter() - t0})  # fmt: skip

    try:
        loop = run_algorithm(model, s, batch, on_generation=generation)
    finally:
        executor.close()
    info = {"generations": loop.generation, "evaluations": int(loop.algorithm.evaluator.n_eval), "wall_s": time.perf_counter() - t0,
            "eval_s": eval_s, "stopped_by": stop_reason(loop.termination), "resumed": 0}  # fmt: skip
    summary, designs, front = describe(cfg, model, loop.algorithm, info)
    history = {c: np.array([float(r[c]) for r in rows]) for c in HISTORY_COLUMNS}
    pareto = None if front is None else {k: np.array([r.get(k) for r in front]) for k in (front[0] if front else {})}
    return OptimizeResult(summary, [Design.from_vector(d) for d in designs], history, pareto, cfg)


def resume(path: PathLike, *, progress: Callable[[dict[str, Any]], None] | None = None, workers: int | None = None,
           dask: str | None = None, on_seed: Callable[[int, dict[str, Any]], None] | None = None) -> Run | Study | DesignResult:  # fmt: skip
    """Continue an interrupted run from its checkpoint, or finish an interrupted study or design job
    (the same result as an uninterrupted one); returns the :class:`Run`, the :class:`Study` or the
    :class:`~arcube.design_job.DesignResult`."""
    from arcube.design_job import STUDY, finish_design, is_design, read_design
    from arcube.optimization import run as runmod
    from arcube.optimization import study as studymod

    run_dir = Path(path)
    if is_design(run_dir):
        read_design(run_dir)
        if not (run_dir / STUDY / "summary.json").exists():
            studymod.resume_study(run_dir / STUDY, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
            write_study_convergence(run_dir / STUDY)
        return finish_design(run_dir)
    if studymod.is_study(run_dir):
        studymod.resume_study(run_dir, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
        write_study_convergence(run_dir)
        return Study(run_dir)
    cfg, raw = runmod.read_config(run_dir)
    runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
    runmod.resume(run_dir, workers=workers if workers is not None else (1 if dask else None), dask=dask, on_generation=progress)
    return Run(run_dir)


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
        plan, settings, fields: as :func:`optimize` takes them (every setting but ``seed``).
        out: the study folder to create (must be absent or empty).
        seeds: ``"1-5"``, ``"1,3,7"``, ``"1-3,10"`` or a sequence of integers.
        workers, dask: run that many seeds at once in local processes, or each seed as a task on a
            dask.distributed scheduler (its workers must see ``out``); each seed's run itself uses one process.
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
    seed_list = studymod.parse_seeds(seeds if isinstance(seeds, str) else ",".join(str(int(s)) for s in seeds))
    s = _settings(settings, fields, "study")
    base = build_config(_plans(plan), s.replace(seed=seed_list[0]))
    studymod.start_study(Path(out), base, seed_list, workers=workers, dask=dask, best_known=best_known, on_seed=on_seed, on_generation=progress)
    write_study_convergence(Path(out))
    return Study(Path(out))


def design(
    plan: TrajectorySet | PathLike | Sequence[TrajectorySet | PathLike] = "reference",
    out: PathLike | None = None,
    *,
    seeds: str | Sequence[int] = "1-3",
    minima: dict[str, float] | None = None,
    maxima: dict[str, float] | None = None,
    drop: Sequence[str] = (),
    settings: RunSettings | None = None,
    workers: int = 1,
    dask: str | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
    on_seed: Callable[[int, dict[str, Any]], None] | None = None,
    **fields: Any,
) -> DesignResult:
    """Find a robot that meets every requirement (``arcube design``; MODEL.md 16-17).

    Args:
        plan: one plan or several (one placement per patient).
        out: the design folder to create (must be absent or empty).
        seeds: one optimization per seed (``"1-3"`` or a sequence).
        minima, maxima: change a requirement's limit (``{"clearance": 8}``, ``{"torque": 15}``);
            the defaults are clearance >= 5 mm, self_clearance >= 2 mm, lateral_error <= 0.5 mm,
            axis_error <= 0.25 deg, torque <= 20 N m.
        drop: requirements to drop (``["torque"]``).
        settings, fields: the optimization's budget, engine, anatomy, objectives, standoff (as
            :func:`optimize` takes them); the free parameters, working mode, guards and limits are
            the design job's.

    Returns:
        A :class:`~arcube.design_job.DesignResult` (``met``, ``summary``, ``rows``, ``design``).
    """
    from arcube.design_job import DESIGN_GENERATIONS, design_settings, start_design
    from arcube.optimization import study as studymod
    from arcube.optimization.requirements import requirements_from

    if out is None:
        raise InputError.of("out", "is required (the design folder)")
    reqs = requirements_from(minima, maxima, drop)
    if settings is None and "generations" not in fields:
        fields = {**fields, "generations": DESIGN_GENERATIONS}  # the design job's budget, as the CLI's
    seed_list = studymod.parse_seeds(seeds if isinstance(seeds, str) else ",".join(str(int(s)) for s in seeds))
    s = design_settings(reqs, _settings(settings, fields, "design"))
    return start_design(Path(out), _plans(plan), s, reqs, seed_list, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
