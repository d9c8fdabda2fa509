"""One design evaluated on a set of trajectories: :class:`Evaluation`, what a person reads.

:func:`evaluate_design` samples the trajectories, runs one batch evaluation and wraps the arrays
in :class:`Evaluation`, which gives the per-trajectory table, the failure counts and their
diagnosis, the JSON object of ``arcube evaluate --json`` (built by :mod:`arcube.evaluation.tables`)
and a pandas DataFrame. The HTML report is drawn by :func:`arcube.report.write_report`.
:func:`arcube.evaluate` (the public API) loads files and validates flags before calling it.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.evaluation import tables
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.reference import Options, PointResults, TaskResults
from arcube.evaluation.tables import TrajectorySummary
from arcube.evaluation.task import MAX_POINTS, Task, build_task
from arcube.errors import InputError
from arcube.io import TrajectorySet, load_trajectories, select
from arcube.model.design import Design
from arcube.model.mechanism import format_mode, parse_mode

if TYPE_CHECKING:
    from arcube.evaluation.anatomy import Anatomy
    from arcube.evaluation.envelope import Envelope


@dataclass(frozen=True)
class Evaluation:
    """A design evaluated on a task: the arrays, and what a person reads of them.

    The tables, the diagnosis and the JSON are built by the plain functions of
    :mod:`arcube.evaluation.tables`; :attr:`summary` is computed once and kept. The HTML report is
    :func:`arcube.report.write_report` (the result does not know its renderer).
    """

    design: Design
    mode: str
    options: Options
    trajectories: TrajectorySet
    task: Task
    results: TaskResults
    engine: str
    anatomy: Anatomy | None = None
    envelope: Envelope | None = None
    """The envelope of the whole patient (MODEL.md 19.5) the clearance was measured to, placed on the whole plan."""

    def per_trajectory(self) -> list[TrajectorySummary]:
        """Summaries per trajectory, in file order."""
        return tables.per_trajectory(self.results.points, self.task, self.trajectories)

    def failure_counts(self) -> dict[str, int]:
        """How many points fail for each reason."""
        return tables.failure_counts(self.results.points)

    def diagnosis(self) -> list[str]:
        """Where a stage cannot serve the task: what the task needs against what each leg offers
        (:func:`arcube.evaluation.tables.diagnosis`)."""
        return tables.diagnosis(self.design, self.task)

    @property
    def points(self) -> PointResults:
        """Per-point arrays ``(P,)`` (reachable, failure, kappa ``(P, 7)``, eta_L, dexterity_pct, rho, delta, sigma)."""
        return self.results.points

    @cached_property
    def summary(self) -> dict[str, Any]:
        """The summary of the JSON output: eta_G (None when not every point is reachable), w_G, dexterity, failures,
        the maxima of MODEL.md 15 and 18.2 and (with ``Outputs.holding_torque``) the moving mass.

        Computed on first access and kept (the evaluation is immutable); :meth:`summary_json` returns a copy."""
        mass = None
        if self.options.outputs.holding_torque:  # MODEL.md 18.3's per-design moving mass, beside the holding torque
            from arcube.evaluation.masses import moving_mass_kg

            mass = float(moving_mass_kg(self.design.to_vector(), self.options))
        return tables.summary(self.results, len(self.task), mass)

    def summary_json(self) -> dict[str, Any]:
        """A fresh copy of :attr:`summary` (the ``summary`` of :meth:`to_json`), safe to modify."""
        return copy.deepcopy(self.summary)

    def to_dataframe(self) -> Any:
        """One row per task point (the fields of :meth:`to_json` ``points``, lists spread into columns); needs pandas."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Evaluation.to_dataframe needs pandas: pip install pandas") from None
        rows = []
        for point in tables.point_rows(self.results.points, self.task):
            row: dict[str, Any] = {}
            for key, value in point.items():
                if isinstance(value, list):
                    row.update({f"{key}_{leg}": v for leg, v in zip("xyz", value)})
                elif isinstance(value, dict):
                    row.update({f"{key}_{name}": v for name, v in value.items()})
                else:
                    row[key] = value
            rows.append(row)
        return pd.DataFrame(rows)

    def to_json(self) -> dict[str, Any]:
        """The JSON object of the issue's contract (values that do not exist are null)."""
        return tables.to_json(self)


def parse_mode_option(text: str) -> np.ndarray:
    """A working mode's text (``"+,+,-,+"``) -> signs ``(4,)``; InputError naming ``mode``."""
    try:
        return parse_mode(text)
    except ValueError as exc:
        raise InputError(f"mode: {exc}", param="mode") from None


def load_trajectory_set(
    trajectories: str, points: int, side: str | None = None, levels: str | None = None,
    ids: str | None = None, transform: Path | None = None,
) -> TrajectorySet:  # fmt: skip
    """Read and subset trajectories, checking ``points`` first (raises InputError)."""
    return load_plan(trajectories, points, side, levels, ids, transform)[1]


def load_plan(
    trajectories: str, points: int, side: str | None = None, levels: str | None = None,
    ids: str | None = None, transform: Path | None = None,
) -> tuple[TrajectorySet, TrajectorySet]:  # fmt: skip
    """(the plan as loaded, its subset): :func:`load_trajectory_set` keeping the whole plan too, for what is placed
    on all of it whatever side is evaluated (the landmarks of the envelope, MODEL.md 19.5; raises InputError)."""
    if not 2 <= points <= MAX_POINTS:
        raise InputError.of("points", f"must be an integer in [2, {MAX_POINTS}] (both ends of a trajectory included), got {points}")
    full = load_trajectories(trajectories, transform=transform)
    return full, select(full, side=side, levels=levels, ids=ids)


def load_task(
    trajectories: str, points: int, side: str | None = None, levels: str | None = None,
    ids: str | None = None, transform: Path | None = None,
) -> tuple[TrajectorySet, Task]:  # fmt: skip
    """Read, subset and sample trajectories into a task (raises InputError)."""
    ts = load_trajectory_set(trajectories, points, side, levels, ids, transform)
    return ts, build_task(ts.entry, ts.target, points, ids=ts.ids)


def evaluate_design(
    design: Design, ts: TrajectorySet, points: int, signs: np.ndarray, options: Options, engine: str = "numpy",
    anatomy: Anatomy | None = None, envelope: Envelope | None = None,
) -> Evaluation:
    """Sample ``ts`` at ``points`` per trajectory and evaluate ``design`` in one batch call. ``envelope``: the envelope of
    the whole patient (MODEL.md 19.5), resolved on the whole plan (:func:`load_plan`), not on ``ts`` alone."""
    task = build_task(ts.entry, ts.target, points, ids=ts.ids)
    distance = None if anatomy is None else anatomy.distance
    results = evaluate_task(design.to_vector(), task.E, task.e, signs, options, engine=engine, want_points=True, anatomy=distance,
                            envelope=envelope)  # fmt: skip
    return Evaluation(
        design=design, mode=format_mode(signs), options=options, trajectories=ts, task=task, results=results, engine=engine,
        anatomy=anatomy, envelope=envelope,
    )  # fmt: skip
