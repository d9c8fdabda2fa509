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
