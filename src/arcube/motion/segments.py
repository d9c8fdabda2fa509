"""The program's pieces (model §17.1): the line of each trajectory, and paths in joint space.

Each trajectory j has one line, from its standoff S_j = A_j + s_j e_j through the entry A_j to the
target B_j; E(s) = S_j - s e_j for s in [0, s_j + |A_j - B_j|] (s: mm travelled from S_j). The
approach, drill and retract run on it; its states are checked once (the tool is exempt there) and
serve all three.

A :class:`Piece` is one rest-to-rest motion: a path q(s) (rad) with its derivatives, the grid of
checked states on it (toppra's grid too), the tip speed cap, and how its rows are made:

* on a line, the row's E is the line's point at s(t), q is the IK of (E, e_j) and q_dot = B^-1 A t
  for the twist t = (s_dot u, 0) (model §7.4): E lies on the line, and the FK of q is E;
* in joint space, q = q(s(t)), q_dot = q'(s) s_dot, and (E, e) is the FK of q in the program's
  assembly mode.

The line's q(s) for timing is the cubic Hermite interpolant of the exact IK and its exact
derivative dq/ds at the checked states (at most 0.5 mm of body motion apart).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from arcube.model import frames
from arcube.model.design import unpack
from arcube.model.mechanism import inverse_kinematics, joint_rates, velocity_model
from arcube.motion.check import Checker, StateChecks, refine
from arcube.motion.timing import PathFn, TimeLaw

__all__ = ["Line", "Piece", "joint_piece", "line_piece", "polyline_fn", "spline_fn"]

Rows = Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[NDArray[np.float64], ...]]
"""(s, s_dot) -> (E, e, q, q_dot) of the rows at those path positions and speeds."""


@dataclass
class Line:
    """Trajectory ``tid``'s line S -> A -> B (mm, R_w) and its checked states."""

    tid: str
    S: NDArray[np.float64]
    A: NDArray[np.float64]
    B: NDArray[np.float64]
    e: NDArray[np.float64]
    depth: float  # s_j = |S - A|
    length: float  # |A - B|
    s: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    checks: StateChecks | None = None

    @property
    def total(self) -> float:
        """|S - B|, mm."""
        return self.depth + self.length

    def E(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Tip positions at s mm from S toward B."""
        return self.S - np.asarray(s, dtype=float)[..., None] * self.e

    def check(self, checker: Checker) -> StateChecks:
        """Check the whole line at the resolution of model §17.2 (the tool exempt); keeps the states."""
        self.s, self.checks = refine(lambda s: checker.poses(self.E(s), self.e), 0.0, self.total)
        return self.checks


@dataclass
class Piece:
    """One rest-to-rest motion of the program."""

    kind: str  # approach, drill, retract or transit
    label: str  # the CSV's trajectory column: "3", or "3->5" in transit
    fn: PathFn
    grid: NDArray[np.float64]  # checked path positions, 0 .. S
    speed: float  # mm/s: the segment's speed (lines) or v_max (transit)
    gain: NDArray[np.float64] | None  # |dE/ds| at the grid (None: 1, s is the tip's arc length)
    rows: Rows
    checks: StateChecks
    law: TimeLaw | None = None
    info: dict[str, object] = field(default_factory=dict)


def _unwrap(q: NDArray[np.float64]) -> NDArray[np.float64]:
    out = q.copy()
    out[:, 3:] = np.unwrap(q[:, 3:], axis=0)
    return out


def line_piece(
    kind: str,
    line: Line,
    s_from: float,
    s_to: float,
    speed: float,
    params: NDArray[np.float64],
    mode: NDArray[np.float64],
) -> Piece:
    """The piece of ``line`` from s_from to s_to (either way) at ``speed`` mm/s."""
    sign = 1.0 if s_to >= s_from else -1.0
    lo, hi = min(s_from, s_to), max(s_from, s_to)
    keep = (line.s > lo) & (line.s < hi)
    s_line = np.concatenate([[lo], line.s[keep], [hi]])
    if sign < 0:
        s_line = s_line[::-1]
    sigma = np.abs(s_line - s_from)  # the piece's own path position: tip arc length from its start
    u = -sign * line.e  # unit direction of the tip's motion
    g = unpack(params)
    u_m = frames.directions_to_mechanism(g, u)

    def ik(sig: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        E = line.E(s_from + sign * sig)
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = inverse_kinematics(params, E, line.e, mode)
            dq = joint_rates(velocity_model(sol, params), u_m, np.zeros(3))
        return np.concatenate([sol.rho, sol.delta], axis=-1), dq

    q_nodes, dq_nodes = ik(sigma)
    q_nodes = _unwrap(q_nodes)
    spline = CubicHermiteSpline(sigma, q_nodes, dq_nodes, axis=0)
    derivs = [spline, spline.derivative(1), spline.derivative(2)]

    def fn(s: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        return derivs[order](s)

    def rows(s: NDArray[np.float64], sd: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        q, dq = ik(s)
        q[:, 3:] = spline(s)[:, 3:] + np.angle(np.exp(1j * (q[:, 3:] - spline(s)[:, 3:])))  # the spline's turn
        return line.E(s_from + sign * s), np.broadcast_to(line.e, (len(s), 3)).copy(), q, dq * sd[:, None]

    idx = np.searchsorted(line.s, s_line).clip(0, len(line.s) - 1)
    return Piece(kind, line.tid, fn, sigma, speed, None, rows, line.checks.take(idx))  # type: ignore[union-attr]


def polyline_fn(waypoints: NDArray[np.float64]) -> tuple[PathFn, NDArray[np.float64]]:
    """The straight joint path through two waypoints, by joint-space arc length: (fn, knots)."""
    a, b = waypoints[0], waypoints[-1]
    length = float(np.linalg.norm(b - a))
    d = (b - a) / length

    def fn(s: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        s = np.asarray(s, dtype=float)
        if order == 0:
            return a + s[:, None] * d
        return np.broadcast_to(d if order == 1 else np.zeros(5), (len(s), 5)).copy()

    return fn, np.array([0.0, length])


def spline_fn(waypoints: NDArray[np.float64]) -> tuple[PathFn, NDArray[np.float64]]:
    """A C2 cubic spline through the waypoints, by chord length, with zero curvature at both ends."""
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1))])
    spline = CubicSpline(knots, waypoints, axis=0, bc_type="natural")
    derivs = [spline, spline.derivative(1), spline.derivative(2)]

    def fn(s: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        return derivs[order](np.asarray(s, dtype=float))

    return fn, knots


def joint_piece(label: str, fn: PathFn, s_end: float, checker: Checker, speed: float) -> Piece:
    """A transit piece along the joint path ``fn`` on [0, s_end], checked at 17.2's resolution (tool
    included). Its ``checks`` tell whether it is allowed (``checks.ok.all()``)."""
    s, checks = refine(lambda s: checker.joints(fn(s, 0), tool=True), 0.0, s_end, stop_on_failure=True)
    gain = None
    if checks.ok.all():
        gain = np.linalg.norm(np.gradient(checks.E, s, axis=0, edge_order=2 if len(s) > 2 else 1), axis=-1)

    def rows(s: NDArray[np.float64], sd: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        q = fn(s, 0)
        E, e, _ = checker.pose_of(q)
        return E, e, q, fn(s, 1) * sd[:, None]

    return Piece("transit", label, fn, s, speed, gain, rows, checks)
