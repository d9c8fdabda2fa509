"""Issue "Hardening IV": flags taken and ignored without a word are refused naming the flag: --class / --tol with no
objective or limit on the robot as built, --aggregate / --placement with one trajectory set, --class under --tol
that sets every length and angle, --anatomy-frame with no anatomy or skin file. A run's rerun line writes none of
them where they would be ignored (it stays a command the tool accepts)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from arcube.optimization.config import build_config
from arcube.patients.anatomy import reference_anatomy_path
from harness import cli_error, run_cli

DATA = Path(__file__).parent / "data"
ROBOT = DATA / "one_robot.json"
OPT = ["optimize", "--trajectories", "reference"]
BOTH = ["lengths=0.05,angles=0.01"]


def _one_line(code: int, err: str, *needles: str) -> None:
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (code, err)
    for needle in needles:
        assert needle in err, err


CASES = [
    ([*OPT, "--class", "f"], "--class f: the tolerances of lateral_error_wc and lateral_error_rms"),
    ([*OPT, "--tol", "r=0.02"], "--tol r=0.02: the tolerances of lateral_error_wc"),
    (["study", "--trajectories", "reference", "--seeds", "1", "--class", "c"], "--class c: the tolerances"),
    ([*OPT, "--max", "lateral_error_rms=0.5", "--class", "f", "--tol", *BOTH], "--class f: the ISO 2768 class"),
    ([*OPT, "--aggregate", "max"], "--aggregate max: how several trajectory sets are combined"),
    ([*OPT, "--placement", "shared"], "--placement shared: how several trajectory sets are combined"),
    (["study", "--trajectories", "reference", "--seeds", "1", "--aggregate", "mean"], "--aggregate mean"),
    ([*OPT, "--anatomy-frame", "RAS"], "--anatomy-frame RAS: the frame of anatomy and skin mesh files"),
    (
        ["tolerance", "--design", str(ROBOT), "--side", "R", "--trajectories", "reference", "--class", "f"]
        + ["--tol", *BOTH],
        "--class f: the ISO 2768 class sets the lengths' and angles' tolerances, and --tol sets them all",
    ),
    (
        ["breach", "--design", str(ROBOT), "--trajectories", "reference", "--class", "v", "--tol", *BOTH],
        "--class v: the ISO 2768 class",
    ),
    (["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--class", "f", "--tol", *BOTH], "--class f"),
    (["evaluate", "--points", "3", "--anatomy-frame", "RAS"], "--anatomy-frame RAS"),
    (["evaluate", "--points", "3", "--anatomy", "default", "--anatomy-frame", "patient"], "--anatomy-frame patient"),
    (
        ["evaluate", "--points", "3", "--anatomy", "spine.seg.nrrd", "--anatomy-frame", "RAS"],
        "a segmentation states its own",
    ),
    (["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--anatomy-frame", "LPS"], "--anatomy-frame LPS"),
]


@pytest.mark.parametrize("argv, needle", CASES, ids=[" ".join(c[0][:1] + c[0][-2:]) for c in CASES])
def test_a_flag_that_would_be_ignored_is_refused(argv: list[str], needle: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    code, err = cli_error([*argv, "--out", str(out)] if argv[0] != "evaluate" else argv, capsys)
    _one_line(code, err, needle)
    assert not out.exists()


def test_an_anatomy_file_takes_its_frame(tmp_path: Path, capsys) -> None:
    """The frame counts with an anatomy file (the bundled anatomy is in the patient frame)."""
    argv = ["evaluate", "--points", "3", "--ids", "1", "--anatomy", str(reference_anatomy_path())]
    code, _, err = run_cli([*argv, "--anatomy-frame", "patient"], capsys)
    assert code == 0, err


def test_the_rerun_line_leaves_out_what_the_run_does_not_use(tmp_path: Path, capsys) -> None:
    """A run over one set without a limit on the robot as built wrote --aggregate, --placement, --class and
    --anatomy-frame into its rerun line, which the command line now refuses: they are left out, and it runs."""
    cfg = build_config(["reference"], population=4, generations=1, points=3, ids="1", free="m_x", seed=3)
    for flag in ("--aggregate", "--placement", "--class", "--tol", "--anatomy-frame", "--compactness"):
        assert flag not in cfg.rerun.split(), cfg.rerun
    argv = shlex.split(cfg.rerun.replace(" DIR ", f" {tmp_path / 'again'} "))
    code, _, err = run_cli([*argv[1:], "--quiet"], capsys)
    assert code == 0, err
    robust = build_config(["reference"], population=4, points=3, free="m_x", maxima={"lateral_error_rms": 1.0})
    assert "--class m" in robust.rerun  # where the class counts, it is written
