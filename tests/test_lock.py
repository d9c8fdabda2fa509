"""The run folder's lock (arcube.optimization.lock): one writer at a time, stale locks taken over."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from arcube.errors import InputError
from arcube.optimization import run as runmod
from arcube.optimization.config import build_config
from arcube.optimization.lock import LOCK_FILE, acquire, release

SETTINGS = {
    "algorithm": "ga",
    "free": "m_x,m_y,m_z",
    "population": 10,
    "generations": 6,
    "points": 2,
    "engine": "numpy",
    "ftol": 0.0,
    "side": "R",
    "seed": 3,
    "checkpoint_every": 2,
}


def _dead_pid() -> int:
    proc = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True, check=True
    )
    return int(proc.stdout)


def test_a_second_writer_is_refused_and_the_lock_goes_with_the_run(tmp_path: Path) -> None:
    cfg = build_config(["reference"], **SETTINGS)
    out = tmp_path / "run"
    runmod.prepare(out, cfg)
    held = acquire(out)  # another live process on this host (here: this one) holds the folder
    with pytest.raises(InputError, match=f"in use by process {os.getpid()} on {socket.gethostname()}"):
        runmod.resume(out)
    assert not (out / "history.csv").exists() or (out / "history.csv").read_text().count("\n") <= 1
    release(held)
    summary = runmod.resume(out)
    assert summary is not None and summary["generations"] == 6 and not (out / LOCK_FILE).exists()


def test_a_stale_lock_of_a_killed_process_is_taken_over(tmp_path: Path) -> None:
    cfg = build_config(["reference"], **SETTINGS)
    out = tmp_path / "run"
    runmod.prepare(out, cfg)
    (out / LOCK_FILE).write_text(json.dumps({"host": socket.gethostname(), "pid": _dead_pid()}))
    assert runmod.resume(out) is not None and not (out / LOCK_FILE).exists()
    runmod.prepare(tmp_path / "other", build_config(["reference"], **SETTINGS))
    (tmp_path / "other" / LOCK_FILE).write_text(json.dumps({"host": "elsewhere", "pid": 1}))
    with pytest.raises(InputError, match="in use by process 1 on elsewhere"):
        runmod.resume(tmp_path / "other")
