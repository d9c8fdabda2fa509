"""Array types of the signatures: ``Floats`` for a float64 array (mm, rad, s as each function says, with its shape)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["Floats"]

Floats = NDArray[np.float64]
"""A float64 array; the function's docstring gives its shape and unit."""
