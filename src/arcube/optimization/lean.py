"""Lean drop-ins for pymoo's per-individual bookkeeping: the same results, far fewer Python calls.

pymoo 0.6 keeps a population as an array of :class:`~pymoo.core.individual.Individual` objects and
reads or writes an attribute through ``Population.get``/``set``, which call ``hasattr`` then
``getattr``/``setattr`` per individual and key (so a property such as ``CV`` is computed twice).
At population 400 that bookkeeping, not the operators' arithmetic, was most of pymoo's time per
generation. The classes here replace only the bookkeeping of the GA's components (one direct
pass over the individuals, then NumPy); every operator (sampling, binary tournament, SBX, PM,
the mating loop) is pymoo's, every comparison and ordering is pymoo's, and every random draw is
the same draw in the same order, so a run gives bit for bit what pymoo's stock components give
(``tests/test_optimize.py`` checks it against ``make_algorithm(..., lean=False)``).

* :class:`LeanEvaluator`: pymoo's Evaluator, but writes the problem's outputs in one pass (row
  copies as pymoo makes them; zero-width ``G``/``H`` rows are left at the individual's own empty
  default) instead of one ``Population.set`` per key.
* :class:`PassRepair`: pymoo's ``NoRepair`` rewrites every X with itself; this returns the
  population as it is.
* :class:`LeanFitnessSurvival`: pymoo's ``FitnessSurvival`` (sort by CV, then F; ``rank``).
* :func:`lean_comp_by_cv_and_fitness`: pymoo's ``comp_by_cv_and_fitness`` (feasibility first,
  then F; a tie is broken by ``random_state.choice([a, b])`` as pymoo does, in the same order).
* :class:`LeanMating`: pymoo's Mating (tournament, SBX, PM) on one array of the parents' X
  instead of a population of parent pairs: selection returns indices, crossover and mutation
  run pymoo's own ``_do`` on arrays with the same draws, and the offspring become individuals
  once, at the end (pymoo builds them after the crossover and rewrites the mutated ones).
* :class:`LeanGA`: pymoo's GA with the lean mating; its optimum (``filter_optimum``: best
  feasible, else least infeasible) is found from arrays, and the offspring's ``n_gen`` /
  ``n_iter`` tags are written in one pass.

The CV itself comes with the evaluation (``ArcubeProblem`` returns it), so pymoo's lazy per-
individual ``calc_cv`` never runs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pymoo.algorithms.soo.nonconvex.ga import GA, FitnessSurvival
from pymoo.core.evaluator import Evaluator
from pymoo.core.individual import Individual
from pymoo.core.mating import Mating
from pymoo.core.population import Population
from pymoo.core.repair import Repair
from pymoo.core.variable import get


def column(pop: Any, key: str) -> np.ndarray:
    """``pop.get(key)`` for a property (X, F, G, CV, ...) or a data key (ETA, VIOL, rank), in one pass."""
    if isinstance(getattr(Individual, key, None), property):
        return np.array([getattr(ind, key) for ind in pop])
    return np.array([ind.data.get(key) for ind in pop])


def cv_column(pop: Any) -> np.ndarray:
    """``pop.get("cv")``: the first constraint violation of each individual ``(n,)``."""
    return np.array([ind.CV[0] for ind in pop], dtype=float)


class LeanEvaluator(Evaluator):
    """pymoo's Evaluator (same skipping and counting) with a one-pass write-back."""

    def _eval(self, problem: Any, pop: Any, evaluate_values_of: list[str], **kwargs: Any) -> None:
        X = np.array([ind.X for ind in pop])
        out = problem.evaluate(X, return_values_of=evaluate_values_of, return_as_dictionary=True, **kwargs)
        for key, val in out.items():
            if val is None or (
                val.ndim > 1 and val.shape[1] == 0 and isinstance(getattr(Individual, key, None), property)
            ):
                continue  # nothing to write (an empty G/H row equals the individual's default)
            rows = [r.copy() for r in val] if val.ndim > 1 else list(val)  # as Population.set: own copies of rows
            if hasattr(Individual, key):
                for ind, v in zip(pop, rows):
                    setattr(ind, key, v)
            else:
                for ind, v in zip(pop, rows):
                    if key in ind.__dict__:
                        setattr(ind, key, v)
                    else:
                        ind.data[key] = v
        keys = list(out)
        for ind in pop:
            ind.evaluated.update(keys)


class PassRepair(Repair):
    """pymoo's NoRepair without rewriting every X with an equal copy of itself."""

    def do(self, problem: Any, pop: Any, **kwargs: Any) -> Any:
        return pop


class LeanFitnessSurvival(FitnessSurvival):
    """pymoo's FitnessSurvival: survivors sorted by constraint violation, then by F."""

    def _do(self, problem: Any, pop: Any, n_survive: int | None = None, **kwargs: Any) -> Any:
        F, cv = column(pop, "F"), cv_column(pop)
        assert F.shape[1] == 1, "FitnessSurvival can only used for single objective single!"
        S = np.lexsort([F[:, 0], cv])
        for ind, rank in zip(pop, np.argsort(S)):
            ind.data["rank"] = rank
        return pop[S[:n_survive]]


def lean_comp_by_cv_and_fitness(pop: Any, P: np.ndarray, random_state: Any = None, **kwargs: Any) -> np.ndarray:
    """pymoo's comp_by_cv_and_fitness: the smaller CV wins when either is infeasible, else the smaller F."""
    a, b = P[:, 0], P[:, 1]
    cv, f = cv_column(pop), column(pop, "F")[:, 0]
    infeasible = (cv[a] > 0.0) | (cv[b] > 0.0)
    va, vb = np.where(infeasible, cv[a], f[a]), np.where(infeasible, cv[b], f[b])
    S = np.where(va < vb, a, b)
    for i in np.flatnonzero(~((va < vb) | (va > vb))):  # ties (and NaN), in pymoo's order
        S[i] = random_state.choice([a[i], b[i]])
    return S[:, None].astype(int)


def new_population(X: np.ndarray) -> Any:
    """``Population.new("X", X)``: one individual per row, each holding its own copy of the row."""
    pop = Population.empty(len(X))
    for ind, row in zip(pop, X):
        ind.X = row.copy()
    return pop


class LeanMating(Mating):
    """pymoo's Mating (selection, crossover, mutation) on arrays; the same draws in the same order.

    pymoo's ``Crossover.do`` gathers the parents' X individual by individual from a population of
    pairs and returns a new population; ``Mutation.do`` reads X back from it and rewrites the
    mutated individuals. Here the selection's indices pick rows of one X array, the operators'
    ``_do`` (SBX, PM) and their probability draws run as in pymoo, and the offspring population
    is made once. Only for operators without ``vtype`` or a built-in ``repair`` (pymoo's defaults).
    """

    def _do(
        self, problem: Any, pop: Any, n_offsprings: int, parents: Any = None, random_state: Any = None, **kwargs: Any
    ) -> Any:
        cx, mu = self.crossover, self.mutation
        assert all(op.vtype is None and op.repair is None for op in (self.selection, cx, mu)), (
            "lean mating needs plain operators"
        )
        n_matings = math.ceil(n_offsprings / cx.n_offsprings)
        if parents is None:
            parents = self.selection(
                problem, pop, n_matings, n_parents=cx.n_parents, to_pop=False, random_state=random_state, **kwargs
            )
        X = np.swapaxes(column(pop, "X")[np.asarray(parents)], 0, 1)  # (n_parents, n_matings, n_var), as Crossover.do
        Xp = self._cross(problem, X, random_state, **kwargs)
        Xm = mu._do(problem, Xp, random_state=random_state, **kwargs)  # Mutation.do: _do, then the per-individual draw
        mutated = random_state.random(size=len(Xp)) <= get(mu.prob, size=len(Xp))
        Xp[mutated] = Xm[mutated]
        return new_population(Xp)

    def _cross(self, problem: Any, X: np.ndarray, random_state: Any, **kwargs: Any) -> np.ndarray:
        """pymoo's ``Crossover.do`` after the gathering of X: offspring X ``(n_offsprings * n_matings, n_var)``."""
        cx = self.crossover
        n_parents, n_off = cx.n_parents, cx.n_offsprings
        n_matings, n_var = X.shape[1], problem.n_var
        Xp = np.empty(shape=(n_off, n_matings, n_var), dtype=X.dtype)
        cross = random_state.random(n_matings) < get(cx.prob, size=n_matings)
        if np.any(cross):
            Q = cx._do(problem, X, random_state=random_state, **kwargs)
            Xp[:, cross] = Q[:, cross]
        for k in np.flatnonzero(~cross):
            if n_off < n_parents:
                s = random_state.choice(np.arange(n_parents), size=n_off, replace=False)
            elif n_off == n_parents:
                s = np.arange(n_parents)
            else:
                s = []
                while len(s) < n_off:
                    s.extend(random_state.permutation(n_parents))
                s = s[:n_off]
            Xp[:, k] = np.copy(X[s, k])
        return Xp.reshape(-1, X.shape[-1])


class LeanGA(GA):
    """pymoo's GA with :class:`LeanMating`; its optimum (best feasible by F, else least CV) is found from arrays."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        m = self.mating
        self.mating = LeanMating(
            m.selection,
            m.crossover,
            m.mutation,
            repair=m.repair,
            eliminate_duplicates=m.eliminate_duplicates,
            n_max_iterations=m.n_max_iterations,
        )

    def infill(self) -> Any:
        """pymoo's ``Algorithm.infill`` with the ``n_gen`` / ``n_iter`` tags set in one pass."""
        if self.problem is None:
            raise Exception("Please call `setup(problem)` before calling next().")
        if not self.is_initialized:
            self._initialize()
            infills = self._initialize_infill()
        else:
            infills = self._infill()
        if infills is not None:
            for ind in infills:
                ind.data["n_gen"] = self.n_iter  # Individual.set of a key that is not an attribute
                ind.data["n_iter"] = self.n_iter
        return infills

    def _set_optimum(self) -> None:
        pop = self.pop
        if pop is None or len(pop) == 0:
            self.opt = None
            return
        cv = cv_column(pop)
        feasible = np.flatnonzero(cv <= pop[0].config.get("cv_eps", 0.0))
        if len(feasible):
            best = feasible[np.argmin(column(pop[feasible], "F")[:, 0])]
        else:
            best = int(np.argmin(cv))
        self.opt = Population.create(pop[best])
