"""Checks of what a command was given as a whole, run once every flag is parsed (:func:`arcube.cli.projection.command`):
a flag that the others make useless, and a named input that does not exist, each refused in one line naming the flag.

They run after each flag's own check (``--workers 100000`` is refused first, whatever else is wrong) and before the
command's work: of several trajectory sets, a missing one is named before the command checks anything else (a design
job with other inputs said something else first)."""

from __future__ import annotations

import os
from typing import Any

from arcube.errors import InputError

__all__ = ["check_given"]

_WORDS = ("default", "none")
"""The words of ``--anatomy`` and ``--envelope`` that name no file."""


def check_given(given: Any, flags: list[Any]) -> None:
    """InputError naming the flag: a trajectory set that does not exist (:func:`_check_plans`), ``--anatomy-frame``
    with no mesh file (:func:`_check_frame_used`). ``given``: a :class:`~arcube.cli.projection.Given`; ``flags``: the
    command's :class:`~arcube.cli.projection.Flag` list."""
    by_dest = {f.dest: f for f in flags}
    _check_plans(given, by_dest)
    _check_frame_used(given, by_dest)


def _check_plans(given: Any, by_dest: dict[str, Any]) -> None:
    """Each ``--trajectories`` value is ``reference`` or a file or folder that exists."""
    flag = by_dest.get("trajectories")
    values = given.values.get(flag.key) if flag is not None else None
    for value in [values] if isinstance(values, str) else values or ():
        if value != "reference" and not os.path.exists(value):
            raise InputError(f"{flag.name} {value}: no such file or folder")


def _check_frame_used(given: Any, by_dest: dict[str, Any]) -> None:
    """``--anatomy-frame`` is given only with an anatomy or skin mesh file: the frame is that of mesh files (the plan's
    default anatomy and envelope are in the patient frame, a segmentation file states its own), else it would be
    ignored."""
    from arcube.io.label_files import LABEL_SUFFIXES

    frame = by_dest.get("anatomy_frame")
    named = [by_dest[d] for d in ("anatomy", "envelope") if d in by_dest]
    if frame is None or frame.key not in given.values or not named:
        return
    values = [given.values.get(f.key) for f in named]
    items = [
        t.strip()
        for v in values
        if v is not None
        for x in ([v] if isinstance(v, str) else v)
        for t in str(x).split(",")
    ]
    if not any(t and t not in _WORDS and not t.lower().endswith(LABEL_SUFFIXES) for t in items):
        raise InputError(
            f"{frame.name} {given.values[frame.key]}: the frame of anatomy and skin mesh files (a segmentation states "
            f"its own), and no mesh file is given ({' or '.join(f'{f.name} FILE.stl' for f in named)}), so it would be "
            "ignored: leave it out"
        )
