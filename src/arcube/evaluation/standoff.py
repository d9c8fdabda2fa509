"""Where the drill can wait outside the patient: the standoff pose of each trajectory (model §17.1).

For trajectory j (entry A_j, target B_j, axis e_j = (A_j - B_j)/|A_j - B_j|) the standoff puts the
tip at S_j = A_j + (s + t_j) e_j, where t_j is the largest t >= 0 at which the ray A_j + t e_j is
still inside the anatomy (0 without anatomy): the ray leaves the anatomy for good at its last
crossing of a surface, and beyond it nothing is crossed again. t_j is found exactly by ray-triangle
intersection (Moller-Trumbore, every triangle of every mesh), not by sampling.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.poses import sample_trajectories

__all__ = ["DEFAULT_STANDOFF_MM", "exit_depths", "standoff_points", "approach_lines"]

DEFAULT_STANDOFF_MM = 20.0
"""s of model §17.1: the tip waits this far outside the anatomy along its own axis."""
_CHUNK = 200_000
"""Ray-triangle pairs per batch (memory: about 20 float64 arrays of this size)."""


def _axes(entry: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    d = entry - target
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def exit_depths(meshes: Sequence[Any], origins: ArrayLike, directions: ArrayLike) -> NDArray[np.float64]:
    """Per ray, the largest t >= 0 at which ``origins + t directions`` crosses a surface of the meshes
    (0 when it crosses none): ``(T,)`` mm, for ``origins`` and unit ``directions`` ``(T, 3)``.

    ``meshes``: closed triangle meshes (anything with ``vertices`` ``(V, 3)`` and ``faces`` ``(F, 3)``).
    """
    O = np.atleast_2d(np.asarray(origins, dtype=float))
    D = np.atleast_2d(np.asarray(directions, dtype=float))
    best = np.zeros(len(O))
    for mesh in meshes:
        tri = np.asarray(mesh.vertices, dtype=float)[np.asarray(mesh.faces, dtype=np.int64)]  # (F, 3, 3)
        v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        step = max(1, _CHUNK // max(len(tri), 1))
        for a in range(0, len(O), step):
            o, d = O[a : a + step, None, :], D[a : a + step, None, :]  # (t, 1, 3)
            p = np.cross(d, e2)  # (t, F, 3)
            det = np.einsum("tfk,fk->tf", p, e1)
            ok = np.abs(det) > 1e-12
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            s = o - v0  # (t, F, 3)
            u = np.einsum("tfk,tfk->tf", s, p) * inv
            q = np.cross(s, e1)
            v = np.einsum("tk,tfk->tf", d[:, 0], q) * inv
            t = np.einsum("fk,tfk->tf", e2, q) * inv
            hit = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t >= 0.0)
            far = np.max(np.where(hit, t, 0.0), axis=1)
            best[a : a + step] = np.maximum(best[a : a + step], far)
    return best


def standoff_points(
    entry: ArrayLike, target: ArrayLike, anatomy: Any = None, standoff_mm: float = DEFAULT_STANDOFF_MM
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(S ``(T, 3)`` mm, s + t ``(T,)`` mm): each trajectory's standoff tip position and its distance from the entry.

    ``anatomy``: an :class:`~arcube.evaluation.anatomy.Anatomy` (its meshes), or None (t_j = 0).
    """
    A = np.atleast_2d(np.asarray(entry, dtype=float))
    B = np.atleast_2d(np.asarray(target, dtype=float))
    e = _axes(A, B)
    t = np.zeros(len(A)) if anatomy is None else exit_depths(anatomy.meshes, A, e)
    depth = standoff_mm + t
    return A + depth[:, None] * e, depth


def approach_lines(
    entry: ArrayLike,
    target: ArrayLike,
    anatomy: Any = None,
    n_points: int = 30,
    standoff_mm: float = DEFAULT_STANDOFF_MM,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The approach segment S_j -> A_j of every trajectory, sampled like a plan's line: (E, e), each
    ``(T * n_points, 3)``, trajectory-major, both ends included; the axis is e_j all along."""
    A = np.atleast_2d(np.asarray(entry, dtype=float))
    S, _ = standoff_points(A, target, anatomy, standoff_mm)
    E, _ = sample_trajectories(S, A, n_points)
    e = _axes(A, np.atleast_2d(np.asarray(target, dtype=float)))
    return E.reshape(-1, 3), np.repeat(e, n_points, axis=0)
