"""Transits S_j -> S_k in joint space (model §17.1): the straight move, else a sampling planner.

1. The straight move q(s) = q_j + s (q_k - q_j) / |q_k - q_j| is checked at 17.2's resolution
   (:func:`arcube.motion.segments.joint_piece`). If it passes, it is the transit.
2. Else OMPL (``ompl`` 2.x) plans (:func:`plan_path`): RRTConnect, then OMPL's path
   simplification (``PathSimplifier``: vertex reduction by shortcuts, close vertices collapsed; its
   B-spline smoothing is left to step 3, in joint space). Its state validity checker and
   its motion validator (a Python subclass that checks a whole edge in one batch) are the planner's
   checker of :mod:`arcube.motion.check` (coarser states, limits raised to match). The random
   seed is set before every call, so a transit's path depends on the seed and its two ends only.
3. The planner's waypoints become a C2 spline (one rest-to-rest piece); if the spline fails the
   fine check, the polyline through them (one piece per leg, stopping at each waypoint), whose every
   leg is checked at the fine resolution too.

The planner samples poses near the two standoffs (:data:`BOX_MM`, :data:`TILT_DEG`); its edges and
its path are straight moves in joint space between the poses' IK solutions.
"""

from __future__ import annotations

import gc
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arcube.model.poses import angles_from_e, e_from_angles
from arcube.motion.check import Checker, StateChecks, refine
from arcube.motion.limits import Planner
from arcube.motion.segments import Piece, joint_piece, polyline_fn, spline_fn

__all__ = ["Transit", "plan_path", "transit"]


@dataclass
class Transit:
    """A transit's pieces (empty when blocked), how it was found, and why the straight move failed."""

    pieces: list[Piece]
    method: str  # straight, planned (spline) or planned (polyline); none (same pose); blocked
    blocked: StateChecks | None  # the straight move's failing state (None if it passed)
    blocked_index: int = -1
    waypoints: int = 2
    planner_s: float = 0.0


def straight(label: str, q_a: NDArray[np.float64], q_b: NDArray[np.float64], checker: Checker, speed: float) -> Piece:
    """The straight move in joint space, checked."""
    fn, knots = polyline_fn(np.stack([q_a, q_b]))
    return joint_piece(label, fn, knots[-1], checker, speed)


def transit(
    label: str, q_a: NDArray[np.float64], q_b: NDArray[np.float64], checker: Checker, speed: float, planner: Planner
) -> Transit:
    """The transit from q_a to q_b (rad, at rest at both ends)."""
    import time

    if np.linalg.norm(q_b - q_a) <= 1e-12:
        return Transit([], "none", None)  # the two standoffs are one pose
    first = straight(label, q_a, q_b, checker, speed)
    if first.checks.ok.all():
        return Transit([first], "straight", None)
    bad = int(np.flatnonzero(~first.checks.ok)[0])
    t0 = time.perf_counter()
    waypoints = plan_path(q_a, q_b, checker.coarse(first.checks.take([0, -1])), planner)
    elapsed = time.perf_counter() - t0
    out = Transit([], "blocked", first.checks, bad, planner_s=elapsed)
    if waypoints is None:
        return out
    out.waypoints = len(waypoints)
    fn, knots = spline_fn(waypoints)
    smooth = joint_piece(label, fn, knots[-1], checker, speed)
    if smooth.checks.ok.all():
        out.pieces, out.method = [smooth], "planned (spline)"
        return out
    legs = [straight(label, a, b, checker, speed) for a, b in zip(waypoints[:-1], waypoints[1:])]
    if all(leg.checks.ok.all() for leg in legs):
        out.pieces, out.method = legs, "planned (polyline)"
    return out


ANGLE_SCALE_MM = 100.0
"""The planner's states are poses (E, 100 mm x psi, 100 mm x theta): a degree of tilt weighs like
1.75 mm of tip motion (the tool and motor reach some 100-300 mm from the tip)."""
BOX_MM, TILT_DEG = 60.0, 30.0
"""The planner searches tip positions within this box around both standoffs' tips, and tilts within
this angle of both axes (psi, theta)."""


def _pose_coords(E: NDArray[np.float64], e: NDArray[np.float64]) -> NDArray[np.float64]:
    psi, theta = angles_from_e(e)
    return np.concatenate([E, ANGLE_SCALE_MM * np.stack([psi, theta], axis=-1)], axis=-1)


def plan_path(
    q_a: NDArray[np.float64], q_b: NDArray[np.float64], checker: Checker, planner: Planner
) -> NDArray[np.float64] | None:
    """OMPL RRTConnect + simplification from q_a to q_b with ``checker`` as the validity check: the
    waypoints ``(m, 5)`` (rad; first q_a, last q_b), or None if no path is found within the time budget.

    OMPL samples poses (x, y, z, psi, theta), where almost every sample has an IK solution (random
    joint vectors rarely assemble); a pose's state is its IK q in the working mode, and an edge is the
    straight joint move between its two ends' q, checked at the checker's resolution: the polyline of
    the waypoints' q is exactly what the planner approved.
    """
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    ou.RNG.setSeed(int(planner.seed))
    E_ab, e_ab, _ = checker.pose_of(np.stack([q_a, q_b]))
    ends = _pose_coords(E_ab, e_ab)
    lo = ends.min(axis=0) - np.r_[[BOX_MM] * 3, [ANGLE_SCALE_MM * np.radians(TILT_DEG)] * 2]
    hi = ends.max(axis=0) + np.r_[[BOX_MM] * 3, [ANGLE_SCALE_MM * np.radians(TILT_DEG)] * 2]
    hi[4] = min(hi[4], ANGLE_SCALE_MM * np.radians(89.0))  # theta stays on the chart |theta| < 90 deg
    lo[4] = max(lo[4], -ANGLE_SCALE_MM * np.radians(89.0))
    space = ob.RealVectorStateSpace(5)
    bounds = ob.RealVectorBounds(5)
    for i in range(5):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    info = setup.getSpaceInformation()
    cache: dict[tuple[float, ...], tuple[bool, NDArray[np.float64]]] = {}

    def state_q(state: object) -> tuple[bool, NDArray[np.float64]]:
        x = tuple(float(state[i]) for i in range(5))  # type: ignore[index]
        if x not in cache:
            E = np.array(x[:3])
            e = e_from_angles(x[3] / ANGLE_SCALE_MM, x[4] / ANGLE_SCALE_MM)
            c = checker.poses(E[None], e, tool=True)
            q = c.q[0].copy()
            q[3:] = q_a[3:] + np.angle(np.exp(1j * (q[3:] - q_a[3:])))  # the turn of the program's deltas
            cache[x] = (bool(c.ok[0]), q)
        return cache[x]

    class EdgeValidator(ob.MotionValidator):  # type: ignore[misc, name-defined]
        def checkMotion(self, s1: object, s2: object, *rest: object) -> bool:  # noqa: N802 (OMPL's name)
            (ok1, a), (ok2, b) = state_q(s1), state_q(s2)
            if not (ok1 and ok2):
                return False
            _, checks = refine(
                lambda s: checker.joints(a + s[:, None] * (b - a)),
                0.0,
                1.0,
                checker.resolution,
                n0=3,
                stop_on_failure=True,
            )
            return bool(checks.ok.all())

    setup.setStateValidityChecker(lambda state: state_q(state)[0])
    validator = EdgeValidator(info)
    info.setMotionValidator(validator)
    start, goal = space.allocState(), space.allocState()
    for i in range(5):
        start[i], goal[i] = float(ends[0, i]), float(ends[1, i])
    cache[tuple(float(v) for v in ends[0])] = (True, q_a)
    cache[tuple(float(v) for v in ends[1])] = (True, q_b)
    setup.setStartAndGoalStates(start, goal)
    rrt = og.RRTConnect(info)
    setup.setPlanner(rrt)
    status = setup.solve(float(planner.time_s))
    waypoints = None
    if bool(status) and str(status) == "Exact solution":
        path = setup.getSolutionPath()
        simplifier = og.PathSimplifier(info)
        steps = 10 * path.getStateCount()
        simplifier.reduceVertices(path, steps, steps)  # shortcuts between random pairs of vertices
        simplifier.collapseCloseVertices(path, steps, steps)
        del simplifier
        waypoints = np.array([state_q(path.getState(i))[1] for i in range(path.getStateCount())])
        del path
        waypoints[0], waypoints[-1] = q_a, q_b
        keep = np.concatenate([[True], np.linalg.norm(np.diff(waypoints, axis=0), axis=1) > 1e-9])
        waypoints = waypoints[keep]
        waypoints[-1] = q_b
    del status, rrt, start, goal, validator, info, setup, bounds, space
    gc.collect()  # OMPL's objects die here, not at exit (nanobind reports the ones still alive then)
    return waypoints
