"""The paper check: Table 2's links against the reference patient (issue 2, MODEL.md 10 item 10)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from scipy.optimize import differential_evolution

from arcube.model.design import Design
from arcube.evaluation.reference import evaluate_task
from arcube.model.mechanism import inverse_kinematics
from arcube.evaluation.task import build_task

from designs import REFERENCE_CSV

PAPER_PCT = (20.26, 40.25, 66.48)


def _reference(side: str):
    rows = [r for r in csv.DictReader(REFERENCE_CSV.open()) if r["side"] == side]
    entry = np.array([[float(r[f"entry_{a}"]) for a in "xyz"] for r in rows])
    target = np.array([[float(r[f"target_{a}"]) for a in "xyz"] for r in rows])
    return build_task(entry, target, 30)


def _with_m(m: np.ndarray) -> np.ndarray:
    base = Design.preset("paper").to_vector()
    params = np.repeat(base[None, :], np.atleast_2d(m).shape[0], axis=0)
    params[:, 0:3] = np.atleast_2d(m)
    return params


def test_table2_reaches_right_side_for_some_placement() -> None:
    """Search m (scipy differential evolution) so that every R point is reachable; print the dexterity."""
    task = _reference("R")

    def objective(m: np.ndarray) -> np.ndarray:
        res = evaluate_task(_with_m(m.T), task.E, task.e)  # the whole population (3, S) in one batch over designs
        # Feasibility first: any feasible m beats every infeasible one.
        return np.where(res.w_G, res.eta_G, 1e3 + res.violation)

    found = differential_evolution(
        objective,
        [(-400.0, 400.0)] * 3,
        seed=7,
        popsize=20,
        maxiter=150,
        tol=1e-10,
        polish=False,
        vectorized=True,
        updating="deferred",
    )
    res = evaluate_task(_with_m(found.x)[0], task.E, task.e)
    print(
        f"\nTable 2 links, right side, m = {np.round(found.x, 2)} mm: reachable {res.reachable_fraction:.0%}, "
        f"inverted dexterity min/mean/max = {res.dexterity_min:.2f} / {res.dexterity_mean:.2f} / {res.dexterity_max:.2f} % "
        f"(paper: {PAPER_PCT[0]} / {PAPER_PCT[1]} / {PAPER_PCT[2]} %), 100/eta_G = {100 / res.eta_G:.2f} %"
    )
    assert bool(res.w_G)
    assert np.all(res.points.reachable)
    assert 0.0 < res.dexterity_min <= res.dexterity_mean <= res.dexterity_max <= 100.0


def test_table2_cannot_reach_left_side_for_any_placement() -> None:
    """The cone argument: the x spherical leg reaches angle(e, +x) only up to alpha_x + beta_x = 102.64 deg.

    Left-side pedicle axes make more than that with +x, whatever m is; the RTS IK depends on e only.
    """
    task = _reference("L")
    d = Design.preset("paper")
    reach_max = d["alpha_x"] + d["beta_x"]
    angle = np.degrees(np.arccos(task.e[:, 0]))  # angle between e and +x, computed here from the points
    assert angle.min() > reach_max
    rng = np.random.default_rng(3)
    placements = rng.uniform(-400.0, 400.0, size=(50, 3))
    sol = inverse_kinematics(_with_m(placements)[:, None, :], task.E[None], task.e[None])
    assert np.all(np.abs(sol.rts_arg[..., 0]) > 1.0)  # RTS x fails at every point for every m
    res = evaluate_task(_with_m(placements), task.E, task.e)
    assert not np.any(res.w_G)
    assert np.all(res.reachable_fraction == 0.0)


@pytest.mark.parametrize("side", ["R", "L"])
def test_bilateral_angles_span_what_the_model_says(side: str) -> None:
    """MODEL.md 10 item 10: bilateral trajectories need angle(e, +x) from about 41 to 139 deg."""
    angle = np.degrees(np.arccos(_reference(side).e[:, 0]))
    if side == "R":
        assert 40.0 < angle.min() and angle.max() < 52.0
    else:
        assert 128.0 < angle.min() and angle.max() < 140.0
