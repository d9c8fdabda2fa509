"""Issue "Hardening IV": inputs without an upper bound were taken (a link of 1e9 mm, a table 1e9 mm away, a drilling
speed of 1e9 mm/s, a margin of 1e9 deg, a best-known eta_G of 1e300, a limit of 1e12 mm, a docking error of 720 deg,
a search bound of 1e9 mm). Each is refused in one line naming its flag (or file and field), exit 2, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import arcube
from arcube.errors import InputError
from harness import cli_error

DATA = Path(__file__).parent / "data"
ROBOT = DATA / "one_robot.json"


def _one_line(code: int, err: str, *needles: str) -> None:
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (code, err)
    for needle in needles:
        assert needle in err, err


def test_a_design_file_with_a_link_of_1e9_mm_is_refused(tmp_path: Path, capsys) -> None:
    design = {**arcube.Design.paper().to_dict(), "d_x": 1e9}
    path = tmp_path / "big.json"
    path.write_text(json.dumps(design))
    report = tmp_path / "r.html"
    code, err = cli_error(["evaluate", "--design", str(path), "--points", "3", "--report", str(report)], capsys)
    _one_line(code, err, "big.json", "d_x", "at most 2000 mm")
    assert not report.exists()
    with pytest.raises(InputError, match="length L must be at most 2000 mm"):
        arcube.Design.from_dict({**design, "d_x": 80.0, "mount_rx": 0, "mount_ry": 0, "mount_rz": 0, "L": 5e3})
    with pytest.raises(InputError, match="c_z .* at most 2000 mm"):
        arcube.Design.from_dict({**design, "d_x": 80.0, "c_z": 1e9})


CASES = [
    (["evaluate", "--points", "3", "--envelope", "default", "--table-z", "1e9", "--report", "{out}.html"], "--table-z"),
    (["joints", "--points", "3", "--speed", "1e9", "--out", "{out}"], "--speed"),
    (["optimize", "--trajectories", "reference", "--margin", "1e9", "--out", "{out}"], "--margin"),
    (["study", "--trajectories", "reference", "--best-known", "1e300", "--out", "{out}"], "--best-known"),
    (["optimize", "--trajectories", "reference", "--bounds", "d_x=1:1e9", "--out", "{out}"], "--bounds d_x"),
    (["optimize", "--trajectories", "reference", "--free", "all,c_z", "--c-z", "1e9", "--out", "{out}"], "--c-z"),
    (
        ["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--max", "lateral_error=1e12", "--out", "{out}"],
        "--max 'lateral_error=1e12'",
    ),
    (
        ["tolerance", "--design", str(ROBOT), "--side", "R", "--trajectories", "reference", "--docking-deg", "720"]
        + ["--out", "{out}"],
        "--docking-deg",
    ),
]


@pytest.mark.parametrize("argv, flag", CASES, ids=[c[1] for c in CASES])
def test_a_value_beyond_any_robot_is_refused_naming_its_flag(
    argv: list[str], flag: str, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "out"
    code, err = cli_error([a.replace("{out}", str(out)) for a in argv], capsys)
    _one_line(code, err, flag)
    assert not out.exists() and not list(tmp_path.iterdir())


def test_the_bounds_hold_in_the_library_too() -> None:
    """The bound is the setting's (or the library check's), not the command line's: the API refuses the same."""
    with pytest.raises(InputError, match="^RunSettings.margin"):
        arcube.RunSettings(margin=1e9)
    with pytest.raises(InputError, match="^RunSettings.table_z"):
        arcube.RunSettings(table_z=1e9)
    with pytest.raises(InputError, match="^speed must be at most 1000 mm/s"):
        arcube.joints("paper", "reference", speed=1e9, points=3)
    with pytest.raises(InputError, match="^table_z must lie within"):
        arcube.evaluate("paper", "reference", points=3, envelope="default", table_z=-1e9)
    with pytest.raises(InputError, match="^ToleranceSettings.docking_deg"):
        arcube.ToleranceSettings(docking_deg=720)
    with pytest.raises(InputError, match="m_x: the base position must stay within"):
        arcube.RunSettings(bounds={"m_x": (-1e9, 0.0)})
    with pytest.raises(InputError, match="torque=1000000000.0.: the value must lie within ±100000 N·m"):
        arcube.RunSettings(maxima={"torque": 1e9})


def test_values_within_the_bounds_are_taken() -> None:
    assert arcube.RunSettings(margin=180, table_z=-500.0, bounds={"d_x": (30.0, 2000.0)}).margin == 180
    assert arcube.Design.from_dict({**arcube.Design.paper().to_dict(), "d_x": 2000.0}).to_dict()["d_x"] == 2000.0
    assert arcube.RunSettings(maxima={"lateral_error": 1e4, "axis_error": 180}).maxima["axis_error"] == 180
