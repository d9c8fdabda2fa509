"""The command line as a projection of the settings models.

A command's options are :class:`Flag` objects. Most are generated from the fields of a settings
model (:func:`model_flags`): the flag is the field's short name with dashes (:meth:`arcube.options.Settings.flag`) (``Loads.thrust_N`` -> ``--thrust``, ``RunSettings.population`` -> ``--population``), the
help is the field's docstring with its default, and the value goes to the field. The few options that
are not settings (``--out``, ``--json``, ``--trajectories``) are declared once with :func:`option`.

:func:`command` turns a list of flags into a Typer command whose function receives only what the
user gave (:class:`Given`), so that every default lives in its model, written once. A library error
that names a setting (``InputError.param`` = ``"Loads.thrust_N"``) is printed with the command's
flag in its place (``--thrust must be >= 0, got -1.0``): this is the one place where settings become
flags. :data:`REGISTRY` holds every command's flags, for the multi-value and path checks of
:func:`arcube.cli.main`, for the docs and for the tests.
"""

from __future__ import annotations

import re

import inspect
import keyword
import types
import typing
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Literal

import typer
from pydantic import BaseModel

from arcube.cli.checks import check_given
from arcube.errors import InputError

__all__ = [
    "Flag",
    "Given",
    "REGISTRY",
    "command",
    "flag_message",
    "flag_of",
    "flag_table",
    "flag_text",
    "model_flags",
    "numbers",
    "option",
]


@dataclass(frozen=True)
class Flag:
    """One command-line option."""

    name: str
    """The flag, ``--thrust``."""
    key: str
    """Where the value goes: a dotted field path in the command's request (``options.loads.thrust_N``), or a plain name."""
    help: str = ""
    kind: Any = str
    """The click type of one value: ``str``, ``int``, ``float``, ``bool`` (an on/off flag) or ``Path``."""
    multiple: bool = False
    """Repeatable (or several values after one flag, for :data:`MULTI_VALUE` flags)."""
    params: tuple[str, ...] = ()
    """The names a library error uses for this value (``Loads.thrust_N``), replaced by :attr:`name` in messages."""
    parse: Callable[[Any, str], Any] | None = None
    """Text -> the Python value the model takes, given (value, flag name)."""
    required: bool = False
    negatable: bool = False
    """A boolean that defaults to True: ``--x/--no-x``."""
    hidden: bool = False
    path: bool = False
    """Names a file or folder: an empty value is refused (it would silently mean the current folder)."""
    spread: bool = False
    """Takes several values after one flag (``--anatomy a.stl b.stl``)."""

    @property
    def dest(self) -> str:
        """The Python identifier of the generated parameter (from the flag: ``--m-delta`` -> ``m_delta``,
        ``--class`` -> ``class_``: a keyword gets a trailing underscore)."""
        name = self.name.lstrip("-").replace("-", "_")
        return name + "_" if keyword.iskeyword(name) else name


REGISTRY: dict[str, list[Flag]] = {}
"""Command name -> its flags (filled as :func:`command` builds the commands)."""


def numbers(value: str, flag: str) -> list[float]:
    """``"0.01"`` or ``"0.01,0.02,0.01,0.01,0.01"`` -> a list of floats (one or more, comma-separated)."""
    try:
        return [float(v) for v in str(value).split(",")]
    except ValueError:
        raise InputError(
            f"{flag} {value!r}: expected numbers separated by commas, e.g. 0.01 or 0.01,0.01,0.02,0.01,0.01"
        ) from None


def _numbers_or_one(value: str, flag: str) -> Any:
    """One number or a list of them, from comma-separated text; text that is not numbers goes to the
    field as it is, whose own check says what it must be."""
    try:
        got = [float(v) for v in str(value).split(",")]
    except ValueError:
        return value
    return got[0] if len(got) == 1 else got


def _default_text(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return ""
    if isinstance(value, tuple) and value and len(set(value)) == 1:
        return _default_text(value[0])
    if isinstance(value, tuple):
        return ",".join(_default_text(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _kind(annotation: Any) -> tuple[Any, bool, Callable[[Any, str], Any] | None]:
    """(click type, multiple, text parser) of a field's annotation."""
    while typing.get_origin(annotation) is Annotated:
        annotation = typing.get_args(annotation)[0]
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return _kind(inner[0]) if len(inner) == 1 else (str, False, None)
    if origin is tuple and args and args[0] in (float, int):
        return str, False, _numbers_or_one
    if origin in (tuple, list) and args and args[0] is str:
        return str, True, None
    if origin is dict:
        return str, True, None
    if origin is Literal:
        return type(args[0]) if not isinstance(args[0], str) else str, False, None
    if annotation in (int, float, bool, str):
        return annotation, False, None
    return str, False, None


def model_flags(
    model: type[BaseModel],
    key: str = "",
    *,
    only: Iterable[str] | None = None,
    skip: Iterable[str] = (),
    names: dict[str, str] | None = None,
    helps: dict[str, str] | None = None,
) -> list[Flag]:
    """The flags of a settings model's fields, in declaration order.

    Args:
        model: a :class:`arcube.options.Settings` subclass.
        key: the dotted path of the model in the command's request (``options.loads``).
        only, skip: keep only these fields / leave these out.
        names: a flag name where the rule (the field's short name with dashes) does not fit this command.
        helps: a help text where the field's docstring does not fit this command.
    """
    keep = None if only is None else list(only)
    out: list[Flag] = []
    fields = model.model_fields
    for name in keep if keep is not None else fields:
        if name in skip:
            continue
        info = fields[name]
        kind, multiple, parse = _kind(info.annotation)
        flag = (names or {}).get(name) or model.flag(name)  # type: ignore[attr-defined]
        text = (helps or {}).get(name) or " ".join((info.description or name).replace("``", "").split())
        default = _default_text(info.default)
        negatable = kind is bool and info.default is True
        if default and not negatable:
            text += f" [default: {default}]"
        out.append(
            Flag(
                flag,
                f"{key}.{name}" if key else name,
                text,
                kind,
                multiple,
                (f"{model.__name__}.{name}",),
                parse,
                negatable=negatable,
            )
        )
    for old, new in getattr(model, "RENAMED", {}).items():  # the old flag, hidden, for one release
        now = next((f for f in out if f.params == (f"{model.__name__}.{new}",)), None)
        if now is not None:
            out.append(
                replace(
                    now,
                    name=model.flag(old),  # type: ignore[attr-defined]
                    key=f"{key}.{old}" if key else old,
                    help=f"Renamed {now.name}.",
                    params=(f"{model.__name__}.{old}",),
                    hidden=True,
                )
            )
    return out


def option(
    name: str,
    help: str,
    kind: Any = str,
    *,
    key: str | None = None,
    multiple: bool = False,
    required: bool = False,
    parse: Callable[[Any, str], Any] | None = None,
    params: tuple[str, ...] = (),
    hidden: bool = False,
    path: bool | None = None,
    spread: bool = False,
) -> Flag:
    """A flag that is not a settings field (``--out``, ``--json``); ``key`` defaults to its dest."""
    flag = Flag(
        name,
        key or "",
        help,
        kind,
        multiple,
        params,
        parse,
        required,
        hidden=hidden,
        path=kind is Path if path is None else path,
        spread=spread,
    )
    return flag if key else replace(flag, key=flag.dest)


def flag_of(flags: Iterable[Flag], key: str) -> Flag:
    """The flag whose value goes to ``key``."""
    return next(f for f in flags if f.key == key)


@dataclass
class Given:
    """What the user gave on the command line: value by key (only the flags given), parsed."""

    values: dict[str, Any] = field(default_factory=dict)
    flags: dict[str, Flag] = field(default_factory=dict)

    def __contains__(self, key: str) -> bool:
        return key in self.values

    def get(self, key: str, default: Any = None) -> Any:
        """The value given for ``key``, else ``default``."""
        return self.values.get(key, default)

    def pop(self, key: str, default: Any = None) -> Any:
        """The value given for ``key`` (removed), else ``default``."""
        return self.values.pop(key, default)

    def tree(self, prefix: str) -> dict[str, Any]:
        """The given values under ``prefix`` as a nested dict (``options`` -> ``{"loads": {"thrust_N": 25.0}}``)."""
        out: dict[str, Any] = {}
        head = prefix + "." if prefix else ""
        for key, value in self.values.items():
            if not key.startswith(head):
                continue
            node = out
            *parents, leaf = key[len(head) :].split(".")
            for p in parents:
                node = node.setdefault(p, {})
            node[leaf] = value
        return out

    def flag(self, key: str) -> str:
        """The flag that sets ``key`` (for messages)."""
        return self.flags[key].name


def flag_text(exc: InputError, flags: Iterable[Flag]) -> InputError:
    """``exc`` with the setting it names replaced by the flag that sets it, and the settings named inside its text by
    theirs (``exc`` itself if none is)."""
    text, param = str(exc), exc.param
    flags = list(flags)
    for f in flags:
        if param and param in f.params and text.startswith(param):
            text, param = f.name + text[len(param) :], f.name
            break
    inside = {p: f.name for f in flags for p in f.params if "." in p}
    for key in sorted((k for k in inside if k in text), key=len, reverse=True):
        text = re.sub(rf"(?<![\w.]){re.escape(key)}(?![\w])", inside[key], text)
    return exc if text == str(exc) else InputError(text, param=param)


def flag_table() -> dict[str, str]:
    """Every setting a library error can name -> its flag, over every command (the first command's
    flag where two commands set it with different flags)."""
    table: dict[str, str] = {}
    for flags in REGISTRY.values():
        for f in flags:
            for p in f.params:
                table.setdefault(p, f.name)
    return table


def flag_message(exc: InputError) -> str:
    """What the CLI prints for ``exc``: its message with the setting it names replaced by its flag
    (unchanged if none); a command's own flags take precedence (:func:`command`)."""
    param = exc.param
    table = flag_table()
    flag = table.get(param) if param else None
    text = str(exc)
    text = flag + text[len(param) :] if flag is not None and param is not None and text.startswith(param) else text
    # a setting named inside the message ("IdentifySettings.holdout sets how many") is the user's flag too
    for key in sorted((k for k in table if "." in k and k in text), key=len, reverse=True):
        text = re.sub(rf"(?<![\w.]){re.escape(key)}(?![\w])", table[key], text)
    return text


def _parameter(f: Flag) -> inspect.Parameter:
    if f.kind is bool:
        names = (f"{f.name}/--no-{f.name[2:]}",) if f.negatable else (f.name,)
        annotation: Any = bool | None
    else:
        names = (f.name,)
        # a path with a parser gets the text as typed: click's Path would drop a trailing '/' ("jdir/" -> "jdir")
        kind = str if f.kind is Path and f.parse is not None else f.kind
        annotation = list[kind] | None if f.multiple or f.spread else kind | None  # type: ignore[valid-type]
    metavar = (
        None if f.kind is bool else f"<{'path' if f.kind is Path else f.kind.__name__}>" + (" ..." if f.spread else "")
    )
    info = typer.Option(*names, help=f.help, hidden=f.hidden, show_default=False, metavar=metavar)
    return inspect.Parameter(
        f.dest, inspect.Parameter.KEYWORD_ONLY, default=None, annotation=Annotated[annotation, info]
    )


def argument(name: str, help: str, kind: type = Path) -> inspect.Parameter:
    """A positional argument of a command (its METAVAR is ``name`` upper-cased), for :func:`command`'s ``arguments``."""
    info = typer.Argument(metavar=name.upper(), help=help)
    return inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=Annotated[kind, info])


_EXCLUSIVE = {("workers", "dask"): "a Dask cluster has its own workers"}
"""Pairs of flags (by key) a command refuses together, naming both, and why (``--workers`` > 1 with ``--dask``)."""


def command(
    app: typer.Typer,
    name: str,
    flags: list[Flag],
    run: Callable[[Given], None],
    *,
    help: str,
    arguments: Iterable[inspect.Parameter] = (),
    registry_name: str | None = None,
) -> None:
    """Register command ``name`` on ``app``: its options are ``flags``, then ``arguments`` (Typer
    parameters of its own, e.g. a positional folder, passed in :attr:`Given.values` by name);
    ``run`` gets what the user gave. Errors naming a setting are printed with its flag. ``registry_name``:
    the command's name in :data:`REGISTRY` (a subcommand's full name, ``calibrate poses``)."""
    dests = [f.dest for f in flags]
    if len(set(dests)) != len(dests) or len({f.name for f in flags}) != len(flags):
        raise ValueError(f"arcube {name}: two flags with one name")
    REGISTRY[registry_name or name] = flags
    extra = list(arguments)
    spread = next((f for f in flags if f.spread), None)
    if (
        spread is not None
    ):  # several values after one flag: arcube.cli.main splits them; in-process callers (tests) do not
        extra.append(
            inspect.Parameter(
                "more_values",
                inspect.Parameter.POSITIONAL_OR_KEYWORD,
                default=None,
                annotation=Annotated[list[str] | None, typer.Argument(hidden=True, metavar="MORE")],
            )
        )

    def fn(**kw: Any) -> None:
        given = Given(flags={f.key: f for f in flags})
        stray = kw.get("more_values") or []
        for f in flags:
            value = kw.get(f.dest)
            if value is None or (isinstance(value, list) and not value):
                if f.required:
                    hint = (
                        f"; {stray[0]!r} is a value without its flag (give {f.name} {stray[0]})"
                        if stray and f.spread
                        else ""
                    )
                    raise InputError(f"{f.name} is required{hint}")
                continue
            try:  # a parser may check with the library's own check, which names the setting: the flag is shown
                given.values[f.key] = (
                    [f.parse(v, f.name) for v in value]
                    if (f.parse and isinstance(value, list))
                    else (f.parse(value, f.name) if f.parse else value)
                )
            except InputError as exc:
                raise flag_text(exc, flags) from None
        more = kw.pop("more_values", None) or []
        for p in extra:
            if p.name != "more_values":
                given.values[p.name] = kw.get(p.name)
        for (a, b), why in _EXCLUSIVE.items():
            if given.get(a) not in (None, 1) and given.get(b) is not None:
                raise InputError(
                    f"{given.flag(a)} {given.get(a)} and {given.flag(b)} {given.get(b)}: one or the other ({why})"
                )
        if more:
            if spread is None or spread.key not in given.values:
                raise InputError(
                    f"unexpected argument {more[0]!r}"
                    + (f" (values go after {spread.name})" if spread is not None else "")
                )
            given.values[spread.key] = [*given.values[spread.key], *more]
        check_given(given, flags)
        try:
            run(given)
        except InputError as exc:
            raise flag_text(exc, flags) from None

    fn.__signature__ = inspect.Signature([*extra, *(_parameter(f) for f in flags)])  # type: ignore[attr-defined]
    fn.__doc__ = help
    fn.__name__ = name.replace("-", "_")
    app.command(name, help=help)(fn)
