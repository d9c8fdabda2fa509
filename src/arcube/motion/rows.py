"""The number of rows a program may have (:data:`~arcube.io.program_files.MAX_PROGRAM_ROWS`), checked
before the rows are allocated.

A program has one row per ``dt`` of its duration, and its duration grows as the speeds shrink: a
drilling feed of 1e-9 mm/s or a step of 1e-7 s asks for terabytes. Every check here refuses with one
:class:`~arcube.errors.InputError` naming the setting to change (``ProgramLimits.feed``, which the CLI
prints as ``--feed``): the step when the program would fit with the default step, else the speed of
the segment that takes longest.

* :func:`check_rows`, before any planning: a lower bound from the plan alone (each line's approach,
  drilling and retract at their speeds);
* :func:`check_piece`, before one piece is sampled (its duration is known once it is timed);
* :func:`check_total`, as the pieces add up.
"""

from __future__ import annotations

import math

import numpy as np

from arcube.errors import InputError
from arcube.io.program_files import MAX_PROGRAM_ROWS
from arcube.io.trajectories import TrajectorySet
from arcube.motion.limits import ProgramLimits

__all__ = ["check_piece", "check_rows", "check_total"]

_DEFAULT_DT = ProgramLimits().dt
_SPEED_OF = {
    "approach": "approach_speed",
    "drill": "feed",
    "retract": "retract_speed",
    "transit": "max_joint_speed_deg",
}
_UNIT = {"approach_speed": "mm/s", "feed": "mm/s", "retract_speed": "mm/s", "max_joint_speed_deg": "deg/s"}


def _refuse(limits: ProgramLimits, seconds: float, what: str, kind: str) -> InputError:
    """The InputError for ``what`` taking ``seconds``: blames ``dt`` when the default step would fit, else ``kind``'s speed."""
    rows = seconds / limits.dt
    if seconds / max(limits.dt, _DEFAULT_DT) <= MAX_PROGRAM_ROWS:
        field, value, unit = "dt", limits.dt, "s"
        fix = f"a larger step (at least {seconds / MAX_PROGRAM_ROWS:.3g} s)"
    else:
        field = _SPEED_OF[kind]
        value, unit = getattr(limits, field), _UNIT[field]
        fix = "faster speeds" if kind != "transit" else "larger joint speed, acceleration or tip speed limits"
    param = f"ProgramLimits.{field}"
    return InputError(
        f"{param} {value:g} {unit}: {what} takes {seconds:.3g} s, {rows:.3g} rows of {limits.dt:g} s; a program has at most "
        f"{MAX_PROGRAM_ROWS} rows: give {fix}",
        param=param,
    )


def check_rows(limits: ProgramLimits, ts: TrajectorySet) -> None:
    """Refuse a plan whose lines alone (approach from the standoff, drilling, retract, at their speeds)
    need more than :data:`MAX_PROGRAM_ROWS` rows of ``limits.dt``."""
    lengths = np.linalg.norm(np.asarray(ts.target) - np.asarray(ts.entry), axis=1)
    standoff = limits.standoff_mm
    parts = {
        "approach": len(ts) * standoff / limits.approach_speed,
        "drill": float(np.sum(lengths)) / limits.feed,
        "retract": float(np.sum(lengths + standoff)) / limits.retract_speed,
    }
    seconds = sum(parts.values())
    if not math.isfinite(seconds) or seconds / limits.dt > MAX_PROGRAM_ROWS:
        kind = max(parts, key=lambda k: parts[k])
        raise _refuse(
            limits,
            seconds,
            f"drilling {len(ts)} trajector{'y' if len(ts) == 1 else 'ies'} (approach, drilling and retract alone)",
            kind,
        )


def check_piece(limits: ProgramLimits, duration: float, kind: str, label: str = "") -> None:
    """Refuse one piece (``kind``: approach, drill, retract or transit) whose ``duration`` (s) needs more
    than :data:`MAX_PROGRAM_ROWS` rows."""
    if not math.isfinite(duration) or duration / limits.dt > MAX_PROGRAM_ROWS:
        raise _refuse(limits, duration, f"the {kind} {label}".rstrip(), kind)


def check_total(limits: ProgramLimits, rows: int, kind: str) -> None:
    """Refuse when the rows so far (the last piece a ``kind``) exceed :data:`MAX_PROGRAM_ROWS`."""
    if rows > MAX_PROGRAM_ROWS:
        raise _refuse(limits, rows * limits.dt, "the program", kind)
