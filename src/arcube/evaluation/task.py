"""A task: the points a design must reach, built from trajectories (model §1.4).

The pipeline is trajectories (:mod:`arcube.io.trajectories`) -> task (this module) ->
evaluation (:mod:`arcube.evaluation.reference`) -> optimization -> report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.poses import angles_from_e, sample_trajectories


MAX_POINTS = 10_000
"""Most samples per trajectory any command takes (0.005 mm apart on a 50 mm trajectory): more only
exhausts memory."""


@dataclass(frozen=True)
class Task:
    """P = T * N points: N samples on each of T trajectories, trajectory-major order."""

    E: NDArray[np.float64]  # (P, 3) drill tips in R_w, mm
    e: NDArray[np.float64]  # (P, 3) unit drill axes
    trajectory: NDArray[np.intp]  # (P,) index of the trajectory of each point
    k: NDArray[np.intp]  # (P,) sample index 0..N-1 along its trajectory
    ids: tuple[str, ...]  # (T,) trajectory ids
    n_points: int  # N

    def __len__(self) -> int:
        return int(self.E.shape[0])

    @property
    def psi_theta(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(psi, theta) of every point in rad, ``(P,)`` each."""
        return angles_from_e(self.e)

    def subset(self, mask: ArrayLike) -> Task:
        """The task restricted to trajectories where ``mask`` ``(T,)`` is true."""
        keep = np.asarray(mask, dtype=bool)
        sel = keep[self.trajectory]
        renum = np.cumsum(keep) - 1
        return Task(
            E=self.E[sel],
            e=self.e[sel],
            trajectory=renum[self.trajectory[sel]],
            k=self.k[sel],
            ids=tuple(i for i, kept in zip(self.ids, keep) if kept),
            n_points=self.n_points,
        )


def build_task(entry: ArrayLike, target: ArrayLike, n_points: int = 30, ids: tuple[str, ...] | None = None) -> Task:
    """Sample T trajectories (``entry``, ``target`` ``(T, 3)`` mm) at ``n_points`` points each."""
    ent = np.atleast_2d(np.asarray(entry, dtype=float))
    tgt = np.atleast_2d(np.asarray(target, dtype=float))
    n_traj = ent.shape[0]
    E, e = sample_trajectories(ent, tgt, n_points)
    return Task(
        E=E.reshape(-1, 3),
        e=np.repeat(e, n_points, axis=0),
        trajectory=np.repeat(np.arange(n_traj), n_points),
        k=np.tile(np.arange(n_points), n_traj),
        ids=tuple(str(i + 1) for i in range(n_traj)) if ids is None else tuple(ids),
        n_points=n_points,
    )
