"""Issue "Breach II", items 1-3 and 6: one truth per screw (model §16-17, 19.6, 22).

A breach figure comes from the robot docked at that patient, with the same "reached" as the docking's report:

* a screw whose trajectory the design job refuses (a guard: the transmission at its entry) has no P(breach),
  ``status = not_reached``, and the command exits 3 naming it (it was ``reached = yes`` with a P);
* a one-side docking on a two-sided plan leaves the other side's screws not reached (it printed P(breach) 100 %);
* a docking file of one patient is refused on another patient's plan (told by the trajectories, not the name);
  a robot's design.json on a new patient is docked first, and says so (it drilled from the reference dockings);
* a calibration records the docking it was measured at, and refuses another side;
* each screw names the source that decides it; ``--registration 0`` leaves the rotation on, as the help says.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.accuracy import ToleranceSettings
from arcube.calibrate.output import covariance_csv
from arcube.io import TrajectorySet, load_trajectories, select, write_csv
from arcube.model.robot import trajectory_digests, write_docking
from arcube.options import Loads
from arcube.pedicles.run import robot_dockings
from harness import cli_error, run_cli

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
PERFECT = ToleranceSettings(tol={"lengths": 0.0, "angles": 0.0, "q0": 0.0}, encoder_deg=0.0, backlash_arcmin=0.0)
MOVED = {"m_x": -35.0, "m_y": -3.0, "m_z": -19.0, "mount_rz": -4.0}
"""The right docking of the demo's robot moved by these (mm, deg): the transmission guard refuses trajectories 7 and 9
at their entry, while the robot still takes every isthmus pose (found by a scan of random moves)."""


def _right() -> TrajectorySet:
    return select(load_trajectories("reference"), side="R")


def _moved() -> arcube.Design:
    d = robot_dockings(ROBOT)["R"]
    return d.replace(**{k: d[k] + v for k, v in MOVED.items()})


def _shifted(dy: float = 3.0) -> TrajectorySet:
    """Another patient: the reference plan moved 3 mm cranially (the same names, other trajectories)."""
    ts = load_trajectories("reference")
    shift = np.array([0.0, dy, 0.0])
    return TrajectorySet(ts.ids, ts.levels, ts.sides, ts.entry + shift, ts.target + shift, "shifted", ts.pedicle)


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_trajectory_the_guards_refuse_has_no_breach_figure() -> None:
    design, plan = _moved(), _right()
    # the oracle: the guarded evaluation of arcube.evaluate (model §8.2), another entry point
    guarded = {t.id: t.reachable_fraction for t in arcube.evaluate(design, plan, guarded=True).per_trajectory()}
    refused = [i for i, f in guarded.items() if f < 1.0]
    assert refused == ["7", "9"]
    # the robot takes every isthmus pose: the Monte Carlo alone called all five reached (the defect)
    assert arcube.pedicles.breach(design, plan, samples=50).reached.all()
    r = arcube.breach(design, plan, samples=400)
    rows = {row["trajectory"]: row for row in r.rows()}
    for tid in plan.ids:
        if tid in refused:
            assert rows[tid]["status"] == "not_reached" and not rows[tid]["reached"]
            assert (
                all(math.isnan(rows[tid][k]) for k in ("p_breach", "p_breach_low", "p_major", "p_robot_alone"))
                and not rows[tid]["deciding_source"]
            )
        else:
            assert rows[tid]["status"] == "assessed" and 0.0 < rows[tid]["p_breach"] < 1.0
    s = r.summary()
    assert s["not_reached"] == refused and s["screws"] == 5 and s["reached"] == 3
    assert s["worst_screw"] not in refused and s["breach_probability"] == max(
        rows[t]["p_breach"] for t in ("1", "3", "5")
    )
    assert s["expected_breaches"] == pytest.approx(sum(rows[t]["p_breach"] for t in ("1", "3", "5")))
    assert "transmission" in r.settings["dockings"]["R"]["not_reached"]["7"]


def test_the_command_exits_3_naming_the_screws_not_reached(tmp_path: Path, capsys) -> None:
    _moved().to_json(tmp_path / "moved.json")
    write_csv(_right(), tmp_path / "right.csv")
    code, out, err = run_cli(
        ["breach", "--design", str(tmp_path / "moved.json"), "--mode", "+,+,-,+", "--trajectories"]
        + [str(tmp_path / "right.csv"), "--samples", "300", "--out", str(tmp_path / "b")],
        capsys,
    )
    assert code == 3, err
    assert err.strip().splitlines()[-1].endswith("screws 7, 9; they have no P(breach)"), err
    assert "over the 3 reached screws of 5" in out and "100.0 %" not in out
    rows = {r["trajectory"]: r for r in _rows(tmp_path / "b" / "breach.csv")}
    assert rows["7"]["status"] == "not_reached" and rows["7"]["p_breach"] == "" and rows["7"]["reached"] == "no"
    assert rows["1"]["status"] == "assessed" and rows["1"]["deciding_source"] in ("robot", "registration", "deflection")
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert summary["not_reached"] == ["7", "9"] and summary["screws"] == 5 and summary["breach_probability"] < 1.0


def _docking_file(folder: Path) -> Path:
    """The demo robot's right docking as ``arcube design`` writes it (patient, side, the plan's digests)."""
    folder.mkdir(parents=True, exist_ok=True)
    write_docking(robot_dockings(ROBOT)["R"], folder / "design.json", "reference", "R", _right())
    return folder / "design.json"


def test_a_one_side_docking_leaves_the_other_side_not_reached(tmp_path: Path, capsys) -> None:
    path = _docking_file(tmp_path / "dock")
    code, out, err = run_cli(
        ["breach", "--design", str(path), "--trajectories", "reference", "--samples", "300"]
        + ["--out", str(tmp_path / "b")],
        capsys,
    )
    assert code == 3 and "screws 2, 4, 6, 8, 10" in err, err
    assert "100.0 %" not in out and "over the 5 reached screws of 10" in out
    rows = _rows(tmp_path / "b" / "breach.csv")
    assert [r["status"] for r in rows] == ["assessed", "not_reached"] * 5
    assert all(r["p_breach"] == "" for r in rows if r["side"] == "L")
    assert "this plan's trajectories" in out


def test_a_docking_of_another_patient_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    path = _docking_file(tmp_path / "dock")
    write_csv(_shifted(), tmp_path / "other.csv")
    code, err = cli_error(
        ["breach", "--design", str(path), "--trajectories", "other.csv", "--side", "R", "--out", "out"], capsys
    )
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "not of this plan's side-R trajectories (5 of 5 differ)" in err and "patient reference" in err
    assert not (tmp_path / "out").exists()
    # the same plan written to a file and read back is the same patient (digests, not names)
    write_csv(_right(), tmp_path / "same.csv")
    assert arcube.breach(path, "same.csv", samples=50).summary()["reached"] == 5


def test_a_robot_on_a_new_patient_is_docked_first_and_says_so() -> None:
    told: list[str] = []
    plan = _shifted()
    r = arcube.breach(ROBOT, plan, side="R", samples=100, dock_evaluations=300, say=told.append)
    note = r.settings["dockings"]["R"]
    assert note["how"].startswith("docked anew as arcube dock docks it") and note["docking"] == "shifted_R"
    assert len(told) == 1 and "has no docking of this plan" in told[0]
    # on its own plan the robot's docking is found by the trajectories, and not docked again
    own = arcube.breach(ROBOT, "reference", side="R", samples=100, say=told.append)
    assert own.settings["dockings"]["R"]["how"] == "the robot file's docking reference_R (this plan's trajectories)"
    assert len(told) == 1
    # the lower level refuses a plan the robot has not docked on, instead of drilling from another patient's docking
    with pytest.raises(arcube.InputError, match="no docking of this plan's side-R trajectories"):
        robot_dockings(ROBOT, select(plan, side="R"))


def test_a_calibration_records_its_docking_and_refuses_another_side(tmp_path: Path, capsys) -> None:
    from arcube.calibrate.design_file import calibrated_dict, load_design

    path = _docking_file(tmp_path / "dock")
    start = load_design(path)
    assert start.labels == {
        "patient": "reference",
        "side": "R",
        "plan_digest": list(trajectory_digests(_right().entry, _right().target)),
    }
    cal = tmp_path / "cal"
    cal.mkdir()
    obj = calibrated_dict(start.vector, np.zeros(5), "+,+,-,+", start.c_z, start.labels)
    (cal / "design.json").write_text(json.dumps(obj))
    (cal / "calibration.json").write_text(
        json.dumps({"design": obj, "settings": {"encoder_deg": 0.0, "backlash_arcmin": 0.0}})
    )
    (cal / "covariance.csv").write_text(covariance_csv(np.eye(31) * 1e-4))
    code, err = cli_error(
        ["breach", "--calibration", str(cal), "--trajectories", "reference", "--side", "L"]
        + ["--out", str(tmp_path / "b")],
        capsys,
    )
    assert code == 2 and "--side" in err and "docking of side R" in err, err
    r = arcube.breach(None, "reference", calibration=cal, samples=100)
    assert [s for s in r.status] == ["assessed", "not_reached"] * 5


def test_a_robots_docking_and_side_are_recorded_by_identify(tmp_path: Path, capsys) -> None:
    """identify on a robot's design.json and a side writes design.json with that docking's patient, side and plan."""
    args = ["--design", str(ROBOT), "--side", "R"]
    assert (
        run_cli(
            ["calibrate", "poses", *args, "--trajectories", "reference", "--count", "30", "--points", "5"]
            + ["--around", "5", "--out", str(tmp_path / "poses.csv")],
            capsys,
        )[0]
        == 0
    )
    assert (
        run_cli(
            ["calibrate", "simulate", *args, "--poses", str(tmp_path / "poses.csv"), "--seed", "2"]
            + ["--out", str(tmp_path / "meas.csv")],
            capsys,
        )[0]
        == 0
    )
    code, _, err = run_cli(
        ["calibrate", "identify", *args, "--measurements", str(tmp_path / "meas.csv"), "--holdout", "0"]
        + ["--out", str(tmp_path / "id")],
        capsys,
    )
    assert code == 0, err
    written = json.loads((tmp_path / "id" / "design.json").read_text())
    assert written["patient"] == "reference" and written["side"] == "R"
    assert written["plan_digest"] == list(trajectory_digests(_right().entry, _right().target))


def test_the_deciding_source_is_the_one_whose_offsets_alone_breach_most() -> None:
    plan = _right()
    kw = {"tolerances": PERFECT, "samples": 400, "loads": Loads(thrust_N=0.0)}
    # a perfect robot, no thrust: the registration is the only source that moves the screw
    reg = arcube.pedicles.breach(robot_dockings(ROBOT)["R"], plan, registration_mm=0.3, registration_deg=0.3, **kw)
    assert set(reg.deciding) == {"registration"}
    assert reg.summary()["deciding_source"] == "registration"
    # tie-break: no source alone breaches (a tiny registration): the one that fills the room most still decides
    tiny = arcube.pedicles.breach(robot_dockings(ROBOT)["R"], plan, registration_mm=0.01, registration_deg=0.0, **kw)
    assert np.all(tiny.p_alone == 0.0) and set(tiny.deciding) == {"registration"}
    # a robot built to class c, no registration: the robot decides
    rob = arcube.pedicles.breach(
        robot_dockings(ROBOT)["R"],
        plan,
        tolerances=ToleranceSettings(tolerance_class="c"),
        registration_mm=0.0,
        registration_deg=0.0,
        samples=400,
        loads=Loads(thrust_N=0.0),
    )
    assert set(rob.deciding) == {"robot"}


def test_registration_0_turns_off_the_translation_only(capsys) -> None:
    plan = _right()
    kw = {"tolerances": PERFECT, "samples": 300, "loads": Loads(thrust_N=0.0)}
    d = robot_dockings(ROBOT)["R"]
    rotation = arcube.pedicles.breach(d, plan, registration_mm=0.0, registration_deg=0.5, **kw)
    off = arcube.pedicles.breach(d, plan, registration_mm=0.0, registration_deg=0.0, **kw)
    assert np.all(off.offset_p95_mm < 1e-9)  # both 0: nothing moves the screw of a perfect robot without thrust
    assert np.all(rotation.offset_p95_mm > 1e-3)  # --registration 0 alone: the rotation still moves every screw
    code, out, _ = run_cli(["breach", "--help"], capsys)
    text = " ".join(out.split())
    assert code == 0 and "0 turns the translation off" in text and "0 turns the rotation off" in text


def test_the_screws_as_slicer_markups_carry_their_verdict(tmp_path: Path, capsys) -> None:
    _moved().to_json(tmp_path / "moved.json")
    write_csv(_right(), tmp_path / "right.csv")
    args = ["breach", "--design", str(tmp_path / "moved.json"), "--mode", "+,+,-,+", "--trajectories"]
    args += [str(tmp_path / "right.csv"), "--samples", "300"]
    code, _, err = run_cli([*args, "--out", str(tmp_path / "b"), "--markups", str(tmp_path / "s.mrk.json")], capsys)
    assert code == 3, err
    back = load_trajectories(tmp_path / "s.mrk.json")  # the plan reads back from the markups
    np.testing.assert_allclose(back.entry, _right().entry, atol=1e-9)
    doc = json.loads((tmp_path / "s.mrk.json").read_text())
    rows = {r["trajectory"]: r for r in _rows(tmp_path / "b" / "breach.csv")}
    for m in doc["markups"]:
        text = m["controlPoints"][1]["description"]
        row = rows[m["name"]]
        assert f"status={row['status']}" in text and f"deciding={row['deciding_source'] or '-'}" in text
        if row["p_breach"]:
            assert text.startswith(f"P(breach)={100 * float(row['p_breach']):.1f}%;")
        else:
            assert "P(breach)" not in text
    # a markups file that exists, or is not a .mrk.json, is refused before any work (no folder written)
    for bad, needle in (("s.mrk.json", "exists"), ("s.json", "name a .mrk.json file")):
        code, err = cli_error([*args, "--out", str(tmp_path / "c"), "--markups", str(tmp_path / bad)], capsys)
        assert code == 2 and needle in err and err.count("\n") == 1, err
        assert not (tmp_path / "c").exists()


def test_the_docking_reports_scene_colours_each_screw_by_its_risk() -> None:
    from arcube.report.html import scene_figure

    ev = arcube.evaluate(robot_dockings(ROBOT)["R"], _right(), points=4)
    fig = scene_figure(ev, {"1": 0.9, "3": 0.1, "5": 0.5, "7": float("nan"), "9": 0.0})
    lines = [t for t in fig.data if t.name and t.name.startswith("screw ")]
    assert [t.name.split(" ")[1] for t in lines] == ["1", "5", "3", "9", "7"]  # the worst first, the unreached last
    assert lines[0].name == "screw 1 (C3 R): P(breach) 90.0 % (worst)" and "not reached" in lines[-1].name

    def rgb(t: object) -> list[float]:
        return [float(v) for v in t.line.color[4:-1].split(",")]

    red, green = rgb(lines[0]), rgb(lines[3])
    assert red[0] > red[1] and green[1] > green[0]  # high risk red, no risk green
    assert rgb(lines[-1])[0] == rgb(lines[-1])[1] == rgb(lines[-1])[2]  # grey: no figure
    plain = scene_figure(ev)  # without risk: the one cyan trace of before
    assert [t.name for t in plain.data][0] == "trajectories"


def test_a_one_side_docking_drills_its_side_with_its_own_registration(tmp_path: Path) -> None:
    """The review: a one-side docking file on a two-sided plan drilled both sides as one docking, its registration
    about the centroid of all ten entries; it is its side's docking, its registration about its own five."""
    path = _docking_file(tmp_path / "dock")
    both = arcube.breach(path, "reference", samples=100)
    alone = arcube.breach(path, "reference", side="R", samples=100)
    assert set(both.summary()["per_docking"]) == {"R", "L"}
    right = [j for j, s in enumerate(both.pedicles.sides) if s == "R"]
    np.testing.assert_array_equal(both.p_first_order[right], alone.p_first_order)  # deterministic: the same centre


def test_a_plain_design_without_c_z_is_judged_as_evaluate_judges_it() -> None:
    """The review: a design file without c_z had its z dyad judged with c_z = d_z, refusing every screw that
    arcube evaluate reaches."""
    design = Path(__file__).parent / "data" / "demo_design.json"
    plan = _right()
    r = arcube.breach(design, plan, samples=50)
    guarded = arcube.evaluate(design, plan, guarded=True)
    expected = [t.reachable_fraction == 1.0 for t in guarded.per_trajectory()]
    assert list(r.reached) == expected and any(expected)
    assert "z dyad not judged" in r.settings["dockings"]["R"]["how"]


def test_ids_with_a_comma_and_screws_without_a_side(tmp_path: Path, capsys) -> None:
    ts = _right()
    odd = TrajectorySet(tuple(f"C,{i}" for i in ts.ids), ts.levels, ts.sides, ts.entry, ts.target, "odd", ts.pedicle)
    r = arcube.breach(robot_dockings(ROBOT)["R"], odd, samples=50, mode="+,+,-,+")
    assert r.pedicles.ids == odd.ids and r.reached.all()
    write_csv(TrajectorySet(ts.ids, ts.levels, ("",) * 5, ts.entry, ts.target, "x", ts.pedicle), tmp_path / "p.csv")
    code, err = cli_error(
        ["breach", "--design", str(ROBOT), "--trajectories", str(tmp_path / "p.csv"), "--out", str(tmp_path / "b")],
        capsys,
    )
    assert code == 2 and "a screw needs its side (R or L)" in err and err.count("\n") == 1, err


def test_breach_csv_reached_is_the_docking_reports_table(tmp_path: Path) -> None:
    """One truth: a docking folder's report.html (its per-trajectory table) and its breach/breach.csv say the same of
    every screw. The moved docking: the transmission guard refuses trajectories 7 and 9 at their entry; the report
    says 0 %, breach.csv reached=no with no P."""
    import re

    from arcube.design_job.at_patient import _job, _settings
    from arcube.design_job.coverage import write_docking_folder
    from arcube.design_job.dock import DockingOutcome, docking_inputs
    from arcube.design_job.dockings import assess_dockings
    from arcube.model.robot import read_robot

    robot = read_robot(ROBOT)
    s, reqs = _settings({}, {}, "reference")
    _, dock, s_job, _ = docking_inputs(_job(robot, "reference", "reference", "R", s, reqs))
    dock.design = _moved()
    assess_dockings([dock], reqs, s_job)
    outcome = DockingOutcome("reference_R", "reference", "R", dock.design, dock.rows, None, 1.0, 0, 0.0, 1, "test")
    write_docking_folder(tmp_path / "d", outcome, dock, s_job, 1)
    html = (tmp_path / "d" / "report.html").read_text()
    table = html.split("<h3>Per trajectory</h3>", 1)[1]
    report = {m[0]: m[1] == "100" for m in re.findall(r"<tr><td>(\d+)</td><td>C\d</td><td>[RL]</td><td>(\d+) %", table)}
    rows = {r["trajectory"]: r for r in _rows(tmp_path / "d" / "breach" / "breach.csv")}
    assert set(report) == set(rows) == {"1", "3", "5", "7", "9"}
    assert {t for t, ok in report.items() if not ok} == {"7", "9"}
    for t, ok in report.items():
        assert rows[t]["reached"] == ("yes" if ok else "no") and (rows[t]["p_breach"] == "") == (not ok)
