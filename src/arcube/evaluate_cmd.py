"""``arcube evaluate``: one design on a set of trajectories, as data for the table and the JSON.

:func:`run_evaluation` validates the user's inputs (raising :class:`InputError` with one line),
runs one batch evaluation and wraps the arrays in :class:`EvaluationReport`.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.design import Design
from arcube.engine import evaluate_task, resolve
from arcube.errors import InputError
from arcube.evaluation import FAILURES, GUARDED_OPTIONS, Options, TaskResults
from arcube.indices import JACOBIAN_NAMES
from arcube.mechanism import format_mode, parse_mode
from arcube.task import Task, build_task
from arcube.trajectories import TrajectorySet, load_trajectories, select


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


@dataclass(frozen=True)
class EvaluationReport:
    """A design evaluated on a task, with everything the text table and the JSON need."""

    design: Design
    mode: str
    options: Options
    trajectories: TrajectorySet
    task: Task
    results: TaskResults
    engine: str

    def per_trajectory(self) -> list[TrajectorySummary]:
        """Summaries per trajectory, in file order."""
        pts = self.results.points
        rows = []
        for t, tid in enumerate(self.task.ids):
            sel = self.task.trajectory == t
            reach = pts.reachable[sel]
            dex = pts.dexterity_pct[sel]
            limiting = None
            if reach.any():
                worst = np.argmax(pts.kappa[sel][reach], axis=-1)
                limiting = JACOBIAN_NAMES[Counter(worst.tolist()).most_common(1)[0][0]]
            first = None
            if not reach.all():
                i = int(np.argmin(reach))
                first = f"{FAILURES[int(pts.failure[sel][i]) - 1]} at k={int(self.task.k[sel][i])}"
            rows.append(
                TrajectorySummary(
                    id=tid,
                    level=self.trajectories.levels[t],
                    side=self.trajectories.sides[t],
                    reachable_fraction=float(reach.mean()),
                    dexterity_min=float(dex.min()),
                    dexterity_mean=float(dex.mean()),
                    dexterity_max=float(dex.max()),
                    limiting_jacobian=limiting,
                    first_failure=first,
                )
            )
        return rows

    def failure_counts(self) -> dict[str, int]:
        """How many points fail for each reason."""
        codes = Counter(int(c) for c in self.results.points.failure if c)
        return {FAILURES[c - 1]: n for c, n in sorted(codes.items())}

    def diagnosis(self) -> list[str]:
        """Where a stage cannot serve the task: what the task needs against what each leg offers.

        TLS leg u reaches u in [m_u - f_u - r - p_u, m_u - f_u - r + p_u] (R_w, MODEL.md 3.2);
        RTS leg u reaches angle(e, +u) in [|alpha_u - beta_u|, alpha_u + beta_u] (MODEL.md 5.2).
        """
        d = self.design
        lines = []
        for i, leg in enumerate("xyz"):
            centre = d[f"m_{leg}"] - d[f"f_{leg}"] - d["r"]
            lo, hi = centre - d[f"p_{leg}"], centre + d[f"p_{leg}"]
            need_lo, need_hi = float(self.task.E[:, i].min()), float(self.task.E[:, i].max())
            if need_lo < lo or need_hi > hi:
                lines.append(
                    f"TLS/{leg}: the task spans {leg} = [{need_lo:.1f}, {need_hi:.1f}] mm but the crank reaches "
                    f"[{lo:.1f}, {hi:.1f}] mm (m_{leg} - f_{leg} - r +- p_{leg}); move m_{leg} by about {(need_lo + need_hi) / 2 - centre:+.1f} mm"
                )
        angles = np.degrees(np.arccos(np.clip(self.task.e[:, :2], -1.0, 1.0)))
        for i, leg in enumerate("xy"):
            a, b = d[f"alpha_{leg}"], d[f"beta_{leg}"]
            need_lo, need_hi = float(angles[:, i].min()), float(angles[:, i].max())
            if need_lo < abs(a - b) or need_hi > a + b:
                lines.append(
                    f"RTS/{leg}: the drill axes make {need_lo:.1f}-{need_hi:.1f} deg with +{leg} but the spherical leg reaches "
                    f"{abs(a - b):.1f}-{a + b:.1f} deg (|alpha_{leg} - beta_{leg}| to alpha_{leg} + beta_{leg}); no placement m can fix this"
                )
        return lines

    def summary_json(self) -> dict[str, Any]:
        r = self.results
        eta_G = float(r.eta_G)
        return {
            "n_points": len(self.task),
            "w_G": bool(r.w_G),
            "reachable_fraction": float(r.reachable_fraction),
            "eta_G": _num(eta_G),
            "dexterity_pct": {"min": float(r.dexterity_min), "mean": float(r.dexterity_mean), "max": float(r.dexterity_max)},
            "inverted_eta_G_pct": _num(100.0 / eta_G) if math.isfinite(eta_G) else None,
            "failures": self.failure_counts(),
        }

    def to_json(self) -> dict[str, Any]:
        """The JSON object of the issue's contract (values that do not exist are null)."""
        pts = self.results.points
        psi, theta = self.task.psi_theta
        rho, delta, sigma = (np.rad2deg(a) for a in (pts.rho, pts.delta, pts.sigma))
        points = []
        for i in range(len(self.task)):
            points.append(
                {
                    "trajectory": self.task.ids[int(self.task.trajectory[i])],
                    "k": int(self.task.k[i]),
                    "x": float(self.task.E[i, 0]),
                    "y": float(self.task.E[i, 1]),
                    "z": float(self.task.E[i, 2]),
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
                }
            )
        return {
            "design": self.design.to_dict(),
            "mode": self.mode,
            "engine": self.engine,
            "guards": self.options.model_dump(),
            "points": points,
            "summary": self.summary_json(),
            "trajectories": [vars(row) for row in self.per_trajectory()],
        }


def _num(value: float) -> float | None:
    """A float for JSON, or None where it does not exist (NaN) or is infinite."""
    v = float(value)
    return v if math.isfinite(v) else None


def parse_mode_option(text: str) -> np.ndarray:
    """``--mode`` value -> signs, with the CLI's error type."""
    try:
        return parse_mode(text)
    except ValueError as exc:
        raise InputError(f"--mode: {exc}") from None


def load_trajectory_set(
    trajectories: str, points: int, side: str | None = None, levels: str | None = None,
    ids: str | None = None, transform: Path | None = None,
) -> TrajectorySet:  # fmt: skip
    """Read and subset trajectories, checking ``points`` first (raises InputError)."""
    if points < 2:
        raise InputError(f"--points must be at least 2 (both ends of a trajectory), got {points}")
    return select(load_trajectories(trajectories, transform=transform), side=side, levels=levels, ids=ids)


def load_task(
    trajectories: str, points: int, side: str | None = None, levels: str | None = None,
    ids: str | None = None, transform: Path | None = None,
) -> tuple[TrajectorySet, Task]:  # fmt: skip
    """Read, subset and sample trajectories into a task (raises InputError)."""
    ts = load_trajectory_set(trajectories, points, side, levels, ids, transform)
    return ts, build_task(ts.entry, ts.target, points, ids=ts.ids)


def run_evaluation(
    design: str, trajectories: str, points: int = 30, mode: str = "+,+,+,+", guards: bool = False,
    side: str | None = None, levels: str | None = None, ids: str | None = None,
    transform: Path | None = None, engine: str = "auto",
) -> EvaluationReport:  # fmt: skip
    """Load everything, evaluate in one batch call, return the report."""
    signs = parse_mode_option(mode)
    try:
        engine_name = resolve(engine)
    except ValueError as exc:
        raise InputError(f"--engine: {exc}") from None
    d = Design.load(design)
    ts = load_trajectory_set(trajectories, points, side, levels, ids, transform)
    return evaluate_design(d, ts, points, signs, GUARDED_OPTIONS if guards else Options(), engine_name)


def evaluate_design(
    design: Design, ts: TrajectorySet, points: int, signs: np.ndarray, options: Options, engine: str = "numpy"
) -> EvaluationReport:
    """Sample ``ts`` at ``points`` per trajectory and evaluate ``design`` in one batch call."""
    task = build_task(ts.entry, ts.target, points, ids=ts.ids)
    results = evaluate_task(design.to_vector(), task.E, task.e, signs, options, engine=engine, want_points=True)
    return EvaluationReport(
        design=design, mode=format_mode(signs), options=options, trajectories=ts, task=task, results=results, engine=engine
    )
