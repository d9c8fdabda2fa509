"""Reading a user's file: the one layer under every reader (trajectory CSV, Slicer markups, rigid
transform, design JSON, anatomy meshes).

Whatever the reader, the same promises and limits hold, and a breach is an
:class:`~arcube.errors.InputError` whose message is one line naming the file and the problem:

* **regular files and pipes only**: a folder, device or socket is refused before anything is read
  (``/dev/zero`` would never end); a pipe or FIFO (a shell's ``--trajectories <(...)``, which names
  ``/dev/fd/63``) is read once, to its end, and its bytes are kept for the rest of the process, since
  a command may read its plan twice and a pipe gives its bytes only once (the files inside a folder
  arcube wrote, a program's or a run's, are read as regular files only: ``pipes=False``);
* **size**: at most :data:`MAX_TEXT_BYTES` (64 MiB) for a text file, :data:`MAX_MESH_BYTES`
  (1 GiB) for a mesh;
* **encoding**: UTF-8, with or without a byte-order mark, or UTF-16 / UTF-32 with their
  byte-order mark (what Windows editors write as "Unicode"); any other bytes (Latin-1, UTF-16
  without a mark) and NUL bytes are refused with the offset of the first bad byte;
* **JSON**: standard JSON nested at most :data:`MAX_JSON_DEPTH` levels; an integer too long to be
  a float (more than 300 digits) is read as a float (``inf`` past 1.8e308), which the readers
  then refuse as not finite rather than overflow;
* **numbers in text** (CSV fields): plain decimal notation only, ``[+-]digits[.digits][e[+-]digits]``;
  ``1_000`` and non-ASCII digits, which Python's ``float`` would take, are refused;
* **coordinates**: every point read from a file lies within ±:data:`COORDINATE_LIMIT_MM` mm
  (100 m) on each axis: beyond that a value is a unit mistake and would only produce meaningless
  numbers and overflow warnings downstream.
"""

from __future__ import annotations

import codecs
import json
import math
import os
import re
import stat
from collections.abc import Callable
from typing import Any

from arcube.errors import InputError

__all__ = [
    "COORDINATE_LIMIT_MM",
    "MAX_JSON_DEPTH",
    "MAX_MESH_BYTES",
    "MAX_TEXT_BYTES",
    "coordinate_problem",
    "decode_text",
    "file_kind",
    "load_json",
    "parse_decimal",
    "parse_json",
    "read_bytes",
    "read_text",
    "short_repr",
]

MAX_TEXT_BYTES = 64 * 2**20
"""Largest text input (CSV, markups, transform, design JSON), bytes: 64 MiB."""
MAX_MESH_BYTES = 2**30
"""Largest mesh file (STL, OBJ, PLY), bytes: 1 GiB (about 20 million triangles of binary STL)."""
MAX_JSON_DEPTH = 64
"""Deepest JSON nesting accepted (the formats read here need at most 6 levels)."""
COORDINATE_LIMIT_MM = 1e5
"""Largest |coordinate| of a point read from a file, mm (100 m)."""
_MAX_INT_DIGITS = 300  # longer JSON integers are read as floats (they cannot be one exactly anyway)

Fail = Callable[[str], InputError]
"""Turns a problem (``"no such file"``) into the reader's InputError (naming the file)."""

_DECIMAL_RE = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NON_FINITE_RE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_BOMS = (  # longest first: the UTF-32 LE mark starts with the UTF-16 LE one
    (codecs.BOM_UTF32_LE, "utf-32-le"),
    (codecs.BOM_UTF32_BE, "utf-32-be"),
    (codecs.BOM_UTF8, "utf-8"),
    (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
)


def _default_fail(path: str | os.PathLike[str]) -> Fail:
    name = os.fspath(path)
    return lambda problem: InputError(f"{name}: {problem}")


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)``, cut to ``limit`` characters (``...`` at the end) for one-line messages."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**_MAX_INT_DIGITS:
        return f"an integer of {len(str(abs(value)))} digits"  # repr would hit Python's int-to-str limit
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` is, in words (``"a FIFO (named pipe)"``)."""
    for test, words in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISREG, "a regular file"),
    ):
        if test(mode):
            return words
    return "a special file"


def what_is(path: str | os.PathLike[str]) -> str:
    """What stands at ``path`` (followed if a link), in words: ``"a file"``, ``"a folder"``, ``"a character device"``."""
    mode = os.stat(path).st_mode
    return "a file" if stat.S_ISREG(mode) else file_kind(mode)


def _mib(n: int) -> str:
    return f"{n / 2**20:.0f} MiB" if n >= 2**20 else f"{n} bytes"


_PIPES: dict[tuple[int, int], bytes] = {}
"""The bytes of each pipe or FIFO read so far, by (device, inode): a pipe gives them only once."""


def read_bytes(
    path: str | os.PathLike[str], limit: int = MAX_TEXT_BYTES, fail: Fail | None = None, *, pipes: bool = True
) -> bytes:
    """The bytes of the regular file, pipe or FIFO ``path``, at most ``limit`` of them (module docstring).
    ``pipes=False``: a regular file only (the files inside a folder arcube wrote: a FIFO there is not its file).

    Raises:
        InputError (through ``fail``): missing, a folder, device or socket (or a pipe), unreadable, or over ``limit``.
    """
    fail = fail or _default_fail(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:  # non-blocking: opening a FIFO must not wait for a writer
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise fail("no such file") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL character in the name
        raise fail(f"cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        st = os.fstat(fd)
        pipe = pipes and stat.S_ISFIFO(st.st_mode)
        if pipe and (st.st_dev, st.st_ino) in _PIPES:
            data = _PIPES[(st.st_dev, st.st_ino)]
            if len(data) > limit:
                raise fail(f"too large: more than {limit} bytes (the limit is {_mib(limit)})")
            return data
        if not (stat.S_ISREG(st.st_mode) or pipe):
            raise fail(f"is {file_kind(st.st_mode)}, not a regular file")
        if st.st_size > limit:
            raise fail(f"too large: {st.st_size} bytes (the limit is {_mib(limit)})")
        os.set_blocking(fd, True)
        chunks, total = [], 0
        while total <= limit:
            chunk = os.read(fd, min(limit + 1 - total, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise fail(f"cannot read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if total > limit:  # grew while being read
        raise fail(f"too large: more than {limit} bytes (the limit is {_mib(limit)})")
    data = b"".join(chunks)
    if pipe:
        if not data:  # a FIFO nobody writes to reads as empty at once (never waits): say so, not "empty file"
            raise fail("is a FIFO (named pipe) that gave no data: no process writes to it")
        _PIPES[(st.st_dev, st.st_ino)] = data
    return data


def decode_text(data: bytes, fail: Fail) -> str:
    """``data`` as text: UTF-8 (a BOM dropped), or UTF-16/32 with a BOM; NUL bytes refused."""
    encoding, start = "utf-8", 0
    for bom, name in _BOMS:
        if data.startswith(bom):
            encoding, start = name, len(bom)
            break
    try:
        text = data[start:].decode(encoding)
    except UnicodeDecodeError as exc:
        bad = data[start + exc.start : start + exc.start + 1]
        detail = (
            f"byte 0x{bad.hex()} at offset {start + exc.start}" if bad else f"truncated at offset {start + exc.start}"
        )
        if encoding != "utf-8":
            detail += ", though its byte-order mark says so"
        raise fail(f"not {encoding.upper()} text ({detail}); save it as UTF-8") from None
    nul = text.find("\x00")
    if nul >= 0:
        raise fail(
            f"holds a NUL character at offset {nul}: a binary file, or UTF-16 text without a "
            "byte-order mark; save it as UTF-8"
        )
    return text


def read_text(
    path: str | os.PathLike[str], limit: int = MAX_TEXT_BYTES, fail: Fail | None = None, *, pipes: bool = True
) -> str:
    """:func:`read_bytes` then :func:`decode_text`."""
    fail = fail or _default_fail(path)
    return decode_text(read_bytes(path, limit, fail, pipes=pipes), fail)


def _parse_int(text: str) -> int | float:
    return int(text) if len(text) <= _MAX_INT_DIGITS else float(text)


def _depth(value: Any) -> int:
    """Nesting depth of parsed JSON (iterative: no recursion limit)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, d = stack.pop()
        if isinstance(item, (list, dict)):
            deepest = max(deepest, d)
            if d > MAX_JSON_DEPTH:
                break
            stack.extend((v, d + 1) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


class _RepeatedKey(ValueError):
    """A key given twice in one JSON object (raised by :func:`_object`)."""


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object as a dict; a key given twice is refused (which copy would count? ``json`` keeps the last)."""
    data = dict(pairs)
    if len(data) < len(pairs):
        seen: set[str] = set()
        key = next(k for k, _ in pairs if k in seen or seen.add(k))
        raise _RepeatedKey(f"key {json.dumps(key)[:80]} appears more than once in one object: which copy would count?")
    return data


def parse_json(text: str, fail: Fail) -> Any:
    """Parse JSON ``text`` within the limits of this module; a key given twice in one object is refused."""
    too_deep = f"JSON nested deeper than {MAX_JSON_DEPTH} levels"
    try:
        data = json.loads(text, parse_int=_parse_int, object_pairs_hook=_object)
    except _RepeatedKey as exc:
        raise fail(str(exc)) from None
    except json.JSONDecodeError as exc:
        raise fail(f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    except RecursionError:
        raise fail(too_deep) from None
    except ValueError as exc:  # e.g. a number json cannot convert
        raise fail(f"not valid JSON: {' '.join(str(exc).split())[:200]}") from None
    if _depth(data) > MAX_JSON_DEPTH:
        raise fail(too_deep)
    return data


def load_json(
    path: str | os.PathLike[str], limit: int = MAX_TEXT_BYTES, fail: Fail | None = None, *, pipes: bool = True
) -> Any:
    """:func:`read_text` then :func:`parse_json`."""
    fail = fail or _default_fail(path)
    return parse_json(read_text(path, limit, fail, pipes=pipes), fail)


def parse_decimal(text: str) -> float | None:
    """A CSV field as a float: plain decimal notation (``-12.5``, ``1e3``), or ``nan``/``inf``
    (returned as such, for the caller to refuse as not finite); None for anything else."""
    if _DECIMAL_RE.fullmatch(text) or _NON_FINITE_RE.fullmatch(text):
        return float(text)
    return None


def coordinate_problem(values: Any) -> str | None:
    """None when every number of ``values`` lies within ±:data:`COORDINATE_LIMIT_MM`, else what is wrong."""
    for v in values:
        if math.isfinite(v) and abs(v) > COORDINATE_LIMIT_MM:
            return f"coordinate {v:g} mm is beyond the ±{COORDINATE_LIMIT_MM:g} mm range"
    return None
