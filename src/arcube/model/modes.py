"""Working modes (model §4.3, 5.3): the signs of the TMS x, TMS y, RTS x and RTS y branches of the
inverse kinematics, as four numbers ``(4,)`` (+1.0 / -1.0) or as text (``"+,+,-,+"``)."""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ALL_MODES", "DEFAULT_MODE", "DEFAULT_MODE_TEXT", "format_mode", "parse_mode"]

DEFAULT_MODE: NDArray[np.float64] = np.ones(4)
"""Working mode (+,+,+,+): the upper sign of Eq 3 everywhere (model §4.3, 5.3)."""
DEFAULT_MODE_TEXT = "+,+,+,+"
"""The default working mode as text (every branch +): where a design or a file names none."""

ALL_MODES: NDArray[np.float64] = np.array(list(itertools.product((1.0, -1.0), repeat=4)))
"""The 16 working modes, ``(16, 4)``, starting with (+,+,+,+)."""


def format_mode(mode: ArrayLike) -> str:
    """(1, 1, -1, 1) -> '+,+,-,+'."""
    return ",".join("+" if s > 0 else "-" for s in np.asarray(mode, dtype=float).reshape(-1))


def parse_mode(text: str) -> NDArray[np.float64]:
    """'+,+,-,+' -> array (1, 1, -1, 1): signs of TMS x, TMS y, RTS x, RTS y. Raises ValueError."""
    parts = [s.strip() for s in text.split(",")]
    if len(parts) != 4 or any(s not in {"+", "-", "+1", "-1", "1"} for s in parts):
        raise ValueError(f"working mode must be four signs 'TMS x,TMS y,RTS x,RTS y' like '+,+,-,+', got {text!r}")
    return np.array([-1.0 if s.startswith("-") else 1.0 for s in parts])
