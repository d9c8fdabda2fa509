"""Ctrl-C on the command line (issue "Hardening II", part A): exit code 130 and the one line
``error: interrupted``, at any moment after Python has started (during the imports, the work and the
writing; counted from the moment its start-up handler is in place), and nothing half-written; an interrupt that a dependency swallows is not lost.

SIGINT is sent to a subprocess at several moments; each case is bounded by a timeout. One moment is
outside arcube's hands: once the command has finished and Python itself shuts down (its last half
second here), Python restores the default handling and the process ends by the signal (the shell
shows exit status 130, without the line); the outputs are complete by then."""

from __future__ import annotations

import ast
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from arcube import interrupts

from designs import PROGRAM_DESIGN as DESIGN

SRC = Path(__file__).resolve().parents[1] / "src"
DELAYS = (0.15, 0.4, 0.8, 1.3, 2.0, 3.0, 4.5)
"""Seconds after the start-up handler is in place: during ``import arcube.cli`` (about 2.5 s here), then
during the work."""


def _interrupted(argv: list[str], delay: float, cwd: Path) -> tuple[int, str]:
    """Run ``python -m arcube argv``; send SIGINT ``delay`` seconds after its start-up handler is in place.

    Python reports each finished import on stderr (``-X importtime``); the handler is installed right
    after ``arcube.interrupts`` is imported. Counting from the process start instead let a slow machine
    send the signal before that, into Python's own default handling (a traceback, outside arcube's hands).
    Returns the exit code and stderr without the import lines."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    p = subprocess.Popen(
        [sys.executable, "-X", "importtime", "-m", "arcube", *argv],
        cwd=cwd,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    ready, started, err = threading.Event(), [], []

    def read() -> None:
        for line in p.stderr:
            if not line.startswith("import time:"):
                err.append(line)
            elif line.rstrip().endswith(" arcube.interrupts"):
                started.append(True)
                ready.set()
        ready.set()  # ended without it: asserted below

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    ready.wait(timeout=120)
    assert started, ("the process ended before its start-up handler", p.wait(timeout=60), "".join(err))
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    code = p.wait(timeout=300)
    reader.join(timeout=60)
    return code, "".join(err)


@pytest.mark.parametrize("delay", (*DELAYS, 6.0))
def test_ctrl_c_at_any_moment_of_a_program_is_one_line_and_leaves_nothing(tmp_path: Path, delay: float) -> None:
    """A program of one trajectory (about 8 s here: imports, planning, timing, writing)."""
    from arcube.model.design import Design

    Design.from_dict(DESIGN).to_json(tmp_path / "design.json")
    argv = [
        "program",
        "--design",
        "design.json",
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
        "--out",
        "prog",
    ]
    code, err = _interrupted(argv, delay, tmp_path)
    whole = ["program.csv", "program.json", "program.png"]
    if code == 0:  # finished before the signal: the program is whole
        assert err == "" and sorted(os.listdir(tmp_path / "prog")) == whole, (code, err)
        return
    if (
        code == -signal.SIGINT
    ):  # the signal came while Python shut down (its handlers reset): the program whole or nothing
        assert err in ("", "error: interrupted\n"), (code, err)
        assert os.listdir(tmp_path) == ["design.json"] or sorted(os.listdir(tmp_path / "prog")) == whole, os.listdir(
            tmp_path
        )
        return
    assert code == 130 and err == "error: interrupted\n", (delay, code, err)
    assert os.listdir(tmp_path) == ["design.json"], os.listdir(tmp_path)


@pytest.mark.parametrize("delay", DELAYS)
def test_ctrl_c_during_an_evaluation_with_a_report_leaves_no_report(tmp_path: Path, delay: float) -> None:
    code, err = _interrupted(
        ["evaluate", "--points", "30", "--engine", "numpy", "--anatomy", "default", "--report", "r.html"],
        delay,
        tmp_path,
    )
    reports = [f for f in os.listdir(tmp_path) if f.endswith(".html")]
    if code == 0:  # finished before the signal: then the report is whole
        assert (tmp_path / "r.html").read_text().rstrip().endswith("</html>")
        return
    if code == -signal.SIGINT:  # Python ended by the signal (a shell shows 130): the report whole, or nothing and said
        assert (err, reports) in (("", ["r.html"]), ("error: interrupted\n", [])), (code, err, reports)
        assert not reports or (tmp_path / "r.html").read_text().rstrip().endswith("</html>")
        return
    assert code == 130 and err == "error: interrupted\n", (delay, code, err)
    assert not reports, os.listdir(tmp_path)


def test_an_interrupt_a_dependency_swallows_is_raised_again() -> None:
    """What trimesh's optional imports do (``except BaseException``), then :func:`interrupts.check`."""
    previous = interrupts.arm()
    try:
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # the handler runs here
        except BaseException:
            pass  # swallowed
        assert interrupts.pending()
        with pytest.raises(KeyboardInterrupt):
            interrupts.check()
    finally:
        interrupts.disarm(previous)
    assert interrupts.arm() is not None and not interrupts.pending()
    interrupts.disarm(previous)


def test_every_import_of_trimesh_is_followed_by_the_check() -> None:
    """trimesh swallows a KeyboardInterrupt raised while it imports: each ``import trimesh`` that runs
    (not under ``if TYPE_CHECKING:``) is followed by ``interrupts.check()`` in the same scope."""
    missing = []
    for path in sorted((SRC / "arcube").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        checked_in_module = "interrupts.check()" in path.read_text(encoding="utf-8")
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if not isinstance(body, list) or (
                isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
            ):
                continue
            for i, stmt in enumerate(body):
                if isinstance(stmt, ast.Import) and any(a.name == "trimesh" for a in stmt.names):
                    after = body[i + 1 :]
                    ok = (
                        any("interrupts.check()" in ast.unparse(s) for s in after)
                        if not isinstance(node, ast.Module)
                        else checked_in_module
                    )
                    if not ok:
                        missing.append(f"{path.relative_to(SRC)}:{stmt.lineno}")
    assert not missing, f"import trimesh without interrupts.check() after it: {missing}"


def test_the_script_s_entry_installs_the_handling_before_the_heavy_imports() -> None:
    """``import arcube`` and the entry module load no NumPy, SciPy, pydantic or typer: the handler is
    in place before they are imported."""
    code = (
        "import sys, arcube.__main__, arcube.interrupts; "
        "print(sorted(m for m in ('numpy', 'scipy', 'pydantic', 'typer', 'trimesh') if m in sys.modules))"
    )
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out


def _screen(data: str) -> list[str]:
    """The lines a terminal shows after ``data``: enough of VT100 for Rich's live display (text, CR, LF,
    erase line ``ESC[2K``, cursor up ``ESC[nA``; colours and cursor visibility ignored)."""
    lines, row, col = [""], 0, 0
    for token in re.findall(r"\x1b\[[0-9;?]*[A-Za-z]|\r|\n|[^\x1b\r\n]+", data):
        if token == "\r":
            col = 0
        elif token == "\n":
            row, col = row + 1, 0
            lines += [""] * (row + 1 - len(lines))
        elif token.startswith("\x1b["):
            if token.endswith("K"):
                lines[row] = ""
            elif token.endswith("A"):
                row = max(row - int(token[2:-1] or 1), 0)
        else:
            line = lines[row].ljust(col)
            lines[row] = line[:col] + token + line[col + len(token) :]
            col += len(token)
    return [ln for ln in lines if ln.strip()]


def test_ctrl_c_under_a_progress_bar_leaves_one_line_on_the_terminal(tmp_path: Path) -> None:
    """On a terminal, optimize draws a progress bar; after Ctrl-C the screen shows the one error line
    (the bar is erased), not the bar's last state and the line."""
    import pty

    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(SRC), "TERM": "xterm", "COLUMNS": "120"}
    argv = [
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
        "20",
        "--generations",
        "100000",
        "--ftol",
        "0",
        "--engine",
        "numpy",
        "--out",
        "r",
    ]
    p = subprocess.Popen(
        [sys.executable, "-m", "arcube", *argv], cwd=tmp_path, env=env, stdin=slave, stdout=slave, stderr=slave
    )
    os.close(slave)
    data = b""
    deadline = time.monotonic() + 240
    while b"evaluations" not in data and time.monotonic() < deadline:  # the bar is up
        data += os.read(master, 65536)
    assert b"evaluations" in data, data[-500:]
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        data += chunk
    os.close(master)
    assert p.wait(timeout=120) == 130
    assert _screen(data.decode("utf-8", "replace")) == ["error: interrupted"], _screen(data.decode("utf-8", "replace"))
