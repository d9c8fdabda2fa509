"""The pedicle's isthmus of a virtual patient (MORPHOMETRY.md section 6, model §22.1): its width and height per level.

The isthmus, outer cortex to outer cortex, measured on CT perpendicular to the pedicle's axis: width W (medio-lateral)
and height H (cranio-caudal), mm. Drawn per level and side like the angles of section 1: a right/left pair of
correlation 0.7, independent across levels, normal, clipped to the range. A patient's isthmus comes from a generator
of its own, seeded (seed, 22): every earlier draw of a seed stays as it was, and the same seed gives the same pedicles
with every technique.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["DEFAULT_SCREW_MM", "ISTHMUS", "ISTHMUS_STREAM", "LEVELS", "draw_isthmus", "isthmus_mean"]

DEFAULT_SCREW_MM = 3.5
"""The screw's diameter d where a plan does not give ``screw_diameter_mm`` (model §22.1), mm: a pedicle no wider than
it leaves the screw no room."""

LEVELS = ("C3", "C4", "C5", "C6", "C7")
ISTHMUS: dict[str, tuple[tuple[float, ...], float, float, float]] = {
    "width_mm": ((4.7, 4.9, 5.4, 5.8, 6.4), 0.8, 2.5, 9.0),
    "height_mm": ((6.4, 6.5, 6.6, 6.7, 6.9), 0.8, 4.0, 10.0),
}
"""Per quantity: the means C3..C7, the SD and the range (mm), MORPHOMETRY.md section 6."""
ISTHMUS_STREAM = 22
"""The second seed of the isthmus's own generator, ``numpy.random.default_rng([seed, 22])``."""
RL_CORRELATION = 0.7


def isthmus_mean(level: str) -> tuple[float, float]:
    """(width, height) mm of a level's mean pedicle isthmus; NaN for a level outside C3-C7."""
    if level not in LEVELS:
        return math.nan, math.nan
    k = LEVELS.index(level)
    return ISTHMUS["width_mm"][0][k], ISTHMUS["height_mm"][0][k]


def draw_isthmus(seed: int | None) -> dict[str, Any]:
    """Per level and side ``{"width_mm", "height_mm"}``: the pairs of the module docstring; the means for the mean
    patient (``seed`` None). Draw order: per level C3..C7, width then height, each a right/left pair of standard normals."""
    rng = None if seed is None else np.random.default_rng([seed, ISTHMUS_STREAM])
    out: dict[str, Any] = {lv: {"R": {}, "L": {}} for lv in LEVELS}
    rho = RL_CORRELATION
    for k, lv in enumerate(LEVELS):
        for name, (means, sd, lo, hi) in ISTHMUS.items():
            z_right, z_other = (
                (0.0, 0.0) if rng is None else (float(rng.standard_normal()), float(rng.standard_normal()))
            )
            out[lv]["R"][name] = float(min(max(means[k] + sd * z_right, lo), hi))
            out[lv]["L"][name] = float(
                min(max(means[k] + sd * (rho * z_right + math.sqrt(1 - rho * rho) * z_other), lo), hi)
            )
    return out
