"""The settings of a drilling program (model §17): speeds, limits, clearances, and the planner's own.

:class:`ProgramLimits` holds what 17.1-17.3 name, with their defaults; :class:`Planner` the sampling
planner's reproducibility knobs (not model). Both are frozen pydantic groups whose ``Field``
constraints are their only checks: a bad value is a one-line :class:`~arcube.errors.InputError`
naming the field (``ProgramLimits.feed must be > 0, got -1.0``), which the CLI maps to its flag.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from arcube.metrics import metric
from arcube.options import Settings

__all__ = ["MAX_SPEED_MM_S", "ORDERS", "Planner", "ProgramLimits", "RESOLUTION_MM"]

ORDERS = ("shortest", "given")
"""The trajectory orders of model §17.1: the shortest total time, or the plan's own."""

RESOLUTION_MM = 0.5
"""model §17.2: no point of the body or tool moves more than this between two checked states."""

MAX_SPEED_MM_S = 1000.0
"""Largest tip speed, mm/s: a metre per second is beyond any drilling robot (a program's speeds, ``joints --speed``)."""
_SPEED = dict(gt=0, le=MAX_SPEED_MM_S, allow_inf_nan=False)


class ProgramLimits(Settings):
    """Speeds and limits of model §17 (mm, s, deg)."""

    SHORT: ClassVar[dict[str, str]] = {
        "standoff_mm": "standoff",
        "max_joint_speed_deg": "max_joint_speed",
        "max_joint_accel_deg": "max_joint_accel",
    }

    standoff_mm: float = Field(default=20.0, gt=0, le=1000.0, allow_inf_nan=False)
    """The tip waits this far outside the anatomy along its axis (model §17.1), mm (at most a metre: beyond the robot's reach)."""
    approach_speed: float = Field(default=10.0, **_SPEED)
    """Standoff -> entry, mm/s (at most 1000)."""
    feed: float = Field(default=1.5, **_SPEED)
    """Drilling feed, entry -> target, mm/s (at most 1000)."""
    retract_speed: float = Field(default=10.0, **_SPEED)
    """Target -> standoff, mm/s (at most 1000)."""
    max_joint_speed_deg: float = Field(default=30.0, gt=0, le=3600.0, allow_inf_nan=False)
    """Largest actuator rate, deg/s (at most 3600: ten turns a second)."""
    max_joint_accel_deg: float = Field(default=120.0, gt=0, le=1e5, allow_inf_nan=False)
    """Largest actuator acceleration, deg/s^2 (at most 1e5)."""
    max_tip_speed: float = Field(default=50.0, **_SPEED)
    """Largest tip speed in transit, mm/s (at most 1000)."""
    tool_radius: float = Field(default=1.5, ge=0, le=100.0, allow_inf_nan=False)
    """Radius of the tool E -> H, which clears the anatomy in transit, mm."""
    dt: float = Field(default=0.01, gt=0, le=1.0, allow_inf_nan=False)
    """Time step of the rows, s."""
    # the three clearance defaults are the design job's limits, kept once in arcube.metrics
    clearance: float = Field(default=metric("clearance").default_limit, ge=0, le=1000.0, allow_inf_nan=False)
    """Body to anatomy everywhere, mm (with an anatomy)."""
    self_clearance: float = Field(
        default=metric("self_clearance").default_limit, ge=-1000.0, le=1000.0, allow_inf_nan=False
    )
    """Between the body's own parts everywhere, mm (negative: an overlap the caller accepts, e.g. a skeleton design)."""
    kappa_max: float = Field(default=100.0, ge=1, le=1e12, allow_inf_nan=False)
    """Largest eta_L everywhere."""
    envelope_clearance: float = Field(default=metric("envelope_clearance").default_limit, allow_inf_nan=False)
    """Body to the envelope of the whole patient and the table everywhere, mm (with an envelope; model §19.5)."""

    @property
    def qd_max(self) -> float:
        """The joint speed limit in rad/s."""
        return math.radians(self.max_joint_speed_deg)

    @property
    def qdd_max(self) -> float:
        """The joint acceleration limit in rad/s^2."""
        return math.radians(self.max_joint_accel_deg)


class Planner(Settings):
    """The sampling planner of the transits (OMPL RRTConnect): a seed and a time budget per transit."""

    SHORT: ClassVar[dict[str, str]] = {"time_s": "plan_time"}

    seed: int = Field(default=1, ge=0, le=2**31 - 1)
    """Random seed of the transit planner (OMPL): the same seed gives the same program."""
    time_s: float = Field(default=10.0, gt=0, le=3600, allow_inf_nan=False)
    """Time budget of one blocked transit's planner, s."""
