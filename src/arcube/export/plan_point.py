"""The task point a MuJoCo model is assembled at (:func:`arcube.export.mjcf.export_mjcf`'s ``plan``,
``points`` and ``at``): the plan's samples, ``"ID:K"`` resolved, and why the IK fails there."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.io.inputs import short_repr

__all__ = ["PlanPoints", "no_ik_reason", "plan_points", "resolve_point"]


@dataclass(frozen=True)
class PlanPoints:
    """The P sample points of a plan: poses (E, e) ``(P, 3)`` in R_w (mm), trajectory ids, each point's
    trajectory index and sample index k ``(P,)``, and the points per trajectory."""

    E: NDArray[np.float64]  # (P, 3)
    e: NDArray[np.float64]
    ids: tuple[str, ...]
    trajectory: NDArray[np.intp]
    k: NDArray[np.intp]
    n_points: int


def plan_points(plan: Any, points: int) -> PlanPoints:
    """The plan (a TrajectorySet, a path, None or "reference") sampled at ``points`` per trajectory."""
    from arcube.coerce import points as checked_points
    from arcube.evaluation.task import build_task
    from arcube.io.load import load_plan

    points = checked_points(points)
    ts = load_plan("reference" if plan is None else plan)
    if len(ts.ids) == 0:
        raise InputError("the plan has no trajectories")
    task = build_task(ts.entry, ts.target, int(points), ids=ts.ids)
    return PlanPoints(task.E, task.e, tuple(task.ids), task.trajectory, task.k, int(points))


def resolve_point(plan: PlanPoints, at: str | tuple[Any, int] | None) -> int:
    """Index into the plan's points of ``at`` = ``"ID:K"`` (or ``(id, k)``); None: first point."""
    if at is None:
        return 0
    if isinstance(at, str):
        tid, sep, ktext = at.strip().rpartition(":")
        if not sep or not tid:
            raise InputError.of(
                "at", f"{short_repr(at)}: expected ID:K, a trajectory id and a sample index, e.g. '1:0'"
            )
        try:
            k = int(ktext)
        except ValueError:
            raise InputError.of(
                "at", f"{short_repr(at)}: the sample index K must be an integer, got {short_repr(ktext)}"
            ) from None
    else:
        tid, k = str(at[0]), int(at[1])
    if tid not in plan.ids:
        shown = ", ".join(plan.ids[:12]) + (", ..." if len(plan.ids) > 12 else "")
        raise InputError.of("at", f"{tid}:{k}: no trajectory with id {short_repr(tid)} in the plan (ids: {shown})")
    if not 0 <= k < plan.n_points:
        raise InputError.of(
            "at", f"{tid}:{k}: sample index k must lie in 0..{plan.n_points - 1} (points={plan.n_points})"
        )
    t = plan.ids.index(tid)
    return int(np.flatnonzero((plan.trajectory == t) & (plan.k == k))[0])


def no_ik_reason(sol: Any) -> str:
    """Why the IK of one pose has no solution: the stages out of reach (one line)."""
    parts, undefined = [], []
    for stage, arg, legs in (("TLS", sol.tls_arg, "xyz"), ("RTS", sol.rts_arg, "xy"), ("TMS", sol.tms_arg, "xy")):
        for leg, a in zip(legs, np.asarray(arg, dtype=float).reshape(-1)):
            if math.isfinite(a) and abs(a) > 1.0:
                parts.append(f"{stage} {leg} out of reach (|arg| = {abs(a):.3g} > 1)")
            elif not math.isfinite(a):
                undefined.append(f"{stage} {leg}")
    # a NaN argument follows from an earlier stage's failure; name it only when nothing else failed
    return ", ".join(parts or undefined) or "a stage has no finite solution"
