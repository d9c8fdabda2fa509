"""One coercion module: the values a caller gives (Python values, or a file's or the command line's
text) as the values the library computes with, each checked once, with one error naming the argument.

* :func:`mode_signs` / :func:`mode_text`: a working mode (model §4.3, 5.3), ``(1, 1, -1, 1)`` or
  ``"+,+,-,+"``, as four signs ``(4,)`` or as its text;
* :func:`points`: samples per trajectory (model §1.4), an integer in ``[2, MAX_POINTS]``;
* :func:`seeds`: ``"1-5"``, ``"1,3,7"``, ``"1-3,10"`` or a sequence of integers, as sorted distinct seeds;
* :func:`limit_pairs`: limits ``NAME=VALUE`` (``--max torque=15``, repeatable) or a mapping, each name
  once, each value a finite number in plain decimal notation (``1_5`` is refused, not read as 15).

A bad value raises :class:`~arcube.errors.InputError` whose ``param`` is the argument's name as a
Python caller writes it (``mode``, ``points``, ``seeds``); the CLI replaces it with its flag.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.errors import InputError
from arcube.metrics import MAX_ETA_G, limit_bound
from arcube.io.inputs import parse_decimal, short_repr
from arcube.evaluation.task import MAX_POINTS
from arcube.model.mechanism import format_mode, parse_mode

__all__ = [
    "MAX_POINTS",
    "MAX_SEEDS",
    "design_mode",
    "engine_name",
    "check_best_known",
    "limit_pairs",
    "mode_signs",
    "mode_text",
    "points",
    "seeds",
]

MAX_SEEDS = 1000
"""The most seeds one study or design job takes (a typo such as 1-100000 is refused instead of run)."""


def mode_signs(mode: Any, *, param: str = "mode") -> NDArray[np.float64]:
    """A working mode as text (``"+,+,-,+"``) or four signs (``(1, 1, -1, 1)``) -> signs ``(4,)`` of
    +1.0 / -1.0 (TMS x, TMS y, RTS x, RTS y)."""
    if isinstance(mode, str):
        text = mode
    else:
        try:
            values = np.asarray(mode, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError.of(param, f"must be four signs like '+,+,-,+' or (1, 1, -1, 1), got {mode!r}") from None
        if values.shape != (4,) or not np.all(np.abs(values) == 1.0):
            raise InputError.of(param, f"must be four signs +1/-1 like (1, 1, -1, 1), got {mode!r}")
        text = format_mode(values)
    try:
        return parse_mode(text)
    except ValueError as exc:
        raise InputError(f"{param}: {exc}", param=param) from None


def design_mode(design: Any, mode: Any = None, *, param: str = "mode") -> NDArray[np.float64]:
    """The working mode a request runs in: ``mode`` when given, else the one the design records
    (:attr:`arcube.Design.mode`), else ``+,+,+,+`` (the paper's); as :func:`mode_signs`."""
    if mode is None:
        mode = getattr(design, "mode", None) or DEFAULT_MODE_TEXT
    return mode_signs(mode, param=param)


def mode_text(mode: Any, *, param: str = "mode") -> str:
    """The text form ``"+,+,-,+"`` of a working mode (as :func:`mode_signs` takes it)."""
    return format_mode(mode_signs(mode, param=param))


def points(value: Any, *, param: str = "points") -> int:
    """Samples per trajectory: an integer in ``[2, MAX_POINTS]`` (both ends of a trajectory included)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 2 <= value <= MAX_POINTS:
        raise InputError.of(
            param, f"must be an integer in [2, {MAX_POINTS}] (both ends of a trajectory included), got {value!r}"
        )
    return int(value)


def seeds(value: str | Sequence[int]) -> list[int]:
    """``"1-5"``, ``"1,3,7"``, ``"1-3,10"`` or a sequence of integers -> ascending distinct seeds in
    ``[0, 2^63)`` (InputError naming ``seeds`` if malformed, empty, repeated or more than :data:`MAX_SEEDS`)."""
    if not isinstance(value, str):
        items = list(value)
        if not all(isinstance(s, (int, np.integer)) and not isinstance(s, bool) for s in items):
            raise InputError.of("seeds", f"must be integers, got {items!r}")
        value = ",".join(str(int(s)) for s in items)
    text = value.strip()
    if not text:
        raise InputError.of("seeds", "is empty: give seeds as 1-5, 1,3,7 or 1-3,10")
    out: list[int] = []
    for item in text.split(","):
        lo_s, dash, hi_s = item.strip().partition("-")
        try:
            lo = int(lo_s)
            hi = int(hi_s) if dash else lo
        except ValueError:
            raise InputError.of(
                "seeds", f"{value!r}: {item.strip()!r} is not a seed or a range A-B of non-negative integers"
            ) from None
        if lo > hi:
            raise InputError.of("seeds", f"{value!r}: range {item.strip()!r} runs backwards")
        if hi - lo + 1 + len(out) > MAX_SEEDS:
            raise InputError.of("seeds", f"{value!r}: more than {MAX_SEEDS} seeds")
        out.extend(range(lo, hi + 1))
    if len(set(out)) != len(out):
        raise InputError.of("seeds", f"{value!r}: a seed is named twice")
    if not all(0 <= s < 2**63 for s in out):
        raise InputError.of("seeds", f"{value!r}: seeds must be integers in [0, 2^63)")
    return sorted(out)


def engine_name(name: Any) -> str:
    """An evaluation engine, ``auto`` / ``numba`` / ``numpy``, resolved to the one that runs (``numba``
    when ``auto`` finds the compiler); InputError naming ``engine`` if unknown."""
    from arcube.evaluation.engine import resolve

    try:
        return resolve(name)
    except (ValueError, TypeError, AttributeError) as exc:
        raise InputError.of("engine", str(exc)) from None


def limit_pairs(value: Any, *, param: str, example: str = "torque=15") -> list[tuple[str, float, str]]:
    """Limits as ``[(name, value, as given)]``, from ``"NAME=VALUE"``, a sequence of them, or a mapping
    name -> number (or its text). InputError naming ``param``: not NAME=VALUE, a value that is not a
    finite number in plain decimal notation (:func:`arcube.io.inputs.parse_decimal`: ``1_5``, ``0x10``
    and ``1,5`` are refused), or a name given twice (which one would count?)."""
    if value is None:
        return []
    if isinstance(value, Mapping):
        items = [(str(k), v, f"{k}={v}") for k, v in value.items()]
    else:
        items = []
        for item in [value] if isinstance(value, str) else list(value):
            name, sep, text = str(item).partition("=")
            if not sep or not name.strip():
                raise InputError.of(param, f"{short_repr(item)}: expected NAME=VALUE, e.g. {example}")
            items.append((name.strip(), text, str(item)))
    out: list[tuple[str, float, str]] = []
    seen: dict[str, str] = {}
    for name, v, shown in items:
        if name in seen:
            raise InputError.of(
                param,
                f"{short_repr(shown)}: {name} is given twice ({short_repr(seen[name])} and {short_repr(shown)}); give it once",
            )
        seen[name] = shown
        if isinstance(v, bool):
            number = None
        elif isinstance(v, (int, float, np.integer, np.floating)):
            number = float(v)
        else:
            number = parse_decimal(str(v).strip())
        if number is None:
            raise InputError.of(
                param,
                f"{short_repr(shown)}: the value {short_repr(str(v).strip())} is not a number (plain decimal notation, e.g. {example})",
            )
        if not np.isfinite(number):
            raise InputError.of(param, f"{short_repr(shown)}: the value must be finite")
        bound = limit_bound(name)
        if bound is not None and abs(number) > bound[0]:
            unit = {"": "", "probability": ""}.get(bound[1], f" {bound[1]}")
            raise InputError.of(
                param, f"{short_repr(shown)}: the value must lie within ±{bound[0]:g}{unit} (a unit mistake?)"
            )
        out.append((name, number, shown))
    return out


def check_best_known(value: Any, *, param: str = "best_known") -> float | None:
    """``value`` (an eta_G to draw as a reference line, or None) if it is a positive number of at most
    :data:`arcube.metrics.MAX_ETA_G`; InputError naming ``param`` otherwise."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0.0):
        raise InputError.of(param, f"must be a positive number (an eta_G), got {value}")
    if value > MAX_ETA_G:
        raise InputError.of(
            param, f"must be at most {MAX_ETA_G:g} (an eta_G: 100/eta_G is the dexterity in %), got {value:g}"
        )
    return float(value)
