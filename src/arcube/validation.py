"""The base of every settings model, and the one place a pydantic error becomes a one-line
:class:`~arcube.errors.InputError` naming the field as a Python caller writes it
(``Loads.thrust_N must be >= 0, got -1.0``); the CLI maps that name to its flag.
"""

from __future__ import annotations

import types
import typing
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, field_validator, model_validator

from arcube.errors import InputError, RenamedWarning

__all__ = ["Settings", "caller_stacklevel", "renamed_keyword", "settings_error", "validated"]


def caller_stacklevel() -> int:
    """The ``stacklevel`` of :func:`warnings.warn`, called by the function that calls this one, that points at the
    first frame outside arcube (and pydantic, whose validators call arcube's): an old name's warning names the
    caller's line, however deep in arcube it was noticed."""
    import sys

    frame, level = sys._getframe(1), 1  # the frame that calls warnings.warn is stacklevel 1
    while frame is not None and str(frame.f_globals.get("__name__", "")).split(".")[0] in ("arcube", "pydantic"):
        frame, level = frame.f_back, level + 1
    return level


def renamed_keyword(keywords: dict[str, Any], old: str, new: str, value: Any, default: Any) -> Any:
    """A function's keyword ``new`` as called: ``value``, or the old name's from ``keywords`` (a function's
    ``**changes``; removed from them), taken for one release with a :class:`RenamedWarning`; the two names given
    together are refused (which one was meant?)."""
    if old not in keywords:
        return value
    if value != default:
        raise InputError.of(old, f"and {new} are one setting (renamed): give {new}")
    import warnings

    warnings.warn(
        f"{old} is now {new} (the old name goes in the next release)", RenamedWarning, stacklevel=caller_stacklevel()
    )
    return keywords.pop(old)


def _leaves(annotation: Any) -> list[Any]:
    """The types an annotation admits, through ``Annotated``, ``Optional`` and unions."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _leaves(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return [leaf for a in typing.get_args(annotation) for leaf in _leaves(a)]
    return [annotation]


def _number_not_bool(annotation: Any) -> bool:
    """Whether a field takes a number (int or float) and not a bool: pydantic would read True there as 1."""
    leaves = _leaves(annotation)
    return any(leaf in (int, float) for leaf in leaves) and not any(leaf is bool or leaf is Any for leaf in leaves)


class Settings(BaseModel):
    """Base of every settings group: frozen, unknown keys refused, defaults validated; each field's
    docstring is its description (the help of its command-line flag)."""

    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True, use_attribute_docstrings=True)

    SHORT: ClassVar[dict[str, str]] = {}
    """Field -> its short name, where the field's name carries a unit the user does not write
    (``thrust_N`` -> ``thrust``): the flat keyword of the Python API, the key of a run's config table,
    and (with dashes) the command-line flag. A field not listed is its own short name."""

    RENAMED: ClassVar[dict[str, str]] = {}
    """Old field name -> the field's name now: the old one is taken for one release, with a :class:`RenamedWarning`
    (the command line keeps the old flag hidden beside the new one)."""
    RENAMED_VALUES: ClassVar[dict[str, dict[str, str]]] = {}
    """Field -> {old spelling: value now}: an old spelling of a value, taken likewise for one release."""

    @classmethod
    def renamed(cls, data: dict[str, Any]) -> dict[str, Any]:
        """``data`` with old names and spellings (:attr:`RENAMED`, :attr:`RENAMED_VALUES`) replaced, each with a
        :class:`RenamedWarning`; an old name given beside its new one is refused (which one was meant?)."""
        if not (cls.RENAMED or cls.RENAMED_VALUES):
            return data
        import warnings

        data = dict(data)
        for old, new in cls.RENAMED.items():
            if old in data:
                if new in data:
                    raise InputError.of(
                        f"{cls.__name__}.{old}",
                        f"and {cls.__name__}.{new} are one setting (renamed): give {cls.__name__}.{new}",
                    )
                warnings.warn(
                    f"{cls.__name__}.{old} is now {cls.__name__}.{new} (the old name goes in the next release)",
                    RenamedWarning,
                    stacklevel=caller_stacklevel(),
                )
                data[new] = data.pop(old)
        for field, spellings in cls.RENAMED_VALUES.items():
            value = data.get(field)
            key = value.strip().lower() if isinstance(value, str) else None
            if key in spellings:
                warnings.warn(
                    f"{cls.__name__}.{field} {key!r} is now spelt {spellings[key]!r} (the old spelling goes in the next release)",
                    RenamedWarning,
                    stacklevel=caller_stacklevel(),
                )
                data[field] = spellings[key]
        return data

    @model_validator(mode="before")
    @classmethod
    def _old_names(cls, data: Any) -> Any:
        return cls.prepare(cls.renamed(dict(data))) if isinstance(data, dict) else data

    @classmethod
    def prepare(cls, data: dict[str, Any]) -> dict[str, Any]:
        """The keys as given, rewritten before validation (``data``: a copy, old names already replaced): a
        subclass's place for flat names and spellings; as given here."""
        return data

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, value: Any, info: ValidationInfo) -> Any:
        # pydantic reads True as 1.0: Guards(envelope_clearance_mm=True) was a silent 1 mm guard
        if (
            isinstance(value, bool)
            and info.field_name is not None
            and _number_not_bool(cls.model_fields[info.field_name].annotation)
        ):
            raise ValueError("must be a number")
        return value

    @classmethod
    def short(cls, name: str) -> str:
        """The short name of field ``name`` (see :attr:`SHORT`)."""
        return cls.SHORT.get(name, name)

    @classmethod
    def flag(cls, name: str) -> str:
        """The command-line flag of field ``name``: its short name with dashes (``thrust_N`` -> ``--thrust``).
        The one naming rule: the CLI's options are generated with it, and a run's rerun line is written with it."""
        return "--" + cls.short(name).replace("_", "-")

    @classmethod
    def field_of(cls, name: str) -> str | None:
        """The field that ``name`` (a field's name or short name) means, None if none."""
        if name in cls.model_fields:
            return name
        return next((f for f, s in cls.SHORT.items() if s == name), None)

    def __init__(self, /, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise settings_error(exc, type(self)) from None

    def merged(self, tree: dict[str, Any]) -> Any:
        """A validated copy with the values of ``tree`` (nested dicts for nested groups: ``{"loads":
        {"thrust_N": 25}}``) merged in, every other value kept."""

        def merge(base: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
            return {
                **base,
                **{
                    k: merge(base[k], v) if isinstance(v, dict) and isinstance(base.get(k), dict) else v
                    for k, v in new.items()
                },
            }

        return validated(type(self), merge(self.model_dump(), type(self).renamed(tree)))

    def replace(self, **changes: Any) -> Any:
        """A validated copy with ``changes`` (InputError naming the field on a bad value)."""
        data = self.model_dump()
        for key, value in type(self).renamed(changes).items():
            data[key] = value.model_dump() if isinstance(value, BaseModel) else value
        return validated(type(self), data)


def _param(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """``Loads.thrust_N`` for the location ``("loads", "thrust_N")`` in ``Options``: the innermost
    model's name and the field, as a caller writes them."""
    cls: Any = model
    for i, item in enumerate(loc):
        field = (
            cls.model_fields.get(item)
            if isinstance(item, str) and isinstance(cls, type) and issubclass(cls, BaseModel)
            else None
        )
        if field is None:
            break
        sub = field.annotation
        if isinstance(sub, type) and issubclass(sub, BaseModel) and i + 1 < len(loc):
            cls = sub
            continue
        return f"{cls.__name__}.{item}"
    return f"{cls.__name__}.{'.'.join(str(x) for x in loc)}" if loc else cls.__name__


_PHRASES = {
    "greater_than_equal": "must be >= {ge}",
    "greater_than": "must be > {gt}",
    "less_than_equal": "must be <= {le}",
    "less_than": "must be < {lt}",
    "finite_number": "must be a finite number",
    "extra_forbidden": "is not a setting",
    "bool_parsing": "must be true or false",
    "bool_type": "must be true or false",
    "float_parsing": "must be a number",
    "float_type": "must be a number",
    "int_parsing": "must be an integer",
    "int_type": "must be an integer",
    "int_from_float": "must be an integer",
    "missing": "is required",
}


def settings_error(exc: ValidationError, model: type[BaseModel]) -> InputError:
    """The first problem of a pydantic ``ValidationError`` as one line naming the field."""
    err = exc.errors(include_url=False)[0]
    inner = (err.get("ctx") or {}).get("error")
    if isinstance(inner, InputError):  # a nested group's own __init__ already named its field
        return inner
    loc = tuple(x for x in err["loc"] if not (isinstance(x, str) and x.startswith("function-")))
    # A per-actuator tuple reports (field, index): name the field, not the slot.
    while loc and isinstance(loc[-1], int):
        loc = loc[:-1]
    param = _param(model, loc)
    phrase = _PHRASES.get(err["type"])
    if err["type"] == "literal_error":
        text = "must be one of " + str((err.get("ctx") or {}).get("expected", "")).replace("'", "").replace(
            " or ", ", "
        )
    elif phrase is not None:
        text = phrase.format(
            **{k: (f"{v:g}" if isinstance(v, (int, float)) else v) for k, v in (err.get("ctx") or {}).items()}
        )
    else:
        text = str(err["msg"]).removeprefix("Value error, ")
        text = text if text.startswith(("must", "is ")) else f"is invalid: {text}"
    if err["type"] != "extra_forbidden" and "input" in err:
        text += f", got {err['input']!r}"
    return InputError(f"{param} {text}", param=param)


def validated(model: type[Any], data: Any = None, /, **fields: Any) -> Any:
    """``model(**data, **fields)`` validated; a bad value -> :class:`InputError` naming the field."""
    try:
        return model.model_validate({**(data or {}), **fields})
    except ValidationError as exc:  # model_validate does not pass through Settings.__init__
        raise settings_error(exc, model) from None
