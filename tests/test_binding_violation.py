"""The requirement that binds at a side not served is chosen by model §16's normalized violation, not by raw margins.

MODEL.md §16 grades a design's violation as V = V_reach + V_fit, G = (1/n) sum over the points and guards of
min(s / S, 1) plus the limits' normalized shortfalls; §19.6 reports per side "the binding requirement and its margin".
The margins of a docking's rows are in different units (a guard's failing points, a clearance's mm, a torque's N m):
comparing them raw named ``transmission -101 failing points`` beside a self clearance of -24.8 mm. Each row now carries
its term of §16 (``violation``), and :func:`binding_row` ranks the failed rows by it, a point not reached first.

Oracles: hand-made rows where the raw-margin rule and §16 disagree; and, on a real robot (tests/data/one_robot.json
placed off its docking on the reference plan's right side), every guard's ``violation`` against the terms recomputed
here from the evaluation's per-point figures by the formulas of MODEL.md 8.2 and §16 (the transmission sines from the
inverse kinematics, eta_L from the condition numbers, rho), and the sum of the guards' and clearances' terms against the
reference's own G (``guard_grade``), the reach row's against its V_reach.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.coerce import design_mode
from arcube.design_job.coverage import COVERAGE_COLUMNS, binding_fields, binding_row, coverage_csv
from arcube.design_job.dockings import PLACEMENT
from arcube.design_job.requirements import assess, design_options, requirements_from
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.reference import FAILURES
from arcube.evaluation.standoff import approach_lines
from arcube.evaluation.task import build_task
from arcube.io import select
from arcube.model.design import unpack
from arcube.model.mechanism import inverse_kinematics
from arcube.model.robot import read_robot
from arcube.model.stages import rts

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
SIN20 = math.sin(math.radians(20.0))


def _row(name: str, kind: str, limit: float, value: float, unit: str, **more: object) -> dict:
    margin = value - limit if kind == "min" else limit - value
    return {
        "requirement": name,
        "kind": kind,
        "limit": limit,
        "value": value,
        "unit": unit,
        "margin": margin,
        "passed": bool(math.isfinite(value) and margin >= 0.0),
        "where": {},
        "part": "",
        **more,
    }


def _side(violations: dict[str, float]) -> list[dict]:
    """A side not served as the user saw it: 101 points failing the transmission guard (so reach fails too, with every
    point solved by the inverse kinematics: V_reach = 0) beside a self clearance of -24.8 mm."""
    return [
        _row("reach", "min", 1.0, 0.66, "fraction", violation=0.0),
        _row("rho_max", "max", 0.0, 0.0, "failing points", violation=0.0),
        _row("transmission", "max", 0.0, 101.0, "failing points", violation=violations["transmission"]),
        _row("kappa_max", "max", 0.0, 0.0, "failing points", violation=0.0),
        _row("clearance", "min", 5.0, 12.0, "mm", violation=0.0),
        _row("self_clearance", "min", 2.0, -24.8, "mm", violation=violations["self_clearance"]),
        _row("torque", "max", 20.0, 9.0, "N·m", violation=0.0),
    ]


def test_the_binding_requirement_is_the_largest_normalized_violation_not_the_least_raw_margin() -> None:
    rows = _side({"transmission": 0.02, "self_clearance": 0.31})
    # raw margins: -101 failing points < -26.8 mm / 2 mm; normalized (MODEL.md §16): 0.31 > 0.02
    bind = binding_row(rows)
    assert bind is not None and bind["requirement"] == "self_clearance"
    fields = binding_fields(rows)
    assert fields["binding"] == "self_clearance" and fields["binding_unit"] == "mm"
    assert fields["binding_margin"] == pytest.approx(-26.8) and fields["binding_violation"] == pytest.approx(0.31)
    # the same rows with the transmission far off (most points at a near-zero sine): now it binds
    assert binding_row(_side({"transmission": 2.5, "self_clearance": 0.31}))["requirement"] == "transmission"
    # a limit without a stored figure (a breach or program row) is graded as §16 grades a --max: (value - limit) / limit
    breach = _row("breach_probability", "max", 0.01, 0.05, "probability")  # 4.0
    assert binding_row([*rows, breach])["requirement"] == "breach_probability"
    # coverage.csv keeps its columns and adds the figure last
    entry = {
        "patient": "p",
        "side": "R",
        "meets_requirements": False,
        "missed": ["reach", "transmission", "self_clearance"],
        "eta_G": None,
        **dict.fromkeys(PLACEMENT, 0.0),
        **fields,
    }
    table = list(csv.reader(io.StringIO(coverage_csv([entry]))))
    assert table[0][:8] == ["patient", "side", "met", "binding", "margin", "unit", "missed", "eta_G"]
    assert table[0][-1] == "binding_violation" == COVERAGE_COLUMNS[-1]
    assert table[1][3:6] == ["self_clearance", "-26.8", "mm"] and float(table[1][-1]) == pytest.approx(0.31)


def test_a_point_not_reached_outranks_every_fit_shortfall_and_an_unmeasured_row_comes_last() -> None:
    far = {"transmission": 3.0, "self_clearance": 1.0}
    rows = _side(far)
    rows[0] = _row("reach", "min", 1.0, 0.98, "fraction", violation=1e-3)  # one point in 300 without an IK solution
    assert binding_row(rows)["requirement"] == "reach"  # V_reach > 0 ranks above any V_fit (MODEL.md §16)
    # the z dyad's row (model §16's amendment: an open dyad is a point not reached) outranks them too
    rows = _side(far)
    rows.insert(1, _row("z_dyad", "max", 0.0, 3.0, "failing points"))
    assert binding_row(rows)["requirement"] == "z_dyad"
    # a reach row failed only by guards (V_reach = 0) does not: the guards carry that violation
    assert binding_row(_side(far))["requirement"] == "transmission"
    # a requirement not measured (no point where it holds is reached) comes after every measured one
    lateral = _row("lateral_error", "max", 0.5, math.nan, "mm", violation=math.nan)
    small = _side({"transmission": 1e-6, "self_clearance": 0.0})
    small[5] = {**small[5], "passed": True, "value": 2.0, "margin": 0.0}
    assert binding_row([lateral, *small])["requirement"] == "transmission"


# two placements of the robot on the reference plan's right side, off its own docking (m in mm, mounting in deg): each
# solves the inverse kinematics at every point but fails guards at many; the first has a kappa_max point, the second
# points outside the majority assembly mode
PLACEMENTS = {
    "kappa": (109.5324, -14.4321, 404.7533, -10.6218, -78.5105, 47.1127),
    "assembly": (87.3243, 15.6712, 382.6950, -5.5452, -86.2069, 33.6559),
}


@pytest.fixture(scope="module")
def scene() -> tuple:
    whole = arcube.load_trajectories("reference")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    return read_robot(ROBOT), select(whole, side="R"), anatomy, resolve_envelope(["default"], whole, anatomy)


@pytest.mark.parametrize("which", list(PLACEMENTS))
def test_assess_carries_each_guards_term_of_the_graded_violation(scene: tuple, which: str) -> None:
    robot, plan, anatomy, envelope = scene
    design = robot.placed(np.array(PLACEMENTS[which]))
    reqs = requirements_from()
    options = design_options(reqs).replace(z_dyad=True, c_z=design.c_z_mm)
    x, mode, points, standoff = design.to_vector(), design_mode(design), 6, 20.0
    rows = {
        r["requirement"]: r
        for r in assess(
            [x],
            mode,
            [plan],
            [anatomy],
            reqs,
            options=options,
            points=points,
            standoff_mm=standoff,
            envelopes=[envelope],
        )
    }
    # the same points, each guard's shortfall s at each point by MODEL.md 8.2 and its term min(s / S, 1) by §16
    g = unpack(x)
    drill = build_task(plan.entry, plan.target, points)
    lines = ((drill.E, drill.e), approach_lines(plan.entry, plan.target, anatomy, points, standoff))
    dyad = FAILURES.index("guard/z_dyad") + 1  # the last code of the IK (the design's own c_z: §16's amendment)
    sums = dict.fromkeys(("rho_max", "transmission", "kappa_max"), 0.0)
    grade = reach = 0.0
    n = 0
    for E, e in lines:
        res = evaluate_task(x, E, e, mode, options, engine="numpy", anatomy=anatomy.distance, envelope=envelope)
        failure = np.asarray(res.points.failure)
        solved = (failure == 0) | (failure > dyad)
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = inverse_kinematics(x, E, e, mode)
            sines = np.concatenate(
                [
                    sol.terms.F / (g.d[:2] * g.c),  # s_F = F_u / (d_u c_u)
                    sol.terms.H / (g.t * g.c),  # s_H = H_u / (t_u c_u)
                    rts.J_AS_diag(sol.e, sol.u_beta) / (np.sin(g.alpha) * np.sin(g.beta)),
                    (rts.det_beta(sol.e, sol.u_beta) / (np.sin(g.beta[0]) * np.sin(g.beta[1])))[:, None],
                ],
                axis=1,
            )
        per_sine = np.minimum(np.maximum(SIN20 - np.abs(sines), 0.0) / SIN20, 1.0)
        sums["transmission"] += float(np.sum(per_sine[solved]))
        eta = np.max(np.asarray(res.points.kappa), axis=1)  # eta_L before the guards (finite where solved)
        sums["kappa_max"] += float(np.sum(np.minimum(np.maximum(eta - 100.0, 0.0) / 100.0, 1.0)[solved]))
        excess = np.sum(np.maximum(np.abs(np.asarray(res.points.rho)) - math.radians(75.0), 0.0), axis=1)
        sums["rho_max"] += float(np.sum(np.minimum(excess / math.radians(10.0), 1.0)[solved]))
        own = evaluate_task(
            x, E, e, mode, options, engine="numpy", anatomy=anatomy.distance, envelope=envelope, c_z=design.c_z_mm
        )
        grade += float(own.guard_grade)  # the reference's G * n of this line set, every guard and clearance
        reach += float(own.violation_reach)
        n += len(failure)
    for name, total in sums.items():
        assert rows[name]["violation"] == pytest.approx(total / n, rel=1e-9, abs=1e-12), name
    assert sums["transmission"] > 0.0 and rows["transmission"]["value"] > 0  # the check is not vacuous
    assert (sums["kappa_max"] > 0.0) if which == "kappa" else (rows["single_assembly_mode"]["violation"] > 0.0)
    graded = (
        "rho_max",
        "transmission",
        "kappa_max",
        "single_assembly_mode",
        *(r.name for r in reqs if "clearance" in r.name),
    )
    assert sum(rows[name]["violation"] for name in graded) == pytest.approx(grade / n, rel=1e-9)
    assert rows["reach"]["violation"] == pytest.approx(reach) and reach == 0.0 and not rows["reach"]["passed"]
    # value, margin and unit are the requirement's own, as before
    assert (
        rows["transmission"]["unit"] == "failing points"
        and rows["transmission"]["margin"] == -rows["transmission"]["value"]
    )
    for r in rows.values():  # a limit's term: its normalized shortfall; a row met: 0
        if r["requirement"] in ("lateral_error", "axis_error", "torque", "holding_torque") and math.isfinite(
            r["value"]
        ):
            assert r["violation"] == pytest.approx(max(r["value"] - r["limit"], 0.0) / r["limit"])
        if r["passed"] and r["requirement"] not in ("rho_max", "transmission", "kappa_max", "single_assembly_mode"):
            assert r["violation"] == 0.0
