"""What a design job writes for each docking it checked, beside its requirement rows: the drilling program (model §17)
and its rows, the accuracy budget as built (model §20), and a z-dyad link for a design without one. Shared by
``arcube design`` (:mod:`arcube.design_job.job`) and ``arcube dock`` (:mod:`arcube.design_job.dock`)."""

from __future__ import annotations

import re
import shutil

import numpy as np
import time
from pathlib import Path
from typing import Any
from collections.abc import Sequence

from arcube.design_job.dockings import Docking
from arcube.design_job.requirements import Requirement, program_rows
from arcube.errors import InputError
from arcube.model.design import Design
from arcube.optimization.settings import RunSettings

__all__ = [
    "ACCURACY",
    "BREACH",
    "PROGRAM",
    "accuracy_budget",
    "breach_check",
    "breach_risk",
    "build_program",
    "closing_c_z",
    "docking_evaluation",
    "trajectory_failures",
    "trajectory_verdict",
]

PROGRAM = "program"
ACCURACY = "accuracy"
BREACH = "breach"
BREACH_SAMPLES = 10_000
"""Samples of a docking's breach Monte Carlo (model §22.4's default)."""


def docking_evaluation(d: Docking, s: RunSettings) -> Any:
    """The evaluation a docking's report shows (:class:`~arcube.evaluation.result.Evaluation`): the NumPy reference at
    the plan's points with the design job's guards and clearances, the z dyad with the robot's own c_z (model §19.2),
    the docking's anatomy and envelope."""
    from arcube.coerce import design_mode
    from arcube.evaluation.result import evaluate_design

    options = s.evaluation_options()
    options = options.replace(
        outputs=options.outputs.replace(clearances=True, tip_metrics=True, clearance_min_exact=True)
    )
    if d.design.c_z is not None:
        options = options.replace(z_dyad=True, c_z=d.design.c_z)
    return evaluate_design(
        d.design, d.plan, s.points, design_mode(d.design), options, "numpy", anatomy=d.anatomy, envelope=d.envelope
    )


def trajectory_verdict(evaluation: Any) -> np.ndarray:
    """``(J,)`` the design job's verdict of each trajectory of an evaluation (:func:`docking_evaluation`): every point
    reachable with the guards (model §16-17), as the docking's report tabulates it (100 % reachable)."""
    return np.array([t.reachable_fraction >= 1.0 for t in evaluation.per_trajectory()], dtype=bool)


def _group(plan: Any) -> str:
    """The name :func:`arcube.pedicles.run.breach` gives one design's screws: their one side, or ``both``."""
    sides = set(plan.sides)
    return next(iter(sides)) if len(sides) == 1 else "both"


def breach_risk(figures: dict[str, Any] | None) -> dict[str, float] | None:
    """Screw id -> P(breach) (NaN where not reached) of a docking's breach figures (:func:`breach_check`), for the
    colours of its report's 3D scene; None when the docking has none."""
    screws = (figures or {}).get("screws")
    if not screws:
        return None
    return {s["trajectory"]: float("nan") if s["p_breach"] is None else float(s["p_breach"]) for s in screws}


def trajectory_failures(evaluation: Any) -> dict[str, str]:
    """Trajectory id -> why the design job refuses it (the report's "first failure", ``transmission at k=0``), for the
    trajectories :func:`trajectory_verdict` refuses."""
    return {t.id: t.first_failure or "" for t in evaluation.per_trajectory() if t.reachable_fraction < 1.0}


def build_program(folder: Path, d: Docking, s: RunSettings, reqs: Sequence[Requirement]) -> list[dict[str, Any]]:
    """Build the drilling program of one docking (model §17) into ``folder/program`` with the design's clearances,
    standoff and z dyad; its requirement rows: the program (met, or the blocked segment named), then ``torque_peak`` /
    ``power_peak`` when required (model §18.3, from its motor figures)."""
    from arcube.motion import program
    from arcube.report.program import timeline_png

    # a dropped clearance requirement leaves no margin, but a program never passes through the patient or itself
    limits = {
        "clearance": 0.0,
        "self_clearance": 0.0,
        "envelope_clearance": 0.0,
        **{r.name: r.limit for r in reqs if r.name in ("clearance", "self_clearance", "envelope_clearance")},
    }
    shutil.rmtree(folder / PROGRAM, ignore_errors=True)  # ours: a resumed job (or the next seed tried) builds it again
    folder.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    row: dict[str, Any] = {
        "requirement": "program",
        "kind": "min",
        "limit": 1.0,
        "unit": "feasible",
        "where": {},
        "part": "",
    }
    try:
        prog = program(
            d.design,
            d.plan,
            folder / PROGRAM,
            options=s.options,
            anatomy=d.anatomy,
            envelope=d.envelope,
            mode=d.design.mode,
            standoff_mm=float(s.standoff or 0.0),
            masses=True,
            **limits,
        )
        timeline_png(prog, folder / PROGRAM / "program.png")
    except InputError as exc:
        return [{**row, "value": 0.0, "margin": -1.0, "passed": False, "part": str(exc)}, *program_rows(reqs, None)]
    summary = prog.summary
    built = {
        **row,
        "value": 1.0,
        "margin": 0.0,
        "passed": True,
        "part": f"total {summary['total_s']:.1f} s, built in {time.perf_counter() - started:.0f} s",
    }
    return [built, *program_rows(reqs, summary.get("motors"))]


def accuracy_budget(out: Path, design: Design, plan: Any, mode: str, s: RunSettings, perfect: Any) -> dict[str, Any]:
    """The accuracy budget of one docking's design as built (model §20, class ``s.tolerance_class``, m by default)
    on its plan, written to ``out/accuracy`` (arcube tolerance's folder); its figures for summary.json,
    beside the perfect robot's ``lateral_error`` (model §15.2) so that figure never stands alone."""
    from arcube.accuracy import budget
    from arcube.evaluation.task import build_task
    from arcube.report.accuracy import write_budget

    shutil.rmtree(out / ACCURACY, ignore_errors=True)  # ours: a resumed job writes it again
    settings = s.accuracy_settings()
    task = build_task(plan.entry, plan.target, s.points, tuple(plan.ids))
    try:
        result = budget(design, task.E, task.e, mode, settings, [task.ids[i] for i in task.trajectory], task.k)
    except InputError as exc:
        return {"tolerance_class": settings.tolerance_class, "not_computed": str(exc)}
    write_budget(result, out / ACCURACY)
    return {
        "tolerance_class": settings.tolerance_class,
        "robots": settings.samples,
        "seed": settings.seed,
        **result.summary,
        "perfect_robot_lateral_error_mm": perfect,
        "tighten_first": [
            {"source": n, "tolerance": t, "unit": u, "share": v} for n, t, u, v in result.ranked_sources()[:3]
        ],
    }


def closing_c_z(design: Design, plan: Any, s: RunSettings, summary: dict[str, Any]) -> float | None:
    """For a design without c_z: a z-dyad link c_z that closes the dyad at every point (the middle of the range the
    export names), or None (c_z = d_z closes it)."""
    from arcube.export.mjcf import export_mjcf

    try:
        export_mjcf(design, plan, points=s.points, mode=summary["mode"])
        return None
    except InputError as exc:
        found = re.search(r"c_z in \[([0-9.eE+-]+), ([0-9.eE+-]+)\]", str(exc))
        if not found:
            raise
        lo, hi = float(found.group(1)), float(found.group(2))
        return 0.5 * (lo + hi)


def breach_check(
    out: Path | None,
    d: Docking,
    s: RunSettings,
    reqs: Sequence[Requirement],
    reached: np.ndarray | None = None,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The breach probability of one docking's screws (model §22), the robot as built to ``s.tolerance_class`` with the
    default registration and the run's thrust, written to ``out/breach`` when ``out`` is given: (its figures for
    summary.json, the ``breach_probability`` row when the requirement is set). A docking whose screws cannot be judged
    (no side, no level) has its reason instead of figures, and fails the requirement. ``reached`` ``(J,)``: the
    docking's verdict per trajectory (:func:`trajectory_verdict`; computed when None): a screw it refuses has no P."""
    from arcube.pedicles.output import write_breach
    from arcube.pedicles.run import breach

    acc = s.accuracy_settings()
    row = next(
        (
            {"requirement": r.name, "kind": r.kind, "limit": r.limit, "unit": "probability", "where": {}, "part": ""}
            for r in reqs
            if r.name == "breach_probability"
        ),
        None,
    )
    if reached is None:
        reached = trajectory_verdict(docking_evaluation(d, s))
    try:
        result = breach(
            d.design,
            d.plan,
            tolerances=acc,
            samples=BREACH_SAMPLES,
            seed=acc.seed,
            loads=s.options.loads,
            reached=reached,
            notes={_group(d.plan): {"docking": d.label, "how": "the design job's docking"}},
            patient=d.name,
        )
    except InputError as exc:
        rows = (
            []
            if row is None
            else [{**row, "value": float("nan"), "margin": float("nan"), "passed": False, "part": str(exc)}]
        )
        return {"not_computed": str(exc)}, rows
    if out is not None:
        shutil.rmtree(out / BREACH, ignore_errors=True)  # ours: a resumed job writes it again
        write_breach(result, out / BREACH)
    summary = result.summary()
    figures = {k: summary[k] for k in ("breach_probability", "worst_screw", "too_wide", "expected_breaches")}
    figures["screws"] = [
        {
            k: r[k]
            for k in (
                "trajectory",
                "level",
                "side",
                "room_mm",
                "too_wide",
                "p_breach",
                "p_breach_low",
                "p_breach_high",
                "p_major",
                "p_robot_alone",
                "p_registration_alone",
                "p_deflection_alone",
                "status",
                "deciding_source",
            )
        }
        for r in result.rows()
    ]
    figures.update(not_reached=summary["not_reached"], deciding_source=summary["deciding_source"])
    if row is None:
        return figures, []
    value = (
        1.0 if summary["breach_probability"] is None else float(summary["breach_probability"])
    )  # every screw too wide
    worst = summary["worst_screw"] or (summary["too_wide"] or [""])[0]
    return figures, [
        {
            **row,
            "value": value,
            "margin": row["limit"] - value,
            "passed": value <= row["limit"] and not summary["too_wide"],
            "part": f"screw {worst}" + (f"; too wide: {', '.join(summary['too_wide'])}" if summary["too_wide"] else ""),
        }
    ]
