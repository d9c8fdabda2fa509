"""``arcube calibrate poses | simulate | identify`` (issue "Calibration"): the command line runs the
library's calibration on a simulated robot, its calibrated design is read by every command, and bad
input is one line, exit 2, nothing left.

Oracle: the simulated robot's ground truth (its real zero offsets) and the library's own results for
the same files (the library is tested against ground truth in tests/test_calibrate*.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.calibrate import IdentifySettings, SimulateSettings
from arcube.calibrate.measurements import read_measurements
from arcube.model.design import Design
from harness import run_cli as _run

PLACED = Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("cal")
    PLACED.to_json(root / "nominal.json")
    return root


def test_poses_simulate_identify_from_the_command_line(folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = str(folder / "nominal.json")
    code, out, err = _run(
        [
            "calibrate",
            "poses",
            "--design",
            d,
            "--trajectories",
            "reference",
            "--side",
            "R",
            "--count",
            "30",
            "--points",
            "5",
            "--around",
            "5",
            "--out",
            str(folder / "poses.csv"),
        ],
        capsys,
    )
    assert code == 0, err
    assert "O1" in out and "not identifiable: f_z" in out  # r and f_x + f_y + f_z enter as one sum (MODEL.md 21.2)
    code, _, err = _run(
        [
            "calibrate",
            "simulate",
            "--design",
            d,
            "--poses",
            str(folder / "poses.csv"),
            "--class",
            "m",
            "--seed",
            "2",
            "--sigma-mm",
            "0",
            "--sigma-deg",
            "0",
            "--out",
            str(folder / "meas.csv"),
        ],
        capsys,
    )
    assert code == 0, err
    sim = arcube.calibrate.simulate(PLACED, folder / "poses.csv", SimulateSettings(seed=2, sigma_mm=0.0, sigma_deg=0.0))
    np.testing.assert_array_equal(
        read_measurements(folder / "meas.csv").E, sim.measurements.E
    )  # the command is the library
    code, out, err = _run(
        [
            "calibrate",
            "identify",
            "--design",
            d,
            "--measurements",
            str(folder / "meas.csv"),
            "--holdout",
            "0",
            "--sigma-mm",
            "0.15",
            "--out",
            str(folder / "id"),
        ],
        capsys,
    )
    assert code == 0, err
    assert sorted(p.name for p in (folder / "id").iterdir()) == [
        "calibration.html",
        "calibration.json",
        "covariance.csv",
        "design.json",
        "residuals.csv",
    ]
    calibrated = Design.from_json(folder / "id" / "design.json")
    np.testing.assert_allclose(calibrated.q0, sim.q0_deg, atol=1e-6)  # noise-free: the real zero offsets, recovered
    doc = json.loads((folder / "id" / "calibration.json").read_text())
    assert set(doc["observability"]) >= {"O1", "condition_number"} and doc["not_identifiable"] == ["f_z"]
    lib = arcube.calibrate.identify(PLACED, folder / "meas.csv", settings=IdentifySettings(holdout=0.0))
    assert lib.calibrated_design() == calibrated  # the command wrote the library's calibrated design
    ev = arcube.evaluate(folder / "id" / "design.json", "reference", side="R", points=4, engine="numpy")
    assert (
        ev.design.q0_deg == calibrated.q0_deg and ev.to_json()["design"]["q0_rho_x"] == calibrated.q0_deg[0]
    )  # read and kept


@pytest.mark.parametrize("case", ["nan", "missing column", "other design"])
def test_bad_measurements_are_one_line_exit_2_and_nothing_written(
    case: str, folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = str(folder / "nominal.json")
    if not (folder / "poses.csv").exists():
        _run(
            [
                "calibrate",
                "poses",
                "--design",
                d,
                "--trajectories",
                "reference",
                "--side",
                "R",
                "--count",
                "30",
                "--points",
                "5",
                "--around",
                "5",
                "--out",
                str(folder / "poses.csv"),
            ],
            capsys,
        )
    lines = (folder / "poses.csv").read_text().splitlines()
    header = lines[0].split(",")
    if case == "nan":
        cells = lines[3].split(",")
        cells[header.index("E_x")] = "nan"
        lines[3] = ",".join(cells)
        argv = [
            "calibrate",
            "identify",
            "--design",
            d,
            "--measurements",
            str(tmp_path / "m.csv"),
            "--out",
            str(tmp_path / "id"),
        ]
        expect = "m.csv"
    elif case == "missing column":
        keep = [i for i, h in enumerate(header) if h != "e_z"]
        lines = [",".join(line.split(",")[i] for i in keep) for line in lines]
        argv = [
            "calibrate",
            "identify",
            "--design",
            d,
            "--measurements",
            str(tmp_path / "m.csv"),
            "--out",
            str(tmp_path / "id"),
        ]
        expect = "e_z"
    else:
        PLACED.replace(r=71.0).to_json(tmp_path / "other.json")
        argv = [
            "calibrate",
            "simulate",
            "--design",
            str(tmp_path / "other.json"),
            "--poses",
            str(tmp_path / "m.csv"),
            "--out",
            str(tmp_path / "id"),
        ]
        expect = "design"
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    code, _, err = _run(argv, capsys)
    assert code == 2 and err.startswith("error: ") and expect in err and err.count("\n") == 1, err
    assert not (tmp_path / "id").exists()
