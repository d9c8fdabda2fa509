"""``arcube tolerance`` and ``arcube.tolerance`` (issue "The accuracy budget"): the command line and the
API give the library's budget, the folder holds exactly the files and columns the issue names, and bad
input is one line, exit 2, nothing left.

Oracles: the library's own budget (tested against brute force and finite differences in
tests/test_accuracy.py) computed here directly from the plan's points; the CSV re-read and checked
against the JSON summary it must agree with.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import arcube
from arcube.accuracy import ToleranceSettings, budget
from arcube.evaluation.task import build_task
from arcube.model.design import Design
from harness import run_cli as _run

PLACED = Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
POINT_COLUMNS = [
    "trajectory",
    "point",
    "lateral_error_wc_mm",
    "axis_error_wc_deg",
    "axial_error_wc_mm",
    "lateral_error_rms_mm",
    "lateral_error_p50_mm",
    "lateral_error_p95_mm",
    "lateral_error_p99_mm",
    "lateral_error_max_mm",
]
SUMMARY = (
    "lateral_error_wc_mm",
    "axis_error_wc_deg",
    "axial_error_wc_mm",
    "lateral_error_rms_mm",
    "lateral_error_p95_mm",
    "axis_error_p95_deg",
)


@pytest.fixture(scope="module")
def design_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("design") / "placed.json"
    PLACED.to_json(path)
    return path


def test_cli_writes_the_budget_the_library_computes(
    design_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "budget"
    code, text, err = _run(
        [
            "tolerance",
            "--design",
            str(design_file),
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--ids",
            "1,3",
            "--points",
            "6",
            "--class",
            "c",
            "--tol",
            "r=0.02",
            "--samples",
            "200",
            "--seed",
            "4",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == [
        "lateral_histogram.png",
        "sensitivity.csv",
        "sources.png",
        "tolerance.json",
        "tolerance_points.csv",
        "trajectories.png",
    ]
    doc = json.loads((out / "tolerance.json").read_text())
    plan = arcube.select(arcube.load_trajectories("reference"), side="R", ids="1,3")
    task = build_task(plan.entry, plan.target, 6, ids=plan.ids)
    settings = ToleranceSettings(tolerance_class="c", tol={"r": 0.02}, samples=200, seed=4)
    want = budget(PLACED, task.E, task.e, "+,+,+,+", settings, [task.ids[i] for i in task.trajectory], task.k)
    for key in SUMMARY:
        assert doc["summary"][key] == pytest.approx(want.summary[key], rel=1e-12), key
    with open(out / "tolerance_points.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == POINT_COLUMNS and len(rows) == 12
    assert [(r["trajectory"], int(r["point"])) for r in rows] == [
        (t, k) for t in ("1", "3") for k in range(6)
    ]  # the plan's order
    assert max(float(r["lateral_error_wc_mm"]) for r in rows) == pytest.approx(
        doc["summary"]["lateral_error_wc_mm"], rel=1e-12
    )
    with open(out / "sensitivity.csv", newline="") as fh:
        sens = list(csv.DictReader(fh))
    assert list(sens[0]) == ["source", "tolerance", "unit", "share"]
    assert sum(float(r["share"]) for r in sens) == pytest.approx(1.0, abs=1e-9)
    assert next(float(r["tolerance"]) for r in sens if r["source"] == "r") == 0.02  # --tol beats the class
    assert "lateral error p95" in text and "tighten first" in text
    api = arcube.tolerance(PLACED, plan, points=6, settings=settings)
    assert api.summary == pytest.approx(want.summary, rel=1e-12)


@pytest.mark.parametrize(
    "bad, message",
    [
        (["--class", "x"], "--class must be one of f, m, c, v"),
        (["--tol", "foo=1"], "--tol 'foo=1': unknown error source"),
        (["--tol", "r=-0.1"], "--tol 'r=-0.1': a tolerance must be a finite number >= 0"),
        (["--samples", "0"], "--samples must be >= 1"),
        (["--q0-deg", "-1"], "--q0-deg must be >= 0"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_nothing_left(
    bad: list[str], message: str, design_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "budget"
    code, _, err = _run(
        [
            "tolerance",
            "--design",
            str(design_file),
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--out",
            str(out),
            *bad,
        ],
        capsys,
    )
    assert code == 2 and err.startswith(f"error: {message}") and err.count("\n") == 1, err
    assert not out.exists()


def test_a_design_without_a_reachable_point_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "budget"
    code, _, err = _run(
        [
            "tolerance",
            "--design",
            "paper",
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--points",
            "3",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and "reaches none" in err and err.count("\n") == 1, err
    assert not out.exists()
