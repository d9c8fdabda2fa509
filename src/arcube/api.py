"""The public Python API: evaluate a design, optimize one, read a run. The CLI calls exactly these.

```python
import arcube
design = arcube.Design.paper()                       # or arcube.Design.load("best_design.json")
plan = arcube.load_trajectories("reference")         # CSV, Slicer markups, a folder
ev = arcube.evaluate(design, plan, points=30, mode="+,+,+,+", guards=False)
ev.summary["eta_G"], ev.points.dexterity_pct
run = arcube.optimize(plan, out="run", population=40, generations=5, seed=1)
run.best_design, run.history, run.pareto
```

Every function raises :class:`arcube.InputError` with the one-line message the CLI prints.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.engine import resolve
from arcube.evaluation.reference import GUARDED_OPTIONS, Options, with_body, with_loads
from arcube.evaluation.result import Evaluation, evaluate_design, load_trajectory_set, parse_mode_option
from arcube.io.trajectories import TrajectorySet, select
from arcube.model.body import BodyRadii
from arcube.model.design import Design

if TYPE_CHECKING:
    from arcube.evaluation.anatomy import Anatomy

__all__ = ["Run", "evaluate", "optimize", "resume"]

PathLike = str | os.PathLike[str]


def _design(design: Design | PathLike) -> Design:
    return design if isinstance(design, Design) else Design.load(os.fspath(design))


def evaluate(
    design: Design | PathLike = "paper",
    plan: TrajectorySet | PathLike = "reference",
    *,
    points: int = 30,
    mode: str = "+,+,+,+",
    guards: bool = False,
    options: Options | None = None,
    side: str | None = None,
    levels: str | None = None,
    ids: str | None = None,
    transform: PathLike | None = None,
    engine: str = "auto",
    anatomy: Anatomy | Sequence[PathLike] | PathLike | None = None,
    anatomy_frame: str = "LPS",
    clearance: float | None = None,
    self_clearance: float | None = None,
    radii: BodyRadii | None = None,
    encoder_deg: float | list[float] | None = None,
    thrust: float | None = None,
    lateral_force: float | None = None,
    actuator_stiffness: float | list[float] | None = None,
) -> Evaluation:
    """Evaluate one design on a drilling plan (MODEL.md 8): reachability, seven condition numbers, dexterity.

    Args:
        design: a :class:`Design`, a preset name (``"paper"``) or a design JSON path.
        plan: a :class:`TrajectorySet` or what :func:`arcube.load_trajectories` reads
            (CSV, Slicer ``.mrk.json`` file or folder, ``"reference"``).
        points: N samples per trajectory (>= 2), both ends included.
        mode: working mode, the signs of TMS x, TMS y, RTS x, RTS y (``"+,+,-,+"``).
        guards: turn on the guards of MODEL.md 8.2 (all but the z dyad); ignored when ``options`` is given.
        options: explicit :class:`Options` (guards, z-dyad check).
        side, levels, ids: keep only some trajectories (``"R"``, ``"C3-C5"``, ``"1,3"``).
        transform: a JSON 4x4 rigid transform from the file's frame to the patient frame (file plans only).
        engine: ``auto`` (compiled kernel when available), ``numba`` or ``numpy`` (the reference).
        anatomy: an :class:`~arcube.evaluation.anatomy.Anatomy`, ``"default"`` (the plan's default
            anatomy, MODEL.md 14.2), mesh files (STL/OBJ/PLY) in ``anatomy_frame`` (LPS, RAS or
            patient), or None: then no clearance to the anatomy is computed.
        clearance, self_clearance: turn on the guards ``clearance >= MM`` (``collision/patient``)
            and ``self_clearance >= MM`` (``collision/self``) of MODEL.md 14.3.
        radii: the body radii of MODEL.md 14.1 (default 8 / 25 / 20 mm, motor 120 mm long).
        encoder_deg, thrust, lateral_force, actuator_stiffness: the parameters of the tip metrics of MODEL.md 15
            (deg, N, N, N·m/rad; encoder and stiffness one value or five); None keeps ``options``'s
            (defaults 0.01 deg, 30 N, 10 N, 1e4 N·m/rad).

    Returns:
        An :class:`Evaluation` (``.summary``, ``.points``, ``.to_json()``, ``.to_dataframe()``, ``.write_report()``).
    """
    signs = parse_mode_option(mode)
    try:
        engine_name = resolve(engine)
    except ValueError as exc:
        raise InputError(f"--engine: {exc}") from None
    d = _design(design)
    if isinstance(plan, TrajectorySet):
        if points < 2:
            raise InputError(f"--points must be at least 2 (both ends of a trajectory), got {points}")
        ts = select(plan, side=side, levels=levels, ids=ids) if (side or levels or ids) else plan
    else:
        ts = load_trajectory_set(os.fspath(plan), points, side, levels, ids, None if transform is None else Path(transform))
    opts = with_body(options if options is not None else (GUARDED_OPTIONS if guards else Options()),
                        clearance=clearance, self_clearance=self_clearance, radii=radii, body=True)
    opts = with_loads(opts, encoder_deg=encoder_deg, thrust=thrust, lateral_force=lateral_force, stiffness=actuator_stiffness)
    anat = resolve_anatomy(anatomy, anatomy_frame, plan)
    if opts.clearance_mm is not None and anat is None:
        raise InputError("--clearance needs an anatomy (--anatomy default or mesh files)")
    return evaluate_design(d, ts, points, signs, opts, engine_name, anatomy=anat)


@dataclass(frozen=True)
class Run:
    """An optimization run folder (``config.toml``, ``history.csv``, ``best_design.json``, ``summary.json``)."""

    path: Path

    @classmethod
    def load(cls, path: PathLike) -> Run:
        """Open an existing run folder (InputError if it is not one)."""
        p = Path(path)
        if not (p / "config.toml").exists():
            raise InputError(f"{p}: not an optimization run (no config.toml)")
        return cls(p)

    @property
    def summary(self) -> dict[str, Any]:
        """``summary.json``: feasible, eta_G, dexterity, generations, wall time, per-task details."""
        try:
            return json.loads((self.path / "summary.json").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{self.path}: the run has not finished (no summary.json)") from None

    @property
    def best_design(self) -> Design:
        """The best design found (right-side placement when the run had two setups)."""
        return Design.from_json(self.path / "best_design.json")

    @property
    def designs(self) -> list[Design]:
        """One complete design per patient (its own placement with per-patient docking, else the shared
        design for every patient); with two setups, the right-side ones."""
        from arcube.optimization import run as runmod

        cfg = runmod.read_config(self.path)[0]
        n = len(cfg["patients"])
        if cfg["settings"].get("docking", "shared") == "per-patient" and n > 1:
            return [Design.from_json(self.path / runmod.placement_file(p)) for p in range(n)]  # each must exist
        return [Design.from_json(self.path / "best_design.json") for _ in range(n)]

    @property
    def history(self) -> dict[str, np.ndarray]:
        """``history.csv`` as columns: generation, evaluations, best_eta_G, ... (NaN where empty)."""
        return _read_columns(self.path / "history.csv")

    @property
    def pareto(self) -> dict[str, np.ndarray] | None:
        """``pareto.csv`` as columns (multi-objective runs), else None."""
        path = self.path / "pareto.csv"
        return _read_columns(path) if path.exists() else None

    def write_report(self, anatomy: Any = None, anatomy_frame: str = "LPS", best_known: float | None = None) -> Path:
        """Write ``report.html`` (and PNGs; ``report_p<K>.html`` for each further patient) into the run folder; returns its path.

        ``anatomy``: None (the run's own, copied into its folder), ``"none"``, ``"default"`` or mesh
        files in ``anatomy_frame``, as :func:`evaluate` takes it. ``best_known``: an eta_G drawn as
        a reference line on the convergence plot.
        """
        from arcube.report.run_report import write_run_report

        override = None
        if anatomy is not None:
            from arcube.optimization import run as runmod

            plans = runmod.read_config(self.path)[0]["settings"].get("trajectories") or ["reference"]
            override = [resolve_anatomy(anatomy, anatomy_frame, plan) or "none" for plan in plans]  # each patient's own
        return write_run_report(self.path, anatomy=override, best_known=best_known)


def _read_columns(path: Path) -> dict[str, np.ndarray]:
    """A CSV of numbers (and a few text columns) as name -> array; numeric columns as float."""
    with path.open(encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return {}
    out: dict[str, np.ndarray] = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        try:
            out[key] = np.array([float(v) if v != "" else np.nan for v in values])
        except ValueError:
            out[key] = np.array(values)
    return out


def optimize(
    plan: TrajectorySet | PathLike | Sequence[TrajectorySet | PathLike] = "reference",
    out: PathLike | None = None,
    *,
    progress: Callable[[dict[str, Any]], None] | None = None,
    workers: int = 1,
    dask: str | None = None,
    **settings: Any,
) -> Run:
    """Optimize the design (MODEL.md 12): minimize eta_G subject to every point reachable.

    Args:
        plan: one plan or several (a robust problem over patients); each a :class:`TrajectorySet`
            or what :func:`arcube.load_trajectories` reads.
        out: the run folder to create (must be absent or empty).
        progress: called with each generation's history row.
        workers, dask: evaluate each population over local processes or a dask.distributed scheduler.
        **settings: the flags of ``arcube optimize`` as keywords: ``algorithm`` (ga, de, cmaes, nsga2),
            ``population``, ``generations``, ``tolerance``, ``points``, ``mode``, ``setups``, ``guards``,
            ``margin``, ``seed``, ``free``, ``design_from``, ``side``, ``levels``, ``ids``, ``engine``,
            ``aggregate``, ``compactness``, ``bounds``, ``checkpoint_every``, ``transform``,
            ``eliminate_duplicates``; ``objectives`` (``"eta_G,lateral_error"``, names of
            :data:`arcube.optimization.objectives.OBJECTIVES`), ``maxima`` / ``minima`` (``["torque=15"]``),
            ``encoder_deg``, ``thrust``, ``lateral_force``, ``actuator_stiffness`` (MODEL.md 15);
            ``docking`` (``"per-patient"``, the default, or ``"shared"``) for several plans.

    Returns:
        The finished :class:`Run`.
    """
    from arcube.optimization import run as runmod
    from arcube.optimization.config import build_config

    if out is None:
        raise InputError("--out DIR is required (the run folder)")
    plans = list(plan) if isinstance(plan, (list, tuple)) else [plan]
    specs = [p if isinstance(p, TrajectorySet) else os.fspath(p) for p in plans]
    cfg = build_config(specs, workers=workers, dask=dask, **settings)
    run_dir = Path(out)
    runmod.check_new_folder(run_dir)
    runmod.start(run_dir, cfg, on_generation=progress)
    return Run(run_dir)


def resume(path: PathLike, *, progress: Callable[[dict[str, Any]], None] | None = None, workers: int | None = None,
           dask: str | None = None, on_seed: Callable[[int, dict[str, Any]], None] | None = None) -> Run | Study:  # fmt: skip
    """Continue an interrupted run from its checkpoint, or finish an interrupted study (the same result
    as an uninterrupted one); returns the :class:`Run` or the :class:`Study`."""
    from arcube.optimization import run as runmod
    from arcube.optimization import study as studymod

    run_dir = Path(path)
    if studymod.is_study(run_dir):
        studymod.resume_study(run_dir, workers=workers, dask=dask, on_seed=on_seed, on_generation=progress)
        return Study(run_dir)
    cfg, raw = runmod.read_config(run_dir)
    runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
    runmod.resume(run_dir, workers=workers if workers is not None else (1 if dask else None), dask=dask, on_generation=progress)
    return Run(run_dir)


@dataclass(frozen=True)
class Study:
    """A design study folder: one optimization run per seed (``seed_<S>/``), ``study.csv``, ``summary.json``."""

    path: Path

    @classmethod
    def load(cls, path: PathLike) -> Study:
        """Open an existing study folder (InputError if it is not one)."""
        from arcube.optimization import study as studymod

        studymod.read_study(Path(path))
        return cls(Path(path))

    @property
    def summary(self) -> dict[str, Any]:
        """``summary.json``: objective, best / median / worst, best_seed, spread_pct, wall_s, one row per seed."""
        try:
            return json.loads((self.path / "summary.json").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{self.path}: the study has not finished (no summary.json)") from None

    @property
    def table(self) -> dict[str, np.ndarray]:
        """``study.csv`` as columns: seed, feasible, objective_<name>..., eta_G, generations, evaluations, wall_s."""
        if not (self.path / "study.csv").exists():
            raise InputError(f"{self.path}: the study has not finished (no study.csv)")
        return _read_columns(self.path / "study.csv")

    @property
    def best_design(self) -> Design:
        """The best seed's best design."""
        return Design.from_json(self.path / "best_design.json")

    @property
    def runs(self) -> dict[int, Run]:
        """Each seed's :class:`Run`."""
        from arcube.optimization import study as studymod

        seeds = studymod.read_study(self.path)[0]["seeds"]
        return {int(s): Run(studymod.seed_dir(self.path, int(s))) for s in seeds}


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
    **settings: Any,
) -> Study:
    """Run the same optimization once per seed and compare: how much does the optimum depend on luck?

    Args:
        plan, settings: as :func:`optimize` takes them (every setting but ``seed``).
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
        raise InputError("--out DIR is required (the study folder)")
    if "seed" in settings:
        raise InputError("a study sets each run's seed from seeds=...; drop seed=")
    seed_list = studymod.parse_seeds(seeds if isinstance(seeds, str) else ",".join(str(int(s)) for s in seeds))
    plans = list(plan) if isinstance(plan, (list, tuple)) else [plan]
    specs = [p if isinstance(p, TrajectorySet) else os.fspath(p) for p in plans]
    base = build_config(specs, seed=seed_list[0], **settings)
    studymod.start_study(Path(out), base, seed_list, workers=workers, dask=dask, best_known=best_known, on_seed=on_seed, on_generation=progress)
    return Study(Path(out))
