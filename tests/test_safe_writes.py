"""Outputs of several files, program folders and the bounds on what a computation may cost (issue
"Hardening II", part A): a user's existing files survive a failed write, a folder is never written by
two programs at once nor an older program overwritten, nothing is written into a FIFO or a device,
and a step count, a standoff or a population the machine cannot afford is refused before the work,
naming the flag, leaving nothing behind."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.errors import InputError
from arcube.io.files import atomic_write_files
from arcube.io.program_files import MAX_PROGRAM_ROWS
from arcube.motion.output import prepare_folder, remove_folder
from arcube.optimization.lock import LOCK_FILE

from designs import PROGRAM_DESIGN as DESIGN, program_object
from harness import cli_error as _cli


# ----------------------------------------------------------------------------- all or none


def test_a_folder_among_the_targets_leaves_every_file_as_it_was(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("old a")
    (tmp_path / "b.json").mkdir()
    with pytest.raises(OSError) as info:
        atomic_write_files({tmp_path / "a.csv": b"new a", tmp_path / "b.json": b"new b"})
    assert info.value.filename == str(tmp_path / "b.json") and "folder" in info.value.strerror
    assert (tmp_path / "a.csv").read_text() == "old a" and sorted(os.listdir(tmp_path)) == ["a.csv", "b.json"]


@pytest.mark.parametrize("error", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_a_rename_that_fails_half_way_puts_the_old_files_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: BaseException
) -> None:
    """The second rename fails (a full disk, or Ctrl-C at that moment): the first file, already
    replaced, gets its old content back, the new one is removed, and no temporary file is left."""
    (tmp_path / "a.csv").write_text("old a")
    real, calls = os.replace, []

    def replace(src: str, dst: str) -> None:
        calls.append(dst)
        if len(calls) == 2:
            raise error
        real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(type(error)):
        atomic_write_files({tmp_path / "a.csv": b"new a", tmp_path / "b.json": b"new b"})
    monkeypatch.undo()
    assert (tmp_path / "a.csv").read_text() == "old a" and os.listdir(tmp_path) == ["a.csv"]


def test_all_new_files_are_written_when_nothing_fails(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("old a")
    atomic_write_files({tmp_path / "a.csv": b"new a", tmp_path / "sub" / "b.json": b"new b"})
    assert (tmp_path / "a.csv").read_text() == "new a" and (tmp_path / "sub" / "b.json").read_text() == "new b"
    assert sorted(os.listdir(tmp_path)) == ["a.csv", "sub"]


# ----------------------------------------------------------------------------- program folders


def test_an_older_program_is_never_overwritten_nor_deleted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "prog"
    out.mkdir()
    (out / "program.csv").write_text("an older program")
    (out / "program.json").mkdir()
    code, err = _cli(
        ["program", "--design", "paper", "--trajectories", "reference", "--ids", "1", "--out", str(out)], capsys
    )
    assert (
        code == 2
        and err.count("\n") == 1
        and err.startswith(f"error: --out {out}: holds an older program (program.csv, program.json (a folder))")
    )
    assert (out / "program.csv").read_text() == "an older program" and sorted(os.listdir(out)) == [
        "program.csv",
        "program.json",
    ]


def test_a_program_folder_is_written_by_one_process_at_a_time(tmp_path: Path) -> None:
    """A live process holds the lock: the second writer is refused (naming the lock file) before any
    work; once that process is gone its lock is stale and taken over."""
    out = tmp_path / "prog"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        out.mkdir()
        (out / LOCK_FILE).write_text(json.dumps({"host": socket.gethostname(), "pid": holder.pid}))
        with pytest.raises(InputError, match=rf"^out {out}: in use by process {holder.pid} .*delete {out / LOCK_FILE}"):
            prepare_folder(out)
    finally:
        holder.kill()
        holder.wait()
    folder, created, lock = prepare_folder(out)  # the holder is gone: its lock is stale
    assert folder == out and not created and json.loads(lock.read_text())["pid"] == os.getpid()
    remove_folder(folder, lock, created)
    assert os.listdir(out) == []


def test_a_program_is_written_as_one_output_and_reads_back(tmp_path: Path) -> None:
    prog = program_object()
    prog.write(tmp_path / "p", {"program.png": b"\x89PNG"})
    assert sorted(os.listdir(tmp_path / "p")) == ["program.csv", "program.json", "program.png"]
    (tmp_path / "q").mkdir()
    (tmp_path / "q" / "program.png").mkdir()  # the figure cannot go: neither can the program
    with pytest.raises(OSError):
        prog.write(tmp_path / "q", {"program.png": b"\x89PNG"})
    assert os.listdir(tmp_path / "q") == ["program.png"]


def test_two_programs_into_one_folder_one_is_refused(tmp_path: Path) -> None:
    """Two ``arcube program`` runs started together into one --out: one writes, the other is refused in one line."""
    design = tmp_path / "design.json"
    arcube.Design.from_dict(DESIGN).to_json(design)
    args = [
        sys.executable,
        "-m",
        "arcube",
        "program",
        "--design",
        str(design),
        "--trajectories",
        "reference",
        "--side",
        "R",
        "--ids",
        "5",
        "--feed",
        "2",
        "--dt",
        "0.05",
        "--quiet",
        "--out",
        "prog",
    ]
    procs = [
        subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    results = [(p.wait(timeout=600), p.stderr.read()) for p in procs]  # type: ignore[union-attr]
    assert sorted(rc for rc, _ in results) == [0, 2], results
    refused = next(err for rc, err in results if rc == 2)
    assert refused.count("\n") == 1 and ("in use by process" in refused or "holds an older program" in refused), refused
    assert sorted(os.listdir(tmp_path / "prog")) == ["program.csv", "program.json", "program.png"]


# ----------------------------------------------------------------------------- export and reports


def test_export_keeps_the_model_when_the_replay_cannot_be_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "p"
    program_object().write(folder)
    (tmp_path / "r.xml").write_text("<old/>")
    (tmp_path / "r.replay.csv").mkdir()
    code, err = _cli(["export", "--program", str(folder), "--out", str(tmp_path / "r.xml")], capsys)
    # Hardening IV: the folder is named first (asking for --force would only lead to this refusal)
    assert code == 2 and f"cannot write {tmp_path / 'r.replay.csv'} (is a folder" in err, err
    assert (tmp_path / "r.xml").read_text() == "<old/>"
    code, err = _cli(["export", "--program", str(folder), "--out", str(tmp_path / "r.xml"), "--force"], capsys)
    assert code == 2 and err.count("\n") == 1 and f"cannot write {tmp_path / 'r.replay.csv'} (is a folder" in err, err
    assert (tmp_path / "r.xml").read_text() == "<old/>"


def test_a_report_is_never_written_into_a_fifo_nor_its_pngs_beside_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    os.mkfifo(tmp_path / "r.html")
    code, err = _cli(
        ["evaluate", "--points", "3", "--ids", "1,2", "--engine", "numpy", "--report", str(tmp_path / "r.html")], capsys
    )
    assert (
        code == 2
        and err.count("\n") == 1
        and "FIFO" in err
        and err.startswith(f"error: --report {tmp_path / 'r.html'}")
    ), err
    assert os.listdir(tmp_path) == ["r.html"]


def test_a_report_where_nothing_can_be_written_names_the_flag(capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _cli(["evaluate", "--points", "3", "--ids", "1,2", "--report", "/proc/r.html"], capsys)
    assert (
        code == 2 and err.startswith("error: --report /proc/r.html: cannot write in /proc") and err.count("\n") == 1
    ), err


# ----------------------------------------------------------------------------- what the computation can afford


@pytest.mark.parametrize(
    ("flag", "value"), [("--dt", "1e-7"), ("--feed", "1e-9"), ("--approach-speed", "1e-6"), ("--retract-speed", "1e-7")]
)
def test_a_program_too_long_to_hold_is_refused_before_the_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, value: str
) -> None:
    out = tmp_path / "prog"
    code, err = _cli(
        ["program", "--design", "paper", "--trajectories", "reference", "--ids", "1,3", flag, value, "--out", str(out)],
        capsys,
    )
    assert (
        code == 2
        and err.count("\n") == 1
        and err.startswith(f"error: {flag} {float(value):g} ")
        and f"at most {MAX_PROGRAM_ROWS} rows" in err
    ), err
    assert not out.exists()


def test_the_row_bound_is_the_plan_s_own_arithmetic() -> None:
    """check_rows refuses exactly when approach + drilling + retract time / dt exceeds the bound (hand-computed)."""
    from arcube.io import select
    from arcube.motion.limits import ProgramLimits
    from arcube.motion.rows import check_rows

    ts = select(arcube.load_trajectories("reference"), ids="1")
    length = float(np.linalg.norm(ts.target[0] - ts.entry[0]))
    lim = ProgramLimits(feed=1.0, approach_speed=10.0, retract_speed=10.0, standoff_mm=20.0)
    seconds = 20.0 / 10.0 + length / 1.0 + (length + 20.0) / 10.0
    check_rows(lim.replace(dt=seconds / MAX_PROGRAM_ROWS * 1.001), ts)  # just fits
    with pytest.raises(InputError, match=r"^ProgramLimits.dt "):
        check_rows(lim.replace(dt=seconds / MAX_PROGRAM_ROWS * 0.999), ts)


@pytest.mark.parametrize(
    ("argv", "start"),
    [
        (["design", "--trajectories", "reference", "--standoff", "1e308"], "error: --standoff must be <= 1000"),
        (
            ["optimize", "--trajectories", "reference", "--algorithm", "ga", "--population", "100000000"],
            "error: --population must be <= 10000",
        ),
        (
            ["program", "--design", "paper", "--trajectories", "reference", "--standoff", "1e308"],
            "error: --standoff must be <= 1000",
        ),
        (
            ["program", "--design", "paper", "--trajectories", "reference", "--max-joint-speed", "1e308"],
            "error: --max-joint-speed must be <= 3600",
        ),
        (
            ["program", "--design", "paper", "--trajectories", "reference", "--thrust", "1e308"],
            "error: --thrust must be <= 100000",
        ),
        (["optimize", "--trajectories", "reference", "--points", "20000000000000000000"], "error: --points must be"),
    ],
)
def test_values_beyond_what_can_be_computed_are_refused_and_leave_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], start: str
) -> None:
    code, err = _cli([*argv, "--out", str(tmp_path / "out")], capsys)
    assert code == 2 and err.startswith(start) and err.count("\n") == 1, err
    assert os.listdir(tmp_path) == []
