"""The program-folder reader and the plan CSVs under hostile input (issue "Hardening II", part A).

Property-based (Hypothesis, derandomized, fixed example counts): program folders as ``arcube program``
writes them, then damaged (a cell in any notation, rows with extra or missing fields, a duplicated
column, a summary field of the wrong type, huge integers, deep nesting), and plan CSVs with rows of
extra and missing fields, duplicated columns and numbers in every notation. The promise checked:
the reader returns, or raises one :class:`~arcube.errors.InputError` whose message is one line naming
the file; no other exception and no warning; and through the command line (``arcube report``,
``arcube export --program``, ``arcube evaluate``) exit 0, or exit 2 with one line and nothing left.

Oracles: a program written by :meth:`arcube.motion.Program.write` reads back to the same numbers
(round trip); a number is accepted exactly when it is in plain decimal notation
(``[+-]digits[.digits][e[+-]digits]``), and then reads as Python's float of its text.
"""

from __future__ import annotations

import json
import math
import os
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from arcube.errors import InputError
from arcube.io import read_csv
from arcube.io.program_files import CSV_COLUMNS, CSV_NAME, JSON_NAME, TORQUE_COLUMNS, read_program_files
from arcube.motion.output import Program

from designs import program_object
from harness import cli_error as _cli

FUZZ = settings(
    max_examples=120,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
CLI_FUZZ = settings(FUZZ, max_examples=20)
DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_tried: dict[str, int] = {"program": 0, "plan": 0, "export": 0, "report": 0, "evaluate": 0}


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[Program, Path]:
    prog = program_object()
    folder = tmp_path_factory.mktemp("prog") / "p"
    prog.write(folder)
    return prog, folder


def _one_line_naming(exc: InputError, name: str) -> None:
    msg = str(exc)
    assert "\n" not in msg and "\r" not in msg and len(msg) < 2000, repr(msg)
    assert name in msg, msg


def _read_or_input_error(folder: Path) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning that reached the user would be a failure
        try:
            return read_program_files(folder)
        except InputError as exc:
            _one_line_naming(exc, str(folder))
            return exc


# ----------------------------------------------------------------------------- round trip


def test_a_written_program_reads_back_to_the_same_numbers(written: tuple[Program, Path]) -> None:
    prog, folder = written
    back = read_program_files(folder)
    for name in ("t_s", "E", "e", "q_deg", "q_dot_deg", "tau_Nm"):
        assert np.array_equal(getattr(back, name), getattr(prog, name)), name  # repr() text: exact
    assert list(back.segment) == list(prog.segment) and list(back.trajectory) == list(prog.trajectory)
    assert back.summary == json.loads((folder / JSON_NAME).read_text())


# ----------------------------------------------------------------------------- strategies

NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-(10**6), max_value=10**6).map(str),
    st.from_regex(r"[+-]?[0-9_]{0,5}[.,]?[0-9]{0,4}([eE][+-]?[0-9]{1,4})?", fullmatch=True),
    st.sampled_from(
        [
            "",
            " ",
            "nan",
            "-inf",
            "1_5",
            "0x10",
            "١٢",
            "１",
            "1e999",
            "19,681",
            "9" * 400,
            "9" * 5000,
            "1e308",
            "-1e308",
            "x" * 200_000,
            "abc",
            "1.5.2",
            "+.5",
            "5.",
            "\u00a01",
        ]
    ),
)
JSON_HOSTILE = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.sampled_from([10**400, -(10**5000), 1e308, "text", [], {}, [1, [2]], {"a": None}]),
    st.text(max_size=8),
    st.lists(st.integers(), max_size=3),
)
SUMMARY_KEYS = [
    "order",
    "transits",
    "trajectories",
    "total_s",
    "drilling_s",
    "dt_s",
    "mode",
    "plan",
    "limits",
    "motors",
    "design",
    "joint_speed_max_deg_s",
    "clearances_along_time",
    "anatomy",
    "eta_L_max",
]


def _csv_lines(folder: Path) -> list[str]:
    return (folder / CSV_NAME).read_text().splitlines()


RESHAPES = ("extra", "missing", "duplicate")
"""Damage that changes a CSV's shape: a field too many in a row, one too few, a duplicated column."""


def _reshape(draw: Any, kind: str, header: list[str], rows: list[list[str]], r: int, extra: Any) -> None:
    """Apply one of :data:`RESHAPES` in place: row ``r`` gains a field drawn from ``extra`` or loses one, or a
    column is duplicated (header and every row)."""
    if kind == "extra":
        rows[r].insert(draw(st.integers(0, len(rows[r]))), draw(extra))
    elif kind == "missing":
        del rows[r][draw(st.integers(0, len(rows[r]) - 1))]
    else:
        j = draw(st.integers(0, len(header) - 1))
        header.append(header[j])
        for row in rows:
            row.append(row[j])


@st.composite
def damaged_csv(draw: Any, lines: list[str]) -> str:
    """program.csv's text with one kind of damage."""
    header, rows = lines[0].split(","), [ln.split(",") for ln in lines[1:]]
    kind = draw(st.sampled_from(["cell", "extra", "missing", "duplicate", "header", "blank"]))
    r = draw(st.integers(0, len(rows) - 1))
    if kind == "cell":
        rows[r][draw(st.integers(0, len(header) - 1))] = draw(NUMBER_TEXT)
    elif kind in RESHAPES:
        _reshape(draw, kind, header, rows, r, NUMBER_TEXT)
    elif kind == "header":
        header[draw(st.integers(0, len(header) - 1))] = draw(
            st.sampled_from(["", "E_X", "e_x", "t_s ", "tau_rho_x_Nm", "segment"])
        )
    else:
        rows.insert(r, [""] * len(header))
    return "\n".join(",".join(x) for x in [header, *rows]) + "\n"


def _dumps(value: object) -> str:
    """JSON text of ``value``, an integer of 5,000 digits included (Python refuses to print one by default; the
    reader under test must still say what is wrong with it, with the default limit back in place)."""
    import sys

    limit = sys.get_int_max_str_digits()
    sys.set_int_max_str_digits(0)
    try:
        return json.dumps(value)
    finally:
        sys.set_int_max_str_digits(limit)


# ----------------------------------------------------------------------------- the reader


@FUZZ
@given(data=st.data())
def test_program_reader_returns_or_says_what_is_wrong(
    written: tuple[Program, Path], tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    _tried["program"] += 1
    _, source = written
    folder = tmp_path_factory.mktemp("bad") / "p"
    folder.mkdir()
    summary = json.loads((source / JSON_NAME).read_text())
    if data.draw(st.booleans(), "damage the CSV"):
        (folder / CSV_NAME).write_text(data.draw(damaged_csv(_csv_lines(source)), "csv"))
        (folder / JSON_NAME).write_text(json.dumps(summary))
    else:
        (folder / CSV_NAME).write_text((source / CSV_NAME).read_text())
        key = data.draw(st.sampled_from(SUMMARY_KEYS), "key")
        summary[key] = data.draw(JSON_HOSTILE, "value")
        (folder / JSON_NAME).write_text(_dumps(summary))
    got = _read_or_input_error(folder)
    if not isinstance(got, InputError):  # accepted: what it holds is within the documented limits
        assert np.all(np.diff(got.t_s) > 0) and got.E.shape == (len(got.t_s), 3)
        finite = np.isfinite(got.q_deg)
        assert np.all(np.abs(got.q_deg[finite]) <= 1e6)


def test_program_reader_says_what_is_wrong_with_a_5000_digit_number(
    written: tuple[Program, Path], tmp_path: Path
) -> None:
    _, source = written
    (tmp_path / CSV_NAME).write_text((source / CSV_NAME).read_text())
    summary = json.loads((source / JSON_NAME).read_text())
    summary["total_s"] = -(10**5000)
    (tmp_path / JSON_NAME).write_text(_dumps(summary))
    assert isinstance(_read_or_input_error(tmp_path), InputError)


@pytest.mark.parametrize(
    ("name", "text", "needle"),
    [
        ("order 5", '{"order": 5}', "order must be a list"),
        ("transits null", '{"transits": null}', "transits must be a list"),
        ("text time", '{"total_s": "abc"}', "total_s must be a number"),
        ("400 digits", '{"total_s": ' + "9" * 400 + "}", "total_s must be a finite number"),
        ("5000 digits", '{"total_s": ' + "9" * 5000 + "}", "total_s must be a finite number"),
        ("deep", '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}", "nested deeper than"),
        ("list", "[1, 2]", "expected a JSON object"),
        ("not json", "{", "not valid JSON"),
    ],
)
def test_each_summary_defect_of_the_issue_is_one_line(
    written: tuple[Program, Path], tmp_path: Path, name: str, text: str, needle: str
) -> None:
    _, source = written
    folder = tmp_path / "p"
    folder.mkdir()
    (folder / CSV_NAME).write_text((source / CSV_NAME).read_text())
    (folder / JSON_NAME).write_text(text)
    with pytest.raises(InputError) as info:
        read_program_files(folder)
    _one_line_naming(info.value, str(folder / JSON_NAME))
    assert needle in str(info.value), str(info.value)


@pytest.mark.parametrize("which", [CSV_NAME, JSON_NAME])
@pytest.mark.parametrize("special", ["/dev/zero", "fifo"])
def test_device_files_and_fifos_are_refused_before_reading(
    written: tuple[Program, Path], tmp_path: Path, which: str, special: str
) -> None:
    """Inside a program folder only regular files are read: /dev/zero would never end, a FIFO could block."""
    _, source = written
    folder = tmp_path / "p"
    folder.mkdir()
    for name in (CSV_NAME, JSON_NAME):
        (folder / name).write_text((source / name).read_text())
    (folder / which).unlink()
    if special == "fifo":
        os.mkfifo(folder / which)
    else:
        os.symlink(special, folder / which)
    kind = "a FIFO (named pipe)" if special == "fifo" else "a character device"
    with pytest.raises(InputError, match=re.escape(f"{folder / which}: is {kind}, not a regular file")):
        read_program_files(folder)


@pytest.mark.parametrize(
    ("cell", "needle"),
    [
        ("x" * 200_000, "longer than"),
        ("9" * 400, "400 characters"),
        ("9" * 5000, "5000 characters"),
        ("1e308", "beyond"),
        ("-1e308", "beyond"),
        ("abc", "not a number"),
        ("1_5", "not a number"),
    ],
)
def test_each_csv_defect_of_the_issue_is_one_line(
    written: tuple[Program, Path], tmp_path: Path, cell: str, needle: str
) -> None:
    _, source = written
    folder = tmp_path / "p"
    folder.mkdir()
    lines = _csv_lines(source)
    row = lines[2].split(",")
    row[CSV_COLUMNS.index("rho_x_dot")] = cell
    (folder / CSV_NAME).write_text("\n".join([lines[0], lines[1], ",".join(row), *lines[3:]]) + "\n")
    (folder / JSON_NAME).write_text((source / JSON_NAME).read_text())
    with pytest.raises(InputError) as info:
        read_program_files(folder)
    _one_line_naming(info.value, f"{folder / CSV_NAME} row 3")
    assert needle in str(info.value)


def test_a_duplicated_column_is_refused_not_used(written: tuple[Program, Path], tmp_path: Path) -> None:
    _, source = written
    folder = tmp_path / "p"
    folder.mkdir()
    lines = _csv_lines(source)
    j = CSV_COLUMNS.index("E_x")
    text = "\n".join([lines[0] + ",E_x", *(ln + ",0.0" for ln in lines[1:])]) + "\n"  # a second E_x that disagrees
    (folder / CSV_NAME).write_text(text)
    (folder / JSON_NAME).write_text((source / JSON_NAME).read_text())
    with pytest.raises(
        InputError,
        match=rf"column E_x appears more than once \(columns {j + 1} and {len(CSV_COLUMNS) + len(TORQUE_COLUMNS) + 1}\)",
    ):
        read_program_files(folder)


# ----------------------------------------------------------------------------- plan CSVs

HEADER = ["trajectory", "level", "side", "entry_x", "entry_y", "entry_z", "target_x", "target_y", "target_z"]


@st.composite
def plan_text(draw: Any) -> tuple[str, dict[str, Any]]:
    """A plan CSV of 1-4 rows with one of: nothing wrong, a cell in any notation, a row with extra or
    missing fields, a duplicated column; and what was done."""
    header = list(HEADER)
    rows = [
        [str(i + 1), "C3", "R", *(repr(float(v)) for v in draw(st.lists(st.floats(-90, 90), min_size=6, max_size=6)))]
        for i in range(draw(st.integers(1, 4)))
    ]
    for row in rows:  # entry != target
        row[8] = repr(float(row[5]) + 10.0)
    kind = draw(st.sampled_from(["none", "cell", "extra", "missing", "duplicate"]))
    r = draw(st.integers(0, len(rows) - 1))
    info: dict[str, Any] = {"kind": kind, "row": r + 2}
    if kind == "cell":
        j = draw(st.integers(3, 8))
        info["text"] = rows[r][j] = draw(NUMBER_TEXT)
        info["column"] = HEADER[j]
    elif kind in RESHAPES:
        _reshape(draw, kind, header, rows, r, st.sampled_from(["681", "", "x", "19"]))
    return "\n".join(",".join(x) for x in [header, *rows]) + "\n", info


def _csv_cell(text: str) -> str:
    """How the csv module reads one unquoted cell back (it is stripped by the reader)."""
    return text.strip()


@FUZZ
@given(case=plan_text())
def test_plan_csv_rows_and_numbers(case: tuple[str, dict[str, Any]], tmp_path_factory: pytest.TempPathFactory) -> None:
    _tried["plan"] += 1
    text, info = case
    path = tmp_path_factory.mktemp("plan") / "plan.csv"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            ts = read_csv(path)
        except InputError as exc:
            ts, err = None, exc
            _one_line_naming(exc, str(path))
    kind = info["kind"]
    if kind in ("extra", "missing"):  # one-sided no more: a row of the wrong width is refused, naming its row
        assert ts is None and f"row {info['row']}:" in str(err) and "the header has 9" in str(err), str(err)
    elif kind == "duplicate":
        assert ts is None and "appears more than once" in str(err), str(err)
    elif kind == "cell":
        cell = _csv_cell(info["text"])
        plain = (
            bool(DECIMAL.fullmatch(cell))
            and len(cell) <= 100
            and math.isfinite(float(cell))
            and abs(float(cell)) <= 1e5
        )
        if "," in info["text"]:  # a decimal comma splits the cell: the row is one field too wide
            assert ts is None and "a decimal comma?" in str(err), str(err)
        elif not plain:
            assert ts is None and f"row {info['row']}" in str(err), str(err)
        elif ts is not None:  # accepted: the number is Python's float of its text, nothing else
            col = info["column"]
            point = ts.entry if col.startswith("entry") else ts.target
            assert point[info["row"] - 2, "xyz".index(col[-1])] == float(cell)
    else:
        assert ts is not None


# ----------------------------------------------------------------------------- through the command line


@CLI_FUZZ
@given(data=st.data())
def test_export_and_report_of_a_damaged_program_folder(
    written: tuple[Program, Path],
    tmp_path_factory: pytest.TempPathFactory,
    capsys: pytest.CaptureFixture[str],
    data: st.DataObject,
) -> None:
    """Exit 2, one line, and no model, replay or report left beside it (the synthetic program is no
    design's, so even an intact one ends in one line: its design is refused)."""
    _tried["export"] += 1
    _, source = written
    base = tmp_path_factory.mktemp("cli")
    folder = base / "p"
    folder.mkdir()
    (folder / CSV_NAME).write_text(data.draw(damaged_csv(_csv_lines(source)), "csv"))
    (folder / JSON_NAME).write_text((source / JSON_NAME).read_text())
    code, err = _cli(["export", "--program", str(folder), "--design", "paper", "--out", str(base / "r.xml")], capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert not (base / "r.xml").exists() and not (base / "r.replay.csv").exists()
    before = set(os.listdir(folder))
    code, err = _cli(["report", str(folder)], capsys)
    _tried["report"] += 1
    assert code in (0, 2), err
    if code == 2:
        assert err.startswith("error: ") and err.count("\n") == 1 and set(os.listdir(folder)) == before, err


@CLI_FUZZ
@given(case=plan_text())
def test_evaluate_on_a_hostile_plan(
    case: tuple[str, dict[str, Any]], tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str]
) -> None:
    _tried["evaluate"] += 1
    text, _ = case
    base = tmp_path_factory.mktemp("ev")
    (base / "plan.csv").write_text(text)
    code, err = _cli(
        [
            "evaluate",
            "--trajectories",
            str(base / "plan.csv"),
            "--points",
            "3",
            "--engine",
            "numpy",
            "--report",
            str(base / "r.html"),
        ],
        capsys,
    )
    assert code in (0, 2) and "Traceback" not in err, err
    if code == 2:
        assert err.startswith("error: ") and err.count("\n") == 1, err
        assert sorted(os.listdir(base)) == ["plan.csv"], os.listdir(base)


def test_the_properties_ran_their_examples() -> None:
    """Runs last in this file: every property above tried its fixed number of examples."""
    print(f"hypothesis examples tried: {_tried}")
    assert _tried["program"] >= 120 and _tried["plan"] >= 120 and _tried["export"] >= 20 and _tried["evaluate"] >= 20
