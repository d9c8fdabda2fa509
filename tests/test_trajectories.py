"""Trajectory sets: CSV reading/writing, subsets, rigid transform, bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from arcube.errors import InputError
from arcube.io import (
    TrajectorySet,
    load_trajectories,
    read_transform,
    select,
    write_csv,
)

DATA = Path(__file__).parent / "data" / "trajectories"
HEADER = "trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z\n"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


# ---------------------------------------------------------------- reading


def test_reference_is_the_bundled_mean_patient() -> None:
    ts = load_trajectories("reference")
    assert ts.source == "reference"
    assert ts.ids == tuple(str(i) for i in range(1, 11))
    assert ts.levels == ("C3", "C3", "C4", "C4", "C5", "C5", "C6", "C6", "C7", "C7")
    assert ts.sides == ("R", "L") * 5
    # First and last rows typed from the CSV file itself.
    assert ts.entry[0].tolist() == [22.205, 35.351, 14.850]
    assert ts.target[9].tolist() == [-3.586, -35.735, -3.632]
    assert ts.entry.shape == ts.target.shape == (10, 3)


def test_extra_columns_ignored_ids_kept_as_strings_and_order_kept() -> None:
    ts = load_trajectories(DATA / "plan_extra_columns.csv")
    assert ts.ids == ("007", "A2", "3")
    assert ts.levels == ("C4", "C4", "")
    assert ts.sides == ("R", "L", "")
    np.testing.assert_array_equal(ts.entry, [[20, 15, 30], [-20, 15, 30], [1.5, -2.25, 0]])
    np.testing.assert_array_equal(ts.target, [[2, 18, 45], [-2, 18, 45], [1.5, -2.25, 10]])
    assert len(ts) == 3


def test_level_and_side_columns_are_optional(tmp_path: Path) -> None:
    p = _write(tmp_path, "a.csv", "trajectory,entry_x,entry_y,entry_z,target_x,target_y,target_z\nx,0,0,0,0,0,1\n")
    ts = load_trajectories(p)
    assert ts.levels == ("",) and ts.sides == ("",)


def test_lengths_property() -> None:
    ts = load_trajectories(DATA / "plan_extra_columns.csv")
    assert ts.lengths[2] == pytest.approx(10.0)
    assert ts.lengths[0] == pytest.approx(math.sqrt(18**2 + 3**2 + 15**2))


def test_set_is_immutable() -> None:
    ts = load_trajectories("reference")
    with pytest.raises(ValueError):
        ts.entry[0, 0] = 1.0


# ---------------------------------------------------------------- writing


def test_write_csv_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    entry = rng.normal(0, 30, (5, 3))
    ts = TrajectorySet(
        ("a", "b", "07", "x y", "5"),
        ("C3", "", "C7", "C5", "C4"),
        ("R", "L", "", "R", "L"),
        entry,
        entry + rng.normal(0, 20, (5, 3)),
        "made",
    )
    out = tmp_path / "sub" / "t.csv"
    write_csv(ts, out)
    back = load_trajectories(out)
    assert back.ids == ts.ids and back.levels == ts.levels and back.sides == ts.sides
    np.testing.assert_array_equal(back.entry, ts.entry)
    np.testing.assert_array_equal(back.target, ts.target)
    assert sorted(f.name for f in out.parent.iterdir()) == ["t.csv"]  # no temporary file left


def test_write_csv_fixed_decimals(tmp_path: Path) -> None:
    ts = TrajectorySet(("1",), ("C5",), ("R",), [[1.23456, -0.0001, 0]], [[0, 0, 1]], "made")
    out = tmp_path / "t.csv"
    write_csv(ts, out, decimals=3)
    assert out.read_text().splitlines()[1] == "1,C5,R,1.235,0.000,0.000,0.000,0.000,1.000"


# ---------------------------------------------------------------- select


@pytest.fixture()
def ref() -> TrajectorySet:
    return load_trajectories("reference")


def test_select_side(ref: TrajectorySet) -> None:
    assert select(ref, side="L").ids == ("2", "4", "6", "8", "10")
    assert select(ref, side="r").sides == ("R",) * 5


def test_select_levels_range_list_and_mixture(ref: TrajectorySet) -> None:
    assert select(ref, levels="C3-C4").ids == ("1", "2", "3", "4")
    assert select(ref, levels="C3,C5").ids == ("1", "2", "5", "6")
    assert select(ref, levels="C3,C6-C7").ids == ("1", "2", "7", "8", "9", "10")
    assert select(ref, levels="C1-C7") == ref


def test_select_ids_keeps_set_order(ref: TrajectorySet) -> None:
    sub = select(ref, ids="5,1,3")
    assert sub.ids == ("1", "3", "5")
    np.testing.assert_array_equal(sub.entry, ref.entry[[0, 2, 4]])


def test_select_filters_combine(ref: TrajectorySet) -> None:
    assert select(ref, side="R", levels="C4-C6", ids="3,4,5,9").ids == ("3", "5")


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"side": "R", "ids": "2"}, "no trajectory"),
        ({"side": "X"}, "expected R or L"),
        ({"levels": "C5-C3"}, "backwards"),
        ({"levels": "C3-T1"}, "C1..C7"),
        ({"levels": "C3,,C4"}, "empty item"),
        ({"ids": "1,99"}, "unknown trajectory id(s) 99"),
        ({"levels": "T1"}, "no trajectory"),
    ],
)
def test_select_errors(ref: TrajectorySet, kwargs: dict[str, str], needle: str) -> None:
    with pytest.raises(InputError) as err:
        select(ref, **kwargs)
    assert needle in str(err.value)


# ---------------------------------------------------------------- transform


def _rot_z(deg: float) -> list[list[float]]:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]


@pytest.mark.parametrize("wrap", [lambda m: {"matrix": m}, lambda m: m])
def test_transform_applied_after_reading(tmp_path: Path, wrap) -> None:
    r = _rot_z(90.0)
    m = [r[0] + [10.0], r[1] + [0.0], r[2] + [-5.0], [0, 0, 0, 1]]
    tf = _write(tmp_path, "tf.json", json.dumps(wrap(m)))
    ts = load_trajectories(DATA / "plan_extra_columns.csv", transform=tf)
    # 90 deg about z maps (x, y, z) to (-y, x, z); then + (10, 0, -5).
    np.testing.assert_allclose(ts.entry[0], [-15 + 10, 20, 30 - 5], atol=1e-12)
    np.testing.assert_allclose(ts.target[2], [2.25 + 10, 1.5, 10 - 5], atol=1e-12)


@pytest.mark.parametrize(
    "content, reason",
    [
        ("{not json", "not valid JSON"),
        (json.dumps({"rows": []}), "'matrix'"),
        (json.dumps([[1, 0, 0], [0, 1, 0], [0, 0, 1]]), "4 rows of 4"),
        (json.dumps([[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]), "orthonormal"),
        (json.dumps([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), "determinant"),
        (json.dumps([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]), "last row"),
        (json.dumps([[1, 0, 0, "a"], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), "4 rows of 4"),
    ],
)
def test_unreadable_transform(tmp_path: Path, content: str, reason: str) -> None:
    tf = _write(tmp_path, "tf.json", content)
    with pytest.raises(InputError) as err:
        load_trajectories("reference", transform=tf)
    msg = str(err.value)
    assert "unreadable transform" in msg and reason in msg and "tf.json" in msg
    assert "\n" not in msg


def test_transform_tolerance_accepts_rounded_rotation(tmp_path: Path) -> None:
    r = np.round(np.array(_rot_z(30.0)), 9)  # 9 decimals: within the 1e-6 rigidity tolerance
    m = np.eye(4)
    m[:3, :3] = r
    assert read_transform(_write(tmp_path, "tf.json", json.dumps(m.tolist()))).shape == (4, 4)


# ---------------------------------------------------------------- bad CSV input


@pytest.mark.parametrize(
    "text, needle",
    [
        ("", "empty file"),
        ("   \n\n", "empty file"),
        (HEADER, "no trajectories"),
        (
            "trajectory,level,side,entry_x,entry_y,target_x,target_y,target_z\n1,C3,R,1,2,3,4,5\n",
            "missing column(s) entry_z",
        ),
        (HEADER + "1,C3,R,1,2,3,4,5,6\n2,C3,L,1,nan,3,4,5,6\n", "row 3: entry_y is not finite ('nan')"),
        (HEADER + "1,C3,R,1,2,inf,4,5,6\n", "row 2: entry_z is not finite ('inf')"),
        (HEADER + "1,C3,R,1,2,3,4,abc,6\n", "row 2: target_y is not a number ('abc')"),
        (HEADER + "1,C3,R,1,2,3,1,2,3\n", "row 2: zero-length trajectory (entry == target)"),
        (HEADER + "1,C3,R,1,2,3,4,5,6\n1,C3,L,1,2,3,4,5,7\n", "row 3: duplicate trajectory id '1'"),
        (HEADER + ",C3,R,1,2,3,4,5,6\n", "row 2: empty trajectory id"),
        (HEADER + "1,C3,X,1,2,3,4,5,6\n", "row 2: side must be R, L or empty"),
        (HEADER + "1,C3,R,1,2,3\n", "row 2: 6 fields"),
    ],
)
def test_bad_csv(tmp_path: Path, text: str, needle: str) -> None:
    p = _write(tmp_path, "bad.csv", text)
    with pytest.raises(InputError) as err:
        load_trajectories(p)
    msg = str(err.value)
    assert needle in msg and "bad.csv" in msg and "\n" not in msg


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        load_trajectories(tmp_path / "nope.csv")


def test_bom_is_accepted(tmp_path: Path) -> None:
    p = tmp_path / "bom.csv"
    p.write_bytes(("\ufeff" + HEADER + "1,C3,R,1,2,3,4,5,6\n").encode("utf-8"))
    assert load_trajectories(p).ids == ("1",)
