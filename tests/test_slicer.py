"""Slicer markups JSON: coordinate systems, ids, round trip, bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.io.slicer import read_markups, write_markups
from arcube.io import load_trajectories, write_csv

DATA = Path(__file__).parent / "data" / "trajectories"
SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/"
    "Resources/Schema/markups-schema-v1.0.3.json#"
)

# The same physical line in both hand-made files. Patient frame: x right, y superior,
# z posterior. RAS (r, a, s) = (20, 30, 15): 20 mm right, 30 mm anterior, 15 mm superior
# -> patient (20, 15, -30). In LPS the same point is (l, p, s) = (-20, -30, 15).
ENTRY = [20.0, 15.0, -30.0]
TARGET = [2.0, 18.0, -45.0]  # RAS (2, 45, 18) / LPS (-2, -45, 18)


@pytest.mark.parametrize("name", ["ras_line.mrk.json", "lps_line.mrk.json"])
def test_coordinate_systems_known_answer(name: str) -> None:
    ts = read_markups(DATA / name)
    assert ts.ids == ("C4 right",)
    np.testing.assert_array_equal(ts.entry, [ENTRY])
    np.testing.assert_array_equal(ts.target, [TARGET])
    assert ts.levels == ("",) and ts.sides == ("",)


def test_absent_system_is_lps_fiducials_skipped_unnamed_ids() -> None:
    ts = load_trajectories(DATA / "mixed_no_system.mrk.json")
    assert ts.ids == ("mixed_no_system-1", "mixed_no_system-2")
    # LPS (1, 2, 3): 1 mm left, 2 mm posterior, 3 mm superior -> patient (-1, 3, 2).
    np.testing.assert_array_equal(ts.entry, [[-1, 3, 2], [1, 3, 2]])
    np.testing.assert_array_equal(ts.target, [[-4, 8, 6], [4, 8, 6]])


def test_single_unnamed_line_takes_file_stem(tmp_path: Path) -> None:
    doc = {
        "@schema": SCHEMA,
        "markups": [
            {
                "type": "Line",
                "coordinateSystem": "RAS",
                "controlPoints": [{"position": [0, 0, 0]}, {"position": [0, -10, 0]}],
            }
        ],
    }
    p = tmp_path / "left C5.mrk.json"
    p.write_text(json.dumps(doc))
    ts = read_markups(p)
    assert ts.ids == ("left C5",)
    # RAS a = -10 is 10 mm posterior -> patient z = +10.
    np.testing.assert_array_equal(ts.target, [[0, 0, 10]])


def test_micrometre_units(tmp_path: Path) -> None:
    doc = {
        "@schema": SCHEMA,
        "markups": [
            {
                "type": "Line",
                "name": "u",
                "coordinateSystem": "RAS",
                "coordinateUnits": "um",
                "controlPoints": [{"position": [1000, 0, 0]}, {"position": [0, 0, 2000]}],
            }
        ],
    }
    p = tmp_path / "u.mrk.json"
    p.write_text(json.dumps(doc))
    ts = read_markups(p)
    np.testing.assert_allclose(ts.entry, [[1, 0, 0]])
    np.testing.assert_allclose(ts.target, [[0, 2, 0]])


def test_folder_of_files_sorted_by_name(tmp_path: Path) -> None:
    shutil.copy(DATA / "ras_line.mrk.json", tmp_path / "b.mrk.json")
    shutil.copy(DATA / "mixed_no_system.mrk.json", tmp_path / "a.mrk.json")
    (tmp_path / "notes.txt").write_text("ignored")
    ts = load_trajectories(tmp_path)
    assert ts.ids == ("a-1", "a-2", "C4 right")


@pytest.mark.parametrize("target", ["plan.mrk.json", "folder"])
def test_csv_slicer_csv_round_trip(tmp_path: Path, target: str) -> None:
    ref = load_trajectories("reference")
    write_markups(ref, tmp_path / target)
    back = load_trajectories(tmp_path / target)
    write_csv(back, tmp_path / "back.csv", decimals=3)
    # The written CSV is the bundled one, byte for byte.
    bundled = Path(__file__).parents[1] / "src" / "arcube" / "data" / "reference_patient.csv"
    assert (tmp_path / "back.csv").read_text() == bundled.read_text()
    again = load_trajectories(tmp_path / "back.csv")
    assert (again.ids, again.levels, again.sides) == (ref.ids, ref.levels, ref.sides)
    np.testing.assert_array_equal(again.entry, ref.entry)
    np.testing.assert_array_equal(again.target, ref.target)


def test_written_file_follows_the_schema(tmp_path: Path) -> None:
    """Required fields and value constraints of markups-schema-v1.0.3 (checked by hand)."""
    ref = load_trajectories("reference")
    out = tmp_path / "plan.mrk.json"
    write_markups(ref, out)
    doc = json.loads(out.read_text())
    assert doc["@schema"] == SCHEMA and isinstance(doc["markups"], list)
    assert len(doc["markups"]) == 10
    for m, tid in zip(doc["markups"], ref.ids):
        assert m["type"] == "Line" and m["name"] == tid
        assert m["coordinateSystem"] in ("LPS", "RAS") and m["coordinateUnits"] in ("mm", "um")
        assert len(m["controlPoints"]) == 2
        for cp in m["controlPoints"]:
            assert isinstance(cp["id"], str) and isinstance(cp["label"], str)
            assert len(cp["position"]) == 3 and all(isinstance(v, float) for v in cp["position"])
            assert len(cp["orientation"]) == 9
            assert cp["positionStatus"] in ("undefined", "preview", "defined")
            assert all(isinstance(cp[k], bool) for k in ("selected", "locked", "visibility"))
    # LPS: trajectory 1 entry (22.205, 35.351, 14.850) patient -> (l, p, s) = (-22.205, 14.85, 35.351)
    assert doc["markups"][0]["controlPoints"][0]["position"] == [-22.205, 14.85, 35.351]


def test_folder_write_refuses_leftover_files(tmp_path: Path) -> None:
    ref = load_trajectories("reference")
    (tmp_path / "old.mrk.json").write_text("{}")
    with pytest.raises(InputError, match="already holds other markups files"):
        write_markups(ref, tmp_path)


def _doc(**markup) -> dict:
    base = {
        "type": "Line",
        "name": "t1",
        "coordinateSystem": "LPS",
        "controlPoints": [{"position": [0, 0, 0]}, {"position": [1, 2, 3]}],
    }
    base.update(markup)
    return {"@schema": SCHEMA, "markups": [base]}


@pytest.mark.parametrize(
    "content, needle",
    [
        (
            _doc(controlPoints=[{"position": [0, 0, 0]}, {"position": [1, 1, 1]}, {"position": [2, 2, 2]}]),
            "markup 1 ('t1'): Line has 3 control points, expected 2",
        ),
        (_doc(controlPoints=[{"position": [0, 0, 0]}]), "Line has 1 control points"),
        (_doc(coordinateSystem="XYZ"), "unknown coordinate system 'XYZ'"),
        (_doc(coordinateUnits="cm"), "unknown coordinateUnits 'cm'"),
        (_doc(controlPoints=[{"position": [0, 0]}, {"position": [1, 2, 3]}]), "control point 1 has no position"),
        (_doc(controlPoints=[{"position": [0, 0, 0]}, {"position": [0, 0, 0]}]), "zero-length trajectory"),
        ({"markups": [{"type": "Fiducial", "controlPoints": []}]}, "no markup of type 'Line'"),
        ({"trajectories": []}, "not a Slicer markups file"),
        ([1, 2, 3], "not a Slicer markups file"),
        ({"@schema": "https://example.org/other-schema.json", "markups": []}, "not a Slicer markups file"),
    ],
)
def test_bad_markups(tmp_path: Path, content: object, needle: str) -> None:
    p = tmp_path / "bad.mrk.json"
    p.write_text(json.dumps(content))
    with pytest.raises(InputError) as err:
        load_trajectories(p)
    msg = str(err.value)
    assert needle in msg and "bad.mrk.json" in msg and "\n" not in msg


def test_non_finite_position(tmp_path: Path) -> None:
    p = tmp_path / "nan.mrk.json"
    p.write_text(json.dumps(_doc(controlPoints=[{"position": [0, 0, float("nan")]}, {"position": [1, 2, 3]}])))
    with pytest.raises(InputError, match="not finite"):
        read_markups(p)


def test_invalid_json_and_duplicate_ids(tmp_path: Path) -> None:
    bad = tmp_path / "broken.mrk.json"
    bad.write_text('{"markups": [')
    with pytest.raises(InputError, match="not valid JSON"):
        read_markups(bad)
    folder = tmp_path / "dups"
    folder.mkdir()
    shutil.copy(DATA / "ras_line.mrk.json", folder / "1.mrk.json")
    shutil.copy(DATA / "lps_line.mrk.json", folder / "2.mrk.json")
    with pytest.raises(InputError, match="duplicate trajectory id 'C4 right'"):
        read_markups(folder)


def test_empty_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no .mrk.json file"):
        load_trajectories(tmp_path)
