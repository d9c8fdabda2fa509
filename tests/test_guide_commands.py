"""Every command of the accuracy guide runs, copy-pasted, from a temporary folder holding what the demo writes.

The demo's one robot is tests/data/one_robot.json (the robot ``arcube demo`` designs, seed 1); its right-side docking
is written where the demo writes it (arcube-demo/one_robot/dockings/reference_R/design.json). Each ``arcube ...``
line of the guide's bash blocks then runs in process, in the guide's order (the calibration's files feed each other)
and must exit 0. The two search commands (``design``, ``optimize``) are parsed and validated up to the search, which
is replaced by a recorder: their minutes belong to benchmarks/, not to the suite.
"""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

import arcube.api
from arcube.cli import app
from arcube.model.robot import design_at_side, write_docking

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "guide" / "accuracy.md"
DEMO_DOCKING = Path("arcube-demo/one_robot/dockings/reference_R/design.json")


def guide_commands() -> list[list[str]]:
    """The guide's ``arcube`` lines, in order, as argv lists (without the leading ``arcube``)."""
    blocks = re.findall(r"```bash\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.DOTALL)
    return [shlex.split(line)[1:] for block in blocks for line in block.splitlines() if line.startswith("arcube ")]


def test_the_guide_names_the_demos_own_files() -> None:
    commands = guide_commands()
    assert len(commands) >= 7
    designs = {argv[argv.index("--design") + 1] for argv in commands if "--design" in argv}
    assert designs == {str(DEMO_DOCKING)}, designs  # no test file, no path the demo never writes


def test_every_command_of_the_guide_runs_from_a_fresh_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / DEMO_DOCKING).parent.mkdir(parents=True)
    write_docking(
        design_at_side(ROOT / "tests" / "data" / "one_robot.json", "R"), tmp_path / DEMO_DOCKING, "reference", "R"
    )
    searched: list[str] = []

    def recorder(name: str):
        def run(*args: object, **kwargs: object) -> None:
            searched.append(name)
            raise SystemExit(0)

        return run

    monkeypatch.setattr(arcube.api, "design", recorder("design"))
    monkeypatch.setattr(arcube.api, "optimize", recorder("optimize"))
    monkeypatch.chdir(tmp_path)
    for argv in guide_commands():
        if argv[0] == "tolerance":
            argv = [*argv, "--samples", "200"]  # the figures are the benchmark's; here: that the command runs
        res = CliRunner().invoke(app, argv, env={"COLUMNS": "120"})
        assert res.exit_code == 0, (argv, res.output, res.exception)
    assert searched == ["design", "optimize"]
    assert (tmp_path / "calibrated" / "design.json").is_file() and (tmp_path / "budget_R" / "tolerance.json").is_file()
    assert os.path.isfile(tmp_path / "measured.truth.json")
