"""A result's summary as a typed object that is still its JSON: :class:`Summary`.

A summary is the dict its JSON holds (``summary["eta_G"]``, ``json.dumps(summary)``, equal to the dict) and, for
each field its class declares, an attribute (``summary.eta_G``) typed by that declaration; a declared field the
result does not have (computed only when asked) reads None, and a name that is not a field raises AttributeError.
Each kind of result declares its fields once, in its own module (:class:`arcube.evaluation.result.EvaluationSummary`,
:class:`arcube.optimization.run_results.RunSummary`), with the unit in the name and a docstring per field.
"""

from __future__ import annotations

import copy
import functools
import inspect
from typing import Any

__all__ = ["Summary"]


class Summary(dict[str, Any]):
    """A result's summary: its JSON object, with each declared field (the class's annotations) as an attribute."""

    __slots__ = ()

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The declared fields, in declaration order (a subclass's after its bases')."""
        return _fields(cls)

    def __getattr__(self, name: str) -> Any:
        if name in type(self).fields():
            return self.get(name)
        raise AttributeError(f"{type(self).__name__} has no field {name!r} (its fields: {', '.join(self.fields())})")

    def to_json(self) -> dict[str, Any]:
        """A plain, independent copy (a dict of JSON values), safe to change."""
        return copy.deepcopy(dict(self))


@functools.cache
def _fields(cls: type[Summary]) -> tuple[str, ...]:
    """:meth:`Summary.fields`, read from the annotations once per class (every attribute read asks)."""
    names: list[str] = []
    for klass in reversed(cls.__mro__):
        if issubclass(klass, Summary) and klass is not Summary:
            names += [n for n in inspect.get_annotations(klass) if n not in names]
    return tuple(names)
