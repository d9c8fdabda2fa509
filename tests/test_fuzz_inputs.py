"""Every reader of a user's file either loads it or raises one InputError (issue "Hardening").

Property-based part (Hypothesis): generated trajectory CSV, Slicer markups JSON, design JSON (and
the design mappings of the Python API) and rigid-transform JSON, in several encodings and with
hostile values (400-digit integers, 1e300, NaN, deep nesting, lists where strings belong, NUL
bytes, duplicated columns), are fed to the readers. The promise checked for each example: the
reader returns, or raises :class:`~arcube.errors.InputError` whose message is one line naming the
file; no other exception and no warning (numpy's RuntimeWarning included) ever escapes. The
example counts are fixed and derandomized so CI runs the same examples in the same time; run
``pytest tests/test_fuzz_inputs.py --hypothesis-show-statistics`` to see how many each tried.

Then one regression test per defect of the issue that these readers own: D1, D2, D3, D4, D5, D6,
D13 (with D18's message), D19 and D22.
"""

from __future__ import annotations

import codecs
import csv
import errno
import json
import os
import stat
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from arcube.errors import InputError
from arcube.io import CSV_COLUMNS, load_trajectories, read_csv, read_markups, read_transform
from arcube.io.files import atomic_write_bytes
from arcube.io.inputs import COORDINATE_LIMIT_MM, MAX_JSON_DEPTH, MAX_TEXT_BYTES
from arcube.io.slicer import MARKUPS_SCHEMA
from arcube.model.design import PARAM_NAMES, PAPER_TABLE2, Design

DATA = Path(__file__).parent / "data" / "trajectories"
HEADER = ",".join(CSV_COLUMNS) + "\n"
FUZZ = settings(
    max_examples=150,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
BIG = 10**400


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


def loads_or_input_error(read: Callable[[Path], Any], path: Path, name: str | None = None) -> Any:
    """``read(path)``; an InputError must be one line naming ``name`` (the path by default)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning that reached the user would be a failure
        try:
            return read(path)
        except InputError as exc:
            msg = str(exc)
            assert "\n" not in msg and "\r" not in msg, repr(msg)
            assert (os.fspath(path) if name is None else name) in msg, msg
            return exc


# ----------------------------------------------------------------------------- strategies

ENCODINGS = ("utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-32", "latin-1")
NUMBER = st.one_of(
    st.floats(),
    st.integers(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([BIG, -BIG, 1e300, -1e308, 0, -0.0, 1e-320, 99999.0, 100001]),
)
LEAF = st.one_of(st.none(), st.booleans(), NUMBER, st.text(max_size=12))
JSON_VALUE = st.recursive(
    LEAF,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=16,
)
NUMBER_TEXT = st.one_of(
    st.floats().map(repr),
    st.integers().map(str),
    st.from_regex(r"[+-]?[0-9_]{0,6}\.?[0-9]{0,4}(e[+-]?[0-9]{1,4})?", fullmatch=True),
    st.sampled_from(["nan", "-inf", "Infinity", "1_4.850", "١٢", "0x10", "1e999", "1e300", " 7 ", "", "１"]),
)
CELL = st.one_of(
    NUMBER_TEXT, st.text(max_size=16), st.sampled_from(["R", "L", "r", "X", "C3", '"', '"a,b"', "\x00", "a" * 140_000])
)


@st.composite
def csv_texts(draw: st.DrawFn) -> bytes:
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=300))
    if draw(st.integers(0, 9)) == 0:
        text = draw(st.text(max_size=300))
    else:
        header = draw(
            st.one_of(
                st.just(list(CSV_COLUMNS)),
                st.lists(st.sampled_from([*CSV_COLUMNS, "note", " Entry_X ", ""]), max_size=12),
            )
        )
        rows = draw(st.lists(st.lists(CELL, min_size=0, max_size=len(header) + 2), max_size=5))
        newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
        text = newline.join(",".join(r) for r in [header, *rows]) + draw(st.sampled_from(["", newline]))
    return text.encode(draw(st.sampled_from(ENCODINGS)), errors="replace")


POINT = st.fixed_dictionaries(
    {"position": st.one_of(st.lists(NUMBER, min_size=3, max_size=3), JSON_VALUE)},
    optional={"description": st.sampled_from(["level=C3;side=R", "level=C4;side=x", "level=;side="]) | JSON_VALUE},
)
MARKUP = st.fixed_dictionaries(
    {
        "type": st.just("Line") | JSON_VALUE,
        "controlPoints": st.lists(POINT, min_size=2, max_size=2) | st.lists(POINT, max_size=3) | JSON_VALUE,
    },
    optional={
        "name": st.text(max_size=8) | JSON_VALUE,
        "coordinateSystem": st.sampled_from(["RAS", "LPS", "IJK"]) | JSON_VALUE,
        "coordinateUnits": st.sampled_from(["mm", "um", ["mm", "UCUM", "millimeter"], [["mm"]], []]) | JSON_VALUE,
    },
)
MARKUPS = st.fixed_dictionaries(
    {"markups": st.lists(MARKUP, max_size=3) | JSON_VALUE}, optional={"@schema": st.just(MARKUPS_SCHEMA) | JSON_VALUE}
)
DESIGN = st.one_of(
    st.dictionaries(st.sampled_from([*PARAM_NAMES, "placements", "mount_rw"]), NUMBER | JSON_VALUE, max_size=6).map(
        lambda changes: {**PAPER_TABLE2, **changes}
    ),
    st.dictionaries(st.sampled_from(PARAM_NAMES), NUMBER, max_size=27),
    JSON_VALUE,
)
ROW = st.lists(NUMBER | LEAF, min_size=4, max_size=4) | st.lists(LEAF, max_size=5)
TRANSFORM = st.one_of(
    st.lists(NUMBER, min_size=3, max_size=3).map(
        lambda t: [[1, 0, 0, t[0]], [0, 1, 0, t[1]], [0, 0, 1, t[2]], [0, 0, 0, 1]]
    ),
    st.lists(ROW, min_size=4, max_size=4),
    st.lists(ROW, max_size=5),
    st.builds(lambda m: {"matrix": m}, st.lists(ROW, min_size=4, max_size=4) | JSON_VALUE),
    JSON_VALUE,
)


@st.composite
def json_bytes(draw: st.DrawFn, documents: st.SearchStrategy[Any]) -> bytes:
    """A generated document as JSON, or broken JSON, in one of several encodings."""
    kind = draw(st.integers(0, 19))
    if kind == 0:
        return draw(st.binary(max_size=200))
    if kind == 1:
        text = draw(st.text(max_size=200))
    elif kind == 2:
        depth = draw(st.integers(MAX_JSON_DEPTH - 2, 5000))
        text = "[" * depth + "1" + "]" * depth * draw(st.integers(0, 1))
    else:
        text = json.dumps(draw(documents), indent=draw(st.sampled_from([None, 2])))
        if kind == 3:  # cut short
            text = text[: draw(st.integers(0, len(text)))]
    return text.encode(draw(st.sampled_from(ENCODINGS)), errors="replace")


# ----------------------------------------------------------------------------- properties


@FUZZ
@given(data=csv_texts())
def test_any_csv_loads_or_is_one_input_error(folder: Path, data: bytes) -> None:
    path = folder / "plan.csv"
    path.write_bytes(data)
    loads_or_input_error(read_csv, path)


@FUZZ
@given(data=json_bytes(MARKUPS))
def test_any_markups_file_loads_or_is_one_input_error(folder: Path, data: bytes) -> None:
    path = folder / "plan.mrk.json"
    path.write_bytes(data)
    loads_or_input_error(read_markups, path)


@FUZZ
@given(data=json_bytes(DESIGN))
def test_any_design_file_loads_or_is_one_input_error(folder: Path, data: bytes) -> None:
    path = folder / "design.json"
    path.write_bytes(data)
    loads_or_input_error(lambda p: Design.load(str(p)), path)


@FUZZ
@given(values=DESIGN)
def test_any_design_mapping_loads_or_is_one_input_error(values: Any) -> None:
    loads_or_input_error(lambda _: Design.from_dict(values), Path("x"), name="design")


@FUZZ
@given(data=json_bytes(TRANSFORM))
def test_any_transform_file_loads_or_is_one_input_error(folder: Path, data: bytes) -> None:
    path = folder / "tf.json"
    path.write_bytes(data)
    loads_or_input_error(lambda p: load_trajectories("reference", transform=p), path)


# ----------------------------------------------------------------------------- regressions


def _raises(read: Callable[[], Any], *needles: str) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError) as info:
            read()
    msg = str(info.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, msg
    return msg


def _markups_doc(**markup_changes: Any) -> dict[str, Any]:
    doc = json.loads((DATA / "ras_line.mrk.json").read_text(encoding="utf-8"))
    doc["markups"][0].update(markup_changes)
    return doc


def test_d1_a_csv_field_over_the_csv_module_limit(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_text(HEADER + "1,C3,R," + "1" * 200_000 + ",2,3,4,5,6\n", encoding="utf-8")
    _raises(lambda: read_csv(path), "long.csv row 2", f"longer than {csv.field_size_limit()} characters")


def test_d1_nul_bytes(tmp_path: Path) -> None:
    path = tmp_path / "zeros.csv"
    path.write_bytes(b"\x00" * 10_000)
    _raises(lambda: read_csv(path), "zeros.csv", "NUL")
    path.write_bytes((HEADER + "1,C3,R,1,2,3,4\x00,5,6\n").encode())
    _raises(lambda: load_trajectories(path), "zeros.csv", "NUL character at offset")


@pytest.mark.parametrize(
    "read",
    [
        lambda p: load_trajectories(p),
        lambda p: Design.load(p),
        lambda p: load_trajectories("reference", transform=p),
        lambda p: read_markups(p),
    ],
    ids=["trajectories", "design", "transform", "markups"],
)
def test_d2_special_files_are_refused_before_reading(tmp_path: Path, read: Callable[[str], Any]) -> None:
    _raises(lambda: read("/dev/zero"), "/dev/zero", "is a character device, not a regular file")
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    _raises(lambda: read(str(fifo)), "pipe.json", "FIFO")  # and it does not wait for a writer


def test_d2_files_over_the_size_limit_are_refused(tmp_path: Path) -> None:
    for name, read in (
        ("big.csv", read_csv),
        ("big.json", lambda p: Design.load(str(p))),
        ("big.mrk.json", read_markups),
        ("tf.json", read_transform),
    ):
        path = tmp_path / name
        with open(path, "wb") as fh:
            fh.truncate(MAX_TEXT_BYTES + 1)  # sparse: nothing written
        _raises(lambda: read(path), name, "too large", "64 MiB")


@pytest.mark.parametrize(
    "key, value",
    [
        ("coordinateSystem", ["RAS"]),
        ("coordinateSystem", {"name": "RAS"}),
        ("coordinateUnits", [["mm"]]),
        ("coordinateUnits", {"unit": "mm"}),
        ("coordinateUnits", 3),
    ],
)
def test_d3_markups_system_or_units_of_the_wrong_type(tmp_path: Path, key: str, value: Any) -> None:
    path = tmp_path / "odd.mrk.json"
    path.write_text(json.dumps(_markups_doc(**{key: value})), encoding="utf-8")
    _raises(lambda: read_markups(path), "odd.mrk.json markup 1", "unknown coordinate")


def test_d4_integers_beyond_the_float_range(tmp_path: Path) -> None:
    design = tmp_path / "d.json"
    design.write_text(json.dumps({**PAPER_TABLE2, "p_x": BIG}), encoding="utf-8")
    _raises(lambda: Design.load(str(design)), "d.json", "p_x is not finite")
    _raises(
        lambda: Design.from_dict({**PAPER_TABLE2, "p_x": BIG}),
        "design: parameter p_x is out of range",
        "an integer of 401 digits",
    )
    _raises(lambda: Design.from_vector([BIG] * 27), "design")
    _raises(lambda: Design(tuple([BIG] * 27)), "design")
    doc = _markups_doc()
    doc["markups"][0]["controlPoints"][0]["position"] = [BIG, 0, 0]
    markups = tmp_path / "m.mrk.json"
    markups.write_text(json.dumps(doc), encoding="utf-8")
    _raises(lambda: read_markups(markups), "m.mrk.json markup 1", "control point 1 position is not finite")
    tf = tmp_path / "tf.json"
    tf.write_text(json.dumps([[1, 0, 0, BIG], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), encoding="utf-8")
    _raises(lambda: read_transform(tf), "tf.json", "non-finite")
    tf.write_text("[[1, 0, 0, " + "9" * 5000 + "], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]", encoding="utf-8")
    _raises(lambda: read_transform(tf), "tf.json", "non-finite")  # past Python's int-from-text limit too


@pytest.mark.parametrize(
    "name, read",
    [
        ("d.json", lambda p: Design.load(str(p))),
        ("m.mrk.json", read_markups),
        ("tf.json", read_transform),
    ],
)
def test_d5_deeply_nested_json(tmp_path: Path, name: str, read: Callable[[Path], Any]) -> None:
    path = tmp_path / name
    for text in ("[" * 100_000, "[" * 100_000 + "]" * 100_000, "[" * 70 + "]" * 70):
        path.write_text(text, encoding="utf-8")
        _raises(lambda: read(path), name, f"nested deeper than {MAX_JSON_DEPTH} levels")


def test_d6_design_files_in_other_encodings(tmp_path: Path) -> None:
    text = json.dumps(PAPER_TABLE2)
    for encoding in ("utf-16", "utf-32", "utf-8-sig"):  # with a byte-order mark: read as such
        path = tmp_path / f"{encoding}.json"
        path.write_bytes(text.encode(encoding))
        assert Design.load(str(path)) == Design.paper()
    latin = tmp_path / "latin.json"
    latin.write_bytes(json.dumps({**PAPER_TABLE2, "note": "Müller"}, ensure_ascii=False).encode("latin-1"))
    _raises(lambda: Design.load(str(latin)), "latin.json", "not UTF-8 text (byte 0xfc at offset", "save it as UTF-8")
    no_bom = tmp_path / "utf16.json"
    no_bom.write_bytes(text.encode("utf-16-le"))
    _raises(lambda: Design.load(str(no_bom)), "utf16.json", "UTF-16 text without a byte-order mark")
    odd = tmp_path / "bad16.json"
    odd.write_bytes(codecs.BOM_UTF16_LE + b"{\x00\x00\xd8")  # a lone surrogate
    _raises(lambda: Design.load(str(odd)), "bad16.json", "not UTF-16-LE text")


def test_the_other_readers_take_the_same_encodings(tmp_path: Path) -> None:
    ref = read_csv(DATA / "plan_extra_columns.csv")
    text = (DATA / "plan_extra_columns.csv").read_text(encoding="utf-8")
    for encoding in ("utf-16", "utf-8-sig"):
        path = tmp_path / f"plan-{encoding}.csv"
        path.write_bytes(text.replace("\n", "\r\n").encode(encoding))
        got = read_csv(path)
        assert got.ids == ref.ids and np.array_equal(got.entry, ref.entry) and np.array_equal(got.target, ref.target)
    markups = tmp_path / "m.mrk.json"
    markups.write_bytes((DATA / "ras_line.mrk.json").read_text(encoding="utf-8").encode("utf-16"))
    assert read_markups(markups).ids == read_markups(DATA / "ras_line.mrk.json").ids


def _mknod(path: Path, kind: int, device: tuple[int, int]) -> None:
    try:
        os.mknod(path, 0o666 | kind, os.makedev(*device))
    except PermissionError:
        pytest.skip("creating device nodes needs root")


def test_d13_a_character_device_is_written_in_place_never_replaced(tmp_path: Path) -> None:
    null = tmp_path / "mynull"
    _mknod(null, stat.S_IFCHR, (1, 3))  # what /dev/null is
    atomic_write_bytes(null, b"x" * 100_000)
    assert stat.S_ISCHR(os.stat(null).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mynull"]  # no temporary file left


def test_d13_a_fifo_is_written_in_place_when_read_and_refused_when_not(tmp_path: Path) -> None:
    fifo = tmp_path / "r.html"
    os.mkfifo(fifo)
    with pytest.raises(OSError) as info:  # no reader: refused at once, never waits
        atomic_write_bytes(fifo, b"<html>")
    assert info.value.errno == errno.ENXIO and info.value.filename == str(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    try:
        atomic_write_bytes(fifo, b"<html>")
        assert os.read(reader, 100) == b"<html>"
    finally:
        os.close(reader)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.html"]


def test_d13_folders_and_block_devices_are_refused(tmp_path: Path) -> None:
    folder = tmp_path / "out"
    folder.mkdir()
    with pytest.raises(IsADirectoryError) as info:
        atomic_write_bytes(folder, b"x")
    assert info.value.filename == str(folder) and "is a folder" in info.value.strerror
    block = tmp_path / "disk"
    _mknod(block, stat.S_IFBLK, (7, 0))
    with pytest.raises(OSError) as info:
        atomic_write_bytes(block, b"x")
    assert "block device" in info.value.strerror and stat.S_ISBLK(os.stat(block).st_mode)


def test_d18_write_errors_name_the_callers_path_not_the_temporary_file(tmp_path: Path) -> None:
    with pytest.raises(OSError) as info:
        atomic_write_bytes("/proc/x_dexterity.png", b"x")
    assert info.value.filename == "/proc/x_dexterity.png" and ".tmp" not in str(info.value)
    (tmp_path / "p.csv").write_text("", encoding="utf-8")
    with pytest.raises(NotADirectoryError) as info:
        atomic_write_bytes(tmp_path / "p.csv" / "r.html", b"x")
    assert info.value.filename == str(tmp_path / "p.csv" / "r.html")
    assert info.value.strerror == f"{tmp_path / 'p.csv'} is a file, not a folder"


def test_d19_coordinates_beyond_the_documented_range(tmp_path: Path) -> None:
    path = tmp_path / "far.csv"
    for value in ("1e300", "1e308", "-100000.5"):
        path.write_text(HEADER + f"1,C3,R,1,2,{value},4,5,6\n", encoding="utf-8")
        _raises(lambda: read_csv(path), "far.csv row 2: entry coordinate", f"±{COORDINATE_LIMIT_MM:g} mm")
    path.write_text(HEADER + "1,C3,R,1,2,-100000,4,5,100000\n", encoding="utf-8")
    assert read_csv(path).entry[0, 2] == -1e5  # the limit itself is in range
    markups = tmp_path / "far.mrk.json"
    doc = _markups_doc()
    doc["markups"][0]["controlPoints"][1]["position"] = [0, 1e300, 0]
    markups.write_text(json.dumps(doc), encoding="utf-8")
    _raises(lambda: read_markups(markups), "far.mrk.json markup 1", "target coordinate")
    tf = tmp_path / "tf.json"
    tf.write_text(json.dumps([[1, 0, 0, 1e6], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), encoding="utf-8")
    _raises(lambda: read_transform(tf), "tf.json", "translation coordinate 1e+06 mm")
    tf.write_text(json.dumps([[1, 0, 0, 99_990.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), encoding="utf-8")
    _raises(lambda: load_trajectories("reference", transform=tf), "after the transform", "tf.json")
    tf.write_text(json.dumps([[1e300, 0, 0, 0], [0, 1e300, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), encoding="utf-8")
    _raises(lambda: read_transform(tf), "tf.json", "not orthonormal")  # no overflow warning on the way


def test_d22_duplicated_columns_and_python_only_number_syntax(tmp_path: Path) -> None:
    path = tmp_path / "plan.csv"
    path.write_text(HEADER.strip() + ",Entry_X\n1,C3,R,1,2,3,4,5,6,7\n", encoding="utf-8")
    _raises(lambda: read_csv(path), "plan.csv: column entry_x appears more than once (columns 4 and 10)")
    for text in ("1_4.850", "١٢", "１", "0x10", "1e", "--1"):
        path.write_text(HEADER + f"1,C3,R,{text},2,3,4,5,6\n", encoding="utf-8")
        _raises(lambda: read_csv(path), "plan.csv row 2: entry_x is not a number")
    path.write_text(HEADER + "1,C3,R,+1.,.5,-2E+1, 3 ,1e0,0\n", encoding="utf-8")
    assert read_csv(path).entry.tolist() == [[1.0, 0.5, -20.0]]
