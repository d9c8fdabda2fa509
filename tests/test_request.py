"""One request (arcube.request): a design on a plan, resolved once, in the order a user's mistakes are best reported."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.io.load import load_plan
from arcube.model.design import Design
from arcube.model.modes import parse_mode
from arcube.options import Options
from arcube.request import Request, with_design_c_z

ROBOT = Path(__file__).parent / "data" / "one_robot.json"


def test_a_robot_file_and_a_side_resolve_to_that_sides_docking_and_plan() -> None:
    r = Request(ROBOT, "reference", side="L", levels="C3-C5").resolve()
    assert r.plan.sides == ("L",) * len(r.plan.ids) and set(r.plan.levels) <= {"C3", "C4", "C5"}
    assert len(r.full.ids) > len(r.plan.ids)  # the envelope's landmarks come from the whole plan
    whole = load_plan("reference")
    np.testing.assert_array_equal(r.full.entry, whole.entry)
    assert r.design.mode is not None and np.array_equal(r.signs, parse_mode(r.design.mode))  # the docking's own mode
    assert r.anatomy is None and r.envelope is None


def test_the_callers_check_runs_on_the_selection_before_the_anatomy_is_read(tmp_path: Path) -> None:
    seen: list[int] = []

    def refuse(ts: object) -> None:
        seen.append(len(ts.ids))  # type: ignore[attr-defined]
        raise InputError("the caller's own check")

    missing = tmp_path / "no_such_anatomy.stl"
    with pytest.raises(InputError, match="the caller's own check"):
        Request("paper", "reference", side="R", anatomy=[str(missing)]).resolve(refuse)
    assert seen == [len(load_plan("reference").ids) // 2]
    with pytest.raises(InputError, match="no_such_anatomy"):  # without the check, the anatomy is what fails
        Request("paper", "reference", side="R", anatomy=[str(missing)]).resolve()


def test_which_c_z_a_request_evaluates_with() -> None:
    own = Design.paper().with_extras(c_z=300.0)
    plain = Design.paper()
    assert with_design_c_z(Options(), own).guards.c_z == 300.0  # the design's own link
    assert with_design_c_z(Options().replace(c_z=250.0), own).guards.c_z == 250.0  # an explicit option wins
    assert with_design_c_z(Options(), plain).guards.c_z is None  # neither: d_z, decided by the model


def test_one_request_asked_of_evaluate_joints_program_and_the_explorer_is_their_keywords() -> None:
    """A public arcube.Request given as ``design`` is the same question as its fields given as keywords."""
    import arcube
    from arcube.explorer import live_model

    opts = Options().replace(thrust=25.0)
    fields = {"side": "R", "levels": "C3-C5", "mode": "+,+,-,+", "points": 7, "options": opts}
    req = arcube.Request(ROBOT, "reference", **fields)
    a, b = arcube.evaluate(req), arcube.evaluate(ROBOT, "reference", **fields)
    assert a.summary == b.summary
    for name in ("reachable", "eta_L", "lateral_error_mm"):
        np.testing.assert_array_equal(getattr(a.points, name), getattr(b.points, name))
    ja, jb = arcube.joints(req, speed=2.0), arcube.joints(ROBOT, "reference", speed=2.0, **fields)
    assert ja.to_csv() == jb.to_csv() and np.isfinite(ja.q_deg).any()
    plan_fields = {k: v for k, v in fields.items() if k != "points"}
    pa = arcube.program(arcube.Request(ROBOT, "reference", **plan_fields), seed=1)
    pb = arcube.program(ROBOT, "reference", seed=1, **plan_fields)
    assert pa.to_csv() == pb.to_csv()
    la, lb = live_model(req), live_model(ROBOT, "reference", **fields)
    assert la.points == lb.points == 7 and la.plan.ids == lb.plan.ids and np.array_equal(la.mode, lb.mode)


@pytest.mark.parametrize("keyword", [{"points": 12}, {"side": "L"}, {"anatomy": "default"}, {"options": Options()}])
def test_a_request_and_a_keyword_it_holds_are_refused_together(keyword: dict) -> None:
    import arcube

    with pytest.raises(InputError, match=rf"^{next(iter(keyword))} is the request's: set it on the arcube.Request"):
        arcube.evaluate(arcube.Request("paper", "reference", side="R"), **keyword)


def test_a_request_where_it_does_not_belong_is_refused() -> None:
    """A Request as the plan; one that sets what the function does not take (program has no points, tolerance no
    anatomy, joints no envelope); a keyword saying what the Request says is accepted."""
    import arcube

    req = arcube.Request("paper", "reference", side="R", points=8)
    with pytest.raises(InputError, match=r"^plan is a Request: give it as the first argument"):
        arcube.evaluate("paper", plan=req)
    with pytest.raises(InputError, match=r"^points is set on the Request, but program does not take it"):
        arcube.program(req)
    with pytest.raises(InputError, match=r"^anatomy is set on the Request, but tolerance does not take it"):
        arcube.tolerance(arcube.Request("paper", "reference", anatomy="default"))
    with pytest.raises(InputError, match=r"^envelope is set on the Request, but joints does not take it"):
        arcube.joints(arcube.Request("paper", "reference", envelope="default"))
    assert arcube.evaluate(req, points=np.int64(8), side="R").summary["n_points"] == 40


def test_an_evaluations_summary_is_typed_and_still_its_json() -> None:
    """Every field of an evaluation's summary is declared (with and without the optional outputs), each an attribute."""
    import json

    import arcube
    from arcube.evaluation.result import EvaluationSummary
    from arcube.options import Outputs

    plain = arcube.evaluate("paper", "reference", side="R", points=6)
    full = arcube.evaluate(
        ROBOT, "reference", side="R", points=6, options=Options(outputs=Outputs(holding_torque=True))
    )
    for e in (plain, full):
        assert isinstance(e.summary, EvaluationSummary) and tuple(e.summary) == EvaluationSummary.fields()
        assert all(getattr(e.summary, k) == e.summary[k] for k in e.summary)
        assert json.loads(json.dumps(e.to_json()))["summary"] == e.summary
    assert full.summary.moving_mass_kg is not None and plain.summary.moving_mass_kg is None


def test_a_request_exports_the_model_its_selection_and_placement_give() -> None:
    """export_mjcf takes a Request too: its plan selected by side and levels, its mode, points and options; the MJCF
    is the one the same design, selected plan and keywords give."""
    import arcube
    from arcube.io import load_trajectories, select

    opts = Options().replace(link_radius=6.0)
    req = arcube.Request(ROBOT, "reference", side="R", levels="C4-C5", mode="+,+,-,+", points=5, options=opts)
    from arcube.model.robot import design_at_side

    plan = select(load_trajectories("reference"), side="R", levels="C4-C5")
    docked = design_at_side(ROBOT, "R")  # a robot file and a side: that side's docking, as the request resolves it
    assert arcube.export_mjcf(req) == arcube.export_mjcf(docked, plan, mode="+,+,-,+", points=5, options=opts)
    with pytest.raises(InputError, match=r"^points is the request's"):
        arcube.export_mjcf(req, points=7)
