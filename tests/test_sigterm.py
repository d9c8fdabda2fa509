"""SIGTERM and worker processes on the command line (issue "Hardening IV": Orphans and Signals).

SIGTERM (``kill``, a scheduler's cancel) ends a command as Ctrl-C does: the line ``error: terminated``, exit code
143, nothing half-written, a resumable run, and its worker processes stopped with it; Ctrl-C with worker processes
prints the one line and no worker traceback; a parent killed outright (SIGKILL) takes its workers with it within a
few seconds; an absurd ``--workers`` is refused in one line before anything starts.

Each command runs in a subprocess (``python -m arcube``) and is signalled once it is at work (its checkpoint or its
staging folder exists); every wait is bounded."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from arcube.optimization import run as runmod
from harness import cli_error

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
OPTIMIZE = [
    "optimize",
    "--trajectories",
    "reference",
    "--ids",
    "1,3",
    "--points",
    "5",
    "--algorithm",
    "ga",
    "--population",
    "40",
    "--generations",
    "5000",
    "--checkpoint-every",
    "1",
    "--ftol",
    "0",
    "--engine",
    "numpy",
    "--quiet",
    "--workers",
    "2",
    "--out",
    "r",
]
"""An optimization over two worker processes that runs until it is stopped (a generation in well under a second)."""
SLOW_START = 180.0
"""Seconds a command may take to be at work (imports, worker start-up; the suite runs beside it)."""

needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the processes from /proc (Linux)")


def _start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    """``python -m arcube argv`` in its own session (a signal to its group reaches it and its workers, as a
    terminal's Ctrl-C does); stderr to a file (a worker that outlived it would hold a pipe open)."""
    return subprocess.Popen(
        [sys.executable, "-m", "arcube", *argv],
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=(cwd / "stderr.txt").open("w"),
        start_new_session=True,
    )


def _wait_for(proc: subprocess.Popen[str], done: callable) -> None:  # type: ignore[valid-type]
    deadline = time.monotonic() + SLOW_START
    while time.monotonic() < deadline and proc.poll() is None and not done():
        time.sleep(0.05)
    assert proc.poll() is None and done(), ("the command did not get to work", proc.poll())


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of process ``pid`` from /proc; None once it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text.rpartition(")")[2].split()
    return fields[0], int(fields[1])


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid``."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            st = _stat(int(entry.name))
            if st is not None and st[1] == pid:
                out.append(int(entry.name))
    return out


def _alive(pids: list[int]) -> list[int]:
    return [p for p in pids if (st := _stat(p)) is not None and st[0] != "Z"]  # a zombie has ended


def _kill(pids: list[int]) -> None:
    """End what a failed test left running (by pid: only the test's own processes)."""
    for pid in _alive(pids):
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def _worker_pids(proc: subprocess.Popen[str]) -> list[int]:
    """The worker processes of ``proc`` (multiprocessing's spawned children), once both are up."""
    deadline, found = time.monotonic() + SLOW_START, []
    while time.monotonic() < deadline and proc.poll() is None:
        found = [
            p
            for p in _children(proc.pid)
            if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes() and _stat(p) is not None
        ]
        if len(found) >= 2:
            break
        time.sleep(0.05)
    assert len(found) >= 2, ("no two worker processes", proc.poll())
    return found


def _ended_within(proc: subprocess.Popen[str], seconds: float) -> tuple[int, float]:
    """(exit code, seconds it took); the process is killed if it takes longer than ``seconds``."""
    t0 = time.monotonic()
    try:
        code = proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        pytest.fail(f"still running {seconds} s after the signal")
    return code, time.monotonic() - t0


def _stray(folder: Path) -> list[str]:
    """Temporary files and locks left under ``folder``: what a half-finished write leaves."""
    return sorted(
        str(p.relative_to(folder))
        for p in folder.rglob("*")
        if p.name.endswith((".tmp", ".old")) or p.name == ".running"
    )


@needs_proc
def test_sigterm_ends_an_optimization_with_workers_as_ctrl_c_does(tmp_path: Path) -> None:
    """One line, exit 143, within seconds; the workers gone with it; the run whole up to its checkpoint and resumable."""
    proc = _start(OPTIMIZE, tmp_path)
    workers: list[int] = []
    try:
        state = tmp_path / "r" / "checkpoint" / "state.json"
        _wait_for(proc, state.exists)
        workers = _worker_pids(proc)
        time.sleep(0.3)  # inside a generation
        proc.send_signal(signal.SIGTERM)
        code, took = _ended_within(proc, 30)
        err = (tmp_path / "stderr.txt").read_text()
        assert code == 143 and err == "error: terminated\n", (code, err)
        assert took < 10, took  # about 0.5 s here: the workers stop at once
        deadline = time.monotonic() + 5
        while _alive(workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(workers)
    finally:
        _kill([proc.pid, *workers])
    run = tmp_path / "r"
    assert _stray(run) == [] and not (run / "summary.json").exists(), _stray(run)
    cfg, raw = runmod.read_config(run)
    saved, _ = runmod.load_checkpoint(run, cfg, raw)  # what resume starts from
    assert saved is not None and saved["generation"] >= 1 and not runmod.is_finished(run)


@needs_proc
def test_ctrl_c_with_workers_is_one_line_without_a_worker_traceback(tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches the command and its workers (its process group): only the command speaks."""
    proc = _start(OPTIMIZE, tmp_path)
    try:
        _wait_for(proc, (tmp_path / "r" / "checkpoint" / "state.json").exists)
        _worker_pids(proc)
        time.sleep(0.3)
        os.killpg(proc.pid, signal.SIGINT)
        code, _ = _ended_within(proc, 30)
    finally:
        _kill([proc.pid])
    err = (tmp_path / "stderr.txt").read_text()
    assert code == 130 and err == "error: interrupted\n", (code, err)


@needs_proc
def test_workers_end_when_their_parent_is_killed(tmp_path: Path) -> None:
    """SIGKILL of the command (a time limit's last word): it cannot clean up, its workers notice it is gone."""
    proc = _start(OPTIMIZE, tmp_path)
    workers: list[int] = []
    try:
        _wait_for(proc, (tmp_path / "r" / "checkpoint" / "state.json").exists)
        workers = _worker_pids(proc)
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=30) == -signal.SIGKILL
        deadline = time.monotonic() + 5
        while _alive(workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(workers), f"workers {_alive(workers)} outlived their parent by 5 s"
    finally:
        _kill([proc.pid, *workers])


@needs_proc
def test_sigterm_of_a_docking_with_workers_leaves_no_stage(tmp_path: Path) -> None:
    """``arcube dock --workers 2`` stopped while both sides are docked: one line, exit 143 within seconds, no staging
    folder or temporary file left, no worker left."""
    argv = ["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--out", "d"]
    argv += ["--levels", "C3", "--points", "6", "--evaluations", "400", "--quiet", "--workers", "2"]
    proc = _start(argv, tmp_path)
    workers: list[int] = []
    try:
        _wait_for(proc, lambda: any((s / "dockings").exists() for s in tmp_path.glob(".d.dock-*.tmp")))
        workers = _worker_pids(proc)
        proc.send_signal(signal.SIGTERM)
        code, took = _ended_within(proc, 30)
        err = (tmp_path / "stderr.txt").read_text()
        assert code == 143 and err == "error: terminated\n", (code, err)
        assert took < 10, took  # about 0.5 s here
        assert not _alive(workers)
    finally:
        _kill([proc.pid, *workers])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stderr.txt"]


@pytest.mark.parametrize(
    "argv",
    [
        ["optimize", "--trajectories", "absent.csv", "--out", "o"],
        ["study", "--seeds", "1,2", "--trajectories", "absent.csv", "--out", "o"],
        ["design", "--trajectories", "absent.csv", "--out", "o"],
        ["dock", "--robot", str(ROBOT), "--trajectories", "absent.csv", "--out", "o"],
        ["resume", "o"],
    ],
    ids=lambda argv: argv[0],
)
def test_an_absurd_workers_count_is_refused_naming_the_flag(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    """``--workers 100000`` is one line, exit 2, before anything is read or started (the bound: 4 x the CPUs)."""
    monkeypatch.chdir(tmp_path)
    code, err = cli_error([*argv, "--workers", "100000"], capsys)
    most = 4 * (os.cpu_count() or 1)
    assert code == 2 and err.count("\n") == 1 and err.startswith(f"error: --workers 100000: at most {most} "), err
    assert list(tmp_path.iterdir()) == []
    code, err = cli_error([*argv, "--workers", str(most)], capsys)  # the bound itself is taken: the next error
    assert code == 2 and "--workers" not in err, err
