"""One design evaluated on a set of trajectories: :class:`Evaluation`, what a person reads.

:func:`evaluate_design` samples the trajectories, runs one batch evaluation and wraps the arrays
in :class:`Evaluation`, which gives the per-trajectory table, the failure counts and their
diagnosis, the JSON object of ``arcube evaluate --json`` (built by :mod:`arcube.evaluation.tables`)
and a pandas DataFrame. The HTML report is drawn by :func:`arcube.report.write_report`.
:func:`arcube.evaluate` (the public API) loads files and coerces arguments before calling it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.evaluation import tables
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.reference import Options, PointResults, TaskResults
from arcube.evaluation.tables import TrajectorySummary
from arcube.evaluation.task import Task, build_task
from arcube.io import TrajectorySet
from arcube.model.design import Design
from arcube.model.mechanism import format_mode
from arcube.summary import Summary

if TYPE_CHECKING:
    from arcube.evaluation.anatomy import Anatomy
    from arcube.evaluation.envelope import Envelope


class EvaluationSummary(Summary):
    """The summary of one evaluation (``Evaluation.summary``, the ``summary`` of ``arcube evaluate --json``)."""

    n_points: int
    """Points of the task (trajectories x points per trajectory)."""
    w_G: bool
    """Whether every point is reachable (model §8.3)."""
    reachable_fraction: float
    """Share of the points reachable, 0-1."""
    eta_G: float | None
    """The global index eta_G (model §8.3); None unless every point is reachable."""
    dexterity_pct: dict[str, float]
    """Inverted condition number over the points, percent: ``min``, ``mean``, ``max``."""
    inverted_eta_G_pct: float | None
    """100 / eta_G, percent."""
    failures: dict[str, int]
    """Points that fail, per reason (model §8.2 and 14.3)."""
    clearance_min_mm: float | None
    """Smallest clearance to the anatomy, mm (model §14.3); None without one."""
    clearance_min_part: str | None
    """The robot's part where it is smallest."""
    self_clearance_min_mm: float | None
    """Smallest clearance between the robot's own parts, mm."""
    envelope_clearance_min_mm: float | None
    """Smallest clearance to the envelope of the whole patient and the table, mm (model §19.5); None without one."""
    envelope_clearance_min_part: str | None
    """The robot's part where it is smallest."""
    envelope_clearance_min_region: str | None
    """The envelope's region there (neck, head, torso, table, skin)."""
    tip_error_max_mm: float | None
    """Largest drill-tip position error from the encoders, mm (model §15.2)."""
    lateral_error_max_mm: float | None
    """Largest lateral error under the drilling loads, mm (model §15)."""
    axial_error_max_mm: float | None
    """Largest axial error, mm."""
    axis_error_max_deg: float | None
    """Largest drill-axis angle error, deg."""
    torque_max_Nm: float | None
    """Largest actuator torque holding the drilling loads, N m (model §15.3)."""
    torque_max_actuator: str | None
    """The actuator that needs it."""
    deflection_max_mm: float | None
    """Largest drill-tip deflection from the actuators' stiffness, mm (model §15.4)."""
    holding_torque_max_Nm: float | None
    """Largest holding torque, gravity and loads, N m (model §18.2); None unless asked."""
    holding_torque_max_actuator: str | None
    """The actuator that needs it."""
    moving_mass_kg: float | None
    """The design's moving mass, kg (model §18.3); None unless the holding torque is asked."""


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
    """The envelope of the whole patient (model §19.5) the clearance was measured to, placed on the whole plan."""

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
    def summary(self) -> EvaluationSummary:
        """The summary of the JSON output: eta_G (None when not every point is reachable), w_G, dexterity, failures,
        the maxima of model §15 and 18.2 and (with ``Outputs.holding_torque``) the moving mass.

        Computed on first access and kept (the evaluation is immutable); :meth:`summary_json` returns a copy."""
        mass = None
        if self.options.outputs.holding_torque:  # model §18.3's per-design moving mass, beside the holding torque
            from arcube.evaluation.masses import moving_mass_kg

            mass = float(moving_mass_kg(self.design.to_vector(), self.options))
        return EvaluationSummary(tables.summary(self.results, len(self.task), mass, self.regions))

    @property
    def regions(self) -> tuple[str, ...]:
        """The envelope's region names (``neck``, ``head``, ``torso``, ``table``, ``skin``), () without one."""
        return () if self.envelope is None else tuple(self.envelope.names)

    def summary_json(self) -> dict[str, Any]:
        """A fresh copy of :attr:`summary` (the ``summary`` of :meth:`to_json`), safe to modify."""
        return self.summary.to_json()

    def to_dataframe(self) -> Any:
        """One row per task point (the fields of :meth:`to_json` ``points``, lists spread into columns); needs pandas."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Evaluation.to_dataframe needs pandas: pip install pandas") from None
        rows = []
        for point in tables.point_rows(self.results.points, self.task, self.regions):
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
        pts = self.results.points
        return {
            "design": self.design.to_file_dict(),
            "mode": self.mode,
            "engine": self.engine,
            "guards": self.options.flat(),
            "anatomy": None if self.anatomy is None else self.anatomy.source,
            "anatomy_segments": None
            if self.anatomy is None or self.anatomy.segments is None
            else [s.to_dict() for s in self.anatomy.segments],
            "envelope": None if self.envelope is None else self.envelope.describe(),
            "points": tables.point_rows(pts, self.task, self.regions),
            "summary": self.summary_json(),
            "trajectories": [vars(row) for row in tables.per_trajectory(pts, self.task, self.trajectories)],
        }


def evaluate_design(
    design: Design,
    ts: TrajectorySet,
    points: int,
    signs: np.ndarray,
    options: Options,
    engine: str = "numpy",
    anatomy: Anatomy | None = None,
    envelope: Envelope | None = None,
) -> Evaluation:
    """Sample ``ts`` at ``points`` per trajectory and evaluate ``design`` in one batch call. ``envelope``: the envelope of
    the whole patient (model §19.5), resolved on the whole plan (before any side or level is kept), not on ``ts`` alone."""
    task = build_task(ts.entry, ts.target, points, ids=ts.ids)
    distance = None if anatomy is None else anatomy.distance
    results = evaluate_task(
        design.to_vector(),
        task.E,
        task.e,
        signs,
        options,
        engine=engine,
        want_points=True,
        anatomy=distance,
        envelope=envelope,
    )
    return Evaluation(
        design=design,
        mode=format_mode(signs),
        options=options,
        trajectories=ts,
        task=task,
        results=results,
        engine=engine,
        anatomy=anatomy,
        envelope=envelope,
    )
