"""``arcube design`` refuses the flags it would ignore (issue Hardening IV), in one line naming the flag, before any work:
``--aggregate`` with one docking, ``--class`` beside a ``--tol`` that sets every length and angle."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness import arcube as run_arcube


@pytest.mark.parametrize(
    "flags, named",
    [
        (["--side", "R", "--aggregate", "mean"], "--aggregate mean"),
        (["--class", "f", "--tol", "lengths=0.05,angles=0.01"], "--class f"),
    ],
)
def test_a_design_flag_that_would_be_ignored_is_refused(tmp_path: Path, flags: list[str], named: str) -> None:
    out = run_arcube("design", "--trajectories", "reference", "--out", "d", "--quiet", *flags, cwd=tmp_path)
    assert out.returncode == 2, out.stdout + out.stderr
    line = out.stderr.strip()
    assert "\n" not in line and line.startswith(f"error: {named}")
    assert "ignored" in line or "change nothing" in line
    assert not (tmp_path / "d").exists()
