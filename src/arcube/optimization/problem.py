"""The optimization problem (model §12): variables, bounds, fixing, objectives, constraint.

Three layers, all picklable and free of pymoo except the last:

* :class:`VariableSpace` maps an optimizer vector ``x`` ``(n_var,)`` to designs and working modes.
  Its variables are, in order: the free design parameters (in :data:`arcube.model.design.PARAM_NAMES`
  order), then for ``setups=2`` the left-side placement of every free ``m_*`` (``m_x_L`` ...),
  then, with per-patient docking over several patients, for each patient k >= 2 its own copy of
  every free placement and mounting parameter (``m_x_p2``, ``mount_rz_p2`` ...; with ``setups=2``
  also ``m_x_L_p2`` ...), then for a free working mode four sign genes ``mode_T_x, mode_T_y,
  mode_R_x, mode_R_y`` in [-1, 1] (sign >= 0 means +1). Fixed parameters keep the start design's
  values. The decoded designs are one per *slot*: a (patient, setup) pair with per-patient
  docking, a setup otherwise (every patient shares the placement: the paper's robust problem).
* :class:`FitnessModel` evaluates a whole population: one batch call of
  :func:`arcube.evaluation.engine.evaluate_task` with params ``(pop, 27)`` per task (a task is one setup of
  one patient). It returns F, the violation VIOL of model §16 (0 exactly when every point of every
  task is reachable, the orientation margin holds and every --max/--min is met; any design that misses
  a point ranks below every design that reaches them all) and the aggregate eta ETA (+inf when infeasible).
* :class:`ArcubeProblem` is the pymoo Problem; it delegates the batch to a callable so that
  run.py can log, replay and distribute evaluations.

Long module: the variable space, the fitness model with model §16's combination over tasks and the pymoo Problem travel to workers together.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymoo.core.problem import Problem

from arcube.evaluation import engine as core_engine
from arcube.evaluation.reference import fit_violation
from arcube.model.design import INDEX, MOUNT_NAMES, N_PARAMS, PARAM_NAMES, SLICES
from arcube.errors import InputError
from arcube.options import Options
from arcube.accuracy.robust import ROBUST_NAMES
from arcube.accuracy.settings import ToleranceSettings
from arcube.optimization.objectives import SUMMARY_KEYS, limit_shortfall, metric_values, needs, objective_columns
from arcube.optimization.compactness import bounding_box, mechanism_points  # noqa: F401 (mechanism_points: still importable from here)
from arcube.optimization.bounds import C_Z, C_Z_BOUNDS
from arcube.optimization.settings import (  # noqa: F401 (DEFAULT_BOUNDS, FREE_GROUPS, parse_*: still importable from here)
    DEFAULT_BOUNDS,
    FREE_GROUPS,
    RunSettings,
    parse_bounds,
    parse_free,
    resolve_bounds,
)
from arcube.model.mechanism import format_mode

Array = NDArray[np.float64]

PLACEMENT_NAMES = ("m_x", "m_y", "m_z")
LINK_NAMES: tuple[str, ...] = PARAM_NAMES[SLICES["f"].start : SLICES["r"] + 1]  # type: ignore[union-attr,operator]
"""The 14 link lengths f_u, p_u, d_u, c_x, c_y, t_x, t_y and r, summed by the ``links`` compactness."""
MODE_GENES = ("mode_T_x", "mode_T_y", "mode_R_x", "mode_R_y")
PENALTY = 1e6
"""F of an infeasible design: PENALTY * (1 + VIOL). Only CMA-ES (no constraint handling) sees it
as a ranking; GA, DE and NSGA-II compare infeasible designs by the constraint (feasibility first)."""
COMPACTNESS = ("links", "bbox")
PLACEMENTS = ("per-patient", "shared")
"""``--placement`` over several trajectory sets: each patient its own placement (and mounting when free), or one for all."""
DOCKING_KEYS = ("VIOL_D", "ETA_D")
"""What a batch of a model with ``by_docking`` holds beside F, VIOL and ETA: each docking's violation and eta_G ``(n, K)``."""
AGGREGATES = ("mean", "max")
"""How eta_G is combined over patients or dockings: the mean, or the worst (``max`` is the same as ``worst``)."""


@dataclass(frozen=True, eq=False)
class TaskData:
    """The points of one setup of one patient (R_w, mm)."""

    patient: int
    setup: int  # 0: the only setup (or the R side when setups=2); 1: the L side
    label: str
    E: Array  # (P, 3)
    e: Array  # (P, 3)
    role: str = "plan"
    """``plan``: the plan's points (eta_G, accuracy, loads, reach, guards, clearances); ``approach``: the
    lines from each trajectory's standoff to its entry (model §17.1: reach, guards, clearances only)."""

    @property
    def n_points(self) -> int:
        return int(self.E.shape[0])


@dataclass(frozen=True, eq=False)
class VariableSpace:
    """Optimizer vector <-> designs (one per slot) and working modes; see the module docstring."""

    base: Array  # (27,) start design: the values of the fixed parameters
    free: tuple[str, ...]
    bounds: dict[str, tuple[float, float]] = field(default_factory=lambda: dict(DEFAULT_BOUNDS))
    setups: int = 1
    mode: Array | None = None  # (4,) fixed working mode; None lets the optimizer choose
    patients: int = 1
    placement: str = "shared"  # "per-patient": each patient has its own placement (and mounting, when free)
    base_c_z: float | None = None  # the start design's c_z (mm): a fixed c_z keeps it; None: d_z (model §6)

    def __post_init__(self) -> None:
        if self.setups not in (1, 2):
            raise InputError.of("RunSettings.setups", f"must be 1 or 2, got {self.setups}")
        if self.placement not in PLACEMENTS:
            raise InputError.of(
                "RunSettings.placement", f"must be one of {', '.join(PLACEMENTS)}, got {self.placement!r}"
            )
        for n in self.free:
            lo, hi = self._bound(n)
            if not lo < hi:
                raise InputError(f"bounds of {n}: need LO < HI, got {lo:g}:{hi:g}")

    @property
    def free_m(self) -> tuple[str, ...]:
        """The free placement parameters that have a left-side copy (``setups=2``)."""
        return tuple(n for n in PLACEMENT_NAMES if n in self.free) if self.setups == 2 else ()

    @property
    def per_patient(self) -> bool:
        """True when each patient has its own placement (per-patient docking over several patients)."""
        return self.placement == "per-patient" and self.patients > 1

    @property
    def docked(self) -> tuple[str, ...]:
        """The free parameters each patient k >= 2 has its own copy of: placement m and mounting angles."""
        return tuple(n for n in (*PLACEMENT_NAMES, *MOUNT_NAMES) if n in self.free) if self.per_patient else ()

    @property
    def n_slots(self) -> int:
        """Designs per optimizer vector: one per (patient, setup) with per-patient docking, else one per setup."""
        return self.setups * (self.patients if self.per_patient else 1)

    def slot(self, patient: int, setup: int) -> int:
        """Index of the design a task of ``patient`` (0-based) and ``setup`` uses in :meth:`decode`'s list."""
        return (patient * self.setups if self.per_patient else 0) + setup

    def genes(self) -> list[tuple[str, str]]:
        """(variable name, parameter it sets) in optimizer-vector order (mode genes set no parameter: '')."""
        out = [(n, n) for n in self.free] + [(f"{n}_L", n) for n in self.free_m]
        for p in range(1, self.patients if self.per_patient else 1):
            out += [(f"{n}_p{p + 1}", n) for n in self.docked] + [(f"{n}_L_p{p + 1}", n) for n in self.free_m]
        return out + ([(g, "") for g in MODE_GENES] if self.mode is None else [])

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(g for g, _ in self.genes())

    @property
    def n_var(self) -> int:
        return len(self.names)

    @property
    def xl(self) -> Array:
        return np.array([self._bound(p)[0] for _, p in self.genes()])

    @property
    def xu(self) -> Array:
        return np.array([self._bound(p)[1] for _, p in self.genes()])

    def _bound(self, param: str) -> tuple[float, float]:
        if param == C_Z:
            return self.bounds.get(C_Z, C_Z_BOUNDS)
        return (-1.0, 1.0) if not param else self.bounds[param]

    @property
    def free_params(self) -> tuple[str, ...]:
        """The free parameters of the 27 (``free`` without c_z, which is last in ``free`` when free)."""
        return tuple(n for n in self.free if n != C_Z)

    def placement_columns(self) -> list[list[int]]:
        """Per docking (slot, with per-patient docking over several patients; one slot otherwise), the optimizer-vector
        columns of its own placement and mounting genes (m_x, m_y, m_z, mount_rx, mount_ry, mount_rz, those that are free)."""
        names = self.names
        own = [n for n in (*PLACEMENT_NAMES, *MOUNT_NAMES) if n in self.free]
        out = [[names.index(n) for n in own]]
        for p in range(1, self.patients if self.per_patient else 1):
            out.append([names.index(f"{n}_p{p + 1}") for n in own if n in self.docked])
        return out

    def c_z(self, X: Array) -> Array | None:
        """Each design's z-dyad link c_z ``(n,)`` mm (model §19.1): its gene when free, else the start design's;
        None when neither (c_z = d_z, or ``Guards.c_z``: every run before c_z became a parameter)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if C_Z in self.free:
            return X[:, len(self.free) - 1].copy()
        return None if self.base_c_z is None else np.full(X.shape[0], float(self.base_c_z))

    def decode(self, X: Array) -> tuple[list[Array], Array]:
        """``X`` ``(n, n_var)`` -> ([params ``(n, 27)`` per slot], modes ``(n, 4)``); c_z: :meth:`c_z`."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n, col = X.shape[0], len(self.free)
        params = np.tile(self.base, (n, 1))
        params[:, [INDEX[nm] for nm in self.free_params]] = X[:, : len(self.free_params)]
        out = []
        for p in range(self.patients if self.per_patient else 1):
            own = params
            if p > 0:
                own = params.copy()
                own[:, [INDEX[nm] for nm in self.docked]] = X[:, col : col + len(self.docked)]
                col += len(self.docked)
            out.append(own)
            if self.setups == 2:
                left = own.copy()
                left[:, [INDEX[nm] for nm in self.free_m]] = X[:, col : col + len(self.free_m)]
                col += len(self.free_m)
                out.append(left)
        if self.mode is None:
            modes = np.where(X[:, -4:] >= 0.0, 1.0, -1.0)
        else:
            modes = np.broadcast_to(np.asarray(self.mode, dtype=float), (n, 4)).copy()
        return out, modes

    def encode(self, design: Array, left_m: Array | None = None, mode: Array | None = None) -> Array:
        """The optimizer vector of a design (27,), clipped into the bounds; every patient starts at its placement."""
        d = np.asarray(design, dtype=float)
        lm = d[:3] if left_m is None else np.asarray(left_m, dtype=float)
        c_z = d[INDEX["d_z"]] if self.base_c_z is None else self.base_c_z
        vals = [
            c_z if p == C_Z else (lm if g[len(p) :].startswith("_L") else d)[INDEX[p]] for g, p in self.genes() if p
        ]  # m_x_L, m_x_L_p2: left side
        if self.mode is None:
            vals += list(0.5 * (np.ones(4) if mode is None else np.asarray(mode, dtype=float)))
        return np.clip(np.array(vals, dtype=float), self.xl, self.xu)


@dataclass(frozen=True, eq=False)
class FitnessModel:
    """Everything a worker needs to evaluate a population; see the module docstring."""

    space: VariableSpace
    tasks: tuple[TaskData, ...]
    n_patients: int = 1
    options: Options = Options()
    engine: str = "numpy"
    aggregate: str = "mean"
    margin_deg: float | None = None
    objectives: tuple[str, ...] = ("eta_G",)  # names of arcube.optimization.objectives.OBJECTIVES
    limits: tuple[tuple[str, str, float], ...] = ()  # (name, "max" | "min", value): --max / --min
    anatomies: tuple[Any, ...] = ()  # per patient: an arcube.evaluation.sdf.AnatomyDistance, or None
    envelopes: tuple[Any, ...] = ()  # per patient: an arcube.evaluation.envelope.Envelope (model §19.5), or None
    by_docking: bool = False
    """model §19.3: each patient entry is a docking, and the violation is the sum of each docking's V (its V_reach and
    its own V_fit over its points and limits); False: one V_fit over every point (every run before 19). A batch then also
    returns each docking's violation and eta_G (``VIOL_D``, ``ETA_D`` ``(n, K)``), and a docking whose placement genes
    are NaN in the batch's first row is left out of it (NaN in its columns): :mod:`arcube.optimization.docked`."""
    docking_plans: tuple[tuple[Array, Array], ...] = ()
    """Per docking, its trajectories' entry and target points ``(T, 3)`` each (R_w, mm), for warm starts between dockings."""
    accuracy: Any = None  # the ToleranceSettings of lateral_error_wc / lateral_error_rms (model §20.3); None: class m
    fine_tasks: tuple[TaskData, ...] = ()
    """The tasks at the program's resolution (model §17.2): the plan's tasks, each approach line and each drill line
    sampled every 0.5 mm (:func:`arcube.optimization.build.sweep_tasks`). A design feasible on :attr:`tasks` is judged
    again on these, and its batch row is theirs: the search calls feasible only what the line check between the points
    would (empty: no approach lines, one pass)."""

    def __post_init__(self) -> None:
        if self.aggregate not in AGGREGATES:
            raise InputError.of(
                "RunSettings.aggregate", f"must be one of {', '.join(AGGREGATES)}, got {self.aggregate!r}"
            )
        RunSettings(objectives=self.objectives)  # validates the names
        e_all = np.concatenate([t.e for t in self.tasks])
        ang = np.degrees(np.arccos(np.clip(e_all[:, :2], -1.0, 1.0)))  # angle(e, +u) for legs x, y
        object.__setattr__(self, "_ang_max", ang.max(axis=0))
        object.__setattr__(self, "_ang_min", ang.min(axis=0))
        object.__setattr__(
            self, "_fine", replace(self, tasks=self.fine_tasks, fine_tasks=()) if self.fine_tasks else None
        )
        # the approach lines need no drill-tip metrics: the drill works between entry and target only
        object.__setattr__(
            self, "_approach_options", self.options.replace(outputs=self.options.outputs.replace(tip_metrics=False))
        )

    @property
    def n_obj(self) -> int:
        return len(self.objectives)

    @property
    def n_points(self) -> int:
        """The plan's points (approach lines not counted)."""
        return sum(t.n_points for t in self.tasks if t.role == "plan")

    def margin_shortfall(self, params: Array) -> Array:
        """Orientation-margin shortfall (rad, 0 when met) ``(n,)`` of model §12.2 [ADDITION]."""
        if self.margin_deg is None:
            return np.zeros(params.shape[0])
        a, b = params[:, SLICES["alpha"]], params[:, SLICES["beta"]]
        mu = self.margin_deg
        short = np.maximum(self._ang_max + mu - (a + b), 0.0) + np.maximum(np.abs(a - b) - (self._ang_min - mu), 0.0)  # type: ignore[attr-defined]
        return np.radians(short.sum(axis=1))

    def _run_tasks(
        self,
        params: list[Array],
        modes: Array,
        want_points: bool,
        c_z: Array | None = None,
        active: tuple[bool, ...] | None = None,
        tasks: Sequence[TaskData] | None = None,
    ) -> list[Any]:
        """Each task's results (None for the tasks of a docking not ``active``); ``tasks``: others than :attr:`tasks`."""
        return [
            core_engine.evaluate_task(
                params[self.space.slot(t.patient, t.setup)],
                t.E,
                t.e,
                modes,
                self.options if t.role == "plan" else self._approach_options,  # type: ignore[attr-defined]
                engine=self.engine,
                want_points=want_points,
                anatomy=self.anatomies[t.patient] if self.anatomies else None,
                envelope=self.envelopes[t.patient] if self.envelopes else None,
                c_z=c_z,
            )
            if active is None or active[t.patient]
            else None
            for t in (self.tasks if tasks is None else tasks)
        ]

    def _combine(self, results: list[Any], params: list[Array]) -> tuple[Array, Array, Array, Array]:
        """Over all tasks, each ``(n,)``: eta (of the plan's tasks; +inf unless the margin holds and every task is
        w_G), the margin shortfall plus every task's V_reach, the guard grades summed over all points, all w_G."""
        n = params[0].shape[0]
        reach = self.margin_shortfall(params[0])
        grade = np.zeros(n)
        all_w = np.ones(n, dtype=bool)
        eta_sum = np.zeros((self.n_patients, n))
        pts = np.zeros(self.n_patients)
        for t, res in zip(self.tasks, results):
            w = np.asarray(res.w_G)
            reach = reach + np.nan_to_num(np.asarray(res.violation_reach, dtype=float), nan=1e6, posinf=1e6)
            grade = grade + np.asarray(res.guard_grade, dtype=float)
            all_w = all_w & w
            if t.role != "plan":
                continue
            eta_sum[t.patient] += t.n_points * np.where(w, np.asarray(res.eta_G, dtype=float), 0.0)
            pts[t.patient] += t.n_points
        eta_p = eta_sum / pts[:, None]
        eta = eta_p.mean(axis=0) if self.aggregate == "mean" else eta_p.max(axis=0)
        return np.where((reach == 0.0) & all_w, eta, np.inf), reach, grade, all_w

    def compactness_values(self, params: list[Array]) -> tuple[Array, Array]:
        """(sum of link lengths mm, largest bounding-box volume over the tasks in litres), each ``(n,)``."""
        links = params[0][:, [INDEX[nm] for nm in LINK_NAMES]].sum(axis=1)
        vol = np.zeros(params[0].shape[0])
        for t in self.tasks:
            lo, hi = bounding_box(params[self.space.slot(t.patient, t.setup)], t.E, t.e)
            vol = np.maximum(vol, np.prod(hi - lo, axis=1) / 1e6)
        return links, vol

    def moving_mass(self, params: list[Array], c_z: Array | None = None) -> Array:
        """The moving mass (kg, model §18.1) of each design ``(n,)``: the links are shared by every slot."""
        from arcube.evaluation.masses import moving_mass_kg

        return moving_mass_kg(params[0], self.options, c_z)

    def evaluate(self, X: Array) -> dict[str, Array]:
        """F ``(n, n_obj)``, VIOL ``(n,)`` and ETA ``(n,)`` of a population ``X`` ``(n, n_var)`` (with ``by_docking``
        also VIOL_D, ETA_D ``(n, K)``, NaN for a docking left out). With :attr:`fine_tasks`, the rows feasible on the
        coarse tasks are evaluated again on the fine ones and take their answers."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        active = self.active_dockings(X) if self.by_docking else None
        batch = self._evaluate(X, active)
        ok = np.flatnonzero(batch["VIOL"] == 0.0)
        if self.fine_tasks and len(ok) and not self.by_docking:  # over dockings, each docking is judged again alone
            fine = self._fine._evaluate(X[ok], active)  # type: ignore[attr-defined]
            for key, value in fine.items():
                batch[key][ok] = value
        return batch

    def _evaluate(self, X: Array, active: tuple[bool, ...] | None) -> dict[str, Array]:
        """:meth:`evaluate` on :attr:`tasks` alone (``active``: the dockings evaluated, with ``by_docking``)."""
        params, modes = self.space.decode(X)
        c_z = self.space.c_z(X)
        if self.by_docking:
            assert active is not None
            results = self._run_tasks(params, modes, want_points=False, c_z=c_z, active=active)
            eta, viol, values, viol_d, eta_d = self._judge_dockings(results, params, modes, c_z, active)
            cols = objective_columns(self.objectives, values, viol == 0.0, viol, PENALTY)
            return {"F": np.stack(cols, axis=1), "VIOL": viol, "ETA": eta, "VIOL_D": viol_d, "ETA_D": eta_d}
        results = self._run_tasks(params, modes, want_points=False, c_z=c_z)
        eta, viol, values = self._judge(results, params, modes, c_z)
        cols = objective_columns(self.objectives, values, viol == 0.0, viol, PENALTY)
        return {"F": np.stack(cols, axis=1), "VIOL": viol, "ETA": eta}

    def active_dockings(self, X: Array) -> tuple[bool, ...]:
        """Per docking: evaluated in this batch, unless its placement genes are NaN in the first row (a docking left out)."""
        row, columns = np.atleast_2d(X)[0], self.space.placement_columns()
        if len(columns) != self.n_patients:  # one placement for every patient: nothing to leave out
            return (True,) * self.n_patients
        return tuple(not (cols and bool(np.isnan(row[cols]).any())) for cols in columns)

    def robust_values(
        self, params: list[Array], modes: Array, want: Array, patient: int | None = None
    ) -> dict[str, Array]:
        """lateral_error_wc and lateral_error_rms (mm, model §20.3) ``(n,)``: the largest over the plan's tasks
        (of one ``patient`` entry, a docking, when given), computed only where ``want`` (the designs that reach
        every point; NaN elsewhere)."""
        from arcube.accuracy.robust import robust_errors

        engine = "numba" if self.engine == "numba" else "numpy"
        n = params[0].shape[0]
        wc, rms = np.full(n, -np.inf), np.full(n, -np.inf)
        for t in self.tasks:
            if t.role != "plan" or (patient is not None and t.patient != patient):
                continue
            w, r = robust_errors(
                params[self.space.slot(t.patient, t.setup)], modes, t.E, t.e, self.accuracy, engine, want
            )
            wc, rms = np.maximum(wc, w), np.maximum(rms, r)  # a NaN stays NaN
        return {
            "lateral_error_wc": np.where(np.isfinite(wc), wc, np.nan),
            "lateral_error_rms": np.where(np.isfinite(rms), rms, np.nan),
        }

    def _judge(
        self, results: list[Any], params: list[Array], modes: Array, c_z: Array | None = None
    ) -> tuple[Array, Array, dict[str, Array]]:
        """(eta, violation, the objectives' and limits' values), each ``(n,)``. The violation is model §16's:
        margin shortfall + sum of the tasks' V_reach + G / (1 + G) / (2n), n = the points of all tasks (approach
        lines too), G = (their guard grades summed) / n + the --max/--min shortfalls; 0 iff feasible. With
        ``by_docking`` (model §19.3) it is :meth:`_judge_dockings`'s, every docking evaluated."""
        if self.by_docking:
            return self._judge_dockings(results, params, modes, c_z, (True,) * self.n_patients)[:3]
        eta, reach, grade, all_w = self._combine(results, params)
        names = set(self.objectives) | {name for name, _, _ in self.limits}
        links = vol = np.zeros(0)
        if names & {"links", "bbox"}:
            links, vol = self.compactness_values(params)
        plan = [r for t, r in zip(self.tasks, results) if t.role == "plan"]
        mass = self.moving_mass(params, c_z) if "mass" in names else None
        # the first order costs ~25 us a point: only for the designs that reach every point of every task
        robust = (
            self.robust_values(params, modes, reach == 0.0)
            if names & {"lateral_error_wc", "lateral_error_rms"}
            else None
        )
        values = metric_values(names, plan, eta, links, vol, clearance_results=results, mass=mass, robust=robust)
        n_all = sum(t.n_points for t in self.tasks)
        fit = fit_violation(
            grade / n_all + limit_shortfall([list(lim) for lim in self.limits], self._defined(values, eta), len(reach)),
            n_all,
        )
        fit = np.where(~all_w & (fit == 0.0), np.finfo(float).tiny, fit)  # a failed guard never passes as feasible
        viol = reach + fit
        return np.where(viol == 0.0, eta, np.inf), viol, values

    @staticmethod
    def _defined(values: dict[str, Array], eta: Array) -> dict[str, Array]:
        """``values`` with eta_G NaN where +inf (a task not w_G: no eta_G to bound; the reach and the guards grade it)."""
        defined = dict(values)
        if "eta_G" in values:
            defined["eta_G"] = np.where(np.isfinite(eta), eta, np.nan)
        return defined

    def _judge_dockings(
        self, results: list[Any], params: list[Array], modes: Array, c_z: Array | None, active: tuple[bool, ...]
    ) -> tuple[Array, Array, dict[str, Array], Array, Array]:
        """model §19.3 over the ``active`` dockings: (eta, violation, values, each docking's violation ``(n, K)``, each
        docking's eta_G ``(n, K)``). Docking k's V_k is its tasks' V_reach plus its own V_fit, G_k / (1 + G_k) / (2 n_k)
        with n_k its points (approach lines too) and G_k its guard grades / n_k plus its own --max/--min shortfalls (the
        values over its tasks); its eta_G is over its plan's points (+inf unless every task of it is w_G). The violation is
        the orientation margin's shortfall plus the sum of the V_k; eta the max (or mean) of the eta_G over the dockings,
        +inf unless the violation is 0; values: the objectives over every active docking."""
        n = params[0].shape[0]
        K = self.n_patients
        names = set(self.objectives) | {name for name, _, _ in self.limits}
        links = vol = np.zeros(0)
        if names & {"links", "bbox"}:
            links, vol = self.compactness_values(params)
        mass = self.moving_mass(params, c_z) if "mass" in names else None
        viol_d, eta_d = np.full((n, K), np.nan), np.full((n, K), np.nan)
        robust_names = {"lateral_error_wc", "lateral_error_rms"}
        robust_d: list[dict[str, Array] | None] = []
        for k in (k for k in range(K) if active[k]):
            mine = [(t, r) for t, r in zip(self.tasks, results) if t.patient == k]
            reach = sum(np.nan_to_num(np.asarray(r.violation_reach, dtype=float), nan=1e6, posinf=1e6) for _, r in mine)
            robust = self.robust_values(params, modes, reach == 0.0, patient=k) if names & robust_names else None
            robust_d.append(robust)
            v_k, eta_k = self._docking_violation(mine, names, links, vol, mass, robust, n)
            rows = np.flatnonzero(v_k == 0.0) if self.fine_tasks else np.zeros(0, dtype=int)
            if len(rows):  # feasible at its points: judged again on its lines at the program's resolution
                sub, sub_c_z = [p[rows] for p in params], None if c_z is None else c_z[rows]
                # the plan's points as evaluated (rows are independent); the lines sampled finely replace the coarse ones
                plan_k = [(t, _rows_of(r, rows)) for t, r in mine if t.role == "plan"]
                fine = [t for t in self.fine_tasks if t.patient == k and t.role != "plan"]
                fine_results = self._run_tasks(sub, modes[rows], want_points=False, c_z=sub_c_z, tasks=fine)
                v_k[rows] = self._docking_violation(
                    plan_k + list(zip(fine, fine_results)),
                    names,
                    links[rows] if len(links) else links,
                    vol[rows] if len(vol) else vol,
                    None if mass is None else mass[rows],
                    None if robust is None else {key: value[rows] for key, value in robust.items()},
                    len(rows),
                )[0]
            viol_d[:, k] = v_k
            eta_d[:, k] = np.where(v_k == 0.0, eta_k, np.inf)
        on = np.array(active)
        viol = self.margin_shortfall(params[0]) + np.sum(viol_d[:, on], axis=1)
        eta = eta_d[:, on].mean(axis=1) if self.aggregate == "mean" else eta_d[:, on].max(axis=1)
        eta = np.where(viol == 0.0, eta, np.inf)
        kept = [r for t, r in zip(self.tasks, results) if active[t.patient]]
        plan = [r for t, r in zip(self.tasks, results) if active[t.patient] and t.role == "plan"]
        robust = None
        if names & robust_names:  # the worst over the dockings (a NaN, a docking not reached, stays NaN)
            robust = {
                name: np.max(np.stack([rd[name] for rd in robust_d if rd is not None]), axis=0) for name in robust_names
            }
        values = metric_values(names, plan, eta, links, vol, clearance_results=kept, mass=mass, robust=robust)
        return eta, viol, values, viol_d, eta_d

    def _docking_violation(
        self,
        mine: list[tuple[TaskData, Any]],
        names: set[str],
        links: Array,
        vol: Array,
        mass: Array | None,
        robust: dict[str, Array] | None,
        n: int,
    ) -> tuple[Array, Array]:
        """One docking's (V_k, eta_G) ``(n,)`` from its tasks' results ``mine`` (model §19.3, see :meth:`_judge_dockings`)."""
        reach, grade, all_w = np.zeros(n), np.zeros(n), np.ones(n, dtype=bool)
        eta_sum, pts = np.zeros(n), 0
        for t, r in mine:
            reach = reach + np.nan_to_num(np.asarray(r.violation_reach, dtype=float), nan=1e6, posinf=1e6)
            grade = grade + np.asarray(r.guard_grade, dtype=float)
            w = np.asarray(r.w_G)
            all_w &= w
            if t.role == "plan":
                eta_sum += t.n_points * np.where(w, np.asarray(r.eta_G, dtype=float), 0.0)
                pts += t.n_points
        eta_k = np.where((reach == 0.0) & all_w, eta_sum / pts, np.inf)
        values = metric_values(
            names,
            [r for t, r in mine if t.role == "plan"],
            eta_k,
            links,
            vol,
            clearance_results=[r for _, r in mine],
            mass=mass,
            robust=robust,
        )
        n_k = sum(t.n_points for t, _ in mine)
        fit = fit_violation(
            grade / n_k + limit_shortfall([list(lim) for lim in self.limits], self._defined(values, eta_k), n), n_k
        )
        fit = np.where(~all_w & (fit == 0.0), np.finfo(float).tiny, fit)  # a failed guard never passes as feasible
        return reach + fit, eta_k

    __call__ = evaluate

    def report(self, x: Array) -> dict[str, Any]:
        """Full description of one optimizer vector: designs, mode, eta, dexterity, compactness, clearances, per task."""
        X = np.atleast_2d(np.asarray(x, dtype=float))
        params, modes = self.space.decode(X)
        masses = needs(
            "masses", self.objectives, [list(lim) for lim in self.limits]
        )  # else the summary stays as it always was
        outputs = self.options.outputs.replace(
            clearances=True, tip_metrics=True, clearance_min_exact=True, holding_torque=masses
        )
        described = replace(self, options=self.options.replace(outputs=outputs))
        metrics = {**_METRICS, **_MASS_METRICS} if masses else _METRICS
        c_z = self.space.c_z(X)
        results = described._run_tasks(params, modes, want_points=True, c_z=c_z)
        eta, viol, values = self._judge(results, params, modes, c_z)
        by_docking = (
            self._judge_dockings(results, params, modes, c_z, (True,) * self.n_patients)[3][0]
            if self.by_docking
            else None
        )
        if (
            self.fine_tasks and not self.by_docking
        ):  # the verdict the search acted on: the fine tasks' where the coarse pass
            batch = self.evaluate(X)
            eta, viol = batch["ETA"], batch["VIOL"]
        dex = np.concatenate(
            [np.asarray(r.points.dexterity_pct)[0] for t, r in zip(self.tasks, results) if t.role == "plan"]
        )
        links, vol = self.compactness_values(params)
        tasks = []
        for t, r in zip(self.tasks, results):
            lo, hi = bounding_box(params[self.space.slot(t.patient, t.setup)], t.E, t.e)
            tasks.append(
                {
                    "label": t.label,
                    **({} if t.role == "plan" else {"role": t.role}),
                    "points": t.n_points,
                    "w_G": bool(r.w_G[0]),
                    "eta_G": _num(r.eta_G[0]),
                    "reachable_fraction": float(r.reachable_fraction[0]),
                    "violation": float(r.violation[0]),
                    "bbox_min_mm": [float(v) for v in lo[0]],
                    "bbox_max_mm": [float(v) for v in hi[0]],
                    "bbox_volume_L": float(np.prod(hi[0] - lo[0]) / 1e6),
                    "clearance_min_mm": _num(r.clearance_min[0]),
                    "self_clearance_min_mm": _num(r.self_clearance_min[0]),
                    **({"envelope_clearance_min_mm": _num(r.envelope_clearance_min[0])} if self.envelopes else {}),
                    **{f"{name}_max": _num(getattr(r, name + "_max")[0]) for name in metrics},
                }
            )
        return {
            "designs": [p[0] for p in params],
            **({} if c_z is None else {"c_z": float(c_z[0])}),
            "mode": format_mode(modes[0]),
            "feasible": bool(viol[0] == 0.0),
            "eta_G": _num(eta[0]),
            "violation": float(viol[0]),
            **({} if by_docking is None else {"docking_violations": [float(v) for v in by_docking]}),
            "margin_shortfall_rad": float(self.margin_shortfall(params[0])[0]),
            "dexterity_pct": {"min": float(dex.min()), "mean": float(dex.mean()), "max": float(dex.max())},
            "links_sum_mm": float(links[0]),
            "clearance_min_mm": _min_num([tk["clearance_min_mm"] for tk in tasks]),
            "self_clearance_min_mm": _min_num([tk["self_clearance_min_mm"] for tk in tasks]),
            **(
                {"envelope_clearance_min_mm": _min_num([tk["envelope_clearance_min_mm"] for tk in tasks])}
                if self.envelopes
                else {}
            ),
            "bbox_volume_L": float(vol[0]),
            **{
                f"{name}_max_{unit}": _max_num([tk[f"{name}_max"] for tk in tasks if "role" not in tk])
                for name, unit in metrics.items()
            },
            **({"moving_mass_kg": float(self.moving_mass(params, c_z)[0])} if masses else {}),
            **{SUMMARY_KEYS[name]: _num(values[name][0]) for name in ROBUST_NAMES if name in values},
            **(
                {"tolerance_class": (self.accuracy or ToleranceSettings()).tolerance_class}
                if set(ROBUST_NAMES) & set(values)
                else {}
            ),
            "tasks": tasks,
        }


_METRICS = {
    "tip_error": "mm",
    "lateral_error": "mm",
    "axial_error": "mm",
    "axis_error": "deg",
    "torque": "Nm",
    "deflection": "mm",
}
"""The summary maxima of model §15.5 (TaskResults fields ``<name>_max``) and their units."""
_MASS_METRICS = {"holding_torque": "Nm"}
"""The maximum of model §18.2, in a report when an objective or limit uses the masses (with ``moving_mass_kg``)."""


def _max_num(values: list[float | None]) -> float | None:
    """The largest of the values, None if any is missing (an unreachable task)."""
    return None if any(v is None for v in values) else max(values)  # type: ignore[type-var]


def _min_num(values: list[float | None]) -> float | None:
    """The smallest of the values that exist, None if none does."""
    known = [v for v in values if v is not None]
    return min(known) if known else None


def _num(v: Any) -> float | None:
    """A finite float, or None (JSON null) for +inf/NaN."""
    f = float(v)
    return f if math.isfinite(f) else None


# Worker-side entry points (kept in this light module so that spawned processes import little).
_WORKER_MODEL: FitnessModel | None = None


def worker_init(model: FitnessModel) -> None:
    """Process-pool initializer: keep the model for the worker's lifetime."""
    global _WORKER_MODEL
    _WORKER_MODEL = model


def worker_evaluate(X: Array) -> dict[str, Array]:
    assert _WORKER_MODEL is not None, "worker_init was not called"
    return _WORKER_MODEL.evaluate(X)


def _rows_of(result: Any, rows: Array) -> Any:
    """A task's results (a :class:`~arcube.evaluation.reference.TaskResults`) for the designs ``rows`` only."""
    return type(result)(*(f[rows] if isinstance(f, np.ndarray) and f.ndim else f for f in result))


def evaluate_with(model: FitnessModel, X: Array) -> dict[str, Array]:
    """Dask task: evaluate ``X`` with a (scattered) model."""
    return model.evaluate(X)


class ArcubeProblem(Problem):
    """pymoo view of a :class:`FitnessModel`; ``batch(X)`` returns the model's dict (maybe remotely).

    With ``penalty_only`` (CMA-ES) the problem has no constraint: F already carries the penalty.
    Otherwise G = VIOL (one inequality, feasible iff VIOL <= 0) and CV = max(VIOL, 0), which is
    what pymoo's ``calc_cv`` would compute from G lazily, individual by individual. ETA and VIOL
    ride along on the individuals for bookkeeping.
    """

    def __init__(
        self, space: VariableSpace, n_obj: int, batch: Callable[[Array], dict[str, Array]], penalty_only: bool = False
    ) -> None:
        super().__init__(
            n_var=space.n_var, n_obj=n_obj, n_ieq_constr=0 if penalty_only else 1, xl=space.xl, xu=space.xu
        )
        self._batch = batch

    def _evaluate(self, X: Array, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
        r = self._batch(np.ascontiguousarray(X, dtype=float))
        out["F"] = r["F"]
        if self.n_ieq_constr:
            out["G"] = r["VIOL"][:, None]
            out["CV"] = np.maximum(r["VIOL"], 0.0)[:, None] + 0.0  # pymoo's calc_cv of one inequality
        out["ETA"] = r["ETA"]
        out["VIOL"] = r["VIOL"]
        for key in DOCKING_KEYS:  # one robot, several dockings (model §19): each docking's own
            if key in r:
                out[key] = r[key]


__all__ = [
    "AGGREGATES",
    "COMPACTNESS",
    "DEFAULT_BOUNDS",
    "DOCKING_KEYS",
    "PLACEMENTS",
    "LINK_NAMES",
    "MODE_GENES",
    "N_PARAMS",
    "PENALTY",
    "ArcubeProblem",
    "FitnessModel",
    "TaskData",
    "VariableSpace",
    "bounding_box",
    "mechanism_points",
    "evaluate_with",
    "parse_bounds",
    "parse_free",
    "resolve_bounds",
    "worker_evaluate",
    "worker_init",
]
