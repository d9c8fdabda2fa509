"""The accuracy budget of one design on a plan's points (model §20): :func:`budget` -> :class:`ToleranceResult`.

The first order (20.3) runs in the compiled kernel (``engine="numba"``, default) or the NumPy
reference (``"numpy"``); the Monte Carlo (20.4) runs the exact closed-form FK batched over
robots x points. Points the nominal design does not reach (in its working mode) get NaN and take no
part in the summaries.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.first_order import FirstOrder, first_order
from arcube.accuracy.monte_carlo import PERCENTILES, monte_carlo, percentiles
from arcube.accuracy.settings import MAX_ROBOT_POINTS, ToleranceSettings
from arcube.accuracy.sources import SOURCE_NAMES, UNITS, sigmas
from arcube.errors import InputError
from arcube.model.design import Design
from arcube.model.mechanism import DEFAULT_MODE, format_mode, inverse_kinematics, parse_mode
from arcube.io.json_values import finite
from arcube.summary import Summary


class ToleranceSummary(Summary):
    """The summary of an accuracy budget (``ToleranceResult.summary``, ``tolerance.json``'s ``summary``): the first
    four the largest over the plan's reachable points (model §20.3), the last two over the built robots (20.4)."""

    lateral_error_wc_mm: float
    """First-order worst case of the drill tip's error across the axis, mm."""
    axis_error_wc_deg: float
    """First-order worst case of the drill axis' angle error, deg."""
    axial_error_wc_mm: float
    """First-order worst case of the error along the axis, mm."""
    lateral_error_rms_mm: float
    """First-order RMS of the lateral error (independent sources), mm."""
    lateral_error_p95_mm: float
    """95th percentile over the Monte Carlo robots of each robot's largest lateral error, mm."""
    axis_error_p95_deg: float
    """95th percentile over the robots of each robot's largest axis error, deg."""


SUMMARY_KEYS: tuple[str, ...] = ToleranceSummary.fields()
"""The summaries of ``tolerance.json`` (the first four: the maximum over the plan's points)."""
POINT_COLUMNS: tuple[str, ...] = (
    "trajectory",
    "point",
    "lateral_error_wc_mm",
    "axis_error_wc_deg",
    "axial_error_wc_mm",
    "lateral_error_rms_mm",
    "lateral_error_p50_mm",
    "lateral_error_p95_mm",
    "lateral_error_p99_mm",
    "lateral_error_max_mm",
)
"""The columns of ``tolerance_points.csv``."""


@dataclass(frozen=True)
class ToleranceResult:
    """The budget of one design on P plan points with n error sources (:data:`SOURCE_NAMES`) and N robots.

    Per-point arrays are NaN where the nominal design does not reach the point; Monte Carlo errors are
    +inf where a robot's FK does not assemble (it cannot drill there).
    """

    settings: ToleranceSettings
    design: NDArray[np.float64]  # (27,) mm, deg
    mode: NDArray[np.float64]  # (4,) working mode
    tolerances: NDArray[np.float64]  # (n,) T of each source, mm or deg (UNITS)
    trajectory: tuple[str, ...]  # (P,) id of each point's trajectory
    point: NDArray[np.intp]  # (P,) index of each point along its trajectory
    first: FirstOrder  # per point (P,): worst cases, RMS, shares (P, n), G_E and G_e (P, 3, n)
    lateral_mm: NDArray[np.float64]  # (P, 4) Monte Carlo p50, p95, p99, max over robots
    axial_mm: NDArray[np.float64]  # (P, 4)
    axis_deg: NDArray[np.float64]  # (P, 4)
    robot_lateral_max_mm: NDArray[np.float64]  # (N,) each robot's largest lateral error over the reached points
    robot_axial_max_mm: NDArray[np.float64]  # (N,)
    robot_axis_max_deg: NDArray[np.float64]  # (N,)
    unassembled: int  # robots x points where the built robot's FK does not assemble
    engine: str  # "numba" or "numpy" (the first order)

    @property
    def sources(self) -> tuple[str, ...]:
        return SOURCE_NAMES

    @property
    def units(self) -> tuple[str, ...]:
        return UNITS

    @property
    def reachable(self) -> NDArray[np.bool_]:
        """``(P,)`` the nominal design reaches the point (the budget exists there)."""
        return self.first.valid

    @property
    def share(self) -> NDArray[np.float64]:
        """``(n,)`` each source's share of the lateral variance, averaged over the reached points (sums to 1)."""
        return np.mean(self.first.share[self.reachable], axis=0)

    def ranked_sources(self) -> list[tuple[str, float, str, float]]:
        """(source, tolerance, unit, share) by decreasing share (ties in source order)."""
        order = np.argsort(-self.share, kind="stable")
        return [(SOURCE_NAMES[i], float(self.tolerances[i]), UNITS[i], float(self.share[i])) for i in order]

    @property
    def summary(self) -> ToleranceSummary:
        """The summaries of model §20.3-20.4 (:data:`SUMMARY_KEYS`)."""
        r = self.reachable
        f = self.first
        return ToleranceSummary(
            lateral_error_wc_mm=float(np.max(f.lateral_wc_mm[r])),
            axis_error_wc_deg=float(np.max(f.axis_wc_deg[r])),
            axial_error_wc_mm=float(np.max(f.axial_wc_mm[r])),
            lateral_error_rms_mm=float(np.max(f.lateral_rms_mm[r])),
            lateral_error_p95_mm=float(percentiles(self.robot_lateral_max_mm, [95.0])[0]),
            axis_error_p95_deg=float(percentiles(self.robot_axis_max_deg, [95.0])[0]),
        )

    def monte_carlo_summary(self) -> dict[str, Any]:
        """Percentiles over robots of each robot's largest error over the plan (lateral, axial, axis)."""
        out: dict[str, Any] = {"robots": int(self.robot_lateral_max_mm.shape[0]), "unassembled": self.unassembled}
        for name, a, unit in (
            ("lateral", self.robot_lateral_max_mm, "mm"),
            ("axial", self.robot_axial_max_mm, "mm"),
            ("axis", self.robot_axis_max_deg, "deg"),
        ):
            values = percentiles(a, PERCENTILES)
            out.update({f"{name}_error_p{q:g}_{unit}": float(v) for q, v in zip(PERCENTILES, values)})
            out[f"{name}_error_max_{unit}"] = float(np.max(a))
        return out

    def point_rows(self) -> list[dict[str, Any]]:
        """One row per plan point, in plan order, keyed by :data:`POINT_COLUMNS`."""
        f = self.first
        rows = []
        for k in range(len(self.trajectory)):
            values = (f.lateral_wc_mm[k], f.axis_wc_deg[k], f.axial_wc_mm[k], f.lateral_rms_mm[k], *self.lateral_mm[k])
            rows.append(
                {
                    "trajectory": self.trajectory[k],
                    "point": int(self.point[k]),
                    **{c: float(v) for c, v in zip(POINT_COLUMNS[2:], values)},
                }
            )
        return rows

    def to_json(self) -> dict[str, Any]:
        """The object of ``tolerance.json`` (non-finite numbers as null)."""
        data = {
            "settings": self.settings.model_dump(),
            "design": Design.from_vector(self.design).to_dict(),
            "mode": format_mode(self.mode),
            "points": len(self.trajectory),
            "reachable_points": int(np.sum(self.reachable)),
            "summary": self.summary,
            "monte_carlo": self.monte_carlo_summary(),
            "engine": self.engine,
            "sources": [{"source": s, "tolerance": t, "unit": u, "share": v} for s, t, u, v in self.ranked_sources()],
        }
        return finite(data)


def _array(value: ArrayLike, name: str, shape: tuple[int, ...]) -> NDArray[np.float64]:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError.of(name, "must be an array of numbers") from None
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise InputError.of(name, f"must be finite numbers of shape {shape}, got shape {a.shape}")
    return a


def budget(
    design: Any,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike | str = DEFAULT_MODE,
    settings: ToleranceSettings | None = None,
    trajectory_ids: Any = None,
    point_index: ArrayLike | None = None,
    engine: str = "numba",
) -> ToleranceResult:
    """The accuracy budget (model §20) of ``design`` at the plan points (E, e).

    Args:
        design: a :class:`~arcube.model.design.Design`, a design JSON path or preset, or 27 (23) numbers (mm, deg).
        E, e: drill tips ``(P, 3)`` (mm) and drill axes ``(P, 3)`` (normalized here) in the patient frame,
            e.g. :func:`arcube.evaluation.task.build_task`'s ``E`` and ``e``.
        mode: the design's working mode, ``(4,)`` signs or text such as ``"+,+,+,-"``.
        settings: tolerances and Monte Carlo (:class:`ToleranceSettings`; default class m).
        trajectory_ids: ``(P,)`` the id of each point's trajectory (default: all "1").
        point_index: ``(P,)`` each point's index along its trajectory (default 0..P-1).
        engine: ``"numba"`` (compiled first order) or ``"numpy"`` (the reference).

    Raises:
        InputError: a bad argument (named), too many robots x points, or a design that reaches none of the points.
    """
    settings = ToleranceSettings() if settings is None else settings
    x = Design.coerce(design).to_vector()
    E_a = np.asarray(E, dtype=float)
    P = E_a.shape[0] if E_a.ndim == 2 else 0
    if P == 0:
        raise InputError.of("E", f"must hold at least one point, shape (P, 3), got shape {E_a.shape}")
    E_a = _array(E_a, "E", (P, 3))
    e_a = _array(e, "e", (P, 3))
    norm = np.linalg.norm(e_a, axis=-1, keepdims=True)
    if np.any(norm == 0.0):
        raise InputError.of("e", "holds a zero vector (a drill axis needs a direction)")
    e_a = e_a / norm
    try:
        signs = parse_mode(mode) if isinstance(mode, str) else _array(mode, "mode", (4,))
    except ValueError as exc:
        raise InputError.of("mode", str(exc)) from None
    if not np.all(np.abs(signs) == 1.0):
        raise InputError.of("mode", f"must be four signs +1/-1, got {signs.tolist()}")
    ids = ("1",) * P if trajectory_ids is None else tuple(str(t) for t in trajectory_ids)
    k = np.arange(P) if point_index is None else np.asarray(point_index, dtype=np.intp)
    if len(ids) != P or k.shape != (P,):
        raise InputError.of("trajectory_ids", f"and point_index must have one entry per point ({P})")
    if engine not in ("numba", "numpy"):
        raise InputError.of("engine", f"must be numba or numpy, got {engine!r}")
    if settings.samples * P > MAX_ROBOT_POINTS:
        raise InputError.of(
            "ToleranceSettings.samples",
            f"x plan points must be <= {MAX_ROBOT_POINTS:,} (memory), got {settings.samples} x {P}",
        )

    T = settings.tolerances(x)
    sig = sigmas(T, settings.distribution)
    if engine == "numba":
        from arcube.accuracy._kernel import first_order_numba

        fo = first_order_numba(x, E_a, e_a, signs, T, sig)
    else:
        fo = first_order(x, E_a, e_a, signs, T, sig)
    reach = np.asarray(fo.valid)
    if not reach.any():
        raise InputError.of(
            "design", f"reaches none of the {P} plan points in working mode {format_mode(signs)}: no accuracy budget"
        )

    sol = inverse_kinematics(x, E_a[reach], e_a[reach], signs)
    q_cmd = np.concatenate([sol.rho, sol.delta], axis=-1)
    errors, _ = monte_carlo(
        x, E_a[reach], e_a[reach], q_cmd, sol.assembly, T, settings.samples, settings.distribution, settings.seed
    )

    def per_point(a: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.full((P, 4), np.nan)
        out[reach, :3] = percentiles(a, PERCENTILES, axis=0).T
        out[reach, 3] = np.max(a, axis=0)
        return out

    return ToleranceResult(
        settings=settings,
        design=x,
        mode=signs,
        tolerances=T,
        trajectory=ids,
        point=k,
        first=fo,
        lateral_mm=per_point(errors.lateral_mm),
        axial_mm=per_point(errors.axial_mm),
        axis_deg=per_point(errors.axis_deg),
        robot_lateral_max_mm=np.max(errors.lateral_mm, axis=1),
        robot_axial_max_mm=np.max(errors.axial_mm, axis=1),
        robot_axis_max_deg=np.max(errors.axis_deg, axis=1),
        unassembled=int(np.sum(np.isinf(errors.lateral_mm))),
        engine=engine,
    )
