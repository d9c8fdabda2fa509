"""arcube dock (MODEL.md 19.6): a built robot docked on patient sides it was not placed for, and its coverage.

Oracles: the NumPy reference re-checks every side reported met (``arcube evaluate`` on its docking file, and
:func:`arcube.evaluate` on its plan and approach lines with the robot's own c_z and the envelope); the robot in every
docking file is the given one, number for number; a patient moved by a known translation (plan, anatomy and envelope
together: the problem is then the same, moved) is docked at least as well as the robot's own docking, moved; the Wilson
interval against its definition (the proportions p whose score test does not reject p̂ at 95 %), solved by bisection;
the same seed gives the same dockings on a dask cluster as in one process.

The robot (tests/data/one_robot.json) is one ``arcube design --trajectories reference --anatomy default`` chose (seeds
1-3, the demo's last step): its design.json, the robot and its two dockings with their trajectories.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.design_job.coverage import binding_row, wilson
from arcube.design_job.dockings import PLACEMENT, ROBOT_NAMES
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.standoff import standoff_points
from arcube.io import select
from harness import arcube as run_arcube
from harness import cli_error

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
SMALL = ["--levels", "C3", "--points", "6", "--evaluations", "400", "--quiet"]
"""One trajectory a side, 6 points a line, 400 evaluations a side: a few seconds a side."""
DOCKED_LEVELS = ["--levels", "C3-C4"]
"""The plan of the ``docked`` fixture: two trajectories a side."""


@pytest.fixture(scope="module")
def docked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The robot docked on both sides of the reference patient, every default but two levels a side (C3-C4: two screws
    and the transit between them), 12 points a line and 1500 evaluations a side (the suite's time)."""
    root = tmp_path_factory.mktemp("dock")
    out = run_arcube(
        "dock",
        "--robot",
        str(ROBOT),
        "--trajectories",
        "reference",
        *DOCKED_LEVELS,
        "--out",
        "d",
        "--quiet",
        "--points",
        "12",
        "--evaluations",
        "1500",
        cwd=root,
    )
    assert out.returncode == 0, out.stdout + out.stderr  # every side served
    assert "the robot serves 2 of 2 sides" in out.stdout
    return root / "d"


def test_every_docking_file_holds_the_given_robot_unchanged(docked: Path) -> None:
    given = json.loads(ROBOT.read_text())
    summary = json.loads((docked / "summary.json").read_text())
    assert summary["robot"] == {n: given[n] for n in ROBOT_NAMES} and summary["mode"] == given["mode"]
    for d in summary["dockings"]:
        design = json.loads((docked / d["folder"] / "design.json").read_text())
        assert {n: design[n] for n in ROBOT_NAMES} == {n: given[n] for n in ROBOT_NAMES}
        assert design["mode"] == given["mode"] and {n: design[n] for n in PLACEMENT} == {n: d[n] for n in PLACEMENT}
        assert (design["patient"], design["side"]) == (
            d["patient"],
            d["side"],
        )  # the docking file says whose and which side


def test_the_summary_and_coverage_csv_agree_and_read_back(docked: Path) -> None:
    summary = json.loads((docked / "summary.json").read_text())
    assert (summary["sides"], summary["met"], summary["coverage"]) == (2, 2, 1.0)
    assert (summary["coverage_low"], summary["coverage_high"]) == pytest.approx(wilson(2, 2)[1:])
    keys = {"patient", "side", "meets_requirements", "missed", "binding", "binding_margin", *PLACEMENT}
    assert all(keys <= set(d) for d in summary["dockings"])
    with open(docked / "coverage.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["patient"], r["side"], r["met"]) for r in rows] == [("reference", "R", "yes"), ("reference", "L", "yes")]
    for r, d in zip(rows, summary["dockings"]):
        assert r["binding"] == d["binding"] and float(r["m_x"]) == pytest.approx(d["m_x"], abs=1e-6)
        assert None not in r.values() and None not in r  # the header's field count on every row
    assert (docked / "report.html").read_text().count("<svg") == 1
    from harness import assert_csvs_read_back

    assert assert_csvs_read_back(docked) >= 7  # coverage, and per side requirements, program, accuracy, breach
    for d in summary["dockings"]:
        assert (docked / d["folder"] / "program" / "program.json").exists() and (
            docked / d["folder"] / "report.html"
        ).exists()


def test_a_side_reported_met_is_met_when_the_numpy_reference_checks_it(docked: Path, tmp_path: Path) -> None:
    """Every side: its docking file, evaluated by ``arcube evaluate`` (the NumPy reference, the mode and c_z read from
    the file) on its plan, and by arcube.evaluate on its plan and approach lines with the envelope placed on the whole
    plan: every point reached, every guard passed, clearance >= 5, self clearance >= 2, envelope clearance >= 10 mm, the
    z dyad closed with the robot's c_z, and the accuracy and torque within their limits on the plan."""
    summary = json.loads((docked / "summary.json").read_text())
    whole = arcube.load_trajectories("reference")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    envelope = resolve_envelope(["default"], whole, anatomy)
    for d in summary["dockings"]:
        file = docked / d["folder"] / "design.json"
        ev = run_arcube(
            "evaluate",
            "--design",
            str(file),
            "--trajectories",
            "reference",
            *DOCKED_LEVELS,
            "--side",
            d["side"],
            "--anatomy",
            "default",
            "--guarded",
            "--clearance",
            "5",
            "--self-clearance",
            "2",
            "--engine",
            "numpy",
            "--json",
            "--points",
            "12",
            cwd=tmp_path,
        )
        assert ev.returncode == 0, ev.stderr
        doc = json.loads(ev.stdout)
        assert doc["summary"]["reachable_fraction"] == 1.0 and doc["summary"]["failures"] == {}
        assert doc["guards"]["c_z"] == json.loads(ROBOT.read_text())["c_z"]
        design = arcube.Design.load(file)
        side = select(whole, side=d["side"], levels=DOCKED_LEVELS[1])
        S, _ = standoff_points(side.entry, side.target, anatomy, 20.0)
        for what, entry, target in (("plan", side.entry, side.target), ("approach", S, side.entry)):
            lines = dataclasses.replace(side, entry=np.asarray(entry), target=np.asarray(target), source=what)
            s = arcube.evaluate(
                design,
                lines,
                points=12,
                guarded=True,
                engine="numpy",
                anatomy=anatomy,
                envelope=envelope,
                clearance=5.0,
                self_clearance=2.0,
                envelope_clearance_mm=10.0,
                z_dyad=True,
                c_z=design.c_z,
            ).summary
            assert s["reachable_fraction"] == 1.0 and s["failures"] == {}, (d["label"], what, s["failures"])
            assert (
                s["clearance_min_mm"] >= 5.0
                and s["self_clearance_min_mm"] >= 2.0
                and s["envelope_clearance_min_mm"] >= 10.0
            )
            if what == "plan":
                assert (
                    s["lateral_error_max_mm"] <= 0.5 and s["axis_error_max_deg"] <= 0.25 and s["torque_max_Nm"] <= 20.0
                )


def test_a_patient_moved_by_a_translation_is_docked_at_least_as_well(
    killed_then_docked: tuple[Path, bool, list[str], subprocess.CompletedProcess[str]], tmp_path: Path
) -> None:
    """The reference patient's plan and anatomy moved by t (the default envelope follows its landmarks): the robot's
    own right docking moved by t is as good there as at home, so the docking found is at least that good. At home:
    the fixture's docking of the right side, with the same flags as the moved one's."""
    t = np.array([35.0, -20.0, 15.0])
    plan = arcube.load_trajectories("reference")
    moved = dataclasses.replace(plan, entry=plan.entry + t, target=plan.target + t, source="moved")
    arcube.write_csv(moved, tmp_path / "moved.csv")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    anatomy.write_stl(tmp_path / "moved_source.stl")
    import trimesh

    mesh = trimesh.load(tmp_path / "moved_source.stl", force="mesh", process=False)
    mesh.apply_translation(t)
    mesh.export(tmp_path / "moved.anatomy.stl")
    out = run_arcube(
        "dock",
        "--robot",
        str(ROBOT),
        "--trajectories",
        "moved.csv",
        "--anatomy",
        "moved.anatomy.stl",
        "--anatomy-frame",
        "patient",
        "--out",
        "d",
        "--side",
        "R",
        *SMALL,
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    found = json.loads((tmp_path / "d" / "summary.json").read_text())["dockings"][0]
    home_root, _, _, home = killed_then_docked  # dock --robot ROBOT --trajectories reference --side R *SMALL
    assert home.returncode == 0, home.stdout + home.stderr
    at_home = json.loads((home_root / "d" / "summary.json").read_text())["dockings"][0]
    assert found["meets_requirements"] and found["eta_G"] <= at_home["eta_G"] + 1e-9


def test_wilson_interval_is_the_score_test_inverted() -> None:
    z = 1.959963984540054
    for k, n in ((0, 1), (0, 4), (3, 4), (19, 20), (76, 80), (80, 80), (5, 11)):
        p_hat, lo, hi = wilson(k, n)
        assert p_hat == k / n

        def rejects(p: float) -> bool:
            return abs(p_hat - p) > z * math.sqrt(p * (1 - p) / n)

        for bound, inside, outside in ((lo, min(p_hat, 1 - 1e-12), 0.0), (hi, max(p_hat, 1e-12), 1.0)):
            if bound in (0.0, 1.0) and bound == outside:
                continue  # the interval reaches the end: nothing beyond to reject
            a, b = inside, outside
            for _ in range(200):
                m = 0.5 * (a + b)
                a, b = (a, m) if rejects(m) else (m, b)
            assert bound == pytest.approx(a, abs=1e-9)
    assert wilson(0, 4)[2] == pytest.approx(z * z / (4 + z * z))  # by hand: k = 0 gives z^2 / (n + z^2)


def test_the_binding_requirement_is_the_tightest_relative_to_its_limit() -> None:
    rows = [
        {"requirement": "reach", "limit": 1.0, "margin": 0.0, "passed": True},
        {"requirement": "clearance", "limit": 5.0, "margin": 2.0, "passed": True},
        {"requirement": "torque", "limit": 20.0, "margin": 4.0, "passed": True},
    ]
    assert binding_row(rows)["requirement"] == "torque"  # 4/20 < 2/5; reach is a pass/fail row, never binding when met
    rows[1] = {**rows[1], "margin": -1.0, "passed": False}
    rows.append({"requirement": "lateral_error", "limit": 0.5, "margin": math.nan, "passed": False})
    assert (
        binding_row(rows)["requirement"] == "clearance"
    )  # a missed one first, a measured one before an unmeasured one


def test_dask_gives_the_dockings_one_process_gives(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        a = arcube.dock(
            str(ROBOT),
            "reference",
            tmp_path / "a",
            seed=3,
            evaluations=300,
            levels="C3",
            points=6,
            dask=cluster.scheduler_address,
        )
    b = arcube.dock(str(ROBOT), "reference", tmp_path / "b", seed=3, evaluations=300, levels="C3", points=6, workers=1)
    for x, y in zip(a.summary["dockings"], b.summary["dockings"]):
        assert {k: x[k] for k in (*PLACEMENT, "meets_requirements", "eta_G")} == {
            k: y[k] for k in (*PLACEMENT, "meets_requirements", "eta_G")
        }


@pytest.fixture(scope="module")
def killed_then_docked(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, bool, list[str], subprocess.CompletedProcess[str]]:
    """``arcube dock`` of both sides (SMALL) killed (SIGKILL) once its first side's stage is written, then the right
    side docked (SMALL) into the same --out: the folder they ran in, whether d/ existed and the stages left right
    after the kill, and the second command's outcome."""
    root = tmp_path_factory.mktemp("killed")
    cmd = [
        sys.executable,
        "-m",
        "arcube",
        "dock",
        "--robot",
        str(ROBOT),
        "--trajectories",
        "reference",
        "--out",
        "d",
        *SMALL,
    ]
    proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not any((s / "dockings").exists() for s in root.glob(".d.dock-*.tmp")):
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    out_after_kill, stages_after_kill = (root / "d").exists(), [s.name for s in root.glob(".d.dock-*.tmp")]
    done = run_arcube(
        "dock", "--robot", str(ROBOT), "--trajectories", "reference", "--out", "d", "--side", "R", *SMALL, cwd=root
    )
    return root, out_after_kill, stages_after_kill, done


def test_a_killed_dock_leaves_no_folder_and_the_next_one_cleans_up(
    killed_then_docked: tuple[Path, bool, list[str], subprocess.CompletedProcess[str]],
) -> None:
    root, out_after_kill, stages_after_kill, done = killed_then_docked
    assert not out_after_kill and stages_after_kill  # killed mid-way: no d/, its stage left
    assert done.returncode in (0, 3), done.stderr
    assert (root / "d" / "summary.json").exists() and not list(root.glob(".d.dock-*.tmp"))


@pytest.mark.parametrize(
    "make, args, needle",
    [
        (lambda p: p.write_text('{"mode": "+,+,+,+"}'), [], "not a robot: missing robot parameter(s)"),
        (
            lambda p: p.write_text(json.dumps({k: v for k, v in json.loads(ROBOT.read_text()).items() if k != "mode"})),
            [],
            "working mode is missing",
        ),
        (None, ["--starts", "0"], "--starts must be an integer >= 1"),
        (None, ["--evaluations", "5"], "--evaluations must be an integer >= 100"),
        (None, ["--cohort", "missing.toml"], "missing.toml: no such file"),
    ],
)
def test_bad_dock_input_is_one_line_exit_2_and_leaves_nothing(
    tmp_path: Path, monkeypatch, capsys, make, args, needle
) -> None:
    monkeypatch.chdir(tmp_path)
    robot = tmp_path / "robot.json"
    if make is not None:
        make(robot)
    plan = [] if "--cohort" in args else ["--trajectories", "reference"]
    code, err = cli_error(
        ["dock", "--robot", str(robot if make else ROBOT), *plan, "--out", "d", "--quiet", *args], capsys
    )
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == (["robot.json"] if make else [])


def test_a_held_out_cohort_that_shares_a_patient_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    from harness import run_cli

    for seed, folder in ((7, "train"), (8, "held")):  # patients seed7, seed8 and seed8, seed9: seed8 is in both
        assert run_cli(["patients", "--seed", str(seed), "--count", "2", "--out", folder], capsys)[0] == 0
    code, err = cli_error(
        ["design", "--cohort", "train/cohort.toml", "--validate", "held/cohort.toml", "--out", "d", "--quiet"], capsys
    )
    assert (
        code == 2 and err.count("\n") == 1 and "--validate" in err and "'seed8' is also in the training cohort" in err
    ), err
    assert not (tmp_path / "d").exists()


def test_the_dock_summary_is_typed(docked: Path) -> None:
    """House II: every field of dock's summary.json is declared (arcube.DockSummary), each an attribute."""
    import arcube
    from arcube.design_job.coverage import DockResult

    summary = json.loads((docked / "summary.json").read_text())
    result = DockResult(docked, True, summary)
    assert isinstance(result.summary, arcube.DockSummary) and set(summary) <= set(arcube.DockSummary.fields())
    assert result.summary.coverage == result.coverage == 1.0 and result.summary.dockings == summary["dockings"]


def test_a_served_side_s_report_names_its_program_folder_where_it_is(docked: Path) -> None:
    """The report of a served side names the drilling program's folder as seen from the page (``program``, beside it),
    not the staging folder the side was written in before it was moved into place."""
    import re

    for d in json.loads((docked / "summary.json").read_text())["dockings"]:
        page = (docked / d["folder"] / "report.html").read_text()
        shown = re.findall(r"<tr><th>folder</th><td>([^<]*)</td></tr>", page)
        assert shown == ["program"] and (docked / d["folder"] / shown[0] / "program.csv").is_file()
        assert re.search(r"\.dock-\d+-\w+\.tmp", page) is None  # the staging folder's name
