"""Issue "Hardening IV": files and messages. A single output file named with a trailing '/' (``joints --out jdir/``)
was written as a file ``jdir``; ``--out`` onto a file said "not an empty folder"; a run folder's config.toml with a
bad ``dask`` blamed ``--dask``, one with a ``[bounds]`` entry that is not a pair printed a TypeError; a FIFO
study.toml was "no config.toml or study.toml"; a robot file without ``--side`` did not name the flag. From the
hostile-input battery: ``patients --out /proc/p.csv`` named its staging file, a program.json holding a 5,000-digit
integer was taken, ``export --program`` onto a kept r.xml whose r.replay.csv is a folder asked for --force without
naming the folder, and a missing second trajectory set of a design job was refused for something else."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from arcube.motion.output import Program
from arcube.optimization import run as runmod
from arcube.optimization.config import build_config
from harness import cli_error

DATA = Path(__file__).parent / "data"
ROBOT = DATA / "one_robot.json"


def _one_line(code: int, err: str, *needles: str) -> None:
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (code, err)
    for needle in needles:
        assert needle in err, err


def _files(folder: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None) for p in folder.rglob("*")}


# ----------------------------------------------------------------------------- C: a file path ending with '/'


@pytest.mark.parametrize(
    "argv, flag, example",
    [
        (["joints", "--points", "3", "--ids", "1", "--out"], "--out", "joints.csv"),
        (["export", "--ids", "1", "--out"], "--out", "robot.xml"),
        (["evaluate", "--points", "3", "--ids", "1", "--report"], "--report", "report.html"),
    ],
)
def test_a_single_output_file_named_as_a_folder_is_refused(
    argv: list[str], flag: str, example: str, tmp_path: Path, capsys
) -> None:
    target = f"{tmp_path / 'jdir'}/"
    code, err = cli_error([*argv, target], capsys)
    _one_line(code, err, f"{flag} {target}: ends with '/', so it names a folder", f"e.g. {flag} {target}{example}")
    assert not list(tmp_path.iterdir())  # no file named jdir


# ----------------------------------------------------------------------------- D: messages


@pytest.mark.parametrize("command", ["dock", "optimize", "study"])
def test_an_output_folder_that_is_a_file_is_called_a_file(command: str, tmp_path: Path, capsys) -> None:
    good = tmp_path / "good.csv"
    good.write_text("kept\n")
    first = ["dock", "--robot", str(ROBOT)] if command == "dock" else [command]
    code, err = cli_error([*first, "--trajectories", "reference", "--out", str(good)], capsys)
    _one_line(code, err, f"--out {good}: is a file, not a folder")
    assert good.read_text() == "kept\n" and sorted(p.name for p in tmp_path.iterdir()) == ["good.csv"]


def _run_folder(tmp_path: Path) -> Path:
    cfg = build_config(["reference"], population=4, generations=1, points=3, ids="1", free="m_x", seed=3)
    run = tmp_path / "run"
    runmod.prepare(run, cfg)  # killed before its first checkpoint: resume starts it
    return run


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, 1))


@pytest.mark.parametrize(
    "old, new, says",
    [
        ('dask = ""', 'dask = "nonsense"', "config.toml: executor.dask 'nonsense': expected a scheduler address"),
        ("m_x = [-400.0, 400.0]", "m_x = 5", "config.toml: [bounds] m_x must be [low, high] (two numbers), got 5"),
        ("m_x = [-400.0, 400.0]", "m_x = [1.0]", "config.toml: [bounds] m_x must be [low, high] (two numbers)"),
    ],
)
def test_a_run_folders_config_is_blamed_not_a_flag(old: str, new: str, says: str, tmp_path: Path, capsys) -> None:
    run = _run_folder(tmp_path)
    _edit(run / "config.toml", old, new)
    before = _files(run)
    code, err = cli_error(["resume", str(run)], capsys)
    _one_line(code, err, says)
    assert "--dask" not in err and "TypeError" not in err
    assert _files(run) == before


def test_a_fifo_study_toml_is_named_as_one(tmp_path: Path, capsys) -> None:
    study = tmp_path / "s"
    study.mkdir()
    os.mkfifo(study / "study.toml")
    (study / "base_config.toml").write_text("")
    code, err = cli_error(["resume", str(study)], capsys)
    _one_line(code, err, f"{study / 'study.toml'}: is a FIFO (named pipe), not a regular file")
    assert sorted(p.name for p in study.iterdir()) == ["base_config.toml", "study.toml"]


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "simulate", "--poses", "poses.csv", "--out", "m.csv"],
        ["calibrate", "identify", "--measurements", "poses.csv", "--out", "cal"],
        ["evaluate", "--points", "3"],
        ["export", "--out", "r.xml"],
    ],
    ids=lambda a: " ".join(a[:2]),
)
def test_a_robot_file_without_side_names_the_flag(argv: list[str], tmp_path: Path, capsys, monkeypatch) -> None:
    (tmp_path / "poses.csv").write_text("not read\n")
    monkeypatch.chdir(tmp_path)
    head = 2 if argv[0] == "calibrate" else 1
    code, err = cli_error([*argv[:head], "--design", str(ROBOT), *argv[head:]], capsys)
    _one_line(code, err, f"--side is needed: {ROBOT} is one robot at 2 dockings (sides R, L)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.csv"]


# ----------------------------------------------------------------------------- E: the hostile-input battery


def test_patients_onto_an_unwritable_folder_names_the_path_given(capsys) -> None:
    code, err = cli_error(["patients", "--mean", "--out", "/proc/p.csv"], capsys)
    _one_line(code, err, "--out /proc/p.csv: cannot write in /proc")
    assert ".tmp" not in err


def _program(folder: Path) -> Path:
    n = 6
    rng = np.random.default_rng(n)
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    Program(
        t_s=np.arange(n) * 0.01,
        segment=np.array((["approach", "drill", "retract", "transit"] * n)[:n]),
        trajectory=np.array(["1"] * (n - 1) + ["1->2"]),
        E=rng.uniform(-80, 80, (n, 3)),
        e=e,
        q_deg=rng.uniform(-170, 170, (n, 5)),
        q_dot_deg=rng.uniform(-30, 30, (n, 5)),
        summary={"order": ["1", "2"], "total_s": 0.05, "transits": [{"from": "1", "to": "2"}]},
        tau_Nm=rng.uniform(-5, 5, (n, 5)),
    ).write(folder)
    return folder


@pytest.mark.parametrize("where", ["note", "transits"])
@pytest.mark.parametrize("command", ["report", "export"])
def test_a_5000_digit_integer_anywhere_in_program_json_is_refused(
    where: str, command: str, tmp_path: Path, capsys
) -> None:
    folder = _program(tmp_path / "p")
    data = json.loads((folder / "program.json").read_text())
    if where == "note":  # a key no reader uses
        data["note"] = "@"
    else:
        data["transits"][0]["s"] = "@"
    (folder / "program.json").write_text(json.dumps(data).replace('"@"', "9" * 5000))
    before = _files(tmp_path)
    argv = ["report", str(folder)] if command == "report" else ["export", "--program", str(folder)]
    code, err = cli_error([*argv, *(["--out", str(tmp_path / "r.xml")] if command == "export" else [])], capsys)
    key = "note" if where == "note" else "transits[0].s"
    _one_line(code, err, f"{folder / 'program.json'}: {key}: a number beyond the float range")
    assert _files(tmp_path) == before


def test_export_program_names_a_replay_that_is_a_folder_before_asking_for_force(tmp_path: Path, capsys) -> None:
    folder = _program(tmp_path / "p")
    (tmp_path / "r.xml").write_text("<kept/>")
    (tmp_path / "r.replay.csv").mkdir()
    for more in ([], ["--force"]):
        code, err = cli_error(["export", "--program", str(folder), "--out", str(tmp_path / "r.xml"), *more], capsys)
        _one_line(code, err, f"cannot write {tmp_path / 'r.replay.csv'} (is a folder")
        assert "--force" not in err
    assert (tmp_path / "r.xml").read_text() == "<kept/>"


def test_a_missing_second_trajectory_set_is_named_first(tmp_path: Path, capsys) -> None:
    missing = tmp_path / "missing.csv"
    out = tmp_path / "d"
    for argv in (
        ["design", "--trajectories", "reference", str(missing), "--out", str(out)],
        ["design", "--trajectories", "reference", str(missing), "--envelope", "none", "--out", str(out)],
        ["optimize", "--trajectories", "reference", str(missing), "--aggregate", "max", "--out", str(out)],
    ):
        code, err = cli_error(argv, capsys)
        _one_line(code, err, f"--trajectories {missing}: no such file or folder")
    assert not list(tmp_path.iterdir())
