"""The second list of a hostile-input review (2026-11-28), each held: flags that a command ignored without a word
(``--side`` with nothing to keep to a side, ``--class`` with a calibration), a calibration folder whose design was
replaced, one patient given twice as two plans, a program folder whose two files disagree, values no robot has, and
messages that named a staging folder or said "not a folder" twice."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from designs import DEMO, program_object, reference_right_csv

from arcube.calibrate.output import covariance_csv
from arcube.errors import InputError
from arcube.io.program_files import JSON_NAME, read_program_files
from arcube.model.design import Design
from arcube.model.robot import design_at_side
from arcube.options import Loads
from harness import run_cli


def _error(argv: list[str], capsys) -> str:
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (code, err)
    return err


def test_a_side_that_nothing_would_use_is_refused(tmp_path: Path) -> None:
    """A plain design has no side, and simulate has no plan: before, ``--side L`` (even ``--side X``) was ignored."""
    with pytest.raises(InputError, match="the side would be ignored") as info:
        design_at_side("paper", "R", alone=True)
    assert info.value.param == "side"
    with pytest.raises(InputError, match="R: the design has no side"):
        design_at_side(Design.paper(), "R", alone=True)
    with pytest.raises(InputError, match="'X': expected R or L"):
        design_at_side("paper", "X")
    assert design_at_side("paper", "R") == "paper"  # a plan filters by the side: not alone
    docking = tmp_path / "d.json"
    docking.write_text(json.dumps({**DEMO.to_file_dict(), "patient": "p", "side": "R"}))
    assert design_at_side(docking, "R", alone=True) == docking  # a docking of that side uses it
    with pytest.raises(InputError, match="is the docking of side R"):
        design_at_side(docking, "L", alone=True)


@pytest.mark.parametrize(
    "argv, says",
    [
        (
            ["calibrate", "simulate", "--poses", "none.csv", "--out", "m.csv", "--side", "L"],
            "--side L: paper has no side",
        ),
        (
            ["calibrate", "simulate", "--poses", "none.csv", "--out", "m.csv", "--side", "X"],
            "--side 'X': expected R or L",
        ),
        (
            ["calibrate", "identify", "--measurements", "none.csv", "--out", "o", "--side", "R"],
            "--side R: paper has no side",
        ),
        (
            [
                "calibrate",
                "identify",
                "--measurements",
                "none.csv",
                "--out",
                "o",
                "--side",
                "R",
                "--trajectories",
                "reference",
            ],
            "none.csv",  # with a plan, the side filters it: the command goes on to the (missing) measurements
        ),
    ],
)
def test_calibrate_refuses_a_side_it_would_ignore(tmp_path: Path, monkeypatch, capsys, argv, says) -> None:
    monkeypatch.chdir(tmp_path)
    err = _error([*argv, "--design", "paper"], capsys)
    assert err.startswith(f"error: {says}"), err
    assert list(tmp_path.iterdir()) == []


def _calibration_folder(folder: Path, design: dict, identified: dict | None) -> Path:
    folder.mkdir()
    (folder / "design.json").write_text(json.dumps(design))
    info = {"settings": {"encoder_deg": 0.0, "backlash_arcmin": 0.0}}
    (folder / "calibration.json").write_text(json.dumps(info if identified is None else {**info, "design": identified}))
    (folder / "covariance.csv").write_text(
        covariance_csv([[0.01 if i == j else 0.0 for j in range(31)] for i in range(31)])
    )
    return folder


def test_a_calibration_folder_whose_design_was_replaced_is_refused(tmp_path: Path) -> None:
    from arcube.pedicles.run import read_calibration

    own = DEMO.to_file_dict()
    design, _, _ = read_calibration(_calibration_folder(tmp_path / "same", own, own))
    assert design.to_dict() == DEMO.to_dict()
    read_calibration(_calibration_folder(tmp_path / "old", own, None))  # a calibration.json without its design
    swapped = _calibration_folder(tmp_path / "swapped", Design.paper().to_file_dict(), own)
    with pytest.raises(InputError, match=r"design.json: is not the design that calibration.json identified"):
        read_calibration(swapped)
    one = _calibration_folder(tmp_path / "one", {**own, "r": own["r"] + 0.5}, own)
    with pytest.raises(InputError, match=r"\(r differ\)"):
        read_calibration(one)


def test_breach_refuses_tolerances_beside_a_calibration(tmp_path: Path, monkeypatch, capsys) -> None:
    """The calibration's covariance draws the robot's errors: ``--class`` and ``--tol`` were silently dropped."""
    from arcube.accuracy import ToleranceSettings
    from arcube.pedicles import breach

    monkeypatch.chdir(tmp_path)
    err = _error(
        ["breach", "--calibration", "cal", "--class", "f", "--trajectories", "reference", "--side", "R", "--out", "o"],
        capsys,
    )
    assert err.startswith("error: --calibration and --class: ") and "give one" in err, err
    err = _error(
        ["breach", "--calibration", "cal", "--encoder-deg", "0.1", "--trajectories", "reference", "--out", "o"], capsys
    )
    assert err.startswith("error: --calibration and --encoder-deg: "), err
    with pytest.raises(InputError, match="its covariance gives the robot's errors") as info:
        breach(None, "reference", calibration="cal", tolerances=ToleranceSettings())
    assert info.value.param == "tolerances"
    assert list(tmp_path.iterdir()) == []


def test_one_patient_given_as_two_plans_is_refused(tmp_path: Path) -> None:
    """``design --trajectories a.csv b.csv`` of one patient counted it twice (a cohort file was already checked)."""
    from arcube.design_job.cohort import plans_as_cohort

    (tmp_path / "a.csv").write_text("\n".join(reference_right_csv()) + "\n")
    (tmp_path / "b.csv").write_text("\n".join(reference_right_csv()) + "\n")
    with pytest.raises(InputError, match=r"b.csv \(plan 2\): the same trajectories .* as plan 1 \(.*a.csv\)") as info:
        plans_as_cohort([str(tmp_path / "a.csv"), str(tmp_path / "b.csv")])
    assert info.value.param == "plan"
    with pytest.raises(InputError, match="plan 3"):
        plans_as_cohort(["reference", str(tmp_path / "a.csv"), "reference"])
    two = plans_as_cohort(["reference", str(tmp_path / "a.csv")])  # the whole patient and its right side differ
    assert [p.name for p in two] == ["reference", "a"]
    from arcube.io import load_trajectories, select

    ts = load_trajectories("reference")  # plans in memory, as arcube.dock and arcube.design take them
    assert len(plans_as_cohort([ts, select(ts, side="R")])) == 2
    with pytest.raises(InputError, match=r"reference \(plan 2\): the same trajectories"):
        plans_as_cohort([ts, load_trajectories("reference")])


def test_a_program_folder_whose_files_disagree_is_refused(tmp_path: Path) -> None:
    prog = program_object()
    prog.write(tmp_path / "p")
    summary = json.loads((tmp_path / "p" / JSON_NAME).read_text())
    for rows, ok in ((len(prog.t_s), True), (len(prog.t_s) + 1, False), (10**9, False)):
        (tmp_path / "p" / JSON_NAME).write_text(json.dumps({**summary, "rows": rows}))
        if ok:
            assert len(read_program_files(tmp_path / "p").t_s) == rows
        else:
            with pytest.raises(InputError, match=rf"rows is {rows}, but program.csv has {len(prog.t_s)}"):
                read_program_files(tmp_path / "p")


def test_a_bad_mode_in_a_program_is_the_programs_fault_not_the_flags(tmp_path: Path) -> None:
    import dataclasses

    from arcube.export.replay import export_program

    prog = program_object()
    bad = dataclasses.replace(prog, summary={**prog.summary, "mode": "x,y"})
    with pytest.raises(InputError, match=r"the program's summary: mode: working mode must be four signs") as info:
        export_program(bad, "paper")
    assert info.value.param == "program"
    listed = dataclasses.replace(prog, summary={**prog.summary, "mode": [1, 1, 1, -1]})
    with pytest.raises(InputError, match=r"mode: must be text like '\+,\+,-,\+', got list"):
        export_program(listed, "paper")


def test_time_that_does_not_increase_is_shown_as_a_plain_number(tmp_path: Path) -> None:
    prog = program_object()
    prog.write(tmp_path / "p")
    lines = (tmp_path / "p" / "program.csv").read_text().splitlines()
    t = lines[0].split(",").index("t_s")
    cells = lines[3].split(",")
    cells[t] = lines[2].split(",")[t]
    lines[3] = ",".join(cells)
    (tmp_path / "p" / "program.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"program.csv row 4: t_s must increase .*, got 0\.01$"):
        read_program_files(tmp_path / "p")


def test_actuator_values_no_robot_has_are_refused() -> None:
    from arcube.options import MAX_ENCODER_DEG, MAX_STIFFNESS

    assert Loads(actuator_stiffness=MAX_STIFFNESS, encoder_deg=MAX_ENCODER_DEG).encoder_deg == (MAX_ENCODER_DEG,) * 5
    assert Loads(actuator_stiffness=[1e4, 2e4, 3e4, 4e4, 5e4]).actuator_stiffness[4] == 5e4
    for changes in ({"actuator_stiffness": 1e300}, {"encoder_deg": 20.0}, {"encoder_deg": [0.01] * 4 + [11.0]}):
        with pytest.raises(InputError, match=r"must be one or five finite numbers > 0 and <= "):
            Loads(**changes)


def test_a_mounting_angle_beyond_a_turn_is_refused() -> None:
    values = DEMO.to_dict()
    assert Design.from_dict({**values, "mount_rx": -360.0}).to_dict()["mount_rx"] == -360.0
    with pytest.raises(InputError, match=r"mounting angle mount_rx must lie within ±360 deg, got 1e\+06"):
        Design.from_dict({**values, "mount_rx": 1e6})


def test_out_messages_say_what_stands_there(tmp_path: Path) -> None:
    from arcube.io.files import write_folder
    from arcube.motion.output import prepare_folder

    if os.path.exists("/dev/null"):
        with pytest.raises(InputError, match=r"^out /dev/null: is a character device, not a folder$"):
            prepare_folder("/dev/null")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    (tmp_path / "link").symlink_to(tmp_path / "full")
    with pytest.raises(InputError, match=r"link: is a link, not a folder"):
        write_folder({"a": b"1"}, tmp_path / "link")
    with pytest.raises(InputError, match=r"x: is a file, not a folder"):
        write_folder({"a": b"1"}, tmp_path / "full" / "x")
    with pytest.raises(InputError, match=r"^out .*x/new/t: cannot create \(.*x is a file, not a folder\)$") as info:
        write_folder({"a": b"1"}, tmp_path / "full" / "x" / "new" / "t")  # named, not the temporary folder beside it
    assert info.value.param == "out" and sorted(os.listdir(tmp_path / "full")) == ["x"]


def test_patients_name_the_file_not_their_staging_folder(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = _error(
        ["patients", "--seed", "1", "--anatomy-format", "seg.nrrd", "--anatomy-spacing-mm", "100", "--out", "pa"],
        capsys,
    )
    assert err.startswith(f"error: {Path('pa') / 'patient_000.anatomy.seg.nrrd'}: segment") and ".tmp" not in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_plan_in_metres_is_refused_a_one_millimetre_trajectory_taken(tmp_path: Path) -> None:
    """The reference plan written in metres (trajectories of some hundredths) was evaluated as a plan in mm."""
    from arcube.io import load_trajectories

    lines = reference_right_csv()
    metres = [lines[0]] + [
        ",".join(c[:3] + [repr(float(v) / 1000.0) for v in c[3:]]) for c in (r.split(",") for r in lines[1:])
    ]
    (tmp_path / "m.csv").write_text("\n".join(metres) + "\n")
    with pytest.raises(InputError, match=r"m.csv row 2: the trajectory is 0.0\d+ mm long, shorter than any screw"):
        load_trajectories(tmp_path / "m.csv")
    head = "trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z\n"
    (tmp_path / "one.csv").write_text(head + "1,C3,R,0,0,0,0,0,1\n")
    assert load_trajectories(tmp_path / "one.csv").lengths[0] == 1.0


@pytest.mark.parametrize(
    "argv, says",
    [
        (["optimize", "--bounds", "d_x=40:50,d_x=60:70"], "error: --bounds d_x: given twice"),
        (
            ["optimize", "--bounds", "d_x=40:50", "--free", "m_x"],
            "error: --bounds d_x: not free, so its bound would be ignored",
        ),
        (
            ["optimize", "--bounds", "mount_rx=-720:720", "--free", "all,mount"],
            "error: --bounds mount_rx: mounting angles must stay within ±360 deg",
        ),
        (
            ["optimize", "--objectives", "eta_G,mass", "--algorithm", "ga"],
            "error: --algorithm ga and --objectives eta_G,mass: 2 objectives are searched by nsga2",
        ),
        (
            ["study", "--seeds", "1-2", "--objectives", "eta_G,mass", "--algorithm", "ga"],
            "error: --algorithm ga and --objectives",
        ),
        (
            ["optimize", "--dockings", "per-side", "--placement", "shared"],
            "error: --dockings gives every docking its own placement: it needs --setups 1 and --placement per-patient",
        ),
        (
            ["optimize", "--setups", "2", "--side", "R"],
            "error: --setups 2 uses both sides (one placement each); leave --side out",
        ),
        (["tolerance", "--design", "paper", "--tol", "r=0.02,r=0.03"], "error: --tol 'r=0.03': r is given twice"),
        (["joints", "--encoder-deg", "5"], "error: No such option: --encoder-deg"),  # joints ignored it
        (["joints", "--envelope-clearance", "5"], "error: No such option: --envelope-clearance"),  # no --envelope
    ],
)
def test_flags_given_twice_or_overridden_are_refused_naming_the_flags(
    tmp_path: Path, monkeypatch, capsys, argv, says
) -> None:
    """The last of two bounds or tolerances won without a word; --algorithm ga with two objectives ran NSGA-II; two
    messages advised a setting by its internal name (docking per-patient, drop side)."""
    monkeypatch.chdir(tmp_path)
    err = _error([*argv, "--trajectories", "reference", "--out", "o"], capsys)
    assert err.startswith(says), err
    assert list(tmp_path.iterdir()) == []
    if "--objectives" in argv:  # without --algorithm the objectives choose it, as before
        from arcube.optimization.settings import RunSettings

        assert RunSettings(objectives="eta_G,mass").algorithm == "nsga2"


def test_explore_refuses_server_flags_with_a_static_scene(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    err = _error(["explore", "--html", "x.html", "--port", "9999", "--save", "d.json", "--points", "2"], capsys)
    assert err == "error: --html writes a static scene, no app is served: leave --port, --save out\n", err
    assert list(tmp_path.iterdir()) == []


def test_a_bound_on_a_free_parameter_is_taken() -> None:
    from arcube.cli.optimize import run_settings
    from arcube.cli.projection import Given

    assert run_settings(Given({"run.bounds": "alpha_x=30:120"})).bounds == {"alpha_x": (30.0, 120.0)}  # free: all
    both = run_settings(Given({"run.bounds": "mount_rx=-360:360", "run.free": "all,mount"}))
    assert both.bounds["mount_rx"] == (-360.0, 360.0)


def test_explore_blames_a_bad_host_not_the_port() -> None:
    """``--host 'bad host'`` said "--port 8080 on bad host is in use or not available"."""
    import socket

    from arcube.explorer.app import check_port

    with pytest.raises(InputError, match=r"^host 'bad host': not an address to listen on") as info:
        check_port("bad host", 8080)
    assert info.value.param == "host"
    with socket.socket() as s:  # a port that is free now
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]
    check_port("127.0.0.1", free)
