"""One robot at several dockings, solved with the problem's structure (``--algorithm docked``, model §19.3).

Long module: the three phases below are one ask-tell algorithm, :class:`DockedCMA`, and the motions it carries.

Given the robot's parameters, the dockings are independent problems of six variables each (the placement m and
the mounting angles). The algorithm uses that, over one budget of ``population x generations`` rows, in three phases:

A. **The robot at its first docking** (:data:`A_SHARE` of the rows): multi-start CMA-ES as ``mscmaes`` searches
   (:mod:`arcube.optimization.multistart`: 8 runs, cma's population, restarts when a run stops) over the robot's genes
   (its 22 parameters and the working mode) and the first docking's six; every other docking is left out of the
   batch (its genes NaN: :meth:`arcube.optimization.problem.FitnessModel.active_dockings`), so a row costs one docking.
B. **Every other docking's placement for that robot** (:data:`B_SHARE`): the first docking's placement carried over
   by the rigid motions that best map its trajectories onto the other docking's (:func:`task_motions`: Kabsch on the
   entry and target points paired by level, and paired in reverse order, since a spine's other side is close to the
   first side turned half a turn about the vertical; and the translation of the centroid); the best of these starts
   a CMA-ES run of that docking's own, in its six variables. All those runs share each batch (a row holds one sample
   of every docking's run; the first docking is left out) and each run is ranked by its own docking's violation and
   eta_G (``VIOL_D``, ``ETA_D``): independent problems, solved side by side. Halfway through (:data:`RESCUE_AT`), a
   docking still infeasible is offered every feasible docking's best placement carried onto its own trajectories the
   same way (:func:`peer_starts`), and its run restarts from its best placement, a peer's when that is better: a docking
   stuck in a bad basin takes a placement that works for a patient like it.
C. **Everything together** (the rest): the assembled design (phase A's robot and first placement, phase B's best
   placements) evaluated whole, then polish runs (``mscmaes``'s polish: 4 runs, small steps) over every variable,
   restarted at the best design when they stop: what one docking gives up for another is settled here.

The best design is the best whole evaluation (every docking evaluated: phase C). A problem with one docking is
``mscmaes`` itself (:func:`make_docked` returns it). Constraint handling by penalty, as ``mscmaes``: a docking's
or the whole design's objective is PENALTY * (1 + violation) where infeasible. Reproducible: every random draw
comes from the algorithm's ``random_state``, in a fixed order, so a run replays from its evaluation log (resume).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any

import numpy as np
from pymoo.core.algorithm import Algorithm

from arcube.errors import InputError
from arcube.model.frames import rotation_matrix
from arcube.optimization.batch_cma import BatchCMA
from arcube.optimization.lean import LeanEvaluator, column, new_population
from arcube.optimization.multistart import (
    AskTell,
    POLISH_RUNS,
    POLISH_SIGMA,
    POLISH_TOL,
    RUNS,
    SIGMA,
    TOL,
    default_popsize,
    into_box,
    make_multistart,
)

__all__ = [
    "A_SHARE",
    "B_SHARE",
    "RESCUE_AT",
    "DockedCMA",
    "DockingStructure",
    "make_docked",
    "peer_starts",
    "row_work",
    "task_motions",
]

A_SHARE = 0.85
"""Share of the rows for phase A (the robot at its first docking)."""
B_SHARE = 0.05
"""Share of the rows for phase B (every other docking's placement); the rest is phase C's."""
B_SIGMA = 0.05
"""Phase B's initial step, in units of a placement gene's range (m: 40 mm of 800; mounting angles: 18 deg)."""
B_POPSIZE = 12
"""Samples per docking and generation in phase B."""
RESCUE_AT = 0.5
"""Share of phase B's rows after which an infeasible docking is offered its feasible peers' placements (:func:`peer_starts`)."""
PENALTY = 1e6
"""As :data:`arcube.optimization.problem.PENALTY`."""


def row_work(rows: float, budget: float, dockings: int) -> float:
    """The work of the first ``rows`` rows of a docked run of ``budget`` rows over ``dockings`` dockings, in
    docking evaluations: a phase-A row evaluates one docking, a phase-B row every other one, a phase-C row all of
    them (the module docstring). One docking (or a run of another algorithm): ``rows``. What a progress line's
    time left extrapolates: phase A's rows are the cheap 85 % of the budget."""
    if dockings <= 1:
        return float(rows)
    a, b = A_SHARE * budget, (A_SHARE + B_SHARE) * budget
    r = min(max(float(rows), 0.0), float(budget))
    return min(r, a) + min(max(r - a, 0.0), b - a) * (dockings - 1) + max(r - b, 0.0) * dockings


@dataclass(frozen=True)
class DockingStructure:
    """Where a design problem over dockings keeps what: the optimizer-vector columns of each docking's placement
    (m_x, m_y, m_z, mount_rx, mount_ry, mount_rz), the robot's (every other column), and each docking's trajectories."""

    placement: tuple[np.ndarray, ...]
    robot: np.ndarray
    plans: tuple[tuple[np.ndarray, np.ndarray], ...]  # per docking: entry, target (T, 3) mm

    @classmethod
    def of(cls, model: Any) -> DockingStructure:
        """The structure of a :class:`~arcube.optimization.problem.FitnessModel` over dockings (InputError otherwise)."""
        columns = model.space.placement_columns()
        if (
            not model.by_docking
            or not model.docking_plans
            or len(columns) != model.n_patients
            or any(len(c) != 6 for c in columns)
        ):
            raise InputError.of(
                "RunSettings.algorithm",
                "docked needs dockings (per-side or per-patient) with every placement and "
                "mounting angle free (free=all,mount,...)",
            )
        placement = tuple(np.array(c, dtype=np.int64) for c in columns)
        taken = np.concatenate(placement)
        robot = np.array([i for i in range(model.space.n_var) if i not in set(taken.tolist())], dtype=np.int64)
        return cls(placement, robot, model.docking_plans)


def _kabsch(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The proper rotation Q and translation t minimizing sum |Q a + t - b|^2 over paired points (rows of A, B)."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    Q = Vt.T @ D @ U.T
    return Q, cb - Q @ ca


def task_motions(
    source: tuple[np.ndarray, np.ndarray], target: tuple[np.ndarray, np.ndarray]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Rigid motions (Q (3, 3), t (3,)) that carry one docking's trajectories (entry, target ``(T, 3)``) near another's:
    Kabsch on the entries and targets paired by level (sorted along y, head first), paired in reverse order, and the
    translation of the centroids (Q = I). With different numbers of trajectories the first ones of each (by level) pair up."""

    def ordered(plan: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        entry, tgt = (np.asarray(a, dtype=float) for a in plan)
        order = np.argsort(-entry[:, 1], kind="stable")
        return entry[order], tgt[order]

    (ea, ta), (eb, tb) = ordered(source), ordered(target)
    n = min(len(ea), len(eb))
    A = np.concatenate([ea[:n], ta[:n]])
    out = []
    for eb_, tb_ in ((eb[:n], tb[:n]), (eb[:n][::-1], tb[:n][::-1])):
        out.append(_kabsch(A, np.concatenate([eb_, tb_])))
    centre = np.concatenate([eb, tb]).mean(axis=0) - np.concatenate([ea, ta]).mean(axis=0)
    out.append((np.eye(3), centre))
    return out


def _angles(M: np.ndarray) -> np.ndarray:
    """(rx, ry, rz) deg of a rotation M = R_z(rz) R_y(ry) R_x(rx) (:func:`arcube.model.frames.rotation_matrix`)."""
    ry = -np.arcsin(np.clip(M[2, 0], -1.0, 1.0))
    return np.degrees([np.arctan2(M[2, 1], M[2, 2]), ry, np.arctan2(M[1, 0], M[0, 0])])


def carried(placement: np.ndarray, motion: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """A placement (m_x, m_y, m_z mm, mount_rx, mount_ry, mount_rz deg) moved by a rigid motion of the patient frame."""
    Q, t = motion
    R = rotation_matrix(np.radians(placement[3:6]))
    return np.concatenate([Q @ placement[:3] + t, _angles(Q @ R)])


def peer_starts(
    k: int, best: Sequence[np.ndarray], feasible: Sequence[bool], plans: Sequence[tuple[np.ndarray, np.ndarray]]
) -> list[np.ndarray]:
    """Starts for docking ``k`` from its peers: every other feasible docking j's best placement ``best[j]`` (6,) carried by
    each of :func:`task_motions` from j's trajectories to k's (``plans``: per docking entry, target ``(T, 3)``), in the
    order of j, then of the motions. Empty when no other docking is feasible."""
    return [
        carried(best[j], m)
        for j in range(len(best))
        if j != k and feasible[j]
        for m in task_motions(plans[j], plans[k])
    ]


class DockedCMA(AskTell):
    """The three phases of the module docstring over ``budget`` rows; ``x0``: the start design (problem units)."""

    def __init__(self, budget: int, structure: DockingStructure, x0: np.ndarray | None = None, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.budget, self.s = int(budget), structure
        self.x0 = None if x0 is None else np.asarray(x0, dtype=float)
        self.phase = "A"
        self.es: BatchCMA | None = None
        self.U = np.zeros((0, 0))
        self.best_a: tuple[float, np.ndarray] | None = None  # (F, the row) of phase A
        self.best_k: dict[int, tuple[float, np.ndarray]] = {}  # per docking k >= 1: (its own F, its placement)
        self.best: Any = None  # the best whole evaluation (an individual)
        self.best_u: np.ndarray | None = None
        self.candidates: list[list[np.ndarray]] = []
        self.rescued = False  # the peers' placements offered (once, at RESCUE_AT of phase B)
        self.rescue: list[int] = []  # the dockings offered them

    # ------------------------------------------------------------------ set-up
    def _setup(self, problem: Any, **kwargs: Any) -> None:
        self.xl, self.xu = np.asarray(problem.xl, float), np.asarray(problem.xu, float)
        self.n = len(self.xl)
        self.active_a = np.concatenate([self.s.robot, self.s.placement[0]])
        self.lam_a = max(2, min(default_popsize(len(self.active_a)), self.budget))
        self.runs_a = max(1, min(RUNS, self.budget // self.lam_a))
        self.lam_c = default_popsize(self.n)
        self.budget_a = int(A_SHARE * self.budget)
        self.budget_b = self.budget_a + int(B_SHARE * self.budget)

    def _norm(self, x: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return np.clip((x - self.xl[cols]) / (self.xu[cols] - self.xl[cols]), 0.0, 1.0)

    def _units(self, u: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return self.xl[cols] + into_box(u) * (self.xu[cols] - self.xl[cols])

    def _rng(self) -> np.random.Generator:
        return np.random.default_rng(self.random_state.integers(2**63))

    # ------------------------------------------------------------------ phases
    def _start_a(self, r: int, first: bool) -> None:
        start = (
            self._norm(self.x0[self.active_a], self.active_a)
            if first and self.x0 is not None
            else self.random_state.random(len(self.active_a))
        )
        self.es.restart(r, start, self._rng())

    def _enter_a(self) -> None:
        self.es = BatchCMA(self.runs_a, len(self.active_a), self.lam_a, SIGMA, TOL)
        for r in range(self.runs_a):
            self._start_a(r, r == 0)

    def _ask_a(self) -> Any:
        self.U = self.es.ask()
        X = np.full((len(self.U), self.n), np.nan)
        X[:, self.active_a] = self._units(self.U, self.active_a)
        return X

    def _tell_a(self, infills: Any) -> None:
        F = column(infills, "F")[:, 0]
        j = int(np.argmin(F))
        if self.best_a is None or F[j] < self.best_a[0]:
            self.best_a = (float(F[j]), np.asarray(infills[j].X, dtype=float).copy())
        for r in np.flatnonzero(self.es.tell(F)):
            self._start_a(int(r), False)
        if self.evaluator.n_eval + len(F) > self.budget_a:
            self._enter_b0()

    def _enter_b0(self) -> None:
        """The warm starts of every other docking: the first docking's placement carried by :func:`task_motions`."""
        self.phase = "B0"
        assert self.best_a is not None
        p0 = self.best_a[1][self.s.placement[0]]
        self.candidates = []
        for k in range(1, len(self.s.placement)):
            cols = self.s.placement[k]
            moved = [carried(p0, m) for m in task_motions(self.s.plans[0], self.s.plans[k])]
            self.candidates.append([np.clip(c, self.xl[cols], self.xu[cols]) for c in [*moved, p0.copy()]])

    def _ask_b0(self) -> Any:
        rows = len(self.candidates[0])
        X = np.tile(self.best_a[1], (rows, 1))
        X[:, self.s.placement[0]] = np.nan  # the first docking is fixed: left out
        for k, cands in enumerate(self.candidates, start=1):
            X[:, self.s.placement[k]] = np.array(cands)
        return X

    def _docking_f(self, infills: Any) -> np.ndarray:
        """``(n, K)``: each docking's own objective, its eta_G where it is feasible, else PENALTY * (1 + its violation)."""
        V, E = column(infills, "VIOL_D"), column(infills, "ETA_D")
        return np.where(V == 0.0, E, PENALTY * (1.0 + V))

    def _keep_best_k(self, infills: Any) -> np.ndarray:
        F = self._docking_f(infills)
        for k in range(1, F.shape[1]):
            j = int(np.argmin(F[:, k]))
            if k not in self.best_k or F[j, k] < self.best_k[k][0]:
                self.best_k[k] = (float(F[j, k]), np.asarray(infills[j].X, dtype=float)[self.s.placement[k]].copy())
        return F

    def _tell_b0(self, infills: Any) -> None:
        self._keep_best_k(infills)
        if self.evaluator.n_eval + B_POPSIZE > self.budget_b:
            self._enter_c0()
            return
        self.phase = "B"
        self.es = BatchCMA(len(self.s.placement) - 1, 6, B_POPSIZE, B_SIGMA, TOL)
        for k in range(1, len(self.s.placement)):
            self.es.restart(k - 1, self._norm(self.best_k[k][1], self.s.placement[k]), self._rng())

    def _ask_b(self) -> Any:
        self.U = self.es.ask()  # (R * lam, 6), run by run
        U = self.U.reshape(self.es.R, self.es.lam, 6)
        X = np.tile(self.best_a[1], (self.es.lam, 1))
        X[:, self.s.placement[0]] = np.nan
        for k in range(1, len(self.s.placement)):
            X[:, self.s.placement[k]] = self._units(U[k - 1], self.s.placement[k])
        return X

    def _tell_b(self, infills: Any) -> None:
        F = self._keep_best_k(infills)
        for r in np.flatnonzero(self.es.tell(F[:, 1:].T.reshape(-1))):  # run k-1 ranks its samples by docking k's own F
            self.es.restart(int(r), self._norm(self.best_k[int(r) + 1][1], self.s.placement[int(r) + 1]), self._rng())
        self._next_b()

    def _next_b(self) -> None:
        """Phase B goes on, offers the peers' placements (once, at RESCUE_AT of its rows), or ends."""
        if self.evaluator.n_eval + self.es.lam > self.budget_b:
            self._enter_c0()
        elif not self.rescued and self.evaluator.n_eval >= self.budget_a + RESCUE_AT * (self.budget_b - self.budget_a):
            self._enter_b1()

    def _enter_b1(self) -> None:
        """Every docking still infeasible gets :func:`peer_starts` (a docking that is not: its own best, as filler)."""
        self.rescued = True
        K = len(self.s.placement)
        best = [self.best_a[1][self.s.placement[0]], *(self.best_k[k][1] for k in range(1, K))]
        feasible = [self.best_a[0] < PENALTY, *(self.best_k[k][0] < PENALTY for k in range(1, K))]
        starts = {k: peer_starts(k, best, feasible, self.s.plans) for k in range(1, K) if not feasible[k]}
        self.rescue = [k for k, c in starts.items() if c]
        if not self.rescue:
            return
        rows = max(len(starts[k]) for k in self.rescue)
        self.candidates = []
        for k in range(1, K):
            cols, own = self.s.placement[k], starts.get(k, [])
            cands = [np.clip(c, self.xl[cols], self.xu[cols]) for c in own] or [best[k]]
            self.candidates.append(cands + [cands[-1]] * (rows - len(cands)))
        self.phase = "B1"

    def _tell_b1(self, infills: Any) -> None:
        self._keep_best_k(infills)
        self.phase = "B"
        for k in self.rescue:
            self.es.restart(k - 1, self._norm(self.best_k[k][1], self.s.placement[k]), self._rng())
        self._next_b()

    def _enter_c0(self) -> None:
        self.phase = "C0"
        x = self.best_a[1].copy()
        for k, (_, p) in self.best_k.items():
            x[self.s.placement[k]] = p
        self.assembled = x

    def _tell_whole(self, infills: Any) -> None:
        F = column(infills, "F")[:, 0]
        j = int(np.argmin(F))
        if self.best is None or F[j] < self.best.F[0]:
            self.best = infills[j]
            self.best_u = (
                self.U[j].copy()
                if self.phase == "C"
                else self._norm(np.asarray(infills[j].X, float), np.arange(self.n))
            )

    def _tell_c0(self, infills: Any) -> None:
        self._tell_whole(infills)
        runs = min(POLISH_RUNS, max(1, (self.budget - self.evaluator.n_eval) // self.lam_c))
        if self.evaluator.n_eval + runs * self.lam_c > self.budget:
            self.phase = "done"
            return
        self.phase = "C"
        self.es = BatchCMA(runs, self.n, self.lam_c, POLISH_SIGMA, POLISH_TOL)
        for r in range(runs):
            self.es.restart(r, self.best_u, self._rng())

    def _tell_c(self, infills: Any) -> None:
        self._tell_whole(infills)
        for r in np.flatnonzero(self.es.tell(column(infills, "F")[:, 0])):
            self.es.restart(int(r), self.best_u, self._rng())
        if self.evaluator.n_eval + self.es.R * self.lam_c > self.budget:
            self.phase = "done"

    def _ask_c(self) -> Any:
        self.U = self.es.ask()
        return self._units(self.U, np.arange(self.n))

    # ------------------------------------------------------------------ pymoo's hooks
    def _ask(self) -> Any:
        if self.phase == "A" and self.evaluator.n_eval + self.runs_a * self.lam_a > self.budget_a:
            self._enter_b0()  # a budget too small for phase A
        X = {
            "A": self._ask_a,
            "B0": self._ask_b0,
            "B1": self._ask_b0,
            "B": self._ask_b,
            "C0": lambda: self.assembled[None, :].copy(),
            "C": self._ask_c,
        }[self.phase]()
        return new_population(X)

    def _tell(self, infills: Any) -> None:
        self.pop = infills
        {
            "A": self._tell_a,
            "B0": self._tell_b0,
            "B1": self._tell_b1,
            "B": self._tell_b,
            "C0": self._tell_c0,
            "C": self._tell_c,
        }[self.phase](infills)
        if self.phase == "done":
            self.termination.force_termination = True

    def _initialize_infill(self) -> Any:
        self._enter_a()
        if (
            self.best_a is None and self.runs_a * self.lam_a > self.budget_a
        ):  # too small for phase A: one batch all the same
            self.budget_a = self.runs_a * self.lam_a
            self.budget_b = max(self.budget_b, self.budget_a)
        return new_population(self._ask_a())


def make_docked(budget: int, seed: int, structure: DockingStructure | None, x0: np.ndarray | None = None) -> Algorithm:
    """The docked algorithm for ``budget`` rows; with one docking (or no structure) ``mscmaes`` itself."""
    if structure is None or len(structure.placement) < 2:
        return make_multistart(budget, seed, x0)
    return DockedCMA(
        budget, structure, x0=x0, seed=int(seed), evaluator=LeanEvaluator(), save_history=False, verbose=False
    )
