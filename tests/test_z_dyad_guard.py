"""MODEL.md 19.2: the z dyad closes in every design problem (the guard on, with the design's own c_z).

Oracles: the z dyad's closure by hand (|d_z - c_z| <= |Q_z - D_z| <= d_z + c_z with the leg's points from the
NumPy reference's mechanism) decides which points fail; the design problem's violation counts exactly those
(the same design with a closing c_z is judged the same elsewhere).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from arcube.design_job import design_settings
from arcube.design_job.requirements import requirements_from
from arcube.evaluation.reference import FAILURES, Options, evaluate_task
from arcube.optimization.build import build_model
from arcube.optimization.config import build_config
from arcube.optimization.settings import RunSettings

from designs import DEMO, plan_right
from naive import oracle_config, rotation


def test_the_guard_is_on_wherever_c_z_is_a_design_parameter() -> None:
    """arcube design: c_z free and the z-dyad guard on; arcube optimize --guarded: on when c_z is free, as before when not."""
    s = design_settings(requirements_from(drop=["clearance", "envelope_clearance"]), RunSettings(envelope=("none",)))
    assert "c_z" in s.free and s.evaluation_options().guards.z_dyad
    assert RunSettings(guarded=True, free="all,c_z").evaluation_options().guards.z_dyad
    assert (
        not RunSettings(guarded=True).evaluation_options().guards.z_dyad
    )  # c_z = d_z, not a parameter: MODEL.md 8.2 as it was
    assert not RunSettings(free="all,c_z").evaluation_options().guards.z_dyad  # no guards asked for


def test_a_design_problem_fails_a_robot_whose_z_dyad_cannot_close() -> None:
    """DEMO's robot on the reference patient's right side in the design job's problem: with c_z = 20 mm its z dyad cannot
    span D_z -> Q_z at the points where it must (by hand: outside [|d_z - c_z|, d_z + c_z]); the problem counts those points
    failed (a violation beyond the same problem's without the guard), and with a c_z that spans every point it does not."""
    reqs = requirements_from(
        drop=["clearance", "envelope_clearance", "lateral_error", "axis_error", "torque", "holding_torque"]
    )
    s = design_settings(reqs, RunSettings(points=5, side="R", envelope=("none",)))
    model = build_model(build_config(["reference"], s), anatomies=(), settings=s)
    assert model.options.guards.z_dyad
    without = dataclasses.replace(
        model, options=model.options.replace(z_dyad=False)
    )  # the same problem, the z-dyad guard off
    mode = np.array([1.0 if c == "+" else -1.0 for c in DEMO.mode.split(",")])
    _, task = plan_right(5)
    x = DEMO.to_vector()
    free = evaluate_task(x, task.E, task.e, mode, Options()).points  # no guard: where the IK solves
    assert np.asarray(free.reachable, bool).all()
    # the task as the unrotated, untooled links see it (tests/designs.place inverted), then the legs by hand
    R, m, L = rotation(x[23:26]), x[:3], x[26]
    e_p = task.e @ R
    E_p = m + (task.E + L * task.e - m) @ R
    cfg = oracle_config(x[:23], E_p, e_p, np.asarray(free.rho), np.asarray(free.delta), np.asarray(free.sigma))
    assert np.abs(cfg.planar).max() < 1e-6  # the hand-built legs are the reference's (MODEL.md 3.1)
    span = np.linalg.norm(cfg.Q[..., 2, :] - cfg.D[..., 2, :], axis=-1)  # |Q_z - D_z|, mm
    d_z = DEMO["d_z"]
    closing = 0.5 * (span.min() + span.max())  # spans every point when max - min <= 2 d_z, as here
    assert span.max() - closing <= d_z and closing - span.min() <= d_z
    judged = {}
    for c_z in (20.0, closing):
        opens = ~((abs(d_z - c_z) <= span) & (span <= d_z + c_z))
        ref = evaluate_task(x, task.E, task.e, mode, s.evaluation_options(), c_z=c_z).points
        assert np.array_equal(np.asarray(ref.failure) == FAILURES.index("guard/z_dyad") + 1, opens), c_z
        X = model.space.encode(x, mode=mode)
        X[model.space.names.index("c_z")] = c_z
        on, off = (float(mdl.evaluate(X[None, :])["VIOL"][0]) for mdl in (model, without))
        judged[c_z] = on, off, int(opens.sum())
    (open_on, open_off, n_open), (closed_on, closed_off, n_closed) = judged[20.0], judged[closing]
    assert n_open == len(span) and n_closed == 0
    assert open_on > open_off  # the open dyad is a violation of the design problem ...
    assert closed_on == closed_off  # ... and the closed one none: the guard counts exactly the z dyad
