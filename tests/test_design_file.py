"""A design file carries what a design needs beside its 27 parameters (issues "One robot for every
patient" and "Calibration"): ``c_z`` (MODEL.md 19.1), the working ``mode``, a calibrated design's joint
zero offsets ``q0_*`` (21.4) and the z dyad's elbow side; old files without them load as before, and
every command takes the mode from the file when none is given.

Oracles: round trips; the same evaluation with the mode given by hand; a calibrated design's joint
angles equal the IK's less q0, computed here from the uncalibrated design's IK.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.errors import InputError
from arcube.model.design import PARAM_NAMES, Q0_KEYS, Design
from arcube.model.mechanism import inverse_kinematics
from harness import run_cli as _run

PLACED = Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
"""Table 2's links placed for the right side (README): reaches the right side's points in +,+,+,+."""
PROGRAMMED = Design.from_json(Path(__file__).with_name("data") / "program_design.json")
"""A design whose right-side program exists (tests/test_program.py's), in +,+,+,+."""


def test_extras_round_trip_and_an_old_file_reads_as_before(tmp_path: Path) -> None:
    d = PLACED.with_extras(c_z=161.5, mode="+,+,+,-", q0_deg=(0.1, -0.2, 0.0, 0.05, -0.05), zdyad_elbow=-1)
    d.to_json(tmp_path / "d.json")
    data = json.loads((tmp_path / "d.json").read_text())
    assert (
        list(data)[:27] == list(PARAM_NAMES)
        and data["c_z"] == 161.5
        and data["mode"] == "+,+,+,-"
        and data["zdyad_elbow"] == -1
    )
    assert [data[k] for k in Q0_KEYS] == [0.1, -0.2, 0.0, 0.05, -0.05]
    back = Design.from_json(tmp_path / "d.json")
    assert back == d and back.c_z_mm == 161.5 and list(back.q0) == [0.1, -0.2, 0.0, 0.05, -0.05]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(PLACED.to_dict()))  # a file written before c_z, mode and q0 existed
    plain = Design.from_json(old)
    assert (
        plain == PLACED
        and plain.c_z is None
        and plain.c_z_mm == PLACED["d_z"]
        and plain.mode is None
        and plain.q0_deg is None
    )
    assert list(plain.q0) == [0.0] * 5 and json.loads((tmp_path / "d.json").read_text()).keys() >= set(PARAM_NAMES)
    assert (
        d.replace(m_x=90.0).q0_deg == d.q0_deg and d.replace(m_x=90.0).c_z == 161.5
    )  # a changed parameter keeps the rest


@pytest.mark.parametrize(
    "extra, message",
    [
        ({"c_z": 0.0}, "c_z (the z dyad's second link) must be a positive length"),
        ({"c_z": "long"}, "c_z is not a number"),
        ({"mode": "+,+"}, "working mode must be four signs"),
        ({"mode": 4}, "mode must be text"),
        ({"q0_rho_x": 0.1}, "needs all five zero offsets"),
        ({**dict.fromkeys(Q0_KEYS, 0.0), "q0_rho_y": 270.0}, "within +-180 deg"),
        ({"zdyad_elbow": 0}, "zdyad_elbow must be +1 or -1"),
    ],
)
def test_bad_extras_are_one_line_naming_the_file(tmp_path: Path, extra: dict, message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({**PLACED.to_dict(), **extra}))
    with pytest.raises(InputError, match=re.escape(message)) as info:
        Design.from_json(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_commands_take_the_mode_from_the_design_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "minus.json"
    PLACED.with_extras(mode="+,+,-,+").to_json(path)
    by_file = arcube.evaluate(path, "reference", side="R", points=4, engine="numpy")
    by_hand = arcube.evaluate(PLACED, "reference", side="R", points=4, engine="numpy", mode="+,+,-,+")
    paper_mode = arcube.evaluate(PLACED, "reference", side="R", points=4, engine="numpy")
    assert by_file.mode == "+,+,-,+" and paper_mode.mode == "+,+,+,+"
    np.testing.assert_array_equal(by_file.results.points.delta, by_hand.results.points.delta)
    assert not np.array_equal(
        np.nan_to_num(by_file.results.points.sigma), np.nan_to_num(paper_mode.results.points.sigma)
    )
    code, out, err = _run(["evaluate", "--design", str(path), "--side", "R", "--points", "4", "--json"], capsys)
    assert code == 0, err and json.loads(out)["mode"] == "+,+,-,+"
    assert json.loads(out)["mode"] == "+,+,-,+" and json.loads(out)["design"]["mode"] == "+,+,-,+"
    code, out, err = _run(
        ["evaluate", "--design", str(path), "--side", "R", "--points", "4", "--json", "--mode=+,+,+,+"], capsys
    )
    assert json.loads(out)["mode"] == "+,+,+,+"  # a given mode wins


def test_a_calibrated_design_commands_ik_less_q0_in_joints_and_program(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    q0 = (0.3, -0.2, 0.1, 0.25, -0.15)
    calibrated, programmed = tmp_path / "cal.json", tmp_path / "prog_cal.json"
    PLACED.with_extras(q0_deg=q0).to_json(calibrated)
    PROGRAMMED.with_extras(q0_deg=q0).to_json(programmed)
    plan = arcube.select(arcube.load_trajectories("reference"), side="R", ids="1")
    # joints: the CSV's actuated angles are the IK's (of the same parameters) less q0
    code, _, err = _run(
        [
            "joints",
            "--design",
            str(calibrated),
            "--side",
            "R",
            "--ids",
            "1",
            "--points",
            "5",
            "--out",
            str(tmp_path / "j.csv"),
        ],
        capsys,
    )
    assert code == 0, err
    rows = list(csv.DictReader((tmp_path / "j.csv").open()))
    task = arcube.evaluation.task.build_task(plan.entry, plan.target, 5, ids=plan.ids)
    sol = inverse_kinematics(PLACED.to_vector(), task.E, task.e)
    ik = np.degrees(np.concatenate([sol.rho, sol.delta], axis=-1))
    got = np.array([[float(r[f"{j}_deg"]) for j in ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")] for r in rows])
    np.testing.assert_allclose(got, ik - np.array(q0), rtol=0, atol=1e-9)
    assert [float(r["sigma_x_deg"]) for r in rows] == pytest.approx(
        np.degrees(sol.sigma[:, 0]), abs=1e-9
    )  # passive angles unchanged
    # program: every row's angles are the IK's at its pose less q0, and the MuJoCo replay drives the real joints (+ q0)
    prog = arcube.program(programmed, plan, tmp_path / "prog", dt=0.05)
    sol = inverse_kinematics(PROGRAMMED.to_vector(), prog.E, prog.e)
    ik = np.degrees(np.concatenate([sol.rho, sol.delta], axis=-1))
    diff = np.remainder(ik - np.array(q0) - prog.q_deg + 180.0, 360.0) - 180.0
    assert np.max(np.abs(diff)) < 1e-6 and prog.summary["q0_deg"]["rho_x"] == 0.3
    with open(tmp_path / "prog" / "program.csv", newline="") as fh:
        first = next(csv.DictReader(fh))
    assert float(first["rho_x"]) == pytest.approx(prog.q_deg[0, 0], abs=1e-9)
    from arcube.export.replay import export_program, read_program, recorded_design

    with pytest.raises(
        InputError, match="closes the z-leg dyad"
    ) as info:  # d_z alone cannot close it: the message names the range
        export_program(tmp_path / "prog")
    lo, hi = (float(v) for v in str(info.value).split("[")[1].split("]")[0].split(","))
    c_z = 0.5 * (lo + hi)
    recorded = recorded_design(read_program(tmp_path / "prog"))
    assert recorded is not None and recorded.c_z is None
    replay = export_program(tmp_path / "prog", recorded.with_extras(c_z=c_z))
    lines = replay.replay_csv.splitlines()
    header, row0 = lines[0].split(","), lines[1].split(",")
    target = float(row0[header.index("ctrl_rho_x")])
    assert np.degrees(target) == pytest.approx(prog.q_deg[0, 0] + q0[0], abs=1e-9)
    # a design without the offsets does not run the calibrated program
    with pytest.raises(InputError, match="does not run this program"):
        export_program(tmp_path / "prog", PROGRAMMED.with_extras(c_z=c_z))
