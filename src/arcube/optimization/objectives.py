"""What the optimizer can minimize or bound (model §15.5): names, parsing of ``--objectives``,
``--max NAME=VALUE`` and ``--min NAME=VALUE``, and the per-design values of a population.

Every value is per design over all tasks of the run: the worst (largest) of the metrics of
model §15 and of the holding torque of 18.2 over the tasks' reachable points, the smallest
clearance, eta_G as aggregated by the run, the sum of link lengths, the bounding-box volume and the
moving mass of 18.1. ``clearance`` is maximized (its objective column is its negative). The holding
torque is computed only when an objective or limit names it (:func:`needs` ``"holding_torque"``): every
other run keeps its speed and its results.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from arcube.metrics import OUTPUTS, metric, objective_names


OBJECTIVES: dict[str, str] = {n: metric(n).description for n in objective_names()}
"""Objective and constraint names (``--objectives``, ``--max``, ``--min``) and what they measure (:mod:`arcube.metrics`)."""

MAXIMIZED = frozenset(n for n in OBJECTIVES if metric(n).maximized)

SUMMARY_KEYS: dict[str, str] = {n: metric(n).summary_key for n in OBJECTIVES}  # type: ignore[misc]
"""The field of a run's summary.json (and of arcube.evaluate's summary) that holds each objective's value."""


def summary_value(summary: dict[str, Any], name: str) -> float | None:
    """The value of objective ``name`` in a run's summary (None when the run has none, e.g. no feasible design)."""
    value = summary.get(SUMMARY_KEYS[name])
    return None if value is None else float(value)


def needs(output: str, objectives: tuple[str, ...], limits: list[list[Any]]) -> bool:
    """Whether these objectives and limits need ``output`` of the evaluation (:data:`arcube.metrics.OUTPUTS`)."""
    if output not in OUTPUTS:
        raise ValueError(
            f"{output!r} is not an output an evaluation computes when asked ({', '.join(sorted(OUTPUTS))})"
        )
    return any(output in metric(n).needs for n in (*objectives, *(n for n, _, _ in limits)))


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
    :data:`~arcube.accuracy.robust.ROBUST_NAMES` per design, needed for those names. How each name's value is
    found: its :class:`arcube.metrics.Metric` (``source``, ``batch_field``, ``maximized``, ``where``)."""
    given = {"eta_G": eta, "mass": mass, "links": links, "bbox": vol}
    out: dict[str, np.ndarray] = {}
    for name in names:
        m = metric(name)
        if m.source == "robust":
            assert robust is not None, "the robust objectives need the designs' accuracy under tolerances"
            out[name] = robust[name]
        elif m.source != "batch":
            assert given[m.source] is not None, f"the {name} objective needs the designs' {m.source} values"
            out[name] = given[m.source]  # type: ignore[assignment]
        else:  # the worst over the tasks; a figure over the whole line reads the plan's and the approach lines' tasks
            over = (clearance_results or results) if m.where == "whole line" else results
            vals = np.stack([np.asarray(getattr(r, m.batch_field), float) for r in over])  # type: ignore[arg-type]
            out[name] = np.where(
                np.isnan(vals).any(axis=0), np.nan, vals.min(axis=0) if m.maximized else vals.max(axis=0)
            )
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
