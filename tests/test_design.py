"""Design parameters: names, preset, JSON I/O and validation (MODEL.md section 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arcube.model.design import PAPER_NAMES, PARAM_NAMES, Design, unpack
from arcube.errors import InputError

# Typed from the paper's Table 2, in MODEL.md's code order.
TABLE2 = [
    31.8694,
    11.9589,
    192.0769,
    123.1147,
    116.9719,
    56.7787,
    134.099,
    149.9886,
    99.8766,
    79.2596,
    99.9402,
    53.5671,
    139.8911,
    106.8319,
    70.9301,
    65.3946,
    70.4466,
    -19.2229,
    43.2917,
    52.6402,
    66.446,
    50.0038,
    62.1208,
]


def test_names_in_model_order() -> None:
    expected = "m_x m_y m_z f_x f_y f_z p_x p_y p_z d_x d_y d_z c_x c_y t_x t_y r o_x o_y alpha_x alpha_y beta_x beta_y"
    assert PAPER_NAMES == tuple(expected.split())
    # MODEL.md 13.3: the 23, then the mounting angles and the tool offset
    assert PARAM_NAMES == (*expected.split(), "mount_rx", "mount_ry", "mount_rz", "L")


def test_paper_preset_is_table2() -> None:
    np.testing.assert_array_equal(Design.preset("paper").to_vector(), [*TABLE2, 0.0, 0.0, 0.0, 0.0])


def test_json_round_trip(tmp_path: Path) -> None:
    d = Design.preset("paper").replace(m_x=-12.5, r=60.0)
    path = tmp_path / "d.json"
    d.to_json(path)
    assert json.loads(path.read_text()) == d.to_dict()
    assert Design.from_json(path) == d
    assert Design.from_vector(d.to_vector()) == d


def test_unpack_converts_angles_to_radians() -> None:
    g = unpack(np.array(TABLE2))
    assert g.alpha[0] == pytest.approx(np.radians(52.6402))
    assert g.o[1] == pytest.approx(np.radians(43.2917))
    assert g.r == 70.4466 and g.c[1] == 106.8319 and g.d[2] == 53.5671
    batch = unpack(np.stack([TABLE2, TABLE2])[:, None, :])
    assert batch.p.shape == (2, 1, 3) and batch.r.shape == (2, 1)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"drop": "r"}, "missing parameter(s) r"),
        ({"add": ("c_w", 50.0)}, "unknown parameter 'c_w'"),  # c_z is a design's own since MODEL.md 19.1
        ({"add": ("c_z", -50.0)}, "c_z (the z dyad's second link) must be a positive length"),
        ({"set": ("p_x", -3.0)}, "length p_x must be positive"),
        ({"set": ("t_y", 0.0)}, "length t_y must be positive"),
        ({"set": ("f_y", "abc")}, "parameter f_y is not a number"),
        ({"set": ("alpha_x", 200.0)}, "alpha_x must lie in (0, 180)"),
        ({"set": ("L", -1.0)}, "tool offset L must be >= 0"),
        ({"mount": (0.0, float("nan"), 0.0)}, "mount_ry is not finite"),
        ({"mount": (None, 5.0, None)}, "missing mount_rx, mount_rz"),
        ({"add": ("mount_rw", 5.0)}, "unknown parameter 'mount_rw'"),
    ],
)
def test_invalid_designs_are_refused(tmp_path: Path, change: dict, message: str) -> None:
    values: dict = dict(zip(PAPER_NAMES, TABLE2))
    if "drop" in change:
        del values[change["drop"]]
    if "add" in change:
        values[change["add"][0]] = change["add"][1]
    if "set" in change:
        values[change["set"][0]] = change["set"][1]
    for name, value in zip(("mount_rx", "mount_ry", "mount_rz"), change.get("mount", ())):
        values["L"] = 100.0  # a mounted design needs its tool offset
        if value is not None:
            values[name] = value
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(values))
    with pytest.raises(InputError, match=None) as info:
        Design.from_json(path)
    assert message in str(info.value) and str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_negative_placement_and_offsets_are_fine() -> None:
    d = Design.preset("paper").replace(m_x=-100.0, o_x=-200.0)
    assert d["m_x"] == -100.0 and d["o_x"] == -200.0


def test_files_without_the_four_additions_load_as_the_paper(tmp_path: Path) -> None:
    path = tmp_path / "d23.json"
    path.write_text(json.dumps(dict(zip(PAPER_NAMES, TABLE2))))
    d = Design.from_json(path)
    assert [d[n] for n in ("mount_rx", "mount_ry", "mount_rz", "L")] == [0.0, 0.0, 0.0, 0.0]
    assert d == Design.preset("paper")
    out = tmp_path / "d27.json"
    d.replace(mount_rz=30.0, L=120.0).to_json(out)
    written = json.loads(out.read_text())
    assert list(written) == list(PARAM_NAMES) and written["L"] == 120.0
