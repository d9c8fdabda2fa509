"""Time-optimal timing of a path under the limits of model §17.2, with toppra (TOPP-RA).

A path is q(s), s in [0, S] (joint angles, rad), with its first and second derivatives; the time
law s(t) starts and ends at rest and is the fastest one with, at every grid point,

* |q_i'(s) s_dot| <= q_dot_max and |q_i''(s) s_dot^2 + q_i'(s) s_ddot| <= q_ddot_max (each actuator);
* g(s) s_dot <= v, where g(s) = |dE/ds| is the tip's speed per unit path speed and v the speed of the
  segment (v_a, v_f, v_r on the lines, where s is the tip's arc length and g = 1; v_max in transit).

toppra solves this by reachability analysis on the grid (refined geometrically toward both ends, where
the motion starts and stops) (Pham and Pham, IEEE T-RO 2018): a linear
program per grid point, exact for the discretized problem, O(N). The speed cap enters as a
per-point joint velocity bound (``JointVelocityConstraintVarying``): ``|q_i'| s_dot <= v |q_i'| / g``
for every i is exactly ``s_dot <= v / g``. Between grid points s_ddot is constant (toppra's
``ParametrizeConstAccel``): s_dot^2 is linear in s, t follows in closed form.

The grid's constraints hold at its points; between them (and through the rows' own exact values)
a bound can be exceeded by a hair. :func:`time_optimal` takes a ``factor`` < 1 that scales every
limit, and the caller retimes with a smaller one when the sampled program exceeds a limit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["TimeLaw", "TimingError", "time_optimal"]

PathFn = Callable[[NDArray[np.float64], int], NDArray[np.float64]]
"""q^(order)(s) ``(n, 5)`` for path positions s ``(n,)``, order 0, 1 or 2."""


class TimingError(RuntimeError):
    """toppra found no time law (the path cannot be followed within the limits)."""


@dataclass(frozen=True)
class TimeLaw:
    """s(t) on a grid: s ``(N+1,)``, s_dot ``(N+1,)``, constant s_ddot per interval ``(N,)``, t ``(N+1,)``."""

    s: NDArray[np.float64]
    sd: NDArray[np.float64]
    sdd: NDArray[np.float64]
    t: NDArray[np.float64]

    @property
    def duration(self) -> float:
        """Time from rest to rest, s."""
        return float(self.t[-1])

    def at(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(s, s_dot, s_ddot) at times t (clamped to [0, duration])."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.sdd) - 1)
        tau = t - self.t[i]
        u = self.sdd[i]
        sd = np.maximum(self.sd[i] + u * tau, 0.0)
        s = np.minimum(self.s[i] + self.sd[i] * tau + 0.5 * u * tau * tau, self.s[-1])
        return s, sd, u


class _Path:
    """A path in toppra's interface (``__call__(s, order)``, ``dof``, ``path_interval``)."""

    def __init__(self, fn: PathFn, s_end: float) -> None:
        self.fn, self.s_end = fn, float(s_end)

    def __call__(self, path_positions: ArrayLike, order: int = 0) -> NDArray[np.float64]:
        s = np.asarray(path_positions, dtype=float)
        out = self.fn(np.atleast_1d(s), order)
        return out[0] if s.ndim == 0 else out

    @property
    def dof(self) -> int:
        return 5

    @property
    def path_interval(self) -> NDArray[np.float64]:
        return np.array([0.0, self.s_end])


def _ends_refined(
    grid: NDArray[np.float64], gain: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The grid with points added at geometrically shrinking distances from both ends (1e-7 of the length
    and up): s_ddot is constant between grid points, so from rest the speed is reached no sooner than the
    first point; without these, a ramp from rest would span the whole first interval."""
    span = grid[-1] - grid[0]
    steps = span * 1e-7 * 2.0 ** np.arange(40)
    head = grid[0] + steps[steps < 0.5 * (grid[1] - grid[0])]
    tail = grid[-1] - steps[steps < 0.5 * (grid[-1] - grid[-2])][::-1]
    out = np.concatenate([grid[:1], head, grid[1:-1], tail, grid[-1:]])
    g = None if gain is None else np.interp(out, grid, np.asarray(gain, dtype=float))
    return out, g


def time_optimal(
    fn: PathFn,
    grid: ArrayLike,
    qd_max: float,
    qdd_max: float,
    speed: float | None = None,
    gain: ArrayLike | None = None,
    factor: float = 1.0,
) -> TimeLaw:
    """The fastest rest-to-rest time law along ``fn`` on ``grid`` (0 = grid[0] < ... < grid[-1] = S).

    ``qd_max``, ``qdd_max`` rad/s, rad/s^2 for every actuator, both multiplied by ``factor``; ``speed``
    (mm/s, as given) caps g(s) s_dot with ``gain`` = g at the grid points (1 where None).
    Raises :class:`TimingError` if toppra finds no time law.
    """
    import toppra
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    toppra.setup_logging("CRITICAL")
    grid, gain = _ends_refined(np.asarray(grid, dtype=float), gain)
    path = _Path(fn, grid[-1])
    vmax, amax = qd_max * factor, qdd_max * factor
    if speed is None:
        vel = constraint.JointVelocityConstraint(np.full(5, vmax))
    else:
        g = np.ones(len(grid)) if gain is None else np.maximum(np.asarray(gain, dtype=float), 1e-12)
        dq = np.abs(fn(grid, 1))
        cap = np.minimum(vmax, speed * dq / g[:, None])
        cap = np.where(dq > 1e-12 * np.max(dq, initial=1.0), cap, vmax)  # a joint that does not move: no bound from it
        cap = np.maximum(cap, 1e-12)
        index = {float(v): i for i, v in enumerate(grid)}

        def vlim(s: float) -> NDArray[np.float64]:
            c = cap[index.get(float(s), int(np.clip(np.searchsorted(grid, s), 0, len(grid) - 1)))]
            return np.stack([-c, c], axis=-1)

        vel = constraint.JointVelocityConstraintVarying(vlim)
    acc = constraint.JointAccelerationConstraint(
        np.full(5, amax), discretization_scheme=constraint.DiscretizationType.Interpolation
    )
    instance = algo.TOPPRA([vel, acc], path, gridpoints=grid, solver_wrapper="seidel")
    sdd, sd, _ = instance.compute_parameterization(0.0, 0.0)
    if sd is None or np.any(~np.isfinite(sd)) or np.any(~np.isfinite(sdd)):
        raise TimingError("no time law within the joint limits (toppra)")
    sd = np.maximum(np.asarray(sd, dtype=float), 0.0)
    sd[0] = sd[-1] = 0.0
    ds = np.diff(grid)
    v_sum = sd[:-1] + sd[1:]
    if np.any(v_sum <= 0.0):
        raise TimingError("the time law stops inside the path (toppra)")
    dt = 2.0 * ds / v_sum
    t = np.concatenate([[0.0], np.cumsum(dt)])
    sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    return TimeLaw(s=grid.copy(), sd=sd, sdd=sdd, t=t)
