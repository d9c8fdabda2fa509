"""The settings of an accuracy budget (model §20): tolerances, their distribution, the Monte Carlo.

Field names follow the flags of ``arcube tolerance`` (``--q0-deg`` -> ``q0_deg``); the class flag
``--class`` is ``tolerance_class`` (``class`` is a Python keyword). A bad value raises
:class:`~arcube.errors.InputError` naming the field (``ToleranceSettings.samples must be >= 1, got 0``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BeforeValidator, Field

from arcube.accuracy.sources import GROUPS, SOURCE_NAMES, tolerances
from arcube.errors import InputError
from arcube.options import Settings

MAX_SAMPLES = 100_000
"""Most robots a Monte Carlo draws (the budget also caps robots x points, :data:`MAX_ROBOT_POINTS`)."""
MAX_ROBOT_POINTS = 5_000_000
"""Most robots x plan points of one Monte Carlo: its per-point percentiles keep three such float arrays (120 MB)."""

_FIELD = "ToleranceSettings.tol"


MAX_TOLERANCE = 1000.0
"""Largest tolerance of one source, mm or deg: beyond it no part is made to a tolerance (1e9 is a typo)."""


def parse_tol(value: Any, field: str = _FIELD) -> dict[str, float]:
    """``{"r": 0.02, "lengths": 0.05}`` or ``["r=0.02", "lengths=0.05"]`` (the flag's text) -> a checked mapping;
    an error names ``field`` (the settings field that holds the mapping)."""
    if value is None:
        return {}
    pairs: list[tuple[str, Any, str]] = []
    if isinstance(value, Mapping):
        pairs = [(str(k), v, f"{k}={v}") for k, v in value.items()]
    else:
        items = [value] if isinstance(value, str) else list(value)
        for item in (part for it in items for part in str(it).split(",")):  # r=0.1,L=0.2 as two items
            name, sep, v = str(item).partition("=")
            if not sep or not name.strip():
                raise InputError.of(field, f"{item!r}: expected NAME=T, e.g. r=0.02 (mm) or angles=0.01 (deg)")
            pairs.append((name.strip(), v, str(item)))
    out: dict[str, float] = {}
    for name, v, shown in pairs:
        if name in out:  # the last copy would win without a word
            raise InputError.of(field, f"{shown!r}: {name} is given twice")
        if name not in SOURCE_NAMES and name not in GROUPS:
            raise InputError.of(
                field,
                f"{shown!r}: unknown error source {name!r} (known: the groups lengths, angles, q0, encoder, backlash; a parameter that moves "
                "the tool, f_x .. r, L, o_x .. beta_y, m_x .. m_z, mount_rx .. mount_rz; q0_J, encoder_J, backlash_J with J one of "
                "rho_x, rho_y, rho_z, delta_x, delta_y)",
            )
        try:
            number = float(v)
        except (TypeError, ValueError):
            raise InputError.of(field, f"{shown!r}: the tolerance {str(v).strip()!r} is not a number") from None
        if not (math.isfinite(number) and 0.0 <= number <= MAX_TOLERANCE):
            raise InputError.of(
                field, f"{shown!r}: a tolerance must be a finite number >= 0 and at most {MAX_TOLERANCE:g} (mm or deg)"
            )
        out[name] = number
    return out


Tolerance = Annotated[float, Field(ge=0, le=MAX_TOLERANCE, allow_inf_nan=False)]
MAX_DOCKING_DEG = 90.0
"""Largest docking error of the mounting angles, deg: a quarter turn is no registration at all (as ``calibrate
simulate``'s ``--docking-deg``); 720 is a typo."""


class ToleranceSettings(Settings):
    """The error sources' tolerances (model §20.1), how they are distributed, and the Monte Carlo (20.4)."""

    SHORT: ClassVar[dict[str, str]] = {"tolerance_class": "class"}

    tolerance_class: Literal["f", "m", "c", "v"] = "m"
    """ISO 2768-1 class of the lengths and angles: f (fine), m (medium), c (coarse), v (very coarse)."""
    tol: Annotated[dict[str, float], BeforeValidator(parse_tol)] = {}
    """Tolerances set by hand, NAME=T (mm or deg): a source (r=0.02, q0_rho_x=0.05) or a group (lengths=0.05, angles=0.01, q0=0.05 for the five joints); a name beats its group."""
    q0_deg: Tolerance = 0.1
    """Joint zero offset of each actuator, once per built robot, deg."""
    encoder_deg: Tolerance = 0.01
    """Encoder resolution of each actuator, at every pose, deg."""
    backlash_arcmin: Tolerance = 1.0
    """Lost motion (backlash) of each actuator's gear, at every pose, arcmin."""
    docking_mm: Tolerance = 0.0
    """Docking (registration) error of the base position m, mm (0: the navigation system's share)."""
    docking_deg: float = Field(default=0.0, ge=0, le=MAX_DOCKING_DEG, allow_inf_nan=False)
    """Docking (registration) error of the mounting angles, deg (at most 90)."""
    distribution: Literal["uniform", "normal"] = "uniform"
    """Distribution of every source: uniform on [-T, T], or normal with sigma = T/3."""
    samples: int = Field(default=1000, ge=1, le=MAX_SAMPLES)
    """Robots the Monte Carlo builds."""
    seed: int = Field(default=1, ge=0)
    """Seed of the Monte Carlo's random numbers."""

    def tolerances(self, params: Any) -> Any:
        """T ``(..., n)`` of every source (:data:`arcube.accuracy.sources.SOURCE_NAMES`) for designs ``(..., 27)``."""
        return tolerances(
            params,
            self.tolerance_class,
            self.tol,
            self.q0_deg,
            self.encoder_deg,
            self.backlash_arcmin,
            self.docking_mm,
            self.docking_deg,
        )
