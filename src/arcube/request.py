"""One request: a design on a plan, with the patient around it, resolved once for every command that evaluates one
design (``evaluate``, ``joints``, ``program``, ``tolerance``, ``explore``, ``export_mjcf``).

A :class:`Request` holds what the caller gave (a design or its file, a plan or its file, the selection of its
trajectories, the anatomy, the envelope, the working mode, the points, the options), as given;
:meth:`Request.resolve` loads and checks it in one order (the design and the side's docking, the mode, the plan and
its selection, then the anatomy and the envelope of model §19.5, placed on the whole plan) and returns a
:class:`Resolved`. The keyword functions of :mod:`arcube.api`, :func:`arcube.motion.program`,
:func:`arcube.explorer.live_model` and :func:`arcube.export_mjcf` build it from their keywords
(:meth:`Request.of`), or take the one given as their design; what is their own (speed, limits, ...) stays with them.
"""

from __future__ import annotations

import inspect
import numbers
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from arcube.errors import InputError

__all__ = ["Request", "Resolved", "with_design_c_z"]


@dataclass(frozen=True)
class Resolved:
    """A request, loaded and checked.

    Attributes:
        design: the :class:`~arcube.model.design.Design` (a robot file's docking for the side asked).
        signs: the working mode ``(4,)`` (the caller's, else the design's own, else +,+,+,+).
        full: the plan as loaded, before any selection (the envelope's landmarks come from all of it).
        plan: the trajectories selected by side, levels and ids.
        anatomy: the :class:`~arcube.evaluation.anatomy.Anatomy`, or None.
        envelope: the :class:`~arcube.evaluation.envelope.Envelope` of model §19.5, or None.
    """

    design: Any
    signs: np.ndarray
    full: Any
    plan: Any
    anatomy: Any
    envelope: Any


@dataclass(frozen=True)
class Request:
    """A design on a plan, as the caller gave them (see :func:`arcube.evaluate` for each field's forms).

    ``arcube.evaluate``, ``joints``, ``program``, ``tolerance``, ``export_mjcf`` and ``explore`` take one in place of
    their ``design``, for the same request asked of several commands::

        req = arcube.Request("paper", "reference", side="R", anatomy="default")
        arcube.evaluate(req).summary["eta_G"], arcube.joints(req, speed=2.0)
    """

    design: Any = "paper"
    plan: Any = "reference"
    side: str | None = None
    levels: str | Sequence[str] | None = None
    ids: str | Sequence[str] | None = None
    transform: Any = None
    anatomy: Any = None
    anatomy_frame: str = "LPS"
    segments: Any = None
    envelope: Any = None
    table_z: float | None = None
    mode: Any = None
    points: int = 30
    """Samples per trajectory (model §9)."""
    options: Any = None
    """The :class:`arcube.Options` of the robot (None: the function's default)."""

    @classmethod
    def of(cls, arguments: Mapping[str, Any], function: Callable[..., Any], taken: Sequence[str] = ()) -> Request:
        """The request a keyword function was called with: ``arguments`` are its keywords (``locals()``), ``function``
        itself (its defaults). A Request given as its ``design`` is that request: the function's other request
        keywords must then keep their defaults (or say what the Request says), and the Request must leave unset what
        the function does not take (``program`` takes no ``points``; ``taken``: the fields it takes through the
        request alone, as ``export_mjcf`` its selection); InputError naming the first that does not."""
        names = [f.name for f in fields(cls) if f.name in arguments]
        for name in names[1:]:
            if isinstance(arguments[name], Request):
                raise InputError.of(name, "is a Request: give it as the first argument (design)")
        given = arguments.get("design")
        if not isinstance(given, Request):
            return cls(**{name: arguments[name] for name in names})
        defaults = inspect.signature(function).parameters
        for name in names[1:]:
            value = arguments[name]
            if not (_same(value, defaults[name].default) or _same(value, getattr(given, name))):
                raise InputError.of(name, "is the request's: set it on the arcube.Request given as design")
        for f in fields(cls):
            if f.name not in (*names, *taken) and not _same(getattr(given, f.name), f.default):
                raise InputError.of(
                    f.name, f"is set on the Request, but {function.__name__} does not take it: leave it unset"
                )
        return given

    def resolve(self, before_anatomy: Callable[[Any], None] | None = None) -> Resolved:
        """Load and check everything, in the order a user's mistakes are best reported: the design, the mode, the
        plan and its selection, then ``before_anatomy(plan)`` (a caller's own check of the selected plan, before the
        slow anatomy is read), the anatomy and the envelope. InputError naming the argument on bad input."""
        from arcube.coerce import design_mode
        from arcube.evaluation.anatomy import resolve_anatomy
        from arcube.evaluation.envelope import resolve_envelope
        from arcube.io.load import load_plan
        from arcube.io.trajectories import select
        from arcube.model.design import Design
        from arcube.model.robot import design_at_side

        d = Design.coerce(design_at_side(self.design, self.side, placed=True))
        signs = design_mode(d, self.mode)
        full = load_plan(self.plan, transform=self.transform)
        chosen = (self.side, self.levels, self.ids) != (None, None, None)
        ts = select(full, side=self.side, levels=self.levels, ids=self.ids) if chosen else full
        if before_anatomy is not None:
            before_anatomy(ts)
        anat = resolve_anatomy(self.anatomy, self.anatomy_frame, self.plan, segments=self.segments)
        env = resolve_envelope(self.envelope, full, anat, self.table_z, self.anatomy_frame)
        return Resolved(d, signs, full, ts, anat, env)


def _same(value: Any, other: Any) -> bool:
    """Whether a keyword's value is ``other`` (the same object, or an equal plain number or text)."""
    plain = (str, numbers.Number, np.generic)
    return value is other or (isinstance(value, plain) and isinstance(other, plain) and bool(value == other))


def with_design_c_z(options: Any, design: Any) -> Any:
    """``options`` with the design's own z-dyad link c_z (model §19.1) where the options set none: the one rule of
    which c_z a request evaluates with (an explicit ``c_z`` option wins, then the design's, then d_z)."""
    if design.c_z is not None and options.guards.c_z is None:
        return options.replace(c_z=design.c_z)
    return options
