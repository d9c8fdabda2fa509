"""What a person reads of an evaluation, as plain functions of its arrays: the per-trajectory table,
the failure counts and their diagnosis, the summary and the JSON object of ``arcube evaluate --json``.

:class:`arcube.evaluation.result.Evaluation` delegates to these (as spatialmath's ``SO3.Rx`` wraps
``rotx``); they take the arrays they read (:class:`PointResults`, :class:`Task`, ...), not the class.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from arcube.evaluation.indices import JACOBIAN_NAMES
from arcube.evaluation.performance import ACTUATOR_NAMES, MAXIMUM_FIELDS
from arcube.evaluation.reference import FAILURES, PointResults, TaskResults
from arcube.evaluation.task import Task
from arcube.io import TrajectorySet
from arcube.model import frames
from arcube.model.body import PART_NAMES
from arcube.model.design import Design, unpack

__all__ = ["TrajectorySummary", "diagnosis", "failure_counts", "per_trajectory", "point_rows", "summary"]


@dataclass(frozen=True)
class TrajectorySummary:
    """One row of the per-trajectory table."""

    id: str
    level: str
    side: str
    reachable_fraction: float
    dexterity_min: float
    dexterity_mean: float
    dexterity_max: float
    limiting_jacobian: str | None  # the Jacobian whose kappa is the largest at most reachable points
    first_failure: str | None  # "<reason> at k=<k>" of the first unreachable point
    clearance_min_mm: float | None = None  # smallest clearance to the anatomy over its reachable points


def per_trajectory(pts: PointResults, task: Task, trajectories: TrajectorySet) -> list[TrajectorySummary]:
    """Summaries per trajectory, in file order."""
    rows = []
    for t, tid in enumerate(task.ids):
        sel = task.trajectory == t
        reach = pts.reachable[sel]
        dex = pts.dexterity_pct[sel]
        limiting = None
        if reach.any():
            worst = np.argmax(pts.kappa[sel][reach], axis=-1)
            limiting = JACOBIAN_NAMES[Counter(worst.tolist()).most_common(1)[0][0]]
        first = None
        if not reach.all():
            i = int(np.argmin(reach))
            first = f"{FAILURES[int(pts.failure[sel][i]) - 1]} at k={int(task.k[sel][i])}"
        rows.append(
            TrajectorySummary(
                id=tid,
                level=trajectories.levels[t],
                side=trajectories.sides[t],
                reachable_fraction=float(reach.mean()),
                dexterity_min=float(dex.min()),
                dexterity_mean=float(dex.mean()),
                dexterity_max=float(dex.max()),
                limiting_jacobian=limiting,
                first_failure=first,
                clearance_min_mm=_min_or_none(pts.clearance_mm[sel][reach]),
            )
        )
    return rows


def failure_counts(pts: PointResults) -> dict[str, int]:
    """How many points fail for each reason."""
    codes = Counter(int(c) for c in pts.failure if c)
    return {FAILURES[c - 1]: n for c, n in sorted(codes.items())}


def diagnosis(design: Design, task: Task) -> list[str]:
    """Where a stage cannot serve the task: what the task needs against what each leg offers.

    In mechanism coordinates at the centre C = E + L e (model §13; R_w shifted by m when the
    design is not rotated): TLS leg u reaches u in [-f_u - r - p_u, -f_u - r + p_u] (model §3.2);
    RTS leg u reaches angle(e, +u) in [|alpha_u - beta_u|, alpha_u + beta_u] (model §5.2).
    """
    d = design
    g = unpack(d.to_vector())
    C_m, e_m = frames.to_mechanism(g, task.E, task.e)
    rotated = not bool(frames.is_unrotated(g))
    lines = []
    for i, leg in enumerate("xyz"):
        centre = -d[f"f_{leg}"] - d["r"]
        lo, hi = centre - d[f"p_{leg}"], centre + d[f"p_{leg}"]
        need_lo, need_hi = float(C_m[:, i].min()), float(C_m[:, i].max())
        if need_lo < lo or need_hi > hi:
            where = f"{leg}_m" if rotated else f"{leg} - m_{leg}"
            fix = "move the mounting" if rotated else f"move m_{leg}"
            lines.append(
                f"TLS/{leg}: the task spans {where} = [{need_lo:.1f}, {need_hi:.1f}] mm but the crank reaches "
                f"[{lo:.1f}, {hi:.1f}] mm (-f_{leg} - r +- p_{leg}); {fix} by about {(need_lo + need_hi) / 2 - centre:+.1f} mm"
            )
    angles = np.degrees(np.arccos(np.clip(e_m[:, :2], -1.0, 1.0)))
    for i, leg in enumerate("xy"):
        a, b = d[f"alpha_{leg}"], d[f"beta_{leg}"]
        need_lo, need_hi = float(angles[:, i].min()), float(angles[:, i].max())
        if need_lo < abs(a - b) or need_hi > a + b:
            fix = (
                "no placement m can fix this"
                if not rotated
                else "only another mounting rotation or wider links can fix this"
            )
            lines.append(
                f"RTS/{leg}: the drill axes make {need_lo:.1f}-{need_hi:.1f} deg with +{leg}_m but the spherical leg reaches "
                f"{abs(a - b):.1f}-{a + b:.1f} deg (|alpha_{leg} - beta_{leg}| to alpha_{leg} + beta_{leg}); {fix}"
            )
    return lines


def summary(
    results: TaskResults, n_points: int, moving_mass_kg: float | None = None, regions: tuple[str, ...] = ()
) -> dict[str, Any]:
    """The summary of the JSON output: eta_G (None when not every point is reachable), w_G, dexterity,
    failures, the smallest clearances, the largest tip errors, torque and deflection, and the largest
    holding torque of model §18.2 with the design's moving mass (None where not computed); ``regions``: the
    envelope's region names (model §19.5), for the part of the envelope its smallest clearance binds at."""
    r = results
    pts = r.points
    eta_G = float(r.eta_G)
    return {
        "n_points": n_points,
        "w_G": bool(r.w_G),
        "reachable_fraction": float(r.reachable_fraction),
        "eta_G": _num(eta_G),
        "dexterity_pct": {
            "min": float(r.dexterity_min),
            "mean": float(r.dexterity_mean),
            "max": float(r.dexterity_max),
        },
        "inverted_eta_G_pct": _num(100.0 / eta_G) if math.isfinite(eta_G) else None,
        "failures": failure_counts(pts),
        "clearance_min_mm": _num(r.clearance_min),
        "clearance_min_part": _name_at(pts, pts.clearance_mm, pts.clearance_part, PART_NAMES),  # the closest part
        "self_clearance_min_mm": _num(r.self_clearance_min),
        # model §19.5: with an envelope (else None); the body part and the envelope's region where it binds
        "envelope_clearance_min_mm": _num(r.envelope_clearance_min),
        "envelope_clearance_min_part": _name_at(pts, pts.envelope_clearance_mm, pts.envelope_part, PART_NAMES),
        "envelope_clearance_min_region": _name_at(pts, pts.envelope_clearance_mm, pts.envelope_region, regions)
        if regions
        else None,
        "tip_error_max_mm": _num(r.tip_error_max),
        "lateral_error_max_mm": _num(r.lateral_error_max),
        "axial_error_max_mm": _num(r.axial_error_max),
        "axis_error_max_deg": _num(r.axis_error_max),
        "torque_max_Nm": _num(r.torque_max),
        # the actuator that needs the largest torque over the reachable points (model §15.3)
        "torque_max_actuator": _name_at(pts, -pts.torque_Nm, pts.torque_actuator, ACTUATOR_NAMES),
        "deflection_max_mm": _num(r.deflection_max),
        # model §18: with Outputs.holding_torque (else None)
        "holding_torque_max_Nm": _num(r.holding_torque_max),
        "holding_torque_max_actuator": _name_at(
            pts, -pts.holding_torque_Nm, pts.holding_torque_actuator, ACTUATOR_NAMES
        ),
        "moving_mass_kg": None if moving_mass_kg is None else _num(moving_mass_kg),
    }


def point_rows(pts: PointResults, task: Task, regions: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    """One JSON object per task point (values that do not exist are None); ``regions``: the envelope's region names."""
    psi, theta = task.psi_theta
    rho, delta, sigma = (np.rad2deg(a) for a in (pts.rho, pts.delta, pts.sigma))
    points = []
    for i in range(len(task)):
        points.append(
            {
                "trajectory": task.ids[int(task.trajectory[i])],
                "k": int(task.k[i]),
                "x": float(task.E[i, 0]),
                "y": float(task.E[i, 1]),
                "z": float(task.E[i, 2]),
                "psi_deg": float(np.rad2deg(psi[i])),
                "theta_deg": float(np.rad2deg(theta[i])),
                "reachable": bool(pts.reachable[i]),
                "failure": None if pts.failure[i] == 0 else FAILURES[int(pts.failure[i]) - 1],
                "rho_deg": [_num(v) for v in rho[i]],
                "delta_deg": [_num(v) for v in delta[i]],
                "sigma_deg": [_num(v) for v in sigma[i]],
                "kappa": {name: _num(pts.kappa[i, j]) for j, name in enumerate(JACOBIAN_NAMES)},
                "eta_L": _num(pts.eta_L[i]),
                "dexterity_pct": float(pts.dexterity_pct[i]),
                "clearance_mm": _num(pts.clearance_mm[i]),
                "clearance_part": PART_NAMES[int(pts.clearance_part[i])] if pts.clearance_part[i] >= 0 else None,
                "self_clearance_mm": _num(pts.self_clearance_mm[i]),
                "envelope_clearance_mm": _num(pts.envelope_clearance_mm[i]),
                "envelope_part": PART_NAMES[int(pts.envelope_part[i])] if pts.envelope_part[i] >= 0 else None,
                "envelope_region": regions[int(pts.envelope_region[i])]
                if pts.envelope_region[i] >= 0 and regions
                else None,
                **{name: _num(getattr(pts, name)[i]) for name in MAXIMUM_FIELDS},
                "torque_actuator": ACTUATOR_NAMES[int(pts.torque_actuator[i])] if pts.torque_actuator[i] >= 0 else None,
                "holding_torque_actuator": ACTUATOR_NAMES[int(pts.holding_torque_actuator[i])]
                if pts.holding_torque_actuator[i] >= 0
                else None,
            }
        )
    return points


def _name_at(pts: PointResults, values: np.ndarray, index: np.ndarray, names: tuple[str, ...]) -> str | None:
    """``names[index]`` at the reachable point of smallest ``values`` (None when no value exists)."""
    v = np.where(pts.reachable & np.isfinite(values), values, np.inf)
    if not np.isfinite(v).any():
        return None
    return names[int(index[int(np.argmin(v))])]


def _min_or_none(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.min()) if len(finite) else None


def _num(value: float) -> float | None:
    """A float for JSON, or None where it does not exist (NaN) or is infinite."""
    v = float(value)
    return v if math.isfinite(v) else None
