"""The calibration's files: the measurement CSV (MODEL.md 21.1), the calibrated design.json, the settings.

Oracles: round trips (write then read gives the same numbers), hand-written CSV texts with one defect
each (the message must name the file, the row and the problem, on one line), hand-computed normalisation.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from arcube.calibrate import IdentifySettings, PoseSettings, SimulateSettings
from arcube.calibrate.design_file import (
    Q0_KEYS,
    design_digest,
    load_design,
    read_calibrated,
    write_calibrated,
)
from arcube.calibrate.measurements import (
    Measurements,
    read_measurements,
    write_measurements,
)
from arcube.errors import InputError
from arcube.model.design import PAPER_TABLE2, Design

HEAD = "rho_x,rho_y,rho_z,delta_x,delta_y,E_x,E_y,E_z,e_x,e_y,e_z"
ROW = "1,2,3,4,5,10,20,30,0,0,2"


def _file(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_round_trip_and_normalisation(tmp_path):
    rng = np.random.default_rng(0)
    q, E, e = rng.uniform(-90, 90, (7, 5)), rng.uniform(-300, 300, (7, 3)), rng.normal(size=(7, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    m = Measurements(q, E, e, tuple(f"p{i}" for i in range(7)), "0123456789abcdef")
    write_measurements(tmp_path / "x.csv", m)
    back = read_measurements(tmp_path / "x.csv")
    assert np.array_equal(back.q_deg, q) and np.array_equal(back.E, E)
    np.testing.assert_allclose(back.e, e, rtol=0, atol=1e-15)
    assert back.pose == m.pose and back.design == m.design
    assert back.rows == tuple(range(2, 9))  # line numbers, the header is row 1

    plain = read_measurements(_file(tmp_path, f"{HEAD}\n{ROW}\n"))  # a tracker's plain file: no pose, no design
    assert plain.pose is None and plain.design is None
    np.testing.assert_array_equal(plain.e, [[0.0, 0.0, 1.0]])  # (0, 0, 2) normalised
    shuffled = "e_z,E_x,E_y,E_z,e_x,e_y,rho_x,rho_y,rho_z,delta_x,delta_y\n2,10,20,30,0,0,1,2,3,4,5\n"
    again = read_measurements(_file(tmp_path, shuffled, "s.csv"))  # columns in any order
    assert np.array_equal(again.q_deg, plain.q_deg) and np.array_equal(again.E, plain.E)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("", ["empty file"]),
        (f"{HEAD}\n", ["no measurements"]),
        (f"{HEAD}\n1,2,3,4,5,10,20,nan,0,0,1\n", ["row 2", "E_z", "not finite"]),
        (f"{HEAD}\n{ROW}\n1,2,inf,4,5,10,20,30,0,0,1\n", ["row 3", "rho_z", "not finite"]),
        (f"{HEAD}\n1,2,3,4,5,10,20,30,0,0,0\n", ["row 2", "(0, 0, 0)"]),
        (f"{HEAD}\n1,2,3,4,5,10,20,30,0,0,abc\n", ["row 2", "e_z", "not a number"]),
        (f"{HEAD}\n1,2,3,4,5,10,20,30,0,0,\n", ["row 2", "e_z", "empty"]),
        (f"{HEAD}\n1,2,3,4,5,10,20,30,0,0\n", ["row 2", "10 fields", "header has 11"]),
        (f"{HEAD}\n{ROW},7\n", ["row 2", "12 fields"]),
        (HEAD.replace(",e_z", "") + "\n1,2,3,4,5,10,20,30,0,0\n", ["missing column", "e_z"]),
        (HEAD + ",E_x\n" + ROW + ",1\n", ["E_x", "more than once"]),
        (HEAD + ",temperature\n" + ROW + ",1\n", ["unknown column", "temperature"]),
        (HEAD.replace("E_x", "e_X") + "\n" + ROW + "\n", ["unknown column", "case-sensitive"]),
        ("pose,design," + HEAD + "\n1,aaaa," + ROW + "\n2,bbbb," + ROW[:-1] + "3\n", ["2 different digests"]),
        (f"{HEAD}\n{ROW}\n{ROW.replace('0,0,2', '0,0,3')}\n{ROW}\n", ["row 4", "same 11 numbers as row 2"]),
        (f"{HEAD}\n1,2,3,4,500,10,20,30,0,0,1\n", ["row 2", "delta_y", "360"]),
    ],
)
def test_bad_files_one_line_naming_file_row_problem(tmp_path, text, words):
    p = _file(tmp_path, text)
    with pytest.raises(InputError) as info:
        read_measurements(p)
    msg = str(info.value)
    assert "\n" not in msg and str(p) in msg
    for w in words:
        assert w in msg


def test_calibrated_design_file_round_trip_and_keys(tmp_path):
    x = Design.paper().to_vector()
    q0 = np.array([0.01, -0.02, 0.03, -0.04, 0.05])
    write_calibrated(tmp_path / "d.json", x, q0, "+,+,+,-", c_z=123.5)
    data = json.loads((tmp_path / "d.json").read_text())
    assert set(data) == set(PAPER_TABLE2) | set(Q0_KEYS) | {"mode", "c_z"}
    design, q0_back = read_calibrated(tmp_path / "d.json")
    assert np.array_equal(design.to_vector(), x) and np.array_equal(q0_back, q0)
    start = load_design(tmp_path / "d.json")
    assert start.c_z == 123.5 and start.mode == "+,+,+,-" and start.calibrated
    plain = load_design("paper")
    assert not plain.calibrated and np.array_equal(plain.q0_deg, np.zeros(5)) and plain.c_z is None
    assert design_digest(x, q0) != design_digest(x, np.zeros(5)) != design_digest(x + 1e-9, np.zeros(5))
    del data["q0_delta_y"]
    (tmp_path / "e.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match="q0_delta_y"):
        load_design(tmp_path / "e.json")


@pytest.mark.parametrize(
    ("cls", "field", "value"),
    [
        (IdentifySettings, "holdout", 0.95),
        (IdentifySettings, "sigma_mm", 0.0),
        (IdentifySettings, "sigma_deg", float("nan")),
        (PoseSettings, "count", 0),
        (PoseSettings, "radius_deg", 90.0),
        (SimulateSettings, "tolerance_class", "x"),
        (SimulateSettings, "sigma_mm", -1.0),
        (IdentifySettings, "seed", -1),
    ],
)
def test_settings_errors_name_the_field(cls, field, value):
    with pytest.raises(InputError) as info:
        cls(**{field: value})
    assert str(info.value).startswith(f"{cls.__name__}.{field} ")
