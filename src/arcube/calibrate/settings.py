"""The settings of a calibration (model §21): pose selection, identification, simulated robots.

Field names follow the flags of ``arcube calibrate poses|identify|simulate`` (``--count`` -> ``count``,
``--sigma-mm`` -> ``sigma_mm``, ``--holdout`` -> ``holdout``); the class flag ``--class`` is
``tolerance_class`` as in :class:`arcube.accuracy.ToleranceSettings` (``class`` is a Python keyword).
A bad value raises :class:`~arcube.errors.InputError` naming the field
(``IdentifySettings.holdout must be < 0.9, got 0.95``).
"""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import Field

from arcube.accuracy.settings import MAX_SAMPLES
from arcube.options import Settings

SigmaMm = Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)]
SigmaDeg = Annotated[float, Field(gt=0, le=30.0, allow_inf_nan=False)]
Seed = Annotated[int, Field(ge=0, lt=2**63)]

MAX_COUNT = 10_000
"""Most poses ``poses`` chooses (each adds 6 rows to the identification Jacobian)."""
MAX_CANDIDATES = 200_000
"""Most candidate poses (plan points x (1 + around)) pose selection considers (memory: 6 x 31 floats each)."""


class PoseSettings(Settings):
    """Which poses to measure (model §21.3): candidates around the plan, greedy D-optimal choice."""

    count: int = Field(default=40, ge=1, le=MAX_COUNT)
    """Poses to choose (K)."""
    seed: Seed = 1
    """Seed of the random candidates around the plan and of the random choice compared against."""
    points: int = Field(default=30, ge=2, le=10_000)
    """Points per trajectory and per approach line, both ends included."""
    around: int = Field(default=20, ge=0, le=1000)
    """Random candidate poses drawn around each plan and approach-line point."""
    radius_mm: float = Field(default=10.0, ge=0, le=1000.0, allow_inf_nan=False)
    """Half width of the box the random candidates' tips are drawn in (each axis), mm."""
    radius_deg: float = Field(default=10.0, ge=0, lt=90.0, allow_inf_nan=False)
    """Largest tilt of a random candidate's axis about each of two axes perpendicular to the plan's axis, deg."""
    standoff: float = Field(default=20.0, gt=0, le=1000.0, allow_inf_nan=False)
    """s of model §17.1: the approach line starts this far outside the anatomy along the axis, mm."""
    sigma_mm: SigmaMm = 0.15
    """Tracker noise of the tip per axis, mm: the weight of the E rows of the Jacobian (model §21.1)."""
    sigma_deg: SigmaDeg = 0.1
    """Tracker noise of the axis, deg: the weight of the e rows of the Jacobian."""


class IdentifySettings(Settings):
    """Identification from measurements (model §21.2, 21.4) and the calibrated robot's accuracy budget."""

    sigma_mm: SigmaMm = 0.15
    """Tracker noise of the tip per axis, mm (the weights of the E residuals)."""
    sigma_deg: SigmaDeg = 0.1
    """Tracker noise of the axis, deg (the weights of the e residuals)."""
    holdout: float = Field(default=0.25, ge=0, lt=0.9, allow_inf_nan=False)
    """Fraction of the measurements left out of the fit and used to check it (seeded)."""
    seed: Seed = 1
    """Seed of the held-out choice and of the budget's Monte Carlo."""
    points: int = Field(default=30, ge=2, le=10_000)
    """Points per trajectory of the plan the budget is computed on (when a plan is given)."""
    samples: int = Field(default=1000, ge=1, le=MAX_SAMPLES)
    """Robots the budget's Monte Carlo draws from the identification's covariance."""
    encoder_deg: float = Field(default=0.01, ge=0, le=10.0, allow_inf_nan=False)
    """Encoder resolution of each actuator in the budget, at every pose, deg (model §20.1)."""
    backlash_arcmin: float = Field(default=1.0, ge=0, le=600.0, allow_inf_nan=False)
    """Lost motion of each actuator's gear in the budget, at every pose, arcmin (model §20.1)."""


class SimulateSettings(Settings):
    """A simulated robot built to a tolerance class and measured with tracker noise."""

    SHORT: ClassVar[dict[str, str]] = {"tolerance_class": "class"}

    tolerance_class: Literal["f", "m", "c", "v"] = "m"
    """ISO 2768-1 class the robot is built to: f (fine), m (medium), c (coarse), v (very coarse)."""
    seed: Seed = 1
    """Seed of the robot's deviations (drawn first) and of the tracker noise."""
    sigma_mm: float = Field(default=0.15, ge=0, le=100.0, allow_inf_nan=False)
    """Tracker noise of the tip per axis, mm (0: noise-free)."""
    sigma_deg: float = Field(default=0.1, ge=0, le=30.0, allow_inf_nan=False)
    """Tracker noise of the axis per axis, deg (0: noise-free)."""
    q0_deg: float = Field(default=0.1, ge=0, le=30.0, allow_inf_nan=False)
    """Tolerance of each joint's zero offset, deg (model §20.1)."""
    docking_mm: float = Field(default=0.0, ge=0, le=1000.0, allow_inf_nan=False)
    """Tolerance of the docking position m, mm (0: the robot stands where the design says)."""
    docking_deg: float = Field(default=0.0, ge=0, le=90.0, allow_inf_nan=False)
    """Tolerance of the docking angles mount, deg."""
    distribution: Literal["uniform", "normal"] = "uniform"
    """Distribution of the robot's deviations: uniform on [-T, T], or normal with sigma = T/3."""


__all__ = ["MAX_CANDIDATES", "MAX_COUNT", "IdentifySettings", "PoseSettings", "SimulateSettings"]
