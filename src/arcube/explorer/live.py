"""The explorer's model: one design on a plan, re-evaluated by the compiled kernel at every change.

:class:`LiveModel` holds what the sliders set (the 27 parameters, the working mode, the body radii,
the guards) and what they do not (the plan, its approach lines, the anatomy, the requirements).
:meth:`LiveModel.evaluate` runs the kernel (:func:`arcube.evaluation.engine.evaluate_task`) on the
whole plan twice, as ``arcube design`` judges a design (:func:`arcube.design_job.requirements.assess`
with the NumPy reference): on the drill points (entry -> target) and on the approach lines (standoff
-> entry, model §17.1). It returns :class:`Figures`: the headline figures of the plan, the
requirement rows with pass/fail against the limits of :func:`~arcube.design_job.requirements.requirements_from`,
and per-point arrays along the *lines*: for each trajectory its approach points, then its drill points.
:meth:`LiveModel.view` is the scene at one point of the lines (:mod:`arcube.explorer.scene`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.performance import ACTUATOR_NAMES
from arcube.evaluation.reference import FAILURES, TaskResults
from arcube.evaluation.standoff import DEFAULT_STANDOFF_MM, approach_lines
from arcube.evaluation.task import build_task
from arcube.explorer import scene
from arcube.io.trajectories import TrajectorySet
from arcube.model.body import PART_NAMES, BodyRadii
from arcube.model.design import PARAM_NAMES, Design
from arcube.model.mechanism import format_mode
from arcube.design_job.requirements import (
    REQUIREMENTS,
    Requirement,
    design_options,
    requirement_figure,
    requirements_from,
)
from arcube.options import GUARDED_OPTIONS, Options

__all__ = ["Figures", "LiveModel", "View"]


@contextmanager
def _one_thread() -> Iterator[None]:
    """The compiled kernel on one thread (numba's setting is per calling thread): one design on a few
    hundred points is fastest serial, and the live loop must not compete with itself for the cores."""
    try:
        import numba
    except ImportError:
        yield
        return
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _min_at(values: NDArray[np.float64]) -> tuple[float, int]:
    """(smallest finite value, its index); (NaN, -1) when none is finite."""
    ok = np.isfinite(values)
    if not ok.any():
        return math.nan, -1
    i = int(np.argmin(np.where(ok, values, np.inf)))
    return float(values[i]), i


def _max_at(values: NDArray[np.float64]) -> tuple[float, int]:
    v, i = _min_at(-values)
    return -v, i


@dataclass(frozen=True)
class Figures:
    """What the kernel says of the current design (see the module docstring)."""

    summary: dict[str, Any]
    """Over the plan's drill points: n_points, reachable, reach_pct, eta_G (inf unless every point is
    reachable), clearance_min_mm and _part, self_clearance_min_mm, lateral_error_max_mm,
    axis_error_max_deg, torque_max_Nm and _actuator, failures {reason: count}."""
    requirements: list[dict[str, Any]]
    """One row per requirement (reach first): requirement, kind, limit, unit, value, part, passed
    (None when it cannot be judged, e.g. a clearance without anatomy)."""
    points: dict[str, NDArray[np.float64]]
    """Along the lines: dexterity_pct, clearance_mm, self_clearance_mm, reachable (0/1)."""
    drill: TaskResults
    approach: TaskResults
    seconds: float
    """Wall time of the two kernel calls."""

    @property
    def passed(self) -> bool:
        """Every requirement that can be judged passes."""
        return all(r["passed"] is not False for r in self.requirements)


@dataclass(frozen=True)
class View:
    """The scene at one point of the lines."""

    index: int
    label: str
    E: NDArray[np.float64]
    e: NDArray[np.float64]
    mp: Any
    solids: scene.Solids
    part_class: NDArray[np.intp]
    part_rgb: NDArray[np.uint8]
    patient: scene.Closest
    self_: scene.Closest


@dataclass
class LiveModel:
    """A design on a plan, with the settings the explorer's controls change."""

    design: Design
    plan: TrajectorySet
    anatomy: Any = None
    mode: NDArray[np.float64] = field(default_factory=lambda: np.ones(4))
    points: int = 30
    radii: BodyRadii = BodyRadii()
    guarded: bool = True
    requirements: Sequence[Requirement] = field(default_factory=requirements_from)
    standoff_mm: float = DEFAULT_STANDOFF_MM
    engine: str = "auto"
    envelope: Any = None
    """The envelope of the whole patient and the table (model §19.5), placed on the whole plan, or None."""

    def __post_init__(self) -> None:
        self.x = self.design.to_vector().astype(float)
        plan, n = self.plan, self.points
        self.task = build_task(plan.entry, plan.target, n, ids=plan.ids)
        self.E_app, self.e_app = approach_lines(plan.entry, plan.target, self.anatomy, n, self.standoff_mm)
        T = len(plan.ids)
        # lines order: per trajectory, its approach points then its drill points
        traj = np.repeat(np.arange(T), 2 * n)
        k = np.tile(np.arange(2 * n), T)
        self.line_drill = k >= n
        self.line_source = traj * n + np.where(
            self.line_drill, k - n, k
        )  # index into the drill task or the approach lines
        self.line_traj, self.line_k = traj, np.where(self.line_drill, k - n, k)
        self.limits = {r.name: r.limit for r in self.requirements}
        self.distance = None if self.anatomy is None else self.anatomy.distance

    # ------------------------------------------------------------------ settings
    def set_param(self, name: str, value: float) -> None:
        """Change one of the 27 parameters (InputError naming it when it is not a finite number)."""
        if name not in PARAM_NAMES:
            raise InputError.of("param", f"{name!r}: unknown parameter (known: {', '.join(PARAM_NAMES)})")
        v = float(value)
        if not math.isfinite(v):
            raise InputError.of(name, f"must be a finite number, got {value!r}")
        self.x[PARAM_NAMES.index(name)] = v

    def current_design(self) -> Design:
        """The design the sliders show, with the loaded design's c_z (model §19.1) and the working mode shown."""
        return self.design.replace(**dict(zip(PARAM_NAMES, self.x.tolist(), strict=True))).with_extras(
            mode=format_mode(self.mode)
        )

    def load(self, design: Design) -> None:
        """Replace all 27 parameters and the design's c_z."""
        self.design = design
        self.x = design.to_vector().astype(float)

    def options(self) -> Options:
        """The kernel's options: with guards, those of ``arcube design`` (model §8.2 and the two
        clearance guards at the requirements' limits; no clearance guard without anatomy); the radii."""
        r = self.radii
        if self.guarded:
            base = design_options(self.requirements, GUARDED_OPTIONS)
            if self.anatomy is None:
                base = base.replace(clearance_mm=None)
            if self.envelope is None:
                base = base.replace(envelope_clearance_mm=None)
        else:
            base = Options()
        base = base.replace(
            link_radius=r.link, actuator_radius=r.actuator, motor_radius=r.motor, motor_length=r.motor_length
        )
        if (
            self.design.c_z is not None
        ):  # the z dyad closed with the design's own c_z, and a guard when guarded (model §19.2)
            base = base.replace(c_z=self.design.c_z, z_dyad=self.guarded)
        holding = any(q.name == "holding_torque" for q in self.requirements)  # model §18.2, as arcube design's
        return base.replace(
            outputs=base.outputs.replace(
                clearances=True, tip_metrics=True, clearance_min_exact=True, holding_torque=holding
            )
        )

    # ------------------------------------------------------------------ figures
    def evaluate(self) -> Figures:
        """The kernel on the whole plan: drill points and approach lines."""
        t0 = time.perf_counter()
        opts = self.options()
        with _one_thread():
            drill, app = (
                evaluate_task(
                    self.x,
                    E,
                    e,
                    self.mode,
                    opts,
                    engine=self.engine,
                    want_points=True,
                    anatomy=self.distance,
                    envelope=self.envelope,
                )
                for E, e in ((self.task.E, self.task.e), (self.E_app, self.e_app))
            )
        seconds = time.perf_counter() - t0
        p = drill.points
        clear, ci = _min_at(np.asarray(p.clearance_mm, float))
        torque, ti = _max_at(np.asarray(p.torque_Nm, float))
        failure = np.asarray(p.failure)
        reach = np.asarray(p.reachable, bool)
        summary = {
            "n_points": int(len(reach)),
            "reachable": int(reach.sum()),
            "reach_pct": 100.0 * float(drill.reachable_fraction),
            "eta_G": float(drill.eta_G),
            "clearance_min_mm": clear,
            "clearance_min_part": PART_NAMES[int(p.clearance_part[ci])]
            if ci >= 0 and p.clearance_part[ci] >= 0
            else "",
            "self_clearance_min_mm": _min_at(np.asarray(p.self_clearance_mm, float))[0],
            "lateral_error_max_mm": _max_at(np.asarray(p.lateral_error_mm, float))[0],
            "axis_error_max_deg": _max_at(np.asarray(p.axis_error_deg, float))[0],
            "torque_max_Nm": torque,
            "torque_max_actuator": ACTUATOR_NAMES[int(p.torque_actuator[ti])]
            if ti >= 0 and p.torque_actuator[ti] >= 0
            else "",
            "failures": {FAILURES[c - 1]: int(n) for c, n in zip(*np.unique(failure[failure > 0], return_counts=True))},
            "mode": format_mode(self.mode),
        }
        holding = getattr(drill, "holding_torque_max", None)  # model §18, when the kernel has it
        if holding is not None:
            summary["holding_torque_max_Nm"] = float(np.asarray(holding))
        return Figures(summary, self._requirement_rows(drill, app), self._line_arrays(drill, app), drill, app, seconds)

    def _requirement_rows(self, drill: TaskResults, app: TaskResults) -> list[dict[str, Any]]:
        """The rows of :func:`~arcube.design_job.requirements.assess` (reach and each requirement), from the kernel."""
        frac = min(float(drill.reachable_fraction), float(app.reachable_fraction))
        rows = [
            {
                "requirement": "reach",
                "kind": "min",
                "limit": 100.0,
                "unit": "%",
                "value": 100.0 * frac,
                "part": "",
                "passed": frac >= 1.0,
            }
        ]
        if self.design.c_z is not None and self.guarded:  # as arcube design's z_dyad row (model §19.2)
            code = FAILURES.index("guard/z_dyad") + 1
            bad = sum(int(np.sum(np.asarray(res.points.failure) == code)) for res in (drill, app))
            rows.append(
                {
                    "requirement": "z_dyad",
                    "kind": "max",
                    "limit": 0.0,
                    "unit": "failing points",
                    "value": float(bad),
                    "part": f"c_z {self.design.c_z:.1f} mm, d_z {self.x[PARAM_NAMES.index('d_z')]:.1f} mm",
                    "passed": bad == 0,
                }
            )
        for r in self.requirements:
            kind, unit, where = REQUIREMENTS[r.name]
            if where == "program":  # judged on the drilling program (arcube design, arcube program), not here
                continue
            segments = (drill,) if where == "drill" else (drill, app)
            best, part = math.nan, ""
            for res in segments:
                values, names = requirement_figure(
                    res.points, r.name, () if self.envelope is None else tuple(self.envelope.names)
                )
                v, i = _min_at(values) if kind == "min" else _max_at(values)
                if math.isfinite(v) and (not math.isfinite(best) or (v < best if kind == "min" else v > best)):
                    best, part = v, names(i)
            judged = math.isfinite(best) or not (
                (r.name == "clearance" and self.anatomy is None)
                or (r.name == "envelope_clearance" and self.envelope is None)
            )
            passed = (
                None
                if not judged
                else bool(math.isfinite(best) and (best >= r.limit if kind == "min" else best <= r.limit))
            )
            rows.append(
                {
                    "requirement": r.name,
                    "kind": kind,
                    "limit": r.limit,
                    "unit": unit,
                    "value": best,
                    "part": part,
                    "passed": passed,
                }
            )
        return rows

    def _line_arrays(self, drill: TaskResults, app: TaskResults) -> dict[str, NDArray[np.float64]]:
        out = {}
        for key in ("dexterity_pct", "clearance_mm", "self_clearance_mm", "reachable"):
            d = np.asarray(getattr(drill.points, key), float)
            a = np.asarray(getattr(app.points, key), float)
            out[key] = np.where(self.line_drill, d[self.line_source], a[self.line_source])
        return out

    # ------------------------------------------------------------------ scene
    def pose_at(self, index: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(E, e) of point ``index`` of the lines."""
        j = int(self.line_source[index])
        return (self.task.E[j], self.task.e[j]) if self.line_drill[index] else (self.E_app[j], self.e_app[j])

    def label(self, index: int) -> str:
        """``trajectory 3 (C5 R) · drill 12/29``."""
        t, k = int(self.line_traj[index]), int(self.line_k[index])
        seg = "drill" if self.line_drill[index] else "approach"
        return (
            f"trajectory {self.plan.ids[t]} ({self.plan.levels[t]} {self.plan.sides[t]}) · {seg} {k}/{self.points - 1}"
        )

    def view(self, index: int) -> View:
        """The body's solids, their colours and the closest pairs at point ``index`` of the lines."""
        index = int(np.clip(index, 0, len(self.line_source) - 1))
        E, e = self.pose_at(index)
        c_z = self.options().guards.c_z
        mp, parts = scene.pose(self.x, E, e, self.mode, self.radii, c_z)
        per_a, patient = scene.anatomy_closest(parts, self.distance)
        per_s, self_pair = scene.self_closest(parts)
        cls, rgb = scene.part_colours(
            scene.part_minimum(per_a),
            scene.part_minimum(per_s),
            self.limits.get("clearance"),
            self.limits.get("self_clearance"),
        )
        return View(index, self.label(index), E, e, mp, scene.body_solids(parts), cls, rgb, patient, self_pair)

    def __len__(self) -> int:
        return int(len(self.line_source))
