"""A CSV file a user may have written or edited: the one strict layer under every CSV arcube reads
(trajectory plans, calibration measurements, ``program.csv``, ``history.csv``).

:func:`read_table` reads the file through :mod:`arcube.io.inputs` (regular file or pipe, size,
encoding) and :func:`parse_table` holds the same promises for every format, each breach one
:class:`~arcube.errors.InputError` naming the file, the row (its line number, the header being
row 1) and the problem:

* a header row, each column named once (a duplicated column is refused: which copy would count?);
* every row has as many fields as the header: a row with one more (a decimal comma, ``19,681``,
  splits a number in two and shifts every column after it) is refused as firmly as a short one;
  blank lines are skipped;
* no field longer than :data:`MAX_FIELD_CHARS` characters;
* numbers (:func:`number`) in plain decimal notation only, as :func:`arcube.io.inputs.parse_decimal`
  takes them (``-12.5``, ``1e3``, ``.5``), at most :data:`MAX_NUMBER_CHARS` characters: ``1_5``,
  ``0x10``, ``١٢`` and ``19,681``, which Python's ``float`` or a spreadsheet might take, are refused.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.io.inputs import MAX_TEXT_BYTES, parse_decimal, read_text, short_repr

__all__ = ["MAX_FIELD_CHARS", "MAX_NUMBER_CHARS", "Table", "number", "parse_table", "read_table"]

MAX_FIELD_CHARS = 1000
"""Longest field accepted, characters (an id, a name or a number is far shorter)."""
MAX_NUMBER_CHARS = 100
"""Longest number accepted, characters (a float64 needs 24; a longer one is a pasted mistake)."""
_CELL = r"(?:[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:[nN][aA][nN]|[iI][nN][fF](?:[iI][nN][iI][tT][yY])?))?"
_COLUMN_RE = re.compile(f"{_CELL}(?:\n{_CELL})*")
"""A column of cells joined by newlines, each empty or a number in :func:`arcube.io.inputs.parse_decimal`'s notation."""


@dataclass(frozen=True)
class Table:
    """A CSV's header and its non-blank rows, each with its line number."""

    name: str
    """The file, as messages name it."""
    header: tuple[str, ...]
    """The column names, as :func:`parse_table`'s ``key`` made them."""
    rows: tuple[tuple[int, tuple[str, ...]], ...]
    """(line number, fields) of each non-blank row, fields stripped of surrounding blanks."""

    def index(self, column: str) -> int:
        """The position of ``column`` in the header (KeyError if absent)."""
        return self.header.index(column)

    def where(self, line: int) -> str:
        """``"FILE row LINE"``, for messages."""
        return f"{self.name} row {line}"

    def column(self, name: str, empty: float | None = None, finite: bool = True) -> NDArray[np.float64]:
        """The cells of column ``name`` as numbers ``(rows,)``, checked as :func:`number` checks one
        (whose ``empty`` and ``finite`` these are), at the speed of a regular expression over the column."""
        j = self.index(name)
        cells = [c[j] for _, c in self.rows]
        joined = "\n".join(cells)
        if not (
            _COLUMN_RE.fullmatch(joined)
            and (empty is not None or "" not in cells)
            and max(map(len, cells), default=0) <= MAX_NUMBER_CHARS
        ):
            for line, c in self.rows:  # the first culprit, for its message
                number(c[j], self.where(line), name, empty=empty, finite=finite)
        values = np.array([empty if c == "" else c for c in cells] if "" in cells else cells, dtype=np.float64).reshape(
            -1
        )
        if finite and not np.all(np.isfinite(values)):
            k = int(np.flatnonzero(~np.isfinite(values))[0])
            line, c = self.rows[k]
            raise InputError(f"{self.where(line)}: {name} is not finite ({short_repr(c[j], 30)})")
        return values

    def numbers(self, columns: Iterable[str], empty: float | None = None, finite: bool = True) -> NDArray[np.float64]:
        """The cells of ``columns`` as numbers ``(rows, len(columns))`` (:meth:`column` each)."""
        names = list(columns)
        out = np.empty((len(self.rows), len(names)))
        for k, c in enumerate(names):
            out[:, k] = self.column(c, empty, finite)
        return out


def number(text: str, where: str, column: str, *, empty: float | None = None, finite: bool = True) -> float:
    """The number in the cell ``text`` (module docstring); InputError ``"<where>: <column> is ..."``.

    ``empty``: the value of an empty cell (None: refused); ``finite``: refuse NaN and infinities
    (written ones and ones that overflow, such as a 400-digit integer)."""
    if text == "":
        if empty is None:
            raise InputError(f"{where}: {column} is empty")
        return empty
    if len(text) > MAX_NUMBER_CHARS:
        raise InputError(
            f"{where}: {column} is not a number ({len(text)} characters, at most {MAX_NUMBER_CHARS}: {short_repr(text, 30)})"
        )
    value = parse_decimal(text)
    if value is None:
        hint = " (write 1.5, not 1,5)" if "," in text else ""
        raise InputError(f"{where}: {column} is not a number ({short_repr(text)}){hint}")
    if finite and not math.isfinite(value):
        raise InputError(f"{where}: {column} is not finite ({short_repr(text, 30)})")
    return value


def _cut(text: str) -> str:
    """The field's text for a message (``short_repr`` works on its start only, at any length)."""
    return short_repr(text[:80])


def parse_table(
    text: str,
    name: str,
    *,
    required: Iterable[str] = (),
    key: Callable[[str], str] = str.strip,
    allowed: Iterable[str] | None = None,
) -> Table:
    """Parse CSV ``text`` (module docstring); ``name`` labels every message.

    ``required``: columns that must be present (after ``key``, which normalises a header name: case,
    blanks); ``allowed``: the only columns accepted (None: any, the others ignored by the caller).
    """
    text = text.removeprefix("\ufeff")
    if not text.strip():
        raise InputError(f"{name}: empty file")
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[tuple[int, tuple[str, ...]]] = []
    try:
        header = tuple(key(h) for h in next(reader))
        _check_header(header, name, required, allowed)
        width = len(header)
        for cells in reader:
            if not any(c.strip() for c in cells):
                continue  # a blank line carries no row
            line = reader.line_num
            if len(cells) != width:
                hint = " (a decimal comma? write 19.681, not 19,681)" if len(cells) > width else ""
                raise InputError(f"{name} row {line}: {len(cells)} fields, the header has {width}{hint}")
            long = next((j for j, c in enumerate(cells) if len(c) > MAX_FIELD_CHARS), None)
            if long is not None:
                raise InputError(
                    f"{name} row {line}: field {long + 1} ({header[long] or 'unnamed'}) has {len(cells[long])} characters "
                    f"(at most {MAX_FIELD_CHARS}): {_cut(cells[long])}"
                )
            rows.append((line, tuple(c.strip() for c in cells)))
    except csv.Error as exc:  # a field over csv.field_size_limit(), a stray quote
        problem = (
            f"a field is longer than {csv.field_size_limit()} characters"
            if "field limit" in str(exc)
            else f"not valid CSV ({exc})"
        )
        raise InputError(f"{name} row {reader.line_num}: {problem}") from None
    return Table(name, header, tuple(rows))


def _label(column: str) -> str:
    """A column name for a message: as it is when short and printable, else quoted and cut."""
    if not column:
        return "(unnamed)"
    return column if len(column) <= 40 and column.isprintable() and "," not in column else short_repr(column[:80], 40)


def _check_header(header: tuple[str, ...], name: str, required: Iterable[str], allowed: Iterable[str] | None) -> None:
    seen: dict[str, int] = {}
    for i, h in enumerate(header):
        if len(h) > MAX_FIELD_CHARS:
            raise InputError(f"{name}: column {i + 1}'s name has {len(h)} characters (at most {MAX_FIELD_CHARS})")
        if h and h in seen:
            raise InputError(f"{name}: column {_label(h)} appears more than once (columns {seen[h] + 1} and {i + 1})")
        seen.setdefault(h, i)
    if allowed is not None:
        known = list(allowed)
        unknown = next((h for h in header if h not in known), None)
        if unknown is not None:
            raise InputError(f"{name}: unknown column {_label(unknown)} (known: {', '.join(known)})")
    missing = [c for c in required if c not in seen]
    if missing:
        semicolons = len(header) == 1 and ";" in header[0]
        raise InputError(
            f"{name}: missing column(s) {', '.join(missing)}"
            + (" (the header is one field with semicolons: separate the columns with commas)" if semicolons else "")
        )


def read_table(path: str | os.PathLike[str], *, limit: int = MAX_TEXT_BYTES, pipes: bool = True, **kw: object) -> Table:
    """:func:`arcube.io.inputs.read_text` (``limit``, ``pipes`` as there) then :func:`parse_table` (keywords as there), named by ``path``."""
    return parse_table(read_text(path, limit, pipes=pipes), os.fspath(path), **kw)  # type: ignore[arg-type]
