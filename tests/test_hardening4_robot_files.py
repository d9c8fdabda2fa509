"""A robot file carries its working mode (issue Hardening IV): a design file with c_z, dockings or zdyad_elbow but no
``mode`` is refused in one line naming ``mode``; a plain 27-parameter design without one still loads (the paper's mode
is the default), and a robot file with its mode loads as before."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import arcube
from arcube.errors import InputError
from arcube.model.design import Design
from designs import PROGRAM_DESIGN
from harness import arcube as run_arcube

ROBOT = Path(__file__).resolve().parent / "data" / "one_robot.json"


@pytest.mark.parametrize("extra", [{"c_z": 250.0}, {"zdyad_elbow": -1}, {"c_z": 250.0, "zdyad_elbow": 1}])
def test_a_robot_file_without_its_mode_is_refused_naming_mode(tmp_path: Path, extra: dict) -> None:
    f = tmp_path / "robot.json"
    f.write_text(json.dumps({**PROGRAM_DESIGN, **extra}))
    with pytest.raises(InputError, match=r"robot\.json: mode: missing; a robot file \(it has " + next(iter(extra))):
        Design.load(str(f))
    f.write_text(json.dumps({**PROGRAM_DESIGN, **extra, "mode": "+,+,-,+"}))
    assert Design.load(str(f)).mode == "+,+,-,+"


def test_the_one_robot_without_its_mode_is_refused_by_the_cli(tmp_path: Path) -> None:
    robot = json.loads(ROBOT.read_text())
    right = robot["dockings"][0]  # the robot at its first docking: a complete design with c_z, but no mode
    data = {k: v for k, v in robot.items() if k not in ("dockings", "mode")}
    data.update({k: right[k] for k in ("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz")})
    (tmp_path / "robot.json").write_text(json.dumps(data))
    out = run_arcube("evaluate", "--design", "robot.json", "--trajectories", "reference", "--side", "R", cwd=tmp_path)
    assert out.returncode == 2 and out.stdout == ""
    line = out.stderr.strip()
    assert "\n" not in line and "mode: missing" in line and "robot.json" in line


def test_a_plain_design_without_a_mode_still_loads(tmp_path: Path) -> None:
    f = tmp_path / "plain.json"
    f.write_text(json.dumps(PROGRAM_DESIGN))
    d = Design.load(str(f))
    assert d.mode is None and d.to_vector().shape == (27,)
    demo = Path(__file__).resolve().parent / "data" / "demo_design.json"
    assert arcube.Design.load(str(demo)).mode == json.loads(demo.read_text())["mode"]


def test_a_dock_folder_is_made_as_mkdir_makes_a_folder(tmp_path: Path) -> None:
    """``dock --out``'s top folder has the mode its subfolders have (0777 less the umask), not mkdtemp's 0700: dask
    workers and a team read it."""
    import os

    from arcube.design_job.coverage import _stage

    stage = _stage(tmp_path / "docked")
    (tmp_path / "plain").mkdir()
    umask = os.umask(0)
    os.umask(umask)
    assert stage.stat().st_mode & 0o777 == (tmp_path / "plain").stat().st_mode & 0o777 == 0o777 & ~umask
