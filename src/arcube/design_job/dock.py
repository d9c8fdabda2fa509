"""Docking a built robot on one patient side (model §19.6): the six-variable problem, its starts, its search, its check.

The robot is fixed (its 22 parameters, working mode and z-dyad elbow, :class:`~arcube.model.robot.BuiltRobot`); the
variables are the placement m and the mounting angles. The problem is the design job's for one docking: the same
settings (:func:`arcube.design_job.job.design_settings`: guards, z dyad with the robot's c_z, envelope, standoff and
approach lines, the requirements as limits), so the violation is model §16's over the plan's points and the approach
lines, and the objective eta_G once it is 0.

The search (:func:`search`): the warm starts (each of the robot's own dockings carried onto this plan by the rigid
motions of :func:`arcube.optimization.docked.task_motions`) and a sample of random placements within the bounds are
evaluated in one batch; the best of them start ``starts`` CMA-ES runs in the six variables, advanced together
(:class:`~arcube.optimization.batch_cma.BatchCMA`), each restarted at a random placement when it stops, until the budget
is spent or, once a placement meets everything, the best has not improved for :data:`STALL` generations. The placements
the runs reached are then re-checked best first (:func:`solve_docking`) as the design job re-checks a robot: the NumPy
reference at the plan's points and approach lines, every requirement, and the drilling program built; the first that
passes is the docking, else the best one found is written as not met.

Every random draw comes from a generator seeded by the job's seed and the docking's label, so a docking's result does
not depend on which process or machine runs it, nor on the other dockings.
"""

from __future__ import annotations

import json
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from arcube.design_job.dockings import PLACEMENT, Docking, assess_dockings
from arcube.design_job.outputs import breach_check, build_program
from arcube.design_job.requirements import Requirement
from arcube.model.robot import BuiltRobot
from arcube.model.design import Design
from arcube.optimization.config import PatientPlan
from arcube.optimization.settings import RunSettings

__all__ = [
    "DOCK_EVALUATIONS",
    "DockingJob",
    "DockingOutcome",
    "docking_inputs",
    "docking_rng",
    "search",
    "solve_docking",
    "warm_starts",
]

DOCK_EVALUATIONS = 6000
"""Evaluations of one docking's search unless set (a search that holds four placements meeting everything stops earlier; 12 s
on one core when it does not, benchmarks/bench_dock.py)."""
RANDOM_SAMPLE = 64
"""Random placements drawn within the bounds, of which the best start the runs that no warm start begins."""
SIGMA = 0.1
"""The runs' initial step, in units of a placement gene's range (80 mm of m's 800, 36 deg of a mounting angle's 360)."""
TOL = 1e-4
"""The runs' stop tolerance on the objective (eta_G, or the penalized violation)."""
STALL = 25
"""Generations without a better best after which a search stops, once it holds :data:`CHECK_TRIES` distinct placements
that meet everything (a program blocked between the sampled points then has others to fall back on)."""
CHECK_TRIES = 4
"""The placements re-checked at most (best first) before the best one is written as not met."""
DISTINCT = 0.02
"""Two placements are told apart when some gene differs by more than this share of its range (16 mm, 7.2 deg)."""
RESTART_SAMPLE = 16
"""Random placements drawn when a run stops; the best of them starts it again."""
PENALTY = 1e6
"""As :data:`arcube.optimization.problem.PENALTY`: an infeasible row's objective is PENALTY * (1 + violation)."""


@dataclass(frozen=True)
class DockingJob:
    """One patient side to dock ``robot`` on; picklable (it runs in a worker process or on a dask worker).

    ``settings``: the design job's (:func:`~arcube.design_job.job.design_settings`), ``side``: ``R``, ``L``, or
    None for one docking over the whole plan (``dockings per-patient``); ``folder``: where the docking's files go."""

    robot: BuiltRobot
    patient: PatientPlan
    side: str | None
    settings: RunSettings
    reqs: tuple[Requirement, ...]
    seed: int
    starts: int
    evaluations: int
    folder: str

    @property
    def label(self) -> str:
        """``<patient>_<side>``: the docking's folder under ``dockings/`` and its name in tables."""
        return f"{self.patient.name}_{self.side or 'both'}"


@dataclass
class DockingOutcome:
    """What docking the robot on one side gave: the design written (the robot unchanged, at the chosen placement),
    its requirement rows (the design job's, the program's last), whether it is met, and the search's figures."""

    label: str
    patient: str
    side: str
    design: Design
    rows: list[dict[str, Any]]
    eta_G: float | None
    violation: float
    evaluations: int
    seconds: float
    tried: int
    found_by: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def met(self) -> bool:
        return bool(self.rows) and all(r["passed"] for r in self.rows)


def docking_rng(seed: int, label: str) -> np.random.Generator:
    """The generator of one docking's search: seeded by the job's seed and the docking's label only."""
    return np.random.default_rng([int(seed), zlib.crc32(label.encode("utf-8"))])


def warm_starts(robot: BuiltRobot, entry: np.ndarray, target: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(name, placement ``(6,)``) of each of the robot's dockings as it is, and carried onto a plan (``entry``, ``target``
    ``(T, 3)`` mm) by each rigid motion of :func:`~arcube.optimization.docked.task_motions` when the file records that
    docking's trajectories."""
    from arcube.optimization.docked import carried, task_motions

    out = []
    for w in robot.starts:
        out.append(
            (f"{w.label} as it is", w.placement.copy())
        )  # the same patient, or one close to it in the same frame
        if w.entry is None or w.target is None:
            continue
        for k, motion in enumerate(task_motions((w.entry, w.target), (entry, target))):
            how = ("by level", "in reverse", "by the centroids")[k]
            out.append((f"{w.label} carried {how}", carried(w.placement, motion)))
    return out


def _objective(batch: dict[str, np.ndarray]) -> np.ndarray:
    """Each row's objective: eta_G where it meets everything, else PENALTY * (1 + violation) (the design job's docking)."""
    V, E = batch["VIOL"], batch["ETA"]
    return np.where(V == 0.0, E, PENALTY * (1.0 + np.nan_to_num(V, nan=1e6, posinf=1e6)))


def search(
    model: Any,
    lo: np.ndarray,
    hi: np.ndarray,
    warm: Sequence[tuple[str, np.ndarray]],
    starts: int,
    evaluations: int,
    rng: np.random.Generator,
    wanted: int = CHECK_TRIES,
) -> tuple[list[tuple[float, np.ndarray, str]], int]:
    """Minimize the docking's objective over the placement box [lo, hi] ``(6,)``; returns the distinct placements the
    runs reached (at least :data:`DISTINCT` of each gene's range apart), best first, as (objective, placement ``(6,)``,
    how its run started), and the evaluations spent. The search stops when the budget is spent, or when ``wanted``
    distinct placements meet everything and the best has not improved for :data:`STALL` generations.

    ``model``: anything with ``evaluate(X (n, 6)) -> {"VIOL", "ETA", ...}``."""
    from arcube.optimization.batch_cma import BatchCMA
    from arcube.optimization.multistart import default_popsize, into_box

    span = hi - lo
    names = [name for name, _ in warm]
    warm_x = np.array([np.clip(x, lo, hi) for _, x in warm]).reshape(-1, 6)
    rand_x = lo + rng.random((RANDOM_SAMPLE, 6)) * span
    X0 = np.concatenate([warm_x, rand_x])
    F0 = _objective(model.evaluate(X0))
    spent = len(X0)
    n_warm = min(len(warm_x), max(1, starts // 2)) if len(warm_x) else 0
    order_w = np.argsort(F0[: len(warm_x)], kind="stable")[:n_warm]
    order_r = len(warm_x) + np.argsort(F0[len(warm_x) :], kind="stable")[: starts - n_warm]
    picks = [*order_w, *order_r]
    origin = [names[i] if i < len(warm_x) else "a random placement" for i in picks]
    lam = default_popsize(6)
    es = BatchCMA(len(picks), 6, lam, SIGMA, TOL)
    for r, i in enumerate(picks):
        es.restart(r, (X0[i] - lo) / span, np.random.default_rng(rng.integers(2**63)))
    run_best: list[tuple[float, np.ndarray, str]] = [
        (float(F0[i]), X0[i].copy(), origin[r]) for r, i in enumerate(picks)
    ]
    reached: list[tuple[float, np.ndarray, str]] = []
    best, stall = float(F0.min()), 0
    while spent + es.R * lam + RESTART_SAMPLE <= evaluations:
        X = lo + into_box(es.ask()) * span
        F = _objective(model.evaluate(X))
        spent += len(X)
        for r in range(es.R):
            j = r * lam + int(np.argmin(F[r * lam : (r + 1) * lam]))
            if F[j] < run_best[r][0]:
                run_best[r] = (float(F[j]), X[j].copy(), run_best[r][2])
        improved = float(F.min()) < best - 1e-9 * max(1.0, abs(best))
        best, stall = (float(F.min()), 0) if improved else (best, stall + 1)
        for r in np.flatnonzero(es.tell(F)):
            reached.append(run_best[r])
            # a fresh start: the best of a few random placements (most of the box reaches nothing)
            sample = lo + rng.random((RESTART_SAMPLE, 6)) * span
            Fs = _objective(model.evaluate(sample))
            spent += RESTART_SAMPLE
            k = int(np.argmin(Fs))
            es.restart(int(r), (sample[k] - lo) / span, np.random.default_rng(rng.integers(2**63)))
            run_best[r] = (float(Fs[k]), sample[k].copy(), "a restart at a random placement")
        if stall >= STALL and len(_distinct([t for t in [*reached, *run_best] if t[0] < PENALTY], span)) >= wanted:
            break
    return _distinct([*reached, *run_best], span), spent


def _distinct(found: Sequence[tuple[float, np.ndarray, str]], span: np.ndarray) -> list[tuple[float, np.ndarray, str]]:
    """``found`` best first, without the placements within :data:`DISTINCT` of a gene's range of a better one."""
    out: list[tuple[float, np.ndarray, str]] = []
    for f, x, how in sorted(found, key=lambda t: t[0]):
        if np.isfinite(f) and not any(np.all(np.abs(x - y) <= DISTINCT * span) for _, y, _ in out):
            out.append((f, x, how))
    return out


def docking_settings(settings: RunSettings, robot: BuiltRobot, side: str | None, seed: int) -> RunSettings:
    """The design job's settings with the robot fixed: only the placement and the mounting angles free, the robot's
    working mode, one docking (the side's, or the whole plan's)."""
    return settings.replace(
        free=list(PLACEMENT),
        mode=robot.design.mode,
        side=side,
        seed=int(seed),
        dockings="per-side" if side else "per-patient",
    )


def docking_inputs(job: DockingJob) -> tuple[Any, Docking, RunSettings, Any]:
    """What the docking is judged on, as the design job judges it: (the run's config, its Docking (plan of that side,
    anatomy, envelope, the robot at its first placement), the settings, the skin meshes of the envelope or None)."""
    from arcube.evaluation.anatomy import resolve_anatomy
    from arcube.evaluation.envelope import Envelope
    from arcube.io.load import load_plan
    from arcube.optimization.config import build_config, own_settings, patient_settings

    s = docking_settings(job.settings, job.robot, job.side, job.seed)
    cfg = build_config([job.patient], s)
    cfg = cfg.replace(design={**job.robot.design.to_dict(), "c_z": float(job.robot.design.c_z_mm)})
    entry = cfg.patients[0]
    ps = patient_settings(s, own_settings(entry))
    spec = job.patient.plan
    plan = load_plan(spec, side=job.side, levels=s.levels, ids=s.ids, transform=s.transform)
    anatomy = resolve_anatomy(list(ps.anatomy), ps.anatomy_frame, spec, segments=ps.segments) if ps.anatomy else None
    skins = None
    record = json.loads(entry["envelope"]) if "envelope" in entry else None
    if record is not None and record.get("skin"):
        from arcube.io.meshes import read_meshes

        skins = (tuple(read_meshes(list(ps.envelope), ps.anatomy_frame)),)
    envelope = None if record is None else Envelope.from_record(record, skins[0] if skins else ())
    return cfg, Docking(job.patient.name, job.side or "both", plan, anatomy, envelope, job.robot.design), s, skins


def _problem(job: DockingJob) -> tuple[Any, Docking, RunSettings, np.ndarray, np.ndarray]:
    """The docking's fitness model (the design job's problem with the robot fixed), its Docking (plan, anatomy, envelope,
    the robot at its first placement), the settings, and the placement bounds (lo, hi) ``(6,)``."""
    from arcube.optimization.build import build_model

    cfg, dock, s, skins = docking_inputs(job)
    anatomy = dock.anatomy
    model = build_model(cfg, anatomies=(anatomy.distance,) if anatomy is not None else (), settings=s, skins=skins)
    lo = np.array([model.space._bound(n)[0] for n in PLACEMENT])
    hi = np.array([model.space._bound(n)[1] for n in PLACEMENT])
    return model, dock, s, lo, hi


def solve_docking(job: DockingJob) -> tuple[DockingOutcome, Docking, RunSettings]:
    """Search the docking (:func:`search`), re-check its placements best first as the design job does (the NumPy
    reference, every requirement, the drilling program built into ``job.folder``/program), and return the first that
    passes, else the best one found (not met), with the docking it was judged on (its plan, anatomy and envelope; the
    chosen design and rows) and the settings. Writes only the program; the caller writes the rest of the folder."""
    started = time.perf_counter()
    model, dock, s, lo, hi = _problem(job)
    warm = warm_starts(job.robot, dock.plan.entry, dock.plan.target)
    found, spent = search(model, lo, hi, warm, job.starts, job.evaluations, docking_rng(job.seed, job.label))
    folder = Path(job.folder)
    tried: list[tuple[float, np.ndarray, str, list[dict[str, Any]]]] = []
    chosen = None
    built = None  # the placement whose program is in folder/program
    for f, x, how in found[:CHECK_TRIES]:
        d = Docking(dock.name, dock.side, dock.plan, dock.anatomy, dock.envelope, job.robot.placed(x))
        assess_dockings([d], job.reqs, s)
        if d.met:
            d.rows = [*d.rows, *build_program(folder, d, s, job.reqs)]
            built = x
        if d.met and any(
            r.name == "breach_probability" for r in job.reqs
        ):  # model §22.4: on a docking that meets the rest
            d.breach, extra = breach_check(None, d, s, job.reqs)
            d.rows = [*d.rows, *extra]
        tried.append((f, x, how, d.rows))
        if d.met:
            chosen = tried[-1]
            break
        if f >= PENALTY:
            break  # the next placements meet even less at the search's own points: the best one is written
    if chosen is None:
        chosen = (
            tried[0]
            if tried
            else (float("inf"), job.robot.starts[0].placement if job.robot.starts else (lo + hi) / 2, "none", [])
        )
        f, x, how, rows = chosen
        if not rows:
            d = Docking(dock.name, dock.side, dock.plan, dock.anatomy, dock.envelope, job.robot.placed(x))
            assess_dockings([d], job.reqs, s)
            rows = d.rows
        if built is not None and not np.array_equal(built, x):
            import shutil

            from arcube.design_job.outputs import PROGRAM

            shutil.rmtree(folder / PROGRAM, ignore_errors=True)  # another placement's program: not this docking's
        chosen = (f, x, how, rows)
    f, x, how, rows = chosen
    batch = model.evaluate(np.asarray(x, dtype=float)[None, :])
    eta = float(batch["ETA"][0])
    design = job.robot.placed(x)
    outcome = DockingOutcome(
        job.label,
        job.patient.name,
        job.side or "both",
        design,
        rows,
        eta if np.isfinite(eta) else None,
        float(batch["VIOL"][0]),
        spent,
        time.perf_counter() - started,
        len(tried),
        how,
    )
    return outcome, Docking(dock.name, dock.side, dock.plan, dock.anatomy, dock.envelope, design, rows), s
