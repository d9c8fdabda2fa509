"""The holding torque of MODEL.md 18.2 and the mass flags on the command line: ``evaluate``'s JSON,
``joints``' columns, ``design``'s requirement, and one-line errors naming the flag (exit 2) for a bad
mass, density, wall or gravity on every command that takes them.

Oracles: the per-point JSON against its own summary and the independent hand-computed moving mass of
tests/naive.py; no gravity -> the holding torque is MODEL.md 15.3's torque; the compiled
engine against the NumPy reference.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from arcube.evaluation.performance import ACTUATOR_NAMES
from arcube.export.joints import CSV_COLUMNS, MASS_COLUMNS
from arcube.model.design import Design
from arcube.options import Masses
from arcube.design_job.requirements import DEFAULTS, REQUIREMENTS, requirements_from

from naive import mass_by_hand
from harness import run_cli as _run


@pytest.fixture(scope="module")
def right(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("design") / "right.json"
    Design.preset("paper").replace(m_x=88.23, m_y=79.40, m_z=56.89).to_json(path)
    return path


def _evaluate(right: Path, capsys, *args: str) -> dict:
    code, out, err = _run(["evaluate", "--design", str(right), "--side", "R", "--points", "4", "--json", *args], capsys)
    assert code == 0, err
    return json.loads(out)


def test_evaluate_reports_the_holding_torque_per_point_and_its_maximum(right: Path, capsys) -> None:
    doc = _evaluate(right, capsys)
    pts, s = doc["points"], doc["summary"]
    assert all(p["reachable"] for p in pts) and len(pts) == 20
    hold = [p["holding_torque_Nm"] for p in pts]
    assert all(isinstance(h, float) and h > 0 for h in hold)
    assert {p["holding_torque_actuator"] for p in pts} <= set(ACTUATOR_NAMES)
    assert s["holding_torque_max_Nm"] == max(hold)
    assert s["holding_torque_max_actuator"] == pts[int(np.argmax(hold))]["holding_torque_actuator"]
    assert s["moving_mass_kg"] == pytest.approx(mass_by_hand(Design.load(right).to_vector()), rel=1e-12)
    assert max(hold) > s["torque_max_Nm"] + 0.1  # the weight matters
    # the compiled kernel (default) against the NumPy reference
    ref = _evaluate(right, capsys, "--engine", "numpy")
    np.testing.assert_allclose(hold, [p["holding_torque_Nm"] for p in ref["points"]], rtol=1e-9)
    assert [p["holding_torque_actuator"] for p in pts] == [p["holding_torque_actuator"] for p in ref["points"]]


def test_evaluate_mass_flags_change_it_and_no_gravity_gives_the_drill_torque(right: Path, capsys) -> None:
    base = _evaluate(right, capsys)
    heavy = _evaluate(right, capsys, "--m-motor", "3", "--m-delta", "1.2", "--wall", "3", "--density", "3000")
    assert heavy["summary"]["holding_torque_max_Nm"] > base["summary"]["holding_torque_max_Nm"]
    assert heavy["summary"]["moving_mass_kg"] > base["summary"]["moving_mass_kg"] + 2.3
    assert heavy["guards"]["m_motor_kg"] == 3.0 and heavy["guards"]["gravity"] == [0.0, 0.0, -9.81]
    free = _evaluate(right, capsys, "--gravity", "0,0,0")
    for p in free["points"]:
        assert p["holding_torque_Nm"] == pytest.approx(p["torque_Nm"], rel=1e-12)
        assert p["holding_torque_actuator"] == p["torque_actuator"]
    # thin links without a mass flag: no masses, no holding torque (as before); with a thinner wall: there
    thin = _evaluate(right, capsys, "--link-radius", "1.5")
    assert thin["summary"]["holding_torque_max_Nm"] is None and thin["summary"]["moving_mass_kg"] is None
    assert thin["summary"]["torque_max_Nm"] == base["summary"]["torque_max_Nm"]
    assert _evaluate(right, capsys, "--link-radius", "1.5", "--wall", "0.5")["summary"]["holding_torque_max_Nm"] > 0.0


def test_joints_adds_the_holding_torque_columns_with_a_mass_flag(right: Path, capsys, tmp_path: Path) -> None:
    rows = {}
    for name, extra in (("plain", []), ("down", ["--gravity", "0,0,-9.81"]), ("free", ["--gravity", "0,0,0"])):
        out = tmp_path / f"{name}.csv"
        code, _, err = _run(
            ["joints", "--design", str(right), "--side", "R", "--points", "4", "--out", str(out), *extra], capsys
        )
        assert code == 0, err
        rows[name] = list(csv.DictReader(out.open()))
    assert tuple(rows["plain"][0]) == CSV_COLUMNS
    assert tuple(rows["down"][0]) == (*CSV_COLUMNS[:-1], *MASS_COLUMNS, "reachable")
    for row in rows["down"]:
        hold = [float(row[f"hold_{n}_max_Nm"]) for n in ACTUATOR_NAMES]
        assert (
            float(row["holding_torque_Nm"]) == max(hold)
            and row["holding_torque_actuator"] == ACTUATOR_NAMES[int(np.argmax(hold))]
        )
    for row in rows["free"]:  # no gravity: MODEL.md 15.3's worst case of each actuator, and no gravity torque
        for n in ACTUATOR_NAMES:
            assert float(row[f"hold_{n}_max_Nm"]) == pytest.approx(float(row[f"tau_{n}_max_Nm"]), rel=1e-12, abs=1e-15)
            assert float(row[f"tau_gravity_{n}_Nm"]) == 0.0


def test_design_requires_a_holding_torque_by_default() -> None:
    assert REQUIREMENTS["holding_torque"] == ("max", "N·m", "drill") and DEFAULTS["holding_torque"] == 20.0
    assert {r.name: r.limit for r in requirements_from(maxima={"holding_torque": 15})}["holding_torque"] == 15.0
    assert "holding_torque" not in {r.name for r in requirements_from(drop=["holding_torque"])}


BAD = [
    (["--wall", "8"], "--wall must be < the link radius (8 mm), got 8"),
    (["--wall", "-1"], "--wall must be > 0"),
    (["--density", "-1"], "--density must be > 0"),
    (["--m-delta", "-0.5"], "--m-delta must be >= 0"),
    (["--m-motor", "-1.5"], "--m-motor must be >= 0"),
    (["--gravity", "0,0"], "--gravity must be three finite numbers"),
    (["--gravity", "0,0,inf"], "--gravity must be three finite numbers"),
    (["--gravity", "down"], "--gravity must be three"),
]
COMMANDS = {
    "evaluate": ["evaluate", "--points", "3"],
    "joints": ["joints", "--points", "3", "--out", "{tmp}/j.csv"],
    "optimize": ["optimize", "--trajectories", "reference", "--out", "{tmp}/run"],
    "design": ["design", "--trajectories", "reference", "--out", "{tmp}/design"],
    "program": ["program", "--design", "paper", "--trajectories", "reference", "--out", "{tmp}/program"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize(("args", "needle"), BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_mass_flags_are_one_line_naming_the_flag(
    command: str, args: list[str], needle: str, capsys, tmp_path: Path
) -> None:
    argv = [a.replace("{tmp}", str(tmp_path)) for a in COMMANDS[command]] + args
    code, out, err = _run(argv, capsys)
    assert code == 2, (out, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_program_passes_the_masses_and_loads(monkeypatch: pytest.MonkeyPatch, capsys, tmp_path: Path) -> None:
    """``arcube program`` hands its mass and load flags to arcube.program (masses=, loads=)."""
    import sys

    from arcube.errors import InputError

    apimod = sys.modules["arcube.api"]  # the command calls arcube.program, with the robot's Options
    seen: dict = {}

    def fake(*args, **kwargs):
        seen.clear()
        seen.update(kwargs)
        raise InputError("stop here")

    monkeypatch.setattr(apimod, "program", fake)
    argv = ["program", "--design", "paper", "--trajectories", "reference", "--out", str(tmp_path / "p")]
    _run([*argv, "--m-motor", "2", "--gravity=0,-9.81,0", "--thrust", "25", "--lateral-force", "5"], capsys)
    masses, loads = seen["options"].masses, seen["options"].loads
    assert masses.m_motor_kg == 2.0 and masses.gravity == (0.0, -9.81, 0.0) and masses.wall_mm == 2.0
    assert (loads.thrust_N, loads.lateral_force_N) == (25.0, 5.0)
    _run(argv, capsys)
    assert seen.get("masses") is None and seen["options"].masses == Masses()  # no mass flag: the program's own defaults
