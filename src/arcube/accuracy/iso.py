"""ISO 2768-1 general tolerances, linear and angular, as model §20.1 tables them.

A nominal size on a row boundary takes the lower row (3 mm is in 0.5-3, 120 mm in 30-120).

Where the table has no value [CHOICE, stated in the model's terms]:

* a length below 0.5 mm (the tool offset L = 0 among them) takes the 0.5-3 row: ISO 2768-1 gives no
  general tolerance there, but the part still has to be made (L = 0 puts the drill tip at the centre
  of the spherical stage, and where the tip really is is still a machined dimension), so the
  smallest row the standard states is used rather than an optimistic 0;
* class v has no 0.5-3 value: sizes up to 3 mm (and below 0.5) take its 3-6 value, 0.5 mm;
* a length above 2000 mm takes the 1000-2000 row (no design of this robot comes near).

Angular tolerances are looked up by the length of the angle's shorter leg (for the spherical links
and the transmitting offsets, the radius r). Every value is a symmetric bound +-T.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

CLASSES: tuple[str, ...] = ("f", "m", "c", "v")
"""The four tolerance classes: fine, medium, coarse, very coarse."""

LINEAR_EDGES_MM: NDArray[np.float64] = np.array([3.0, 6.0, 30.0, 120.0, 400.0, 1000.0])
"""Upper edges (mm, inclusive) of the rows 0.5-3, 3-6, 6-30, 30-120, 120-400, 400-1000; the last row is 1000-2000."""

LINEAR_MM: dict[str, tuple[float, ...]] = {
    "f": (0.05, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5),
    "m": (0.1, 0.1, 0.2, 0.3, 0.5, 0.8, 1.2),
    "c": (0.2, 0.3, 0.5, 0.8, 1.2, 2.0, 3.0),
    "v": (0.5, 0.5, 1.0, 1.5, 2.5, 4.0, 6.0),  # the 0.5-3 value is ISO's "-": the 3-6 value stands in
}
"""+- mm by row (0.5-3, 3-6, 6-30, 30-120, 120-400, 400-1000, 1000-2000)."""

ANGULAR_EDGES_MM: NDArray[np.float64] = np.array([10.0, 50.0, 120.0, 400.0])
"""Upper edges (mm, inclusive) of the shorter-leg rows <= 10, 10-50, 50-120, 120-400; the last row is > 400."""

ANGULAR_DEG: dict[str, tuple[float, ...]] = {
    "f": (1.0, 30 / 60, 20 / 60, 10 / 60, 5 / 60),
    "m": (1.0, 30 / 60, 20 / 60, 10 / 60, 5 / 60),
    "c": (1.5, 1.0, 30 / 60, 15 / 60, 10 / 60),
    "v": (3.0, 2.0, 1.0, 30 / 60, 20 / 60),
}
"""+- deg by row (1 deg 30' = 1.5 deg, 30' = 0.5 deg, ...)."""


def _row(size: ArrayLike, edges: NDArray[np.float64]) -> NDArray[np.intp]:
    """Row index of each size: the first row whose upper edge is >= size (a boundary takes the lower row)."""
    return np.searchsorted(edges, np.asarray(size, dtype=float), side="left")


def linear_tolerance(length_mm: ArrayLike, tolerance_class: str) -> NDArray[np.float64]:
    """ISO 2768-1 linear tolerance (+- mm) of nominal lengths ``(...)`` mm in class f, m, c or v."""
    table = np.asarray(LINEAR_MM[tolerance_class])
    return table[_row(np.abs(np.asarray(length_mm, dtype=float)), LINEAR_EDGES_MM)]


def angular_tolerance(shorter_leg_mm: ArrayLike, tolerance_class: str) -> NDArray[np.float64]:
    """ISO 2768-1 angular tolerance (+- deg) for angles whose shorter leg is ``(...)`` mm long, class f, m, c or v."""
    table = np.asarray(ANGULAR_DEG[tolerance_class])
    return table[_row(np.abs(np.asarray(shorter_leg_mm, dtype=float)), ANGULAR_EDGES_MM)]
