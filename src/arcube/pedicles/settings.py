"""The settings of a breach Monte Carlo (model §22): the registration, the screw, the samples.

The robot's own errors are those of :class:`arcube.accuracy.ToleranceSettings` (class, tolerances by hand, encoders,
lost motion) or of a calibration; the thrust and the actuators' stiffness those of :class:`arcube.options.Loads`.
"""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from arcube.options import Settings

__all__ = ["BreachSettings", "MAX_BREACH_SAMPLES"]

MAX_BREACH_SAMPLES = 1_000_000
"""Most samples of one Monte Carlo."""


class BreachSettings(Settings):
    """What moves the screw besides the robot, the screw itself, and the Monte Carlo (model §22.2-22.4)."""

    SHORT: ClassVar[dict[str, str]] = {"registration_mm": "registration", "screw_mm": "screw"}

    registration_mm: float = Field(default=0.5, ge=0.0, le=100.0, allow_inf_nan=False)
    """Registration error of the patient frame, 3-D RMS translation (mm), one rigid motion per docking; 0 turns the translation off (the rotation is --registration-deg: give both 0 for no registration error)."""
    registration_deg: float = Field(default=0.5, ge=0.0, le=45.0, allow_inf_nan=False)
    """Registration error of the patient frame, 3-D RMS rotation about the centroid of the docking's entry points (deg); 0 turns the rotation off."""
    screw_mm: float = Field(default=3.5, gt=0.0, lt=20.0, allow_inf_nan=False)
    """Screw diameter where the plan gives none (its screw_diameter_mm column), mm."""
    samples: int = Field(default=10_000, ge=1, le=MAX_BREACH_SAMPLES)
    """Samples of the Monte Carlo: each a built robot, a registration and the deflection."""
    seed: int = Field(default=1, ge=0)
    """Seed of the Monte Carlo's random numbers."""
    target: float = Field(default=0.01, gt=0.0, lt=1.0, allow_inf_nan=False)
    """The P(breach) the inverse questions aim at (what_it_takes.csv): the registration, the screw and the tolerance class that reach it per level, by the first-order P (model §22)."""
