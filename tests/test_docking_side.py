"""A docking file says whose docking it is and which side; a command's side is held to it (model §19.1, 19.6).

Oracles: the docking a robot's design.json gives for a side is the robot's parameters with that docking's
placement, compared number by number with the file; a contradicting side is refused in one line naming the
side and the file, by the Python API and by the CLI (exit 2); a written docking file reads back to the same design.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from harness import cli_error

import arcube
from arcube.errors import InputError
from arcube.model.design import PLACEMENT, ROBOT_NAMES, Design
from arcube.model.robot import design_at_side, read_robot, write_docking

ROBOT = Path(__file__).parent / "data" / "one_robot.json"


def _docking(side: str) -> dict:
    return next(e for e in json.loads(ROBOT.read_text())["dockings"] if e["side"] == side)


@pytest.mark.parametrize("side", ["R", "L", "l"])
def test_a_robots_design_json_and_a_side_give_that_sides_docking(side: str) -> None:
    d = design_at_side(ROBOT, side)
    raw, entry = json.loads(ROBOT.read_text()), _docking(side.upper())
    for name in ROBOT_NAMES:
        assert d[name] == raw[name] if name != "c_z" else d.c_z == raw["c_z"]
    for name in PLACEMENT:
        assert d[name] == entry[name]
    assert d.mode == raw["mode"]


def test_without_a_side_the_robot_file_is_not_a_design_and_says_so() -> None:
    assert design_at_side(ROBOT, None) == ROBOT  # nothing chosen: Design.coerce gives its message
    with pytest.raises(InputError, match="or the side whose docking to use"):
        Design.coerce(ROBOT)


def test_a_docking_file_records_its_patient_and_side_and_reads_back(tmp_path: Path) -> None:
    d = design_at_side(ROBOT, "R")
    path = tmp_path / "reference_R" / "design.json"
    path.parent.mkdir()
    write_docking(d, path, "reference", "R")
    data = json.loads(path.read_text())
    assert (data["patient"], data["side"]) == ("reference", "R")
    again = Design.load(path)
    np.testing.assert_array_equal(again.to_vector(), d.to_vector())
    assert (again.c_z, again.mode) == (d.c_z, d.mode)
    assert read_robot(path).starts[0].label == "reference_R"
    assert design_at_side(path, "R") == path  # the same side: the file as it is


def test_a_side_that_contradicts_the_docking_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for side in ("R", "L"):
        (tmp_path / f"reference_{side}").mkdir()
        write_docking(design_at_side(ROBOT, side), tmp_path / f"reference_{side}" / "design.json", "reference", side)
    right = tmp_path / "reference_R" / "design.json"
    with pytest.raises(InputError) as info:
        design_at_side(right, "L")
    text = str(info.value)
    assert (
        text.startswith("side L: ")
        and "docking of side R" in text
        and str(tmp_path / "reference_L" / "design.json") in text
    )
    with pytest.raises(InputError, match="side L"):
        arcube.evaluate(right, "reference", side="L", points=3)
    code, err = cli_error(
        ["evaluate", "--design", str(right), "--trajectories", "reference", "--side", "L", "--points", "3"], capsys
    )
    assert code == 2 and err.startswith("error: --side L: ") and err.count("\n") == 1, err


def test_a_bad_label_in_a_docking_file_is_named(tmp_path: Path) -> None:
    data = {**design_at_side(ROBOT, "R").to_file_dict(), "side": "X"}
    (tmp_path / "d.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"side must be \"R\" or \"L\""):
        Design.load(tmp_path / "d.json")


def test_a_cohort_robot_asks_for_the_patients_docking(tmp_path: Path) -> None:
    raw = json.loads(ROBOT.read_text())
    raw["dockings"] = [*raw["dockings"], {**_docking("R"), "patient": "seed7"}]
    (tmp_path / "design.json").write_text(json.dumps(raw))
    with pytest.raises(InputError, match="docks it 2 times on side R; give one docking's file"):
        design_at_side(tmp_path / "design.json", "R")
    assert design_at_side(tmp_path / "design.json", "L")["m_x"] == _docking("L")["m_x"]
    with pytest.raises(InputError, match="docks 2 times on side R"):
        arcube.breach(tmp_path / "design.json", "reference", samples=200)
