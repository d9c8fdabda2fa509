"""Which unknowns the measurements can tell apart (model §21.2), and the observability of a pose set.

QR decomposition with column pivoting of the scaled identification Jacobian J ``(m, n)`` (rows:
every residual of the measured poses; columns: the unknowns, each per unit of its typical size):
J P = Q R, |R_11| >= |R_22| >= ... The unknowns whose pivot |R_jj| is below ``tol`` x |R_11|
(default 1e-6) are not identifiable: fixed at their nominal values.

**Confounded with.** With the pivoted columns split into identified (I, the first r) and not (N),
J_N = J_I C + (residual of norm |R_22| <= tol |R_11|) with C = R_II^-1 R_IN (the least-squares fit of each
non-identified column on the identified ones). So a deviation z_k of a non-identified unknown k moves
every residual as the deviations z_I = C[:, k] z_k of the identified ones do: the identification
reads z_k as those, and cannot tell them apart. Unknown k is reported *confounded with* the
identified unknowns i whose share of that fit is not negligible, |C_ik| |J_i| >= 1e-3 |J_k|, with the
coefficient in design units, C_ik s_i / s_k (a deviation du_k looks like du_i = coefficient x du_k).
An unknown whose column is 0 (it moves nothing at these poses) is confounded with nothing.

Observability (Borm and Menq): O1 = (prod_j sigma_j)^(1/n) / sqrt(K) over the n singular values of J
restricted to the identifiable columns, K the number of poses; the condition number sigma_1 / sigma_n.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

PIVOT_TOL = 1e-6
"""|R_jj| / |R_11| below which an unknown is not identifiable (model §21.2)."""
SHARE_TOL = 1e-3
"""|C_ik| |J_i| / |J_k| from which an identified unknown i is listed among those k is confounded with."""


class Identifiability(NamedTuple):
    """Identifiability of n unknowns, every array in the unknowns' order."""

    identifiable: NDArray[np.bool_]  # (n,)
    pivot: NDArray[np.float64]  # (n,) |R_jj| / |R_11| of the unknown's pivot (0 beyond the rank)
    alias: NDArray[
        np.float64
    ]  # (n, n) C: column k (non-identifiable) holds its fit on the identified columns, scaled units
    norms: NDArray[np.float64]  # (n,) |J_j|

    @property
    def rank(self) -> int:
        return int(np.sum(self.identifiable))

    def confounded_with(self, k: int, scale: ArrayLike | None = None) -> list[tuple[int, float]]:
        """(i, coefficient) of the identified unknowns that unknown k is confounded with (empty for an
        identifiable k), largest share first; coefficient in design units when ``scale`` (n,) is given
        (du_i = coefficient x du_k), else in scaled units."""
        if self.identifiable[k] or self.norms[k] == 0.0:
            return []
        c = self.alias[:, k]
        share = np.abs(c) * self.norms
        idx = np.flatnonzero(share >= SHARE_TOL * self.norms[k])
        idx = idx[np.argsort(-share[idx], kind="stable")]
        s = np.ones(len(c)) if scale is None else np.asarray(scale, dtype=float)
        return [(int(i), float(c[i] * s[i] / s[k])) for i in idx]


def identifiability(J: ArrayLike, tol: float = PIVOT_TOL) -> Identifiability:
    """QR with column pivoting of J ``(m, n)`` (scipy.linalg.qr, pivoting=True): which columns are
    identifiable, their pivots, and each non-identifiable column's fit on the identifiable ones."""
    A = np.asarray(J, dtype=float)
    m, n = A.shape
    norms = np.linalg.norm(A, axis=0)
    if m == 0 or not np.any(norms > 0.0):
        return Identifiability(np.zeros(n, bool), np.zeros(n), np.zeros((n, n)), norms)
    _, R, perm = scipy.linalg.qr(A, mode="economic", pivoting=True)
    d = np.zeros(n)
    k = min(m, n)
    d[:k] = np.abs(np.diag(R)[:k])
    rel = d / d[0]
    r = int(np.sum(rel >= tol))  # the pivoted diagonal does not increase: the first r pass
    ident = np.zeros(n, bool)
    ident[perm[:r]] = True
    pivot = np.zeros(n)
    pivot[perm] = rel
    alias = np.zeros((n, n))
    if r < n:
        C = scipy.linalg.solve_triangular(R[:r, :r], R[:r, r:]) if r > 0 else np.zeros((0, n - r))
        alias[np.ix_(perm[:r], perm[r:])] = C
    return Identifiability(ident, pivot, alias, norms)


def observability(J: ArrayLike, n_poses: int) -> tuple[float, float]:
    """(O1, condition number) of the scaled Jacobian J ``(m, n)`` of ``n_poses`` poses (identifiable columns only)."""
    A = np.asarray(J, dtype=float)
    s = np.linalg.svd(A, compute_uv=False)
    if s.size == 0 or s.size < A.shape[1] or s[-1] <= 0.0:
        return 0.0, float("inf")
    o1 = float(np.exp(np.mean(np.log(s))) / np.sqrt(n_poses))
    return o1, float(s[0] / s[-1])
