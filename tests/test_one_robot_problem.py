"""One robot, several dockings (MODEL.md 19.1-19.3): the design problem, checked without running a job.

Oracles: the problem over two dockings against each docking's problem alone (the violation is the sum of the
dockings' own, eta_G their max or mean); a docking left out of a batch (NaN genes) against the other docking
alone; a placement carried by a rigid motion of the patient frame against the same robot on the moved plan
(the evaluation is invariant: the rigid motion's exact inverse, by construction); Kabsch's motion of a plan
moved by a known motion is that motion; config.toml of a run without these settings is as before.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.evaluation.reference import Options, evaluate_task
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select
from arcube.model.design import Design
from arcube.model.frames import rotation_matrix
from arcube.optimization.build import build_model
from arcube.optimization.config import build_config, docking_groups
from arcube.optimization.docked import carried, peer_starts, task_motions
from arcube.optimization.settings import RunSettings

from designs import DEMO

GUARDS = {"guards": {"z_dyad": True, "self_clearance_mm": 2.0}}
"""Guards with no anatomy: the problems below are built in memory (no run folder)."""


def _model(**fields):
    s = RunSettings(
        free="all,mount,L,c_z",
        mode="free",
        guarded=True,
        points=5,
        seed=1,
        options=GUARDS,
        maxima={"lateral_error": 0.5},
        **fields,
    )
    return build_model(build_config(["reference"], s), anatomies=(), settings=s), s


def _vector(model, placements: list[np.ndarray], c_z: float) -> np.ndarray:
    """The optimizer vector of DEMO's robot with a placement (6,) per docking, c_z and DEMO's mode."""
    x = model.space.encode(DEMO.to_vector(), mode=np.array([1.0 if c == "+" else -1.0 for c in DEMO.mode.split(",")]))
    names = model.space.names
    x[names.index("c_z")] = c_z
    for cols, p in zip(model.space.placement_columns(), placements):
        x[cols] = p
    return x


@pytest.fixture(scope="module")
def two():
    """The reference plan's two sides as two dockings, and DEMO's placement moved to the left side."""
    model, s = _model(dockings="per-side", aggregate="max")
    v = DEMO.to_dict()
    right = np.array([v[n] for n in ("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz")])
    plans = model.docking_plans
    left = carried(right, task_motions(plans[0], plans[1])[1])  # a half turn about the vertical: the other side
    return model, right, left


def test_the_violation_is_the_sum_over_dockings_and_eta_the_worst(two) -> None:
    model, right, left = two
    X = np.stack([_vector(model, [right, left], c) for c in (250.0, 320.0, 30.0)])
    both = model.evaluate(X)
    alone = []
    for side, p in (("R", right), ("L", left)):
        m1, _ = _model(dockings="per-side", side=side)
        alone.append(m1.evaluate(np.stack([_vector(m1, [p], c) for c in (250.0, 320.0, 30.0)])))
    np.testing.assert_allclose(both["VIOL"], alone[0]["VIOL"] + alone[1]["VIOL"], rtol=1e-12)
    np.testing.assert_allclose(both["VIOL_D"], np.stack([a["VIOL"] for a in alone], axis=1), rtol=1e-12)
    worst = np.maximum(alone[0]["ETA"], alone[1]["ETA"])
    np.testing.assert_array_equal(both["ETA"], np.where(both["VIOL"] == 0.0, worst, np.inf))
    assert both["VIOL"][2] > 0.0  # c_z = 30 mm: the z dyad cannot close (MODEL.md 19.2)


def test_a_docking_left_out_is_not_evaluated(two) -> None:
    model, right, left = two
    X = np.stack([_vector(model, [right, left], c) for c in (250.0, 320.0)])
    X[:, model.space.placement_columns()[1]] = np.nan
    got = model.evaluate(X)
    m1, _ = _model(dockings="per-side", side="R")
    want = m1.evaluate(np.stack([_vector(m1, [right], c) for c in (250.0, 320.0)]))
    np.testing.assert_array_equal(got["VIOL"], want["VIOL"])
    assert np.isnan(got["VIOL_D"][:, 1]).all() and np.isnan(got["ETA_D"][:, 1]).all()


def test_the_mean_aggregate(two) -> None:
    model, right, left = two
    mean, _ = _model(dockings="per-side", aggregate="mean")
    X = np.stack([_vector(model, [right, left], c) for c in (250.0, 320.0)])
    a, b = model.evaluate(X), mean.evaluate(X)
    np.testing.assert_array_equal(a["VIOL"], b["VIOL"])
    finite = np.isfinite(a["ETA"])
    np.testing.assert_allclose(b["ETA"][finite], a["ETA_D"][finite].mean(axis=1), rtol=1e-14)


def test_a_placement_carried_by_a_rigid_motion_sees_the_moved_plan_alike() -> None:
    """Invariance: robot at placement p on plan A == robot at carried(p, (Q, t)) on the plan Q A + t."""
    ts = select(load_trajectories("reference"), side="R")
    Q = rotation_matrix(np.radians([10.0, -25.0, 170.0]))
    t = np.array([12.0, -30.0, 5.0])
    v = DEMO.to_dict()
    p = np.array([v[n] for n in ("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz")])
    q = carried(p, (Q, t))
    moved = DEMO.replace(**dict(zip(("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz"), q)))
    a = build_task(ts.entry, ts.target, 6)
    b = build_task(ts.entry @ Q.T + t, ts.target @ Q.T + t, 6)
    mode = np.array([1.0 if c == "+" else -1.0 for c in DEMO.mode.split(",")])
    ra = evaluate_task(DEMO.to_vector(), a.E, a.e, mode, Options(z_dyad=True, c_z=300.0, clearances=True))
    rb = evaluate_task(moved.to_vector(), b.E, b.e, mode, Options(z_dyad=True, c_z=300.0, clearances=True))
    np.testing.assert_array_equal(ra.points.failure, rb.points.failure)
    np.testing.assert_allclose(rb.points.eta_L, ra.points.eta_L, rtol=1e-8)
    np.testing.assert_allclose(rb.points.self_clearance_mm, ra.points.self_clearance_mm, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize(
    "angles, which", [((5.0, 4.0, 10.0), 0), ((5.0, 4.0, 180.0), 1)], ids=["levels in order", "half a turn"]
)
def test_kabsch_recovers_a_known_motion(angles, which) -> None:
    """A plan moved by (Q, t): the level pairing finds a motion that keeps the levels' order, the reversed pairing one
    that turns them over (a half turn about the vertical, as between a spine's two sides)."""
    ts = select(load_trajectories("reference"), side="R")
    Q = rotation_matrix(np.radians(angles))
    t = np.array([3.0, 4.0, -5.0])
    found = task_motions((ts.entry, ts.target), (ts.entry @ Q.T + t, ts.target @ Q.T + t))[which]
    np.testing.assert_allclose(found[0], Q, atol=1e-10)
    np.testing.assert_allclose(found[1], t, atol=1e-8)


def test_an_infeasible_docking_is_offered_each_feasible_peers_placement_carried_onto_its_plan() -> None:
    """peer_starts: three dockings, plans 1 and 2 the plan 0 moved by known motions; docking 2 infeasible. Its starts are
    docking 0's and docking 1's best placements carried by the motions from their plans onto plan 2 (three each, in
    order); the level pairing's start from docking 0 is the placement moved by the known motion (by hand: Q m + t, and
    the mounting Q R); docking 2 itself and infeasible peers give none; with no feasible peer, no start."""
    ts = select(load_trajectories("reference"), side="R")
    Q1, t1 = rotation_matrix(np.radians([3.0, -4.0, 8.0])), np.array([10.0, -20.0, 5.0])
    Q2, t2 = rotation_matrix(np.radians([-6.0, 2.0, 15.0])), np.array([-15.0, 25.0, 0.0])
    plans = [
        (ts.entry, ts.target),
        (ts.entry @ Q1.T + t1, ts.target @ Q1.T + t1),
        (ts.entry @ Q2.T + t2, ts.target @ Q2.T + t2),
    ]
    best = [
        np.array([-80.0, 60.0, 200.0, 20.0, -70.0, 5.0]),
        np.array([-60.0, 40.0, 210.0, 25.0, -65.0, 12.0]),
        np.zeros(6),
    ]
    starts = peer_starts(2, best, [True, True, False], plans)
    want = [carried(best[j], m) for j in (0, 1) for m in task_motions(plans[j], plans[2])]
    assert len(starts) == len(want) == 6 and all(np.array_equal(a, b) for a, b in zip(starts, want, strict=True))
    np.testing.assert_allclose(starts[0][:3], Q2 @ best[0][:3] + t2, atol=1e-8)
    np.testing.assert_allclose(
        rotation_matrix(np.radians(starts[0][3:])), Q2 @ rotation_matrix(np.radians(best[0][3:])), atol=1e-10
    )
    assert len(peer_starts(2, best, [False, True, False], plans)) == 3
    assert peer_starts(2, best, [False, False, True], plans) == []


def test_per_side_dockings_split_each_plan_by_side() -> None:
    ts = load_trajectories("reference")
    groups = docking_groups(ts, "per-side")
    assert [g[0] for g in groups] == ["R", "L"] and all(set(g[1].sides) == {g[0]} for g in groups)
    assert sorted(sum((list(g[1].ids) for g in groups), [])) == sorted(ts.ids)
    assert [g[0] for g in docking_groups(ts, "per-patient")] == ["both"]
    assert docking_groups(select(ts, side="L"), "per-patient")[0][0] == "L"


def test_a_run_without_these_settings_writes_the_config_it_always_did() -> None:
    s = RunSettings(seed=3)
    cfg = build_config(["reference"], s).to_toml()
    assert "c_z" not in cfg["bounds"] and "c_z" not in cfg["design"] and "dockings" not in cfg["settings"]
    assert all("name" not in p and "side" not in p for p in cfg["patients"])
    assert RunSettings.from_config(cfg) == s


def test_c_z_bounds_and_free_names() -> None:
    s = RunSettings(free="all,c_z", bounds="c_z=100:300")
    assert s.free[-1] == "c_z" and s.all_bounds["c_z"] == (100.0, 300.0)
    assert RunSettings(free="all,c_z").all_bounds["c_z"] == (20.0, 500.0)  # MODEL.md 19.1
    from arcube.errors import InputError

    with pytest.raises(InputError, match="c_z: a length needs a lower bound > 0"):
        RunSettings(bounds="c_z=0:300")


def test_a_start_design_keeps_its_c_z_when_c_z_is_fixed(tmp_path) -> None:
    path = tmp_path / "start.json"
    DEMO.with_extras(c_z=333.0).to_json(path)
    s = RunSettings(design_from=str(path), free="m_x,m_y,m_z", points=4, seed=1, mode=DEMO.mode)
    model = build_model(build_config(["reference"], s), anatomies=(), settings=s)
    x = model.space.encode(model.space.base)
    np.testing.assert_array_equal(model.space.c_z(x[None]), [333.0])
    assert Design.from_json(path).c_z == 333.0
