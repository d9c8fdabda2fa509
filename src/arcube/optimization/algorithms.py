"""pymoo algorithm and termination factories.

* ``mscmaes`` (default): multi-start CMA-ES, :mod:`arcube.optimization.multistart`; its budget is
  ``population * generations`` design evaluations (the GA's at the same flags), spent in batches
  of 8 runs x cma's default population; ``--ftol`` does not apply (its runs restart on their
  own stop criteria until the budget is spent).
* ``ga`` (the paper's): real-coded GA, SBX crossover (prob 0.9, eta 15), polynomial
  mutation (eta 20), binary tournament that compares feasibility first (constraint violation,
  then eta), elitist (mu + lambda) survival sorted by violation then eta. Duplicates are kept by
  default, as in Matlab's ``ga`` (the paper's tool), which has no duplicate elimination. pymoo's
  GA default (``eliminate_duplicates=True``) compares each offspring batch with the population
  and with itself (pairwise distances) and mates again to refill what it dropped (about 1.4
  extra rounds per generation here); at population 400 that was about 7 ms of the 27 ms per
  generation, and with the lean bookkeeping below it would still double pymoo's time. Over 8
  seeds at paper scale the best eta_G was the same on average (1.290 kept, 1.289 eliminated).
  Setting ``eliminate_duplicates`` (flag ``--eliminate-duplicates``) brings pymoo's default
  back; configs written before the setting existed resume with it. The GA's bookkeeping goes
  through :mod:`arcube.optimization.lean` (bit-identical to pymoo's stock components, faster).
* ``de``: differential evolution DE/rand/1/bin (F 0.5, CR 0.9), feasibility-first replacement.
* ``cmaes``: pymoo's CMA-ES (the ``cma`` package), no restarts, sigma 0.2 of the normalized box,
  started from the start design; it has no constraint handling, so it sees the penalized F.
* ``nsga2``: NSGA-II (SBX, PM, rank and crowding, constrained domination) for eta vs compactness.
* ``docked``: one robot at several dockings (model §19.3), :mod:`arcube.optimization.docked`; ``mscmaes`` with one docking.

All random draws go through the algorithm's ``random_state`` (``np.random.default_rng(seed)``,
made in ``Algorithm.setup``); CMA-ES also seeds numpy's global RNG through ``cma`` from a number
drawn from that generator. Each run sets the algorithm up afresh from its seed.

DE, CMA-ES and NSGA-II are imported when asked for: ``cma`` alone (it imports scipy.stats and
matplotlib) took about 0.7 s of a GA run's start-up.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pymoo.algorithms.soo.nonconvex.ga import GA, FitnessSurvival, comp_by_cv_and_fitness
from pymoo.core.algorithm import Algorithm
from pymoo.core.sampling import Sampling
from pymoo.core.termination import Termination
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.sampling.rnd import FloatRandomSampling
from pymoo.operators.selection.tournament import TournamentSelection
from pymoo.termination.collection import TerminationCollection
from pymoo.termination.ftol import MultiObjectiveSpaceTermination, SingleObjectiveSpaceTermination
from pymoo.termination.max_eval import MaximumFunctionCallTermination
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.termination.robust import RobustTermination

from arcube.errors import InputError
from arcube.optimization.lean import LeanEvaluator, LeanFitnessSurvival, LeanGA, PassRepair, lean_comp_by_cv_and_fitness
from arcube.optimization.settings import (  # noqa: F401 (DEFAULT_ALGORITHM, check_algorithm: still importable from here)
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    DEFAULT_PERIOD,
    MULTI_OBJECTIVE_ALGORITHMS,
    check_algorithm,
)

BUDGETED: frozenset[str] = frozenset({"mscmaes", "docked"})
"""Algorithms whose budget is population * generations design evaluations, not generations."""
MULTI_OBJECTIVE: frozenset[str] = MULTI_OBJECTIVE_ALGORITHMS
PENALTY_ONLY: frozenset[str] = frozenset({"cmaes", "mscmaes", "docked"})
DOCKED_SLACK = 8
"""Rows ``docked`` may spend beyond its budget when the budget is smaller than its phases (its warm starts and the one
whole evaluation it always ends with); it stops itself otherwise (:mod:`arcube.optimization.docked`)."""
"""Algorithms without constraint handling: they minimize the penalized F of problem.PENALTY."""


class SeededSampling(Sampling):
    """Uniform random sampling in the bounds (pymoo's FloatRandomSampling) with the first
    individual replaced by ``x0`` (the start design), when given."""

    def __init__(self, x0: np.ndarray | None = None) -> None:
        super().__init__()
        self.x0 = None if x0 is None else np.asarray(x0, dtype=float)

    def _do(self, problem: Any, n_samples: int, *args: Any, random_state: Any = None, **kwargs: Any) -> np.ndarray:
        X = FloatRandomSampling()._do(problem, n_samples, random_state=random_state)
        if self.x0 is not None and n_samples > 0:
            X[0] = self.x0
        return X


def make_algorithm(
    name: str,
    population: int,
    seed: int,
    x0: np.ndarray | None = None,
    *,
    eliminate_duplicates: bool = False,
    lean: bool = True,
    n_obj: int = 2,
    generations: int = 300,
    structure: Any = None,
) -> Algorithm:
    """A fresh pymoo algorithm; ``x0`` (an optimizer vector) seeds the initial population.

    ``generations`` matters to the budgeted algorithms (``mscmaes``, ``docked``: ``population * generations`` evaluations);
    ``structure``: ``docked``'s :class:`~arcube.optimization.docked.DockingStructure` (None: ``mscmaes``).

    ``eliminate_duplicates`` applies to ``ga`` (see the module docstring); ``lean=False`` builds
    the GA from pymoo's stock components (the reference the lean ones must equal bit for bit).
    """
    check_algorithm(name, population)
    common: dict[str, Any] = {"seed": int(seed), "save_history": False, "verbose": False}
    if name == "mscmaes":
        from arcube.optimization.multistart import make_multistart  # noqa: PLC0415

        return make_multistart(population * generations, seed, x0)
    if name == "docked":
        from arcube.optimization.docked import make_docked  # noqa: PLC0415

        return make_docked(population * generations, seed, structure, x0)
    if name == "ga":
        if lean:  # offspring are always new individuals: nothing to skip, no check needed
            common.update(evaluator=LeanEvaluator(skip_already_evaluated=False), repair=PassRepair())
        return (LeanGA if lean else GA)(
            pop_size=population,
            sampling=SeededSampling(x0),
            selection=TournamentSelection(func_comp=lean_comp_by_cv_and_fitness if lean else comp_by_cv_and_fitness),
            crossover=SBX(prob=0.9, eta=15),
            mutation=PM(eta=20),
            survival=LeanFitnessSurvival() if lean else FitnessSurvival(),
            eliminate_duplicates=bool(eliminate_duplicates),
            **common,
        )
    if lean:
        common["evaluator"] = LeanEvaluator()
    if name == "de":
        from pymoo.algorithms.soo.nonconvex.de import DE  # noqa: PLC0415

        return DE(pop_size=population, sampling=SeededSampling(x0), variant="DE/rand/1/bin", F=0.5, CR=0.9, **common)
    if name == "cmaes":
        from pymoo.algorithms.soo.nonconvex.cmaes import CMAES  # noqa: PLC0415

        start = None if x0 is None else np.asarray(x0, dtype=float)
        return CMAES(x0=start, sigma=0.2, pop_size=population, restarts=0, seed=int(seed))
    if name == "nsga3":  # many objectives: reference directions spread by Riesz energy, one per individual
        from pymoo.algorithms.moo.nsga3 import NSGA3  # noqa: PLC0415
        from pymoo.util.ref_dirs import get_reference_directions  # noqa: PLC0415

        ref_dirs = get_reference_directions("energy", int(n_obj), int(population), seed=int(seed))
        return NSGA3(ref_dirs=ref_dirs, **_evolution(population, x0), **common)
    from pymoo.algorithms.moo.nsga2 import NSGA2  # noqa: PLC0415

    return NSGA2(**_evolution(population, x0), **common)


def _evolution(population: int, x0: Any) -> dict[str, Any]:
    """NSGA-II's and NSGA-III's operators: the seeded start, SBX and polynomial mutation, duplicates eliminated."""
    return {
        "pop_size": population,
        "sampling": SeededSampling(x0),
        "crossover": SBX(prob=0.9, eta=15),
        "mutation": PM(eta=20),
        "eliminate_duplicates": True,
    }


def make_termination(
    name: str, generations: int, tolerance: float, period: int = DEFAULT_PERIOD, population: int = 1
) -> TerminationCollection:
    """At most ``generations`` generations; with ``tolerance > 0`` also pymoo's ftol criterion
    (the best feasible objective, or the feasible front for nsga2, moved by at most
    ``tolerance`` over ``period`` generations). ``tolerance == 0`` runs every generation.
    A budgeted algorithm (``mscmaes``) stops at ``population * generations`` evaluations instead."""
    if generations < 1:
        raise InputError.of("RunSettings.generations", f"must be at least 1, got {generations}")
    if not (tolerance >= 0.0 and np.isfinite(tolerance)):
        raise InputError.of("RunSettings.ftol", f"must be a finite number >= 0, got {tolerance}")
    if name in BUDGETED:
        return TerminationCollection(
            MaximumFunctionCallTermination(population * generations + (DOCKED_SLACK if name == "docked" else 0))
        )
    criteria: list[Termination] = [MaximumGenerationTermination(generations)]
    if tolerance > 0.0:
        ftol = (
            MultiObjectiveSpaceTermination(tolerance, only_feas=True)
            if name in MULTI_OBJECTIVE
            else SingleObjectiveSpaceTermination(tolerance, only_feas=True)
        )
        criteria.append(RobustTermination(ftol, period=period))
    return TerminationCollection(*criteria)


def stop_reason(termination: TerminationCollection) -> str:
    """Why a run stopped: 'generations', 'evaluations' (a budgeted algorithm), 'tolerance' or 'algorithm'
    (CMA-ES's own stop), else 'running'."""
    parts = termination.terminations
    if isinstance(parts[0], MaximumFunctionCallTermination):  # mscmaes also stops itself before overspending
        return "evaluations" if parts[0].has_terminated() or termination.force_termination else "running"
    if parts[0].has_terminated():
        return "generations"
    if len(parts) > 1 and parts[1].has_terminated():
        return "tolerance"
    if termination.force_termination:
        return "algorithm"
    return "running"
