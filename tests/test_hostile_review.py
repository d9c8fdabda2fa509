"""What a hostile-input review of the newer commands found (2026-11-28), each held: an internal error for a
standoff of 0, a design JSON with a key given twice (the last copy silently won), and ``arcube patients``
writing over a user's file."""

from __future__ import annotations

from pathlib import Path

import pytest

from arcube.calibrate.settings import PoseSettings
from arcube.errors import InputError
from arcube.io.inputs import parse_json
from arcube.motion.limits import ProgramLimits
from harness import run_cli


@pytest.mark.parametrize("make", [lambda s: ProgramLimits(standoff_mm=s), lambda s: PoseSettings(standoff=s)])
def test_a_standoff_of_zero_is_refused_a_small_one_taken(make) -> None:
    """A standoff of 0 puts the standoff pose on the entry without anatomy: an approach of length 0, which the
    program's spline (and the poses' approach line) cannot take; it was an internal error."""
    with pytest.raises(InputError, match="standoff"):
        make(0.0)
    assert make(0.5) is not None


@pytest.mark.parametrize("argv", [["program", "--out", "p"], ["calibrate", "poses", "--out", "p.csv"]])
def test_the_commands_refuse_a_standoff_of_zero_in_one_line(tmp_path: Path, monkeypatch, capsys, argv) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli([*argv, "--design", "paper", "--trajectories", "reference", "--standoff", "0"], capsys)
    assert code == 2 and err == "error: --standoff must be > 0, got 0.0\n", err
    assert list(tmp_path.iterdir()) == []


def test_a_json_key_given_twice_is_refused_naming_it() -> None:
    def fail(problem: str) -> InputError:
        return InputError(f"d.json: {problem}")

    assert parse_json('{"a": 1, "b": {"a": 2}}', fail) == {"a": 1, "b": {"a": 2}}  # the same key in two objects
    with pytest.raises(InputError, match=r'^d.json: key "f_x" appears more than once in one object'):
        parse_json('{"f_x": 1.0, "g": 2, "f_x": 3.0}', fail)
    with pytest.raises(InputError, match=r'key "r" appears more than once'):
        parse_json('[{"dockings": [{"r": 1, "r": 1}]}]', fail)  # nested, and the same value twice


def test_a_design_file_with_a_key_twice_is_refused_by_the_command_line(tmp_path: Path, monkeypatch, capsys) -> None:
    from arcube.model.design import Design

    monkeypatch.chdir(tmp_path)
    Design.paper().to_json(tmp_path / "d.json")
    text = (tmp_path / "d.json").read_text()
    (tmp_path / "d.json").write_text(text.replace("{", '{"f_x": 1.0,', 1))
    code, _, err = run_cli(["evaluate", "--design", "d.json", "--trajectories", "reference", "--points", "2"], capsys)
    assert code == 2 and err.count("\n") == 1 and 'd.json: key "f_x" appears more than once' in err, err


def test_patients_do_not_replace_a_file_without_force(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.csv").write_text("precious\n")
    code, _, err = run_cli(["patients", "--seed", "1", "--out", "p.csv"], capsys)
    assert code == 2 and err == "error: --out p.csv: p.csv exists; give --force to replace it\n", err
    assert (tmp_path / "p.csv").read_text() == "precious\n" and sorted(f.name for f in tmp_path.iterdir()) == ["p.csv"]
    # a file beside the plan (its anatomy) counts too; --force replaces them all
    (tmp_path / "p.csv").unlink()
    (tmp_path / "p.anatomy.stl").write_text("mine\n")
    assert run_cli(["patients", "--seed", "1", "--out", "p.csv"], capsys)[0] == 2
    assert (tmp_path / "p.anatomy.stl").read_text() == "mine\n" and not (tmp_path / "p.csv").exists()
    assert run_cli(["patients", "--seed", "1", "--out", "p.csv", "--force"], capsys)[0] == 0
    assert (tmp_path / "p.anatomy.stl").read_bytes() != b"mine\n" and (tmp_path / "p.csv").exists()


def test_patients_into_a_folder_already_holding_a_cohort_need_force(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert run_cli(["patients", "--seed", "1", "--count", "2", "--out", "c"], capsys)[0] == 0
    before = {f.name: f.read_bytes() for f in (tmp_path / "c").iterdir()}
    code, _, err = run_cli(["patients", "--seed", "2", "--out", "c"], capsys)
    assert code == 2 and "c/patient_000.csv exists; give --force" in err, err
    assert {f.name: f.read_bytes() for f in (tmp_path / "c").iterdir()} == before


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--count", "2", "--out", "two.csv"], "--out two.csv: a .csv path holds one patient; give a folder for 2"),
        (["--count", "10001", "--out", "many"], "--count 10001: at most 10000 patients in one folder"),
    ],
)
def test_patients_refuse_an_out_or_count_that_cannot_be_meant(tmp_path: Path, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(["patients", "--seed", "1", *argv], capsys)
    assert code == 2 and err == f"error: {needle}\n", err
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- one patient given twice


def _plan_copies(tmp_path: Path) -> None:
    """plans/a.csv and plans/b.csv: the reference patient's right side, the same numbers in two files."""
    from designs import reference_right_csv

    lines = reference_right_csv()
    (tmp_path / "plans").mkdir()
    for name in ("a", "b"):
        (tmp_path / "plans" / f"{name}.csv").write_text("\n".join(lines) + "\n")
    lines[1] = lines[1].replace(lines[1].split(",")[3], "1.5", 1)  # one entry moved: another patient
    (tmp_path / "plans" / "c.csv").write_text("\n".join(lines) + "\n")


def _cohort(path: Path, **plans: str) -> Path:
    path.write_text(
        "".join(f'[[patient]]\nname = "{n}"\nplan = "plans/{p}.csv"\nanatomy = ["none"]\n' for n, p in plans.items())
    )
    return path


def test_a_cohort_refuses_one_plan_under_two_names_and_takes_two_patients(tmp_path: Path) -> None:
    """Hostile-input review: the same patient under two names counted twice in the coverage."""
    from arcube.design_job.cohort import read_cohort

    _plan_copies(tmp_path)
    with pytest.raises(InputError, match=r"patient 2 \(q\): plan: the same trajectories .* as patient 1 \(p\)") as info:
        read_cohort(_cohort(tmp_path / "twice.toml", p="a", q="b"))  # two files, one geometry
    assert info.value.param == "cohort"
    assert [p.name for p in read_cohort(_cohort(tmp_path / "two.toml", p="a", q="c"))] == ["p", "q"]


def test_a_held_out_cohort_is_refused_when_it_renames_a_training_patient(tmp_path: Path) -> None:
    """--validate compared names only: the training patients renamed passed as held-out ones."""
    from arcube.design_job.cohort import read_cohort
    from arcube.design_job.held_out import check_held_out
    from arcube.optimization.settings import RunSettings

    _plan_copies(tmp_path)
    training = read_cohort(_cohort(tmp_path / "train.toml", p="a"))
    with pytest.raises(InputError, match="patient 'q' has the trajectories of training patient 'p'") as info:
        check_held_out(_cohort(tmp_path / "held.toml", q="b"), training, RunSettings())
    assert info.value.param == "validate"
    assert check_held_out(_cohort(tmp_path / "other.toml", q="c"), training, RunSettings()).endswith("other.toml")
    with pytest.raises(InputError, match="^validate .*nosuch.toml: no such file") as info:
        check_held_out(tmp_path / "nosuch.toml", training, RunSettings())  # the file named as --validate's
    (tmp_path / "twice.toml").write_text(_cohort(tmp_path / "t.toml", q="b", r="c").read_text().replace('"r"', '"q"'))
    for bad in ("twice.toml", "t.toml"):  # a name given twice; a key the file does not take
        if bad == "t.toml":
            (tmp_path / bad).write_text("oops = 1\n")
        with pytest.raises(InputError) as info:
            check_held_out(tmp_path / bad, training, RunSettings())
        assert info.value.param == "validate", info.value


# ----------------------------------------------------------------------------- messages that name the user's flag


def test_advice_and_settings_in_messages_are_the_commands_flags(tmp_path: Path, monkeypatch, capsys) -> None:
    """The review: dock's seed was named RunSettings.seed; breach advised "(side)"; calibrate advised a side it did not
    take (it now takes a robot's docking on --side, as evaluate, program and tolerance do)."""
    import json

    monkeypatch.chdir(tmp_path)
    robot = Path(__file__).parent / "data" / "one_robot.json"
    code, _, err = run_cli(
        ["dock", "--robot", str(robot), "--trajectories", "reference", "--seed", "-1", "--out", "d"], capsys
    )
    assert code == 2 and err == "error: --seed must be >= 0, got -1\n", err
    data = json.loads(robot.read_text())
    data["dockings"] = [d for d in data["dockings"] if d["side"] == "R"]
    (tmp_path / "r_only.json").write_text(json.dumps(data))
    # a robot with no docking of the plan's left side is docked there first, and says so (issue "Breach II": it was
    # refused, advising --side R; before that, it drilled from another docking)
    code, out, err = run_cli(
        ["breach", "--design", "r_only.json", "--trajectories", "reference", "--samples", "100"]
        + ["--dock-evaluations", "200", "--out", "b"],
        capsys,
    )
    assert code in (0, 3) and "note: side L: r_only.json has no docking of this plan: docking the robot first" in err
    assert "side L: docked anew as arcube dock docks it (seed 1)" in out, out
    argv = ["calibrate", "poses", "--design", str(robot), "--trajectories", "reference", "--side", "R"]
    code, _, err = run_cli([*argv, "--points", "3", "--count", "12", "--around", "1", "--out", "p.csv"], capsys)
    assert code == 0 and (tmp_path / "p.csv").is_file(), err
    assert (
        run_cli(
            ["calibrate", "simulate", "--design", str(robot), "--side", "R", "--poses", "p.csv", "--out", "m.csv"],
            capsys,
        )[0]
        == 0
    )
    code, _, err = run_cli(
        ["calibrate", "simulate", "--design", str(robot), "--side", "L", "--poses", "p.csv", "--out", "n.csv"], capsys
    )
    assert code == 2 and "chosen for another design" in err, err  # the other side's docking is another design


@pytest.mark.parametrize(
    "command", [["export", "--out", "e.xml"], ["program", "--out", "p"], ["calibrate", "poses", "--out", "p.csv"]]
)
def test_a_mistyped_anatomy_frame_is_refused_without_an_anatomy_too(
    tmp_path: Path, monkeypatch, capsys, command
) -> None:
    """The review: --anatomy-frame XYZ passed silently where no --anatomy was given (dock refused it)."""
    monkeypatch.chdir(tmp_path)
    argv = [*command, "--design", "paper", "--trajectories", "reference", "--anatomy-frame", "XYZ"]
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and err == "error: --anatomy-frame 'XYZ': expected one of LPS, RAS, patient\n", err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "edit, needle",
    [
        (lambda d: d["dockings"][0].update(side="X"), "docking 1: side 'X': expected R, L or both"),
        (lambda d: d["dockings"][0].update(foo=1), "docking 1: unknown key 'foo'"),
        (
            lambda d: d["dockings"].append(dict(d["dockings"][0])),
            "docking 3: the same patient, side and placement as docking 1",
        ),
    ],
)
def test_a_robot_file_with_a_docking_that_cannot_be_meant_is_refused(tmp_path: Path, edit, needle) -> None:
    """The review: dock --robot and breach --design took a docking of side "X", an unknown key in a docking, and one
    docking twice."""
    import json

    from arcube.model.robot import read_robot

    data = json.loads((Path(__file__).parent / "data" / "one_robot.json").read_text())
    assert len(read_robot(Path(__file__).parent / "data" / "one_robot.json").starts) == 2
    edit(data)
    (tmp_path / "robot.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=needle):
        read_robot(tmp_path / "robot.json")


def test_a_tolerance_or_a_body_size_beyond_a_metre_or_a_thousand_degrees_is_refused() -> None:
    """The review: --tol r=1e9, --docking-deg 1e9, --q0-deg 1e9 and --link-radius 1e9 were taken (a p95 of inf)."""
    from arcube.accuracy.settings import ToleranceSettings, parse_tol
    from arcube.options import Body, Guards

    assert parse_tol("r=1000") == {"r": 1000.0}
    with pytest.raises(InputError, match=">= 0 and at most 1000"):
        parse_tol("r=1e9")
    # the docking angles at most a quarter turn (Hardening IV: --docking-deg 720 was taken)
    for field, most in (("docking_deg", 90.0), ("q0_deg", 1000.0), ("docking_mm", 1000.0)):
        assert getattr(ToleranceSettings(**{field: most}), field) == most
        with pytest.raises(InputError, match=field):
            ToleranceSettings(**{field: 1e9 if most > 90 else 720.0})
    assert Body(link_radius=1000.0).link_radius == 1000.0
    with pytest.raises(InputError, match="link_radius"):
        Body(link_radius=1e9)
    with pytest.raises(InputError, match="clearance_mm"):
        Guards(clearance_mm=1001.0)


@pytest.mark.parametrize("command", [["export", "--out", "e.xml"], ["calibrate", "poses", "--out", "p.csv"]])
def test_segments_without_an_anatomy_are_refused_not_ignored(tmp_path: Path, monkeypatch, capsys, command) -> None:
    """The review: export and calibrate poses ignored --segments C3 given without --anatomy (program refused it)."""
    monkeypatch.chdir(tmp_path)
    argv = [*command, "--design", "paper", "--trajectories", "reference", "--segments", "C3"]
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and err == "error: --segments needs an anatomy (a segmentation file, or 'default')\n", err
    assert list(tmp_path.iterdir()) == []
