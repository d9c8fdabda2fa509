"""From a piece to its rows: time it (toppra), sample it every dt, and verify the sampled rows.

A piece of duration T takes ceil(T / dt) steps: its rows are at t = 0, dt, ..., and it holds its
last pose at rest until the next multiple of dt, where the next piece starts (at most dt of wait per
piece), so every row of the program lies on one grid of step dt.

Verification (what a controller sees and what the tests measure): on the piece's rows, both ends
included, the rates |q_dot| (exact, and (q[k+1] - q[k]) / dt), the accelerations ((q_dot[k+1] -
q_dot[k]) / dt and (q[k+1] - 2 q[k] + q[k-1]) / dt^2) and the tip speed (|E[k+1] - E[k]| / dt) must
not exceed their limits. toppra enforces them at its grid points; where the sampled rows exceed one
by a ratio r > 1, the joint limits (and in transit the tip speed) are scaled by 0.999 / r and the
piece is timed again. A line keeps its own speed (the feed stays the feed): there the tip speed is
s_dot, capped exactly.
"""

from __future__ import annotations

import math

import numpy as np

from arcube.arrays import Floats
from arcube.motion.limits import ProgramLimits
from arcube.motion.output import JOINTS
from arcube.motion.rows import check_piece
from arcube.motion.segments import Piece
from arcube.motion.timing import TimingError, time_optimal

__all__ = ["LINE_SPEED_TOL", "cruise_problem", "sample_piece"]

LINE_SPEED_TOL = 1e-9
"""Relative tolerance of a line's tip speed (toppra's linear programs solve s_dot = v to rounding)."""
_ATTEMPTS = 8


def cruise_problem(piece: Piece, limits: ProgramLimits) -> str | None:
    """Why a line piece cannot run at its speed within the joint speed limit (None if it can)."""
    dq = np.abs(piece.fn(piece.grid, 1))
    need = piece.speed * dq
    worst = np.unravel_index(int(np.argmax(need)), need.shape)
    if need[worst] <= limits.qd_max:
        return None
    return (
        f"{piece.speed:g} mm/s needs {JOINTS[worst[1]]} at {math.degrees(need[worst]):.4g} deg/s "
        f"> max_joint_speed_deg {limits.max_joint_speed_deg:g}"
    )


def _ratio(
    E: Floats,
    q: Floats,
    qd: Floats,
    dt: float,
    limits: ProgramLimits,
    speed: float,
    line: bool,
) -> tuple[float, float]:
    """(joint ratio, tip-speed ratio): the largest sampled value over its limit."""
    rate = max(np.max(np.abs(qd), initial=0.0), np.max(np.abs(np.diff(q, axis=0)) / dt, initial=0.0)) / limits.qd_max
    acc = np.max(np.abs(np.diff(qd, axis=0)) / dt, initial=0.0)
    if len(q) > 2:
        acc = max(acc, np.max(np.abs(q[2:] - 2.0 * q[1:-1] + q[:-2]) / dt**2))
    tip = np.max(np.linalg.norm(np.diff(E, axis=0), axis=-1) / dt, initial=0.0) / speed
    return max(rate, acc / limits.qdd_max), tip


def sample_piece(piece: Piece, limits: ProgramLimits, line: bool) -> dict[str, Floats]:
    """Time ``piece`` (sets ``piece.law``) and return its rows at t = 0, dt, ..., n dt (the last at rest):
    ``t`` (from the piece's start), ``E``, ``e``, ``q``, ``qd`` (rad, rad/s). Raises TimingError."""
    dt = limits.dt
    factor = 1.0
    for _ in range(_ATTEMPTS):
        law = time_optimal(
            piece.fn,
            piece.grid,
            limits.qd_max,
            limits.qdd_max,
            piece.speed * (1.0 if line else factor),
            piece.gain,
            factor=factor,
        )
        check_piece(limits, law.duration, "transit" if not line else piece.kind)  # before the rows are allocated
        n = max(int(math.ceil(law.duration / dt - 1e-9)), 1)
        t = np.arange(n + 1) * dt
        s, sd, _ = law.at(t)
        E, e, q, qd = piece.rows(s, sd)
        joint, tip = _ratio(E, q, qd, dt, limits, piece.speed, line)
        worst = max(joint, 1.0 if line else tip)
        if worst <= 1.0 and (not line or tip <= 1.0 + LINE_SPEED_TOL):
            piece.law = law
            return {"t": t, "E": E, "e": e, "q": q, "qd": qd}
        factor *= 0.999 / max(worst, 1.0 + 1e-6)
    raise TimingError(f"the sampled rows exceed a limit after {_ATTEMPTS} retimings (last ratio {worst:.6g})")
