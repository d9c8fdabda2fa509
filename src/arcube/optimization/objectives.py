"""What the optimizer can minimize or bound (model §15.5): names, parsing of ``--objectives``,
``--max NAME=VALUE`` and ``--min NAME=VALUE``, and the per-design values of a population.

Every value is per design over all tasks of the run: the worst (largest) of the metrics of
model §15 and of the holding torque of 18.2 over the tasks' reachable points, the smallest
clearance, eta_G as aggregated by the run, the sum of link lengths, the bounding-box volume and the
moving mass of 18.1. ``clearance`` is maximized (its objective column is its negative). The holding
torque is computed only when an objective or limit names it (:func:`needs_holding_torque`): every
other run keeps its speed and its results.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from arcube.accuracy.robust import ROBUST_NAMES


OBJECTIVES: dict[str, str] = {
    "eta_G": "the paper's global conditioning index (mean of the worst kappa), lower is better",
    "tip_error": "largest drill-tip error over the plan, mm (model §15.2)",
    "lateral_error": "largest error across the drill axis, mm (15.2)",
    "axial_error": "largest error along the drill axis, mm (15.2)",
    "axis_error": "largest drill-direction error, deg (15.2)",
    "torque": "largest actuator torque under the drilling loads, N·m (15.3)",
    "deflection": "largest lateral tip deflection under the loads, mm (15.4)",
    "holding_torque": "largest actuator torque holding the robot's weight and the drilling loads, N·m (18.2)",
    "mass": "moving mass of the robot, kg (18.1)",
    "links": "sum of the 14 link lengths, mm",
    "bbox": "largest bounding-box volume of the body over a task, litres",
    "clearance": "smallest clearance to the anatomy, mm (maximized; needs --anatomy)",
    "envelope_clearance": "smallest clearance to the envelope of the whole patient and the table, mm (maximized; model §19.5)",
    "lateral_error_wc": "largest first-order worst-case lateral error of the robot as built to --class / --tol, mm (model §20.3)",
    "lateral_error_rms": "largest RMS lateral error of the robot as built to --class / --tol, mm (model §20.3)",
}
"""Objective and constraint names (``--objectives``, ``--max``, ``--min``) and what they measure."""

MAXIMIZED = frozenset({"clearance", "envelope_clearance"})
_SUMMARY = {
    "tip_error": "tip_error_max",
    "lateral_error": "lateral_error_max",
    "axial_error": "axial_error_max",
    "axis_error": "axis_error_max",
    "torque": "torque_max",
    "deflection": "deflection_max",
    "holding_torque": "holding_torque_max",
}

SUMMARY_KEYS: dict[str, str] = {
    "eta_G": "eta_G",
    "tip_error": "tip_error_max_mm",
    "lateral_error": "lateral_error_max_mm",
    "axial_error": "axial_error_max_mm",
    "axis_error": "axis_error_max_deg",
    "torque": "torque_max_Nm",
    "deflection": "deflection_max_mm",
    "links": "links_sum_mm",
    "bbox": "bbox_volume_L",
    "clearance": "clearance_min_mm",
    "holding_torque": "holding_torque_max_Nm",
    "mass": "moving_mass_kg",
    "envelope_clearance": "envelope_clearance_min_mm",
    "lateral_error_wc": "lateral_error_wc_mm",
    "lateral_error_rms": "lateral_error_rms_mm",
}
"""The field of a run's summary.json (and of arcube.evaluate's summary) that holds each objective's value."""


def summary_value(summary: dict[str, Any], name: str) -> float | None:
    """The value of objective ``name`` in a run's summary (None when the run has none, e.g. no feasible design)."""
    value = summary.get(SUMMARY_KEYS[name])
    return None if value is None else float(value)


def needs_clearance(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether the clearance to the anatomy must be computed for these objectives and limits."""
    return "clearance" in objectives or any(n == "clearance" for n, _, _ in limits)


def needs_envelope_clearance(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether the clearance to the envelope (model §19.5) must be computed for these objectives and limits."""
    return "envelope_clearance" in objectives or any(n == "envelope_clearance" for n, _, _ in limits)


def needs_robust(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether the accuracy under tolerances (model §20.3, :mod:`arcube.accuracy.robust`) must be computed."""
    return any(n in ROBUST_NAMES for n in (*objectives, *(n for n, _, _ in limits)))


def needs_tip_metrics(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether the metrics of model §15 must be computed for these objectives and limits."""
    return any(n in _SUMMARY for n in objectives) or any(n in _SUMMARY for n, _, _ in limits)


def needs_holding_torque(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether the holding torque of model §18.2 must be computed for these objectives and limits."""
    return "holding_torque" in objectives or any(n == "holding_torque" for n, _, _ in limits)


def needs_masses(objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether these objectives and limits use the mass model of model §18.1 (holding torque, moving mass)."""
    return any(n in ("holding_torque", "mass") for n in (*objectives, *(n for n, _, _ in limits)))


def metric_values(
    names: set[str],
    results: list[Any],
    eta: np.ndarray,
    links: np.ndarray,
    vol: np.ndarray,
    clearance_results: list[Any] | None = None,
    mass: np.ndarray | None = None,
    robust: dict[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Per design ``(n,)``, the value of each name over all tasks (NaN where no point is reachable);
    the clearance over ``clearance_results`` when given (the plan's and the approach lines' tasks);
    ``mass``: the moving mass per design (kg), needed for the name ``mass``; ``robust``: the values of
    :data:`~arcube.accuracy.robust.ROBUST_NAMES` per design, needed for those names."""
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name in ROBUST_NAMES:
            assert robust is not None, "the robust objectives need the designs' accuracy under tolerances"
            out[name] = robust[name]
        elif name == "eta_G":
            out[name] = eta
        elif name == "mass":
            assert mass is not None, "the mass objective needs the designs' moving masses"
            out[name] = mass
        elif name == "links":
            out[name] = links
        elif name == "bbox":
            out[name] = vol
        elif name in ("clearance", "envelope_clearance"):
            vals = np.stack([np.asarray(getattr(r, f"{name}_min"), float) for r in (clearance_results or results)])
            out[name] = np.where(np.isnan(vals).any(axis=0), np.nan, vals.min(axis=0))
        else:
            vals = np.stack([np.asarray(getattr(r, _SUMMARY[name]), float) for r in results])
            out[name] = np.where(np.isnan(vals).any(axis=0), np.nan, vals.max(axis=0))
    return out


def limit_shortfall(limits: list[list[Any]], values: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Sum of the normalized shortfalls ``(n,)``: (value - limit) / limit above a --max, (limit - value) /
    max(|limit|, 1) below a --min; 0 exactly when every limit is met (and where a value does not exist:
    an unreachable point already makes the design infeasible)."""
    short = np.zeros(n)
    for name, kind, limit in limits:
        v = values[name]
        s = (v - limit) / limit if kind == "max" else (limit - v) / max(abs(limit), 1.0)
        short = short + np.where(np.isnan(s), 0.0, np.maximum(s, 0.0))
    return short


def objective_columns(
    objectives: tuple[str, ...], values: dict[str, np.ndarray], feasible: np.ndarray, viol: np.ndarray, penalty: float
) -> list[np.ndarray]:
    """The F columns: each objective's value (negated when maximized); infeasible designs and missing
    values get ``penalty * (1 + viol)`` so that single-objective algorithms rank them last."""
    cols = []
    for name in objectives:
        v = -values[name] if name in MAXIMIZED else values[name]
        bad = ~feasible | ~np.isfinite(v)
        cols.append(np.where(bad, penalty * (1.0 + viol), v))
    return cols
