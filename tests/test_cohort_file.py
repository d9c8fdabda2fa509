"""Cohort files (``arcube design --cohort``, issue 30): what ``arcube patients --count N`` writes reads back as its
patients, and every bad entry is one line naming the file and the entry, exit 2, before anything is written.

Oracles: the patients' own files (the cohort names each patient's CSV and anatomy, and reading the cohort back gives
those plans); for bad input, the message names the file, the entry and the key, and the output folder is absent.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from arcube.design_job.cohort import COHORT_KEYS, read_cohort
from arcube.io import load_trajectories
from arcube.patients.anatomy import reference_anatomy_path

from designs import reference_right_csv
from harness import run_cli as _run


@pytest.fixture()
def folder(tmp_path: Path) -> Path:
    """A folder with a plan (the reference patient's right side, C3-C4) and its anatomy mesh."""
    (tmp_path / "plans").mkdir()
    (tmp_path / "plans" / "right.csv").write_text("\n".join(reference_right_csv()) + "\n")
    (tmp_path / "plans" / "anatomy.stl").write_bytes(reference_anatomy_path().read_bytes())
    return tmp_path


_GOOD = (
    '[[patient]]\nname = "a"\nplan = "plans/right.csv"\nanatomy = ["plans/anatomy.stl"]\nanatomy_frame = "patient"\n'
)


def test_patients_write_a_cohort_that_reads_back_as_their_plans(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _run(["patients", "--seed", "7", "--count", "2", "--out", str(tmp_path / "c")], capsys)
    assert code == 0, err
    assert f"{tmp_path / 'c' / 'cohort.toml'}" in out
    patients = read_cohort(tmp_path / "c" / "cohort.toml")
    assert [p.name for p in patients] == [
        "seed7",
        "seed8",
    ]  # named by the seed that makes each patient (patient k: seed 7 + k)
    assert [Path(p.plan).name for p in patients] == sorted(f.name for f in (tmp_path / "c").glob("*.csv"))
    for p in patients:
        plan = Path(p.plan)
        assert plan.parent == (tmp_path / "c").resolve() and plan.suffix == ".csv"
        assert p.anatomy == (str(plan.with_suffix(".anatomy.stl")),) and p.anatomy_frame == "patient"
        a, b = load_trajectories(plan), load_trajectories(tmp_path / "c" / plan.name)
        assert np.array_equal(a.entry, b.entry) and a.ids == b.ids


def test_a_good_cohort_reads(folder: Path) -> None:
    (folder / "cohort.toml").write_text(
        _GOOD + '\n[[patient]]\nname = "b"\nplan = "reference"\nanatomy = "default"\nsegments = [3, "C4"]\n'
    )
    a, b = read_cohort(folder / "cohort.toml")
    assert a.plan == str((folder / "plans" / "right.csv").resolve()) and a.anatomy == (
        str((folder / "plans" / "anatomy.stl").resolve()),
    )
    assert (b.plan, b.anatomy, b.anatomy_frame, b.segments) == ("reference", ("default",), "LPS", ("3", "C4"))


@pytest.mark.parametrize(
    "text, needle",
    [
        (
            _GOOD.replace("anatomy_frame", "anatomy_frames"),
            "patient 1 (a): unknown key 'anatomy_frames' (known: " + ", ".join(COHORT_KEYS),
        ),
        (_GOOD + _GOOD, "patient 2 (a): the name is already patient 1's"),
        (_GOOD.replace("plans/right.csv", "plans/gone.csv"), "patient 1 (a): plan 'plans/gone.csv' does not exist"),
        (
            _GOOD.replace("plans/anatomy.stl", "plans/gone.stl"),
            "patient 1 (a): anatomy file 'plans/gone.stl' does not exist",
        ),
        (
            _GOOD.replace("plans/right.csv", "../elsewhere/right.csv"),
            "patient 1 (a): plan '../elsewhere/right.csv' does not exist",
        ),
        ('[[patient]]\nname = "a"\nanatomy = "default"\n', "patient 1 (a): plan is missing"),
        (_GOOD.replace('"a"', '"a/b"'), "patient 1 (a/b): name must be 1-64 letters"),
        (_GOOD.replace('"patient"', '"XYZ"'), "patient 1 (a): anatomy_frame must be one of LPS, RAS, patient"),
        (_GOOD + "table_z = nan\n", "patient 1 (a): table_z must be a finite number"),
        ('title = "x"\n' + _GOOD, "unknown key 'title' (a cohort file holds [[patient]] tables only)"),
        ("", "no [[patient]] entries"),
    ],
)
def test_a_bad_cohort_is_one_line_exit_2_nothing_written(
    folder: Path, capsys: pytest.CaptureFixture[str], text: str, needle: str
) -> None:
    (folder / "cohort.toml").write_text(text)
    code, _, err = _run(
        ["design", "--cohort", str(folder / "cohort.toml"), "--out", str(folder / "out"), "--quiet"], capsys
    )
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: --cohort {folder / 'cohort.toml'}: ") and needle in err, err
    assert not (folder / "out").exists()


def test_a_patient_without_trajectories_is_refused(folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A plan with no trajectory after the run's selection (only right ones, --side L) or none at all (a header)."""
    (folder / "plans" / "empty.csv").write_text(
        "trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z\n"
    )
    for text, extra, needle in (
        (_GOOD, ["--side", "L"], "patient 1 (a): plan: no trajectory of"),
        (_GOOD.replace("right.csv", "empty.csv"), [], "patient 1 (a): plan: "),
    ):
        (folder / "cohort.toml").write_text(text)
        code, _, err = _run(
            ["design", "--cohort", str(folder / "cohort.toml"), "--out", str(folder / "out"), "--quiet", *extra], capsys
        )
        assert code == 2 and err.count("\n") == 1 and needle in err and str(folder / "cohort.toml") in err, err
        assert not (folder / "out").exists()


def test_a_cohort_with_trajectories_too_is_refused(folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (folder / "cohort.toml").write_text(_GOOD)
    code, _, err = _run(
        [
            "design",
            "--cohort",
            str(folder / "cohort.toml"),
            "--trajectories",
            "reference",
            "--out",
            str(folder / "out"),
        ],
        capsys,
    )
    assert code == 2 and err.count("\n") == 1 and "--cohort" in err, err
    assert not (folder / "out").exists()
