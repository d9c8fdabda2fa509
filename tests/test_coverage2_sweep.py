"""The search sees its lines at the program's resolution (model §17.2): a design feasible on the coarse points is judged
again on every line sampled every 0.5 mm, and the search acts on that verdict.

Oracles: hand-computed sample counts; the sweep's points lie on the lines with the coarse points among them; a batch
against its rows evaluated by the coarse and the fine model separately; a model whose fine lines hold a point no design
reaches refuses every design the coarse points accept.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from arcube.optimization.build import SWEEP_MM, build_model, sweep_points, sweep_tasks
from arcube.optimization.config import build_config
from arcube.optimization.problem import TaskData
from arcube.optimization.settings import RunSettings
from tests.designs import PROGRAM_DESIGN, right_plan


def test_sweep_counts_put_the_coarse_points_among_samples_at_most_half_a_millimetre_apart() -> None:
    A = np.zeros((2, 3))
    B = np.array([[0.0, 0.0, 100.0], [0.0, 0.0, 10.0]])
    # the longest line, 100 mm, at 30 coarse points: 29 m intervals of at most 0.5 mm -> m = ceil(100 / 14.5) = 7
    assert sweep_points(A, B, 30) == 29 * 7 + 1
    assert sweep_points(A, B[1:], 30) == 30  # 10 mm at 29 intervals is already finer than 0.5 mm
    assert sweep_points(A, np.array([[0.0, 0.0, 14.5]]), 30) == 30  # exactly 0.5 mm: no refinement
    assert sweep_points(A, np.array([[0.0, 0.0, 14.5001]]), 30) == 59


def test_sweep_tasks_lie_on_the_lines_and_keep_the_coarse_points() -> None:
    S = np.array([[10.0, 0.0, 80.0]])
    A = np.array([[10.0, 0.0, 10.0]])
    B = np.array([[10.0, 0.0, -15.0]])
    approach, drill = sweep_tasks(0, 0, "p R", S, A, B, 6)
    assert (approach.role, drill.role) == ("approach", "sweep")
    step = np.linalg.norm(np.diff(approach.E, axis=0), axis=1)
    assert step.max() <= SWEEP_MM + 1e-12 and np.allclose(approach.E[[0, -1]], [S[0], A[0]])
    assert np.allclose(np.linalg.norm(np.diff(drill.E, axis=0), axis=1).max(), 25.0 / (drill.n_points - 1))
    assert np.allclose(drill.E[[0, -1]], [A[0], B[0]]) and np.allclose(approach.e, [0.0, 0.0, 1.0])
    coarse = np.linspace(S[0], A[0], 6)
    k = (approach.n_points - 1) // 5
    np.testing.assert_allclose(approach.E[::k], coarse, atol=1e-12)


@pytest.fixture(scope="module")
def model(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    design = tmp_path_factory.mktemp("d") / "design.json"
    design.write_text(json.dumps(PROGRAM_DESIGN))
    s = RunSettings(design_from=str(design), free=("m_x", "m_y", "m_z"), standoff=25.0, points=6, population=8)
    return build_model(build_config([right_plan("1,3")], s))


def test_a_run_with_approach_lines_has_fine_tasks_at_the_program_resolution(model) -> None:  # noqa: ANN001
    roles = [(t.role, t.n_points) for t in model.fine_tasks]
    assert [r for r, _ in roles] == ["plan", "approach", "sweep"]
    assert roles[0][1] == model.tasks[0].n_points  # the plan's points as they were: eta_G unchanged
    assert roles[1][1] > model.tasks[1].n_points
    for t in model.fine_tasks[1:]:
        lines = t.E.reshape(2, -1, 3)
        assert np.linalg.norm(np.diff(lines, axis=1), axis=2).max() <= SWEEP_MM + 1e-9
    plain = build_model(build_config([right_plan("1,3")], RunSettings(points=6, population=8)))
    assert plain.fine_tasks == ()  # no approach lines: one pass, as before


def _rows(model) -> np.ndarray:  # noqa: ANN001
    x = np.array([PROGRAM_DESIGN[n] for n in ("m_x", "m_y", "m_z")])
    rng = np.random.default_rng(3)
    return np.vstack([x, x + rng.normal(0.0, 1.0, (5, 3)), x + rng.normal(0.0, 60.0, (6, 3))])


def test_rows_feasible_on_the_coarse_points_take_the_fine_answer(model) -> None:  # noqa: ANN001
    X = _rows(model)
    batch = model.evaluate(X)
    coarse = model._evaluate(X, None)
    fine = replace(model, tasks=model.fine_tasks, fine_tasks=())._evaluate(X, None)
    ok = coarse["VIOL"] == 0.0
    assert 0 < ok.sum() < len(X)  # both kinds of rows in the batch
    for key in batch:
        np.testing.assert_array_equal(batch[key][ok], fine[key][ok])
        np.testing.assert_array_equal(batch[key][~ok], coarse[key][~ok])


def test_a_failure_between_the_coarse_points_makes_the_search_refuse(model) -> None:  # noqa: ANN001
    far = TaskData(0, 0, "p R sweep", np.array([[5000.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]), role="sweep")
    trap = replace(model, fine_tasks=(*model.fine_tasks, far))
    X = _rows(model)
    coarse = trap._evaluate(X, None)
    assert (coarse["VIOL"] == 0.0).any()
    batch = trap.evaluate(X)
    assert (batch["VIOL"] > 0.0).all() and np.isinf(batch["ETA"]).all()
    assert trap.report(X[0])["feasible"] is False


@pytest.fixture(scope="module")
def docked_model(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    """Two dockings (the R and L trajectories 1-4 of the reference plan), the placement free at each."""
    from arcube.io import load_trajectories, select

    design = tmp_path_factory.mktemp("d") / "design.json"
    design.write_text(json.dumps(PROGRAM_DESIGN))
    plan = select(load_trajectories("reference"), ids="1,2,3,4")
    s = RunSettings(
        design_from=str(design), free=("m_x", "m_y", "m_z"), standoff=25.0, points=6, population=8, dockings="per-side"
    )
    return build_model(build_config([plan], s))


def test_over_dockings_each_docking_feasible_at_its_points_is_judged_again_alone(docked_model) -> None:  # noqa: ANN001
    m = docked_model
    assert m.by_docking and m.n_patients == 2
    x = np.array([PROGRAM_DESIGN[n] for n in ("m_x", "m_y", "m_z")])
    rng = np.random.default_rng(5)
    X = np.vstack([np.concatenate([x + rng.normal(0.0, 1.0, 3), x + rng.normal(0.0, 80.0, 3)]) for _ in range(8)])
    coarse = replace(m, fine_tasks=())
    c = coarse.evaluate(X)
    ok0 = c["VIOL_D"][:, 0] == 0.0
    assert ok0.any() and (c["VIOL"][ok0] > 0.0).any()  # docking R feasible in rows the whole problem is not
    # oracle: docking R alone, its fine tasks as the whole model's tasks
    alone = replace(m, tasks=tuple(t for t in m.fine_tasks if t.patient == 0), fine_tasks=())
    with np.errstate(invalid="ignore", divide="ignore"):  # docking L has no task in the oracle: its columns are NaN
        a = alone.evaluate(X)
    b = m.evaluate(X)
    np.testing.assert_array_equal(b["VIOL_D"][ok0, 0], a["VIOL_D"][ok0, 0])
    np.testing.assert_array_equal(b["VIOL_D"][~ok0, 0], c["VIOL_D"][~ok0, 0])
    # a point no design reaches, on docking R's fine lines only: every row feasible at R's points now fails at R
    far = TaskData(0, 0, "patient R sweep", np.array([[5000.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]), role="sweep")
    trap = replace(m, fine_tasks=(*m.fine_tasks, far)).evaluate(X)
    assert (trap["VIOL_D"][ok0, 0] > 0.0).all() and np.isinf(trap["ETA_D"][ok0, 0]).all()
    np.testing.assert_array_equal(trap["VIOL_D"][:, 1], b["VIOL_D"][:, 1])  # docking L untouched
