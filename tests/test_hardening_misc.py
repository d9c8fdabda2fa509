"""The rest of issue "Hardening II", part A: limits and requirements as the user types them, numbers in
every notation, messages that name what the user wrote, noise on stderr, a plan from a pipe, an install
the user cannot write to, and the Python API's errors."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import arcube
from arcube.cli import _one_line
from arcube.coerce import limit_pairs
from arcube.design_job.requirements import DEFAULTS, requirements_from
from arcube.errors import InputError
from arcube.io import TrajectorySet, load_trajectories, select, write_csv
from harness import cli_error as _cli

SRC = Path(__file__).resolve().parents[1] / "src"
DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


# ----------------------------------------------------------------------------- limits and requirements


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--max", "torque=1_5"], "the value '1_5' is not a number"),
        (["--max", "torque=1", "--max", "torque=50"], "torque is given twice ('torque=1' and 'torque=50')"),
        (["--min", "clearance=0x10", "--anatomy", "default"], "the value '0x10' is not a number"),
        (["--max", "torque=1,5"], "the value '1,5' is not a number"),
    ],
)
def test_optimize_limits_are_refused_as_typed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    code, err = _cli(["optimize", "--trajectories", "reference", *argv, "--out", str(tmp_path / "r")], capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: --m") and needle in err, err
    assert os.listdir(tmp_path) == []


def test_design_refuses_a_requirement_both_dropped_and_limited(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _cli(
        ["design", "--trajectories", "reference", "--no-torque", "--max", "torque=5", "--out", str(tmp_path / "d")],
        capsys,
    )
    assert (
        code == 2
        and err.count("\n") == 1
        and err.startswith("error: --max torque=5: the torque requirement is also dropped")
    ), err
    assert os.listdir(tmp_path) == []


def test_requirements_from_texts_as_the_command_line_gives_them() -> None:
    reqs = {
        r.name: r.limit for r in requirements_from(["clearance=8"], ["torque=15", "power_peak=40"], drop=["axis_error"])
    }
    assert reqs == {
        **{k: v for k, v in DEFAULTS.items() if k != "axis_error"},
        "clearance": 8.0,
        "torque": 15.0,
        "power_peak": 40.0,
    }
    for minima, maxima, drop, needle in [
        (None, ["torque=1_5"], (), "'1_5' is not a number"),
        (None, ["torque=1", "torque=50"], (), "given twice"),
        (None, {"torque": 5.0}, ["torque"], "also dropped"),
        (["clearance=-21.25"], None, (), "must be a finite number >= 0"),
        (["clearance=nan"], None, (), "must be finite"),
    ]:
        with pytest.raises(InputError, match=re.escape(needle)) as info:
            requirements_from(minima, maxima, drop)
        assert info.value.param in ("requirements.min", "requirements.max")


@settings(max_examples=200, derandomize=True, deadline=None, database=None)
@given(
    text=st.one_of(
        st.from_regex(r"[+-]?[0-9_]{0,4}[.]?[0-9_]{0,3}([eE][+-]?[0-9]{1,3})?", fullmatch=True),
        st.sampled_from(["nan", "inf", "-Infinity", "1_5", "١", "１", "0x10", "1e400", " 2 ", ".5", "5.", "+.5e-3"]),
    )
)
def test_limit_values_in_every_notation(text: str) -> None:
    """A value is taken exactly when it is a finite number in plain decimal notation (within the torque's bound,
    1e5 N·m: Hardening IV), and is then Python's float of its text (Python's float alone would take ``1_5``, ``١``,
    ``１``)."""
    plain = DECIMAL.fullmatch(text.strip()) is not None and np.isfinite(float(text.strip()))
    plain = plain and abs(float(text.strip())) <= 1e5
    try:
        got = limit_pairs([f"torque={text}"], param="p")
    except InputError:
        assert not plain
    else:
        assert plain and got == [("torque", float(text.strip()), f"torque={text}")]


# ----------------------------------------------------------------------------- messages and noise


def test_long_numbers_in_messages_are_shortened(capsys: pytest.CaptureFixture[str]) -> None:
    big = "9" * 300
    code, err = _cli(["export", "--out", "r.xml", "--at", f"1:{big}"], capsys)
    assert (
        code == 2 and err == "error: --at 1:999999999999...(300 digits): sample index k must lie in 0..29 (points=30)\n"
    ), err
    assert _one_line("x " + "1" * 24 + "\n y") == "x " + "1" * 24 + " y"


def test_at_on_an_unreachable_point_names_the_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _cli(["export", "--design", "paper", "--at", "1:0", "--out", str(tmp_path / "r.xml")], capsys)
    assert (
        code == 2
        and err.startswith("error: --at '1:0': the design has no IK solution at trajectory 1, k=0")
        and err.count("\n") == 1
    ), err


def test_dask_with_workers_names_both_flags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _cli(
        [
            "optimize",
            "--trajectories",
            "reference",
            "--dask",
            "127.0.0.1:8786",
            "--workers",
            "2",
            "--out",
            str(tmp_path / "r"),
        ],
        capsys,
    )
    assert (
        code == 2
        and err
        == "error: --workers 2 and --dask 127.0.0.1:8786: one or the other (a Dask cluster has its own workers)\n"
    ), err


def test_an_anatomy_too_large_names_its_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import trimesh

    trimesh.creation.box(extents=(5000.0, 5000.0, 5000.0)).export(tmp_path / "big.stl")
    code, err = _cli(
        ["evaluate", "--points", "3", "--ids", "1,2", "--engine", "numpy", "--anatomy", str(tmp_path / "big.stl")],
        capsys,
    )
    assert (
        code == 2
        and err.startswith(f"error: --anatomy {tmp_path / 'big.stl'} (LPS): spans 5000 x 5000 x 5000 mm")
        and err.count("\n") == 1
    ), err


def test_a_control_character_in_a_segment_name_is_refused(tmp_path: Path) -> None:
    from arcube.io.segmentations import read_segmentation

    head = (
        "NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\nsizes: 2 2 2\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\nendian: little\n"
        "encoding: raw\nspace origin: (0,0,0)\nSegment0_ID:=Segment_1\nSegment0_Name:=C3\x00x\n"
        "Segment0_LabelValue:=1\nSegment0_Layer:=0\n\n"
    )
    path = tmp_path / "nul.seg.nrrd"
    path.write_bytes(head.encode() + np.ones(8, dtype=np.uint8).tobytes())
    with pytest.raises(
        InputError, match=r"nul.seg.nrrd: Segment0_Name 'C3\\x00x' holds a control character \(U\+0000\) at position 2"
    ):
        read_segmentation(path)


# ----------------------------------------------------------------------------- a plan from a pipe


def test_a_plan_read_from_a_pipe_is_accepted(tmp_path: Path) -> None:
    """``--trajectories <(...)``: the shell passes /dev/fd/N, a pipe; it is read once (the command reads its plan twice)."""
    write_csv(select(load_trajectories("reference"), ids="1,2"), tmp_path / "plan.csv")
    text = (tmp_path / "plan.csv").read_bytes()
    r, w = os.pipe()
    os.write(w, text)
    os.close(w)
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "arcube",
            "evaluate",
            "--points",
            "3",
            "--engine",
            "numpy",
            "--json",
            "--trajectories",
            f"/dev/fd/{r}",
            "--anatomy",
            "none",
        ],
        pass_fds=(r,),
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    os.close(r)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert '"1"' in out.stdout and '"2"' in out.stdout


def test_an_empty_fifo_is_named_not_waited_for(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "plan.csv")
    with pytest.raises(InputError, match="plan.csv: is a FIFO \\(named pipe\\) that gave no data"):
        load_trajectories(tmp_path / "plan.csv")


# ----------------------------------------------------------------------------- an install nobody can write to


def test_the_numba_cache_moves_to_a_private_folder_when_the_install_is_read_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from arcube import caches

    # set, then removed: monkeypatch records the variable, so the value configure() writes into os.environ is undone
    # after the test (a bare delenv of an unset variable records nothing: the private cache leaked into every later
    # command this worker started, and the first of them compiled the whole kernel again into it)
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(caches, "_in_tree_writable", lambda: False)
    monkeypatch.setattr(sys, "modules", {k: v for k, v in sys.modules.items() if k != "numba"})
    assert caches.configure() == str(tmp_path / "xdg" / "arcube" / "numba") == os.environ["NUMBA_CACHE_DIR"]
    assert (os.stat(tmp_path / "xdg" / "arcube" / "numba").st_mode & 0o777) == 0o700
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    os.chmod(shared, 0o777)
    assert not caches._writable(str(shared))  # another user could plant code there: not used


@pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("setpriv") is None, reason="needs root and setpriv to run as nobody"
)
def test_an_unprivileged_user_with_no_home_loads_the_compiled_kernel() -> None:
    """The source tree is root's (not writable by nobody), HOME is missing: Numba used to refuse the
    ``cache=True`` functions at import (``no locator available``); now they cache in a private folder
    under the temporary directory. (Importing decorates them: the refusal needs no compilation.)"""
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="arcube-nobody-"))
    try:
        os.chmod(tmp, 0o1777)
        env = {"PATH": "/usr/bin:/bin", "HOME": "/nonexistent", "PYTHONPATH": str(SRC), "TMPDIR": str(tmp)}
        code = "import os, arcube.evaluation.kernel, arcube.accuracy._kernel, arcube.evaluation.sdf; print(os.environ['NUMBA_CACHE_DIR'])"
        out = subprocess.run(
            ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups", sys.executable, "-c", code],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp,
            timeout=300,
        )
        assert out.returncode == 0 and out.stderr == "", out.stderr[-2000:]
        folder = Path(out.stdout.strip())
        assert (
            folder.parent == tmp and folder.name.startswith("arcube-numba-") and folder.stat().st_mode & 0o777 == 0o700
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# ----------------------------------------------------------------------------- the Python API


def test_the_api_raises_input_error_for_a_missing_or_empty_plan() -> None:
    empty = TrajectorySet((), (), (), np.zeros((0, 3)), np.zeros((0, 3)), "hand")
    for plan, needle in ((None, "got NoneType"), (5, "got int"), (empty, "hand has no trajectories")):
        with pytest.raises(InputError, match=needle) as info:
            arcube.evaluate("paper", plan)
        assert info.value.param == "plan"


def test_dir_of_the_package_shows_only_public_names_and_every_returned_type_is_exported() -> None:
    """House II: dir(arcube) leaked TYPE_CHECKING, annotations, importlib, caches; DesignResult and JointTrajectory (returned
    by arcube.design and arcube.joints) were not exported. Every name dir lists resolves."""
    import arcube

    names = dir(arcube)
    assert not {"TYPE_CHECKING", "annotations", "importlib", "caches"} & set(names)
    assert {"DesignResult", "JointTrajectory", "DockResult", "BreachResult", "dock", "breach"} <= set(names)
    for name in names:
        getattr(arcube, name)


def test_every_type_a_public_function_returns_is_exported() -> None:
    """House II: what an entry point returns can be named as ``arcube.X`` (``arcube.explore`` returned an
    ExplorerApp that was not): every class its return annotation names is in ``dir(arcube)``."""
    import inspect
    import re

    import arcube

    plain = {"Path", "Any", "None", "NDArray"}  # the standard library's, typing's and NumPy's
    missing = {}
    for name in arcube.__all__:
        obj = getattr(arcube, name)
        if inspect.isclass(obj) or not callable(obj):
            continue
        returned = set(re.findall(r"\b[A-Z]\w*", str(inspect.signature(obj).return_annotation))) - plain
        if returned - set(dir(arcube)):
            missing[name] = sorted(returned - set(dir(arcube)))
    assert not missing, f"returned but not exported: {missing}"


def test_every_settings_field_has_a_description() -> None:
    """House II: a field without a docstring gave its flag the help text of its name (--segments showed 'segments')."""
    from arcube.accuracy import ToleranceSettings
    from arcube.optimization.settings import RunSettings
    from arcube.options import Body, Guards, Loads, Masses, Outputs
    from arcube.pedicles.settings import BreachSettings

    for model in (RunSettings, ToleranceSettings, Guards, Body, Loads, Masses, Outputs, BreachSettings):
        missing = [
            n for n, f in model.model_fields.items() if not (f.description or "").strip() or f.description.strip() == n
        ]
        assert not missing, f"{model.__name__}: {missing}"


@pytest.mark.parametrize(
    "drop, needle",
    [
        (("mount_rx",), "the mounting rotation needs all of mount_rx, mount_ry, mount_rz; missing mount_rx"),
        (("L",), "a mounted design needs its tool offset L"),
    ],
)
def test_a_partial_design_file_is_refused_naming_what_is_missing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], drop, needle
) -> None:
    """Hardening III: without mount_rx evaluate gave eta_G 2.05 instead of 1.38, without L 3.36, and said nothing."""
    import json

    from designs import DEMO

    values = {k: v for k, v in DEMO.to_file_dict().items() if k not in drop}
    (tmp_path / "d.json").write_text(json.dumps(values))
    code, err = _cli(["evaluate", "--design", str(tmp_path / "d.json"), "--trajectories", "reference"], capsys)
    assert code == 2 and err.count("\n") == 1 and needle in err, err
    paper = {
        k: v for k, v in arcube.Design.paper().to_dict().items() if k not in ("mount_rx", "mount_ry", "mount_rz", "L")
    }
    assert arcube.Design.from_dict(paper).to_dict()["L"] == 0.0  # a paper-style file without mount and L stays valid


@pytest.mark.parametrize(
    "argv, needle",
    [
        (
            ["evaluate", "--design", "papper", "--trajectories", "reference"],
            "papper: no such file, and not a preset (presets: paper)",
        ),
        (
            ["evaluate", "--trajectories", "SEMI"],
            "the header is one field with semicolons: separate the columns with commas",
        ),
        (
            ["optimize", "foo.csv", "--out", "run"],
            "--trajectories is required; 'foo.csv' is a value without its flag (give --trajectories foo.csv)",
        ),
    ],
)
def test_smaller_mistakes_get_a_line_that_says_what_to_do(tmp_path: Path, monkeypatch, capsys, argv, needle) -> None:
    """Hardening III's smaller items: a misspelt preset, a semicolon-separated CSV, a plan given without its flag."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "semi.csv").write_text("trajectory;entry_x;entry_y;entry_z;target_x;target_y;target_z\n1;0;0;0;0;0;1\n")
    code, err = _cli([a.replace("SEMI", "semi.csv") for a in argv], capsys)
    assert code == 2 and err.count("\n") == 1 and needle in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["semi.csv"]


def test_tol_takes_a_comma_list_as_several_items() -> None:
    from arcube.accuracy.settings import parse_tol

    assert parse_tol(["r=0.1,L=0.2", "angles=0.01"]) == {"r": 0.1, "L": 0.2, "angles": 0.01}
    with pytest.raises(arcube.InputError, match="'L=x': the tolerance 'x' is not a number"):
        parse_tol("r=0.1,L=x")


@pytest.mark.parametrize("command", ["joints", "export", "poses", "simulate"])
def test_a_single_file_output_is_not_replaced_without_force(tmp_path: Path, monkeypatch, capsys, command: str) -> None:
    """Hardening III item 2: calibrate poses --out real_measurements.csv overwrote a user's file; so did simulate,
    export and joints. Without --force the file is left as it was; with it, it is replaced."""
    monkeypatch.chdir(tmp_path)
    from arcube.pedicles.run import robot_dockings

    robot_dockings(Path(__file__).parent / "data" / "one_robot.json")["R"].to_json(
        tmp_path / "d.json"
    )  # the demo robot's right docking
    mine = tmp_path / "mine.out"
    mine.write_text("the tracker's readings, taken by hand\n")
    argv = {
        "joints": [
            "joints",
            "--design",
            "d.json",
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--points",
            "3",
            "--out",
            "mine.out",
        ],
        "export": ["export", "--design", "d.json", "--trajectories", "reference", "--side", "R", "--out", "mine.out"],
        "poses": [
            "calibrate",
            "poses",
            "--design",
            "d.json",
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--count",
            "12",
            "--points",
            "3",
            "--around",
            "2",
            "--out",
            "mine.out",
        ],
        "simulate": ["calibrate", "simulate", "--design", "d.json", "--poses", "poses.csv", "--out", "mine.out"],
    }[command]
    if command == "simulate":
        assert (
            _cli(
                [
                    "calibrate",
                    "poses",
                    "--design",
                    "d.json",
                    "--trajectories",
                    "reference",
                    "--side",
                    "R",
                    "--count",
                    "12",
                    "--points",
                    "3",
                    "--around",
                    "2",
                    "--out",
                    "poses.csv",
                ],
                capsys,
            )[0]
            == 0
        )
    code, err = _cli(argv, capsys)
    assert code == 2 and err.count("\n") == 1 and "exists; give --force to replace it" in err, err
    assert mine.read_text() == "the tracker's readings, taken by hand\n"
    from harness import run_cli

    assert run_cli([*argv, "--force"], capsys)[0] == 0
    assert mine.read_text() != "the tracker's readings, taken by hand\n"
    if command == "simulate":  # the rehearsal's ground truth beside its measurements: a design file arcube reads
        assert arcube.Design.load(tmp_path / "mine.truth.json").q0_deg is not None


def test_a_calibration_cannot_fool_itself(tmp_path: Path, monkeypatch, capsys) -> None:
    """Hardening III item 3: the nominal poses given as measurements, measurements of another design's poses, and too
    few poses are refused in one line naming the problem (they exited 0 with a 'calibrated' design equal to the nominal,
    or with O1 0 and condition number inf)."""
    from arcube.pedicles.run import robot_dockings

    monkeypatch.chdir(tmp_path)
    right = robot_dockings(Path(__file__).parent / "data" / "one_robot.json")["R"]
    right.to_json(tmp_path / "d.json")
    right.replace(r=right["r"] + 1.0).to_json(tmp_path / "other.json")
    poses = [
        "calibrate",
        "poses",
        "--design",
        "d.json",
        "--trajectories",
        "reference",
        "--side",
        "R",
        "--points",
        "3",
        "--around",
        "2",
    ]
    code, err = _cli([*poses, "--count", "3", "--out", "few.csv"], capsys)
    assert (
        code == 2
        and "--count is 3, but the" in err
        and "identifiable unknowns need at least" in err
        and not (tmp_path / "few.csv").exists()
    )
    assert _cli([*poses, "--count", "12", "--out", "poses.csv"], capsys)[0] == 0
    code, err = _cli(
        ["calibrate", "identify", "--design", "d.json", "--measurements", "poses.csv", "--out", "cal"], capsys
    )
    assert code == 2 and err.count("\n") == 1 and "these are the poses to measure, not measurements" in err, err
    code, err = _cli(
        ["calibrate", "identify", "--design", "other.json", "--measurements", "poses.csv", "--out", "cal"], capsys
    )
    assert code == 2 and "measured at poses chosen for another design" in err, err
    assert not (tmp_path / "cal").exists()
