"""The optimization composer, in the spirit of pymoo's ``minimize``: problem, algorithm and
termination are built apart and joined here, and nothing here touches a file.

:func:`run_algorithm` runs a :class:`~arcube.optimization.problem.FitnessModel` under a run's
:class:`~arcube.optimization.settings.RunSettings`, answering the algorithm's batches through
``batch`` (an executor, or the checkpoint's replaying log) and calling ``on_generation`` after
each generation. :func:`describe` turns the finished algorithm into the run's summary, designs
and front, the same whether a run folder is written (:mod:`arcube.optimization.run`) or not
(:func:`arcube.optimize` with no ``out``).
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.model.design import PARAM_NAMES
from arcube.optimization.algorithms import MULTI_OBJECTIVE, PENALTY_ONLY, make_algorithm, make_termination
from arcube.optimization.lean import column
from arcube.optimization.objectives import MAXIMIZED
from arcube.optimization.problem import ArcubeProblem, FitnessModel
from arcube.optimization.settings import RunSettings

if TYPE_CHECKING:
    from arcube.optimization.run_config import RunConfig

__all__ = [
    "HISTORY_COLUMNS",
    "Loop",
    "Observer",
    "Progress",
    "describe",
    "generation_stats",
    "observed",
    "pick_best",
    "run_algorithm",
]

HISTORY_COLUMNS = (
    "generation",
    "evaluations",
    "best_eta_G",
    "mean_eta_G",
    "feasible_fraction",
    "best_violation",
    "seconds",
)
GC_GEN0_THRESHOLD = 100_000
"""During a run the cyclic garbage collector's first threshold is raised to this many allocations
(Python's default is 700): pymoo makes a few thousand small objects per generation (individuals,
their dicts and arrays) and frees them by reference counting, so the default threshold only made
the collector rescan them about ten times per generation. Restored when the run returns."""


@dataclass
class Loop:
    """A finished (or interrupted) run of the algorithm: the algorithm, its termination, the last
    generation and the time spent in the algorithm's own steps (s)."""

    algorithm: Any
    termination: Any
    generation: int = 0
    algorithm_s: float = 0.0
    rows: list[dict[str, Any]] = field(default_factory=list)


def generation_stats(algorithm: Any) -> dict[str, float]:
    """best / mean feasible eta_G, feasible fraction and best violation of the current population."""
    viol = np.asarray(column(algorithm.pop, "VIOL"), float).reshape(-1)
    eta = np.asarray(column(algorithm.pop, "ETA"), float).reshape(-1)
    best = np.asarray(column(algorithm.opt, "ETA"), float).reshape(-1) if algorithm.opt is not None else eta
    feas = eta[np.isfinite(eta)]
    return {
        "best_eta_G": float(np.min(best)) if np.isfinite(best).any() else math.inf,
        "mean_eta_G": float(np.mean(feas)) if len(feas) else math.inf,
        "feasible_fraction": float(np.mean(viol == 0.0)),
        "best_violation": float(np.min(viol)),
    }


def run_algorithm(
    model: FitnessModel,
    s: RunSettings,
    batch: Callable[[np.ndarray], dict[str, np.ndarray]],
    *,
    on_generation: Callable[[Loop, dict[str, Any]], None] | None = None,
    done_generation: int = 0,
    clock: Callable[[], float] = time.perf_counter,
) -> Loop:
    """Run the algorithm of ``s`` on ``model`` to its termination.

    ``on_generation(loop, row)`` is called after every generation past ``done_generation`` (the
    ones a resume replays are skipped) with its history row (the columns of HISTORY_COLUMNS but
    ``seconds``, which the caller's clock owns). ``s.seed`` must be set.
    """
    assert s.seed is not None, "the composer runs a seeded problem"
    structure = None
    if s.algorithm == "docked" and model.n_patients > 1:
        from arcube.optimization.docked import DockingStructure

        structure = DockingStructure.of(model)
    algo = make_algorithm(
        s.algorithm,
        s.population,
        s.seed,
        model.space.encode(model.space.base),
        n_obj=model.n_obj,
        eliminate_duplicates=s.eliminate_duplicates,
        generations=s.generations,
        structure=structure,
    )
    problem = ArcubeProblem(model.space, model.n_obj, batch, penalty_only=s.algorithm in PENALTY_ONLY)
    termination = make_termination(s.algorithm, s.generations, s.ftol, s.period, s.population)
    algo.setup(problem, termination=termination, seed=s.seed, verbose=False)
    loop = Loop(algo, termination)
    thresholds = gc.get_threshold()
    gc.set_threshold(max(thresholds[0], GC_GEN0_THRESHOLD), *thresholds[1:])
    try:
        while algo.has_next():
            t_step = clock()
            algo.next()
            loop.algorithm_s += clock() - t_step
            if algo.n_iter - 1 == loop.generation:
                continue
            loop.generation = algo.n_iter - 1
            if loop.generation <= done_generation:
                continue
            row = {"generation": loop.generation, "evaluations": algo.evaluator.n_eval, **generation_stats(algo)}
            if on_generation is not None:
                on_generation(loop, row)
    finally:
        gc.set_threshold(*thresholds)
    return loop


class Observer:
    """Watches a run (:func:`observed`), in the spirit of pymoo's ``Callback``: :meth:`generation` is
    called after every generation with its history row (``seconds`` included) and the session's timing."""

    def generation(self, loop: Loop, row: dict[str, Any], timing: dict[str, float]) -> None:
        """After each generation: ``row`` (:data:`HISTORY_COLUMNS`), ``timing`` (``session_s`` wall time
        of this session, ``eval_s`` in the evaluations, ``optimizer_s`` in pymoo's own steps, ``total``
        generations and ``total_evaluations`` of the budget)."""


@dataclass
class Progress(Observer):
    """Passes each generation's row and timing, merged, to ``callback`` (a progress bar)."""

    callback: Callable[[dict[str, Any]], None]

    def generation(self, loop: Loop, row: dict[str, Any], timing: dict[str, float]) -> None:
        self.callback({**row, **timing})


def observed(
    model: FitnessModel,
    s: RunSettings,
    log: Any,
    observers: list[Observer],
    *,
    done_generation: int = 0,
    prior_s: float = 0.0,
) -> Loop:
    """Run ``model`` under ``s`` to its termination, answering batches through ``log`` (an
    :class:`~arcube.optimization.checkpoint.EvalLog`: it times the evaluations and replays a
    checkpoint), and tell every observer about every generation past ``done_generation``.
    ``prior_s``: the wall time of earlier sessions (a resumed run), added to each row's ``seconds``."""
    t0 = time.perf_counter()
    budget = s.population * s.generations  # evaluations at most (the GA's own count at full length)

    def generation(loop: Loop, row: dict[str, Any]) -> None:
        now = time.perf_counter()
        row = {**row, "seconds": prior_s + now - t0}
        timing = {
            "total": s.generations,
            "total_evaluations": budget,
            "eval_s": log.eval_s,
            "optimizer_s": loop.algorithm_s - log.call_s,
            "session_s": now - t0,
        }
        for observer in observers:
            observer.generation(loop, row, timing)

    return run_algorithm(model, s, log, on_generation=generation, done_generation=done_generation)


def pick_best(algorithm: Any) -> Any:
    """The best individual: pymoo's optimum (best feasible, else least infeasible); on a front, lowest eta."""
    opt = algorithm.opt
    if len(opt) == 1:
        return opt[0]
    F, viol = opt.get("F"), np.asarray(opt.get("VIOL"), float)
    order = np.lexsort([F[:, 0], viol])
    return opt[int(order[0])]


def front_rows(model: FitnessModel, algorithm: Any) -> list[dict[str, Any]]:
    """The feasible front of a multi-objective run: objectives, size measures, parameters, one row per design."""
    opt = algorithm.opt
    feas = np.asarray(opt.get("VIOL"), float) == 0.0
    X, F = opt.get("X")[feas], opt.get("F")[feas]
    rows = []
    for i in np.lexsort([F[:, 1], F[:, 0]]):
        rep = model.report(X[i])
        big = max(rep["tasks"], key=lambda t: t["bbox_volume_L"])
        ext = [hi - lo for lo, hi in zip(big["bbox_min_mm"], big["bbox_max_mm"])]
        row = {
            f"objective_{name}": float(F[i, j]) * (-1.0 if name in MAXIMIZED else 1.0)
            for j, name in enumerate(model.objectives)
        }
        row |= {
            "eta_G": rep["eta_G"],
            "links_sum_mm": rep["links_sum_mm"],
            "bbox_volume_L": rep["bbox_volume_L"],
            "bbox_dx_mm": ext[0],
            "bbox_dy_mm": ext[1],
            "bbox_dz_mm": ext[2],
            "dexterity_mean_pct": rep["dexterity_pct"]["mean"],
            "feasible": rep["feasible"],
            "mode": rep["mode"],
            "clearance_min_mm": rep["clearance_min_mm"],
            "self_clearance_min_mm": rep["self_clearance_min_mm"],
            **{k: v for k, v in rep.items() if k.endswith(("_max_mm", "_max_deg", "_max_Nm")) or k in _EXTRA},
        }
        row.update(dict(zip(PARAM_NAMES, (float(v) for v in rep["designs"][0]))))
        if "c_z" in rep:
            row["c_z"] = rep["c_z"]
        space = model.space
        for p in range(space.patients if space.per_patient else 1):
            for setup in range(space.setups):
                if p or setup:  # the first patient's (R side's) values are the parameter columns
                    suffix = ("_L" if setup else "") + (f"_p{p + 1}" if p else "")
                    d = rep["designs"][space.slot(p, setup)]
                    row.update(
                        {
                            f"{n}{suffix}": float(d[PARAM_NAMES.index(n)])
                            for n in (("m_x", "m_y", "m_z") if setup else space.docked)
                        }
                    )
        rows.append(row)
    return rows


_EXTRA = ("moving_mass_kg", "lateral_error_wc_mm", "lateral_error_rms_mm", "tolerance_class")
"""A report's figures that only some runs have (the masses of 18.1, the accuracy under tolerances of 20.3)."""


def describe(
    cfg: RunConfig, model: FitnessModel, algorithm: Any, info: dict[str, Any]
) -> tuple[dict[str, Any], list[np.ndarray], list[dict[str, Any]] | None]:
    """(summary, the best design of each slot ``(27,)``, the front's rows or None) of a finished run."""
    rep = model.report(pick_best(algorithm).X)
    designs = rep.pop("designs")
    s = cfg.settings
    summary: dict[str, Any] = {
        "feasible": rep["feasible"],
        "eta_G": rep["eta_G"],
        "dexterity_pct": rep["dexterity_pct"],
        "generations": info["generations"],
        "evaluations": info["evaluations"],
        "seed": s.seed,
        "wall_s": round(info["wall_s"], 3),
        "eval_s": round(info["eval_s"], 3),
        "stopped_by": info["stopped_by"],
        "algorithm": s.algorithm,
        "population": s.population,
        "engine": cfg.engine_resolved,
        "mode": rep["mode"],
        "setups": s.setups,
        "aggregate": s.aggregate,
        "free": list(s.free),
        "violation": rep["violation"],
        **({"docking_violations": rep["docking_violations"]} if "docking_violations" in rep else {}),
        "margin_shortfall_rad": rep["margin_shortfall_rad"],
        "links_sum_mm": rep["links_sum_mm"],
        "bbox_volume_L": rep["bbox_volume_L"],
        "clearance_min_mm": rep["clearance_min_mm"],
        "self_clearance_min_mm": rep["self_clearance_min_mm"],
        **{
            k: v
            for k, v in rep.items()
            if k.endswith(("_max_mm", "_max_deg", "_max_Nm")) or k in (*_EXTRA, "envelope_clearance_min_mm")
        },
        **({"c_z": rep["c_z"]} if "c_z" in rep else {}),
        "objectives": list(model.objectives),
        "limits": [list(lim) for lim in model.limits],
        "anatomy": [p.get("anatomy_source") for p in cfg.patients] if s.anatomy else None,
        "tasks": rep["tasks"],
        "points": model.n_points,
        "files": {},
        "resumed": info["resumed"],
        "placement": s.placement,
        "docking": s.placement,  # the field's name before 0.3, kept for one release
    }
    front = None
    if s.algorithm in MULTI_OBJECTIVE:
        front = front_rows(model, algorithm)
        summary["front_size"], summary["compactness"] = len(front), s.compactness
    return summary, designs, front
