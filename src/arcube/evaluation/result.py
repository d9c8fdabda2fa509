"""One design evaluated on a set of trajectories: :class:`Evaluation`, what a person reads.

:func:`evaluate_design` samples the trajectories, runs one batch evaluation and wraps the arrays
in :class:`Evaluation`, which gives the per-trajectory table, the failure counts and their
diagnosis, the JSON object of ``arcube evaluate --json``, a pandas DataFrame and the HTML report.
:func:`arcube.evaluate` (the public API) loads files and validates flags before calling it.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arcube.model import frames
from arcube.model.body import PART_NAMES
from arcube.model.design import Design, unpack
from arcube.evaluation.engine import evaluate_task, resolve
from arcube.errors import InputError
from arcube.evaluation.reference import FAILURES, Options, PointResults, TaskResults
from arcube.evaluation.indices import JACOBIAN_NAMES
from arcube.evaluation.performance import ACTUATOR_NAMES, PERFORMANCE_FIELDS
from arcube.model.mechanism import format_mode, parse_mode
from arcube.evaluation.task import Task, build_task
from arcube.io import TrajectorySet, load_trajectories, select

if TYPE_CHECKING:
    from arcube.evaluation.anatomy import Anatomy


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


@dataclass(frozen=True)
class Evaluation:
    """A design evaluated on a task, with everything the text table and the JSON need."""

    design: Design
    mode: str
    options: Options
    trajectories: TrajectorySet
    task: Task
    results: TaskResults
    engine: str
    anatomy: Anatomy | None = None

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
                    clearance_min_mm=_min_or_none(pts.clearance_mm[sel][reach]),
                )
            )
        return rows

    def failure_counts(self) -> dict[str, int]:
        """How many points fail for each reason."""
        codes = Counter(int(c) for c in self.results.points.failure if c)
        return {FAILURES[c - 1]: n for c, n in sorted(codes.items())}

    def diagnosis(self) -> list[str]:
        """Where a stage cannot serve the task: what the task needs against what each leg offers.

        In mechanism coordinates at the centre C = E + L e (MODEL.md 13; R_w shifted by m when the
        design is not rotated): TLS leg u reaches u in [-f_u - r - p_u, -f_u - r + p_u] (MODEL.md 3.2);
        RTS leg u reaches angle(e, +u) in [|alpha_u - beta_u|, alpha_u + beta_u] (MODEL.md 5.2).
        """
        d = self.design
        g = unpack(d.to_vector())
        C_m, e_m = frames.to_mechanism(g, self.task.E, self.task.e)
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
                fix = "no placement m can fix this" if not rotated else "only another mounting rotation or wider links can fix this"
                lines.append(
                    f"RTS/{leg}: the drill axes make {need_lo:.1f}-{need_hi:.1f} deg with +{leg}_m but the spherical leg reaches "
                    f"{abs(a - b):.1f}-{a + b:.1f} deg (|alpha_{leg} - beta_{leg}| to alpha_{leg} + beta_{leg}); {fix}"
                )
        return lines

    @property
    def points(self) -> PointResults:
        """Per-point arrays ``(P,)`` (reachable, failure, kappa ``(P, 7)``, eta_L, dexterity_pct, rho, delta, sigma)."""
        return self.results.points

    @property
    def summary(self) -> dict[str, Any]:
        """The summary of the JSON output: eta_G (None when not every point is reachable), w_G, dexterity, failures."""
        return self.summary_json()

    def to_dataframe(self) -> Any:
        """One row per task point (the fields of :meth:`to_json` ``points``, lists spread into columns); needs pandas."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Evaluation.to_dataframe needs pandas: pip install pandas") from None
        rows = []
        for point in self.to_json()["points"]:
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

    def write_report(self, path: str | os.PathLike[str]) -> Path:
        """Write the self-contained HTML report (plots, 3D mechanism) and its PNGs; returns the path.

        Raises :class:`InputError` if the path does not end in .html/.htm (the PNGs are named from its stem).
        """
        from arcube.report.html import write_evaluation_report

        out = Path(path)
        if out.suffix.lower() not in (".html", ".htm"):
            raise InputError(f"--report {out}: the report file must end in .html")
        return write_evaluation_report(self, out)

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
            "clearance_min_mm": _num(r.clearance_min),
            "clearance_min_part": self._closest_part(),
            "self_clearance_min_mm": _num(r.self_clearance_min),
            "tip_error_max_mm": _num(r.tip_error_max),
            "lateral_error_max_mm": _num(r.lateral_error_max),
            "axial_error_max_mm": _num(r.axial_error_max),
            "axis_error_max_deg": _num(r.axis_error_max),
            "torque_max_Nm": _num(r.torque_max),
            "torque_max_actuator": self._torque_actuator(),
            "deflection_max_mm": _num(r.deflection_max),
        }

    def _torque_actuator(self) -> str | None:
        """The actuator that needs the largest torque over the reachable points (MODEL.md 15.3)."""
        pts = self.results.points
        return self._name_at(-pts.torque_Nm, pts.torque_actuator, ACTUATOR_NAMES)

    def _name_at(self, values: np.ndarray, index: np.ndarray, names: tuple[str, ...]) -> str | None:
        """``names[index]`` at the reachable point of smallest ``values`` (None when no value exists)."""
        v = np.where(self.results.points.reachable & np.isfinite(values), values, np.inf)
        if not np.isfinite(v).any():
            return None
        return names[int(index[int(np.argmin(v))])]

    def _closest_part(self) -> str | None:
        """The part attaining the smallest clearance over the reachable points, None without anatomy."""
        pts = self.results.points
        return self._name_at(pts.clearance_mm, pts.clearance_part, PART_NAMES)

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
                    "clearance_mm": _num(pts.clearance_mm[i]),
                    "clearance_part": PART_NAMES[int(pts.clearance_part[i])] if pts.clearance_part[i] >= 0 else None,
                    "self_clearance_mm": _num(pts.self_clearance_mm[i]),
                    **{name: _num(getattr(pts, name)[i]) for name in PERFORMANCE_FIELDS},
                    "torque_actuator": ACTUATOR_NAMES[int(pts.torque_actuator[i])] if pts.torque_actuator[i] >= 0 else None,
                }
            )
        return {
            "design": self.design.to_dict(),
            "mode": self.mode,
            "engine": self.engine,
            "guards": self.options.model_dump(),
            "anatomy": None if self.anatomy is None else self.anatomy.source,
            "points": points,
            "summary": self.summary_json(),
            "trajectories": [vars(row) for row in self.per_trajectory()],
        }


def _min_or_none(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.min()) if len(finite) else None


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


def evaluate_design(
    design: Design, ts: TrajectorySet, points: int, signs: np.ndarray, options: Options, engine: str = "numpy",
    anatomy: Anatomy | None = None,
) -> Evaluation:
    """Sample ``ts`` at ``points`` per trajectory and evaluate ``design`` in one batch call."""
    task = build_task(ts.entry, ts.target, points, ids=ts.ids)
    distance = None if anatomy is None else anatomy.distance
    results = evaluate_task(design.to_vector(), task.E, task.e, signs, options, engine=engine, want_points=True, anatomy=distance)
    return Evaluation(
        design=design, mode=format_mode(signs), options=options, trajectories=ts, task=task, results=results, engine=engine,
        anatomy=anatomy,
    )  # fmt: skip
