"""Several independent CMA-ES runs advanced together as array operations (the engine of ``mscmaes``).

:class:`BatchCMA` holds ``R`` runs of the (mu/mu_w, lambda)-CMA-ES in ``n`` dimensions, each with
its own mean, step size, covariance matrix and evolution paths, stacked along a first axis: one
``ask`` samples all ``R x lam`` candidates, one ``tell`` ranks and updates all runs (NumPy batched
matrix products and one batched ``eigh`` per generation). It replaces ``R`` objects of the ``cma``
package, whose per-run ask/tell cost ~1.5 ms in Python bookkeeping per run and generation, several
times the evaluation of the run's candidates.

The algorithm is the one of the ``cma`` package (4.x) with its default options, as used before
(Hansen, "The CMA Evolution Strategy: A Tutorial", 2016, with cma's own constants; see
:func:`parameters`): active covariance update (negative weights for the worse half, their vectors
rescaled to Mahalanobis length sqrt(n)), cumulative step-size adaptation with cma's ``cs``,
``damps`` and exact E||N(0, I)||, the hsig stall of the rank-one path, the change of log sigma
clipped to +-1, an eigendecomposition every generation (cma's lazy gap 1/(c1+cmu)/n/10 is below one
generation here), no elitism, no bounds (the caller maps samples into its box), and no mirrored
samples (cma mirrors only populations below 6, which ``mscmaes`` uses only for tiny budgets).

Stop tests, each cma's (options ``tolfun = tolfunhist = tol``, ``tolx = tol/10``, the rest cma's
defaults): tolfun (this generation's values and the best-of-generation history both span less
than tol), tolfunhist (that history, once over 9 generations long, spans less than tol), tolx,
tolfacupx, tolconditioncov, noeffectcoord, noeffectaxis, tolflatfitness. Left out: tolstagnation
(no improvement over ~900 generations at n = 23: in the paper's problem every search run stops by
tolfun/tolfunhist after ~350-700 generations, and the polish phase is ~230 generations long),
tolxstagnation (a mean that moves less than 1e-9 for 20+ generations: tolx comes first),
tolupsigma, maxiter, and cma's alleviation of a condition number above 1e8.

Randomness: each run draws its standard normals from its own ``numpy.random.Generator`` (given at
:meth:`restart`), one ``(lam, n)`` array per generation as cma's ``randn`` option does, and starts
with cma's initial C = diag(exp(1e-4 i / n)) (distinct variances, so the eigenvectors do not
depend on round-off). Fed the same start and generator, a run samples the same candidates as a
``cma`` run to ~1e-10 and stops at the same generation (tests/test_multistart.py), until two
nearly equal function values rank the other way round.
"""

from __future__ import annotations

import math

import numpy as np

TOLFACUPX = 1e3
"""cma's tolfacupx: stop when a coordinate's standard deviation grows above 1000 x the initial sigma."""
TOLCONDITIONCOV = 1e14
"""cma's tolconditioncov: stop when the condition number of C exceeds this."""


def parameters(n: int, lam: int) -> dict[str, float | np.ndarray]:
    """cma's default strategy parameters for ``n`` variables and population ``lam``.

    ``weights`` (lam,): log-rank weights, the positive ones summing to 1, the negative ones scaled
    as cma's ``RecombinationWeights.finalize_negative_weights``; ``mu`` the number of positive
    ones; ``mueff`` their variance effective selection mass; learning rates ``cc, c1, cmu, cs``,
    damping ``damps`` and ``chin`` = E||N(0, I_n)||. tests/test_multistart.py checks them against cma.
    """
    raw = np.array([math.log((lam + 1) / 2.0) - math.log(i) for i in range(1, lam + 1)])
    pos, neg = raw > 0, raw < 0
    w = raw.copy()
    w[pos] /= raw[pos].sum()
    mueff = 1.0 / float(np.sum(w[pos] ** 2))
    c1 = min(1.0, lam / 6.0) * 2.0 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1.0 - c1, 2.0 * (0.25 + mueff - 2.0 + 1.0 / mueff) / ((n + 2.0) ** 2 + 2.0 * mueff / 2.0))
    if neg.any():
        mueffm = float(raw[neg].sum() ** 2 / np.sum(raw[neg] ** 2))
        total = min(1.0 + c1 / cmu, (1.0 - c1 - cmu) / cmu / n, 1.0 + 2.0 * mueffm / (mueff + 2.0))
        w[neg] *= total / -raw[neg].sum()
    cs = min(0.5, (mueff + 2.0) / (n + mueff + 3.0))
    d_in = max(1.0, 3.0 * (1.0 - 0.5 ** (n / 9.0)))
    damps = 0.5 + 0.5 + 2.0 * max(0.0, d_in * ((mueff - 1.0) / (n + 1.0)) ** 0.5 - 1.0) + cs  # no mirrors
    cc = (4.0 + mueff / n) / (n + 4.0 + 2.0 * mueff / n)
    chin = math.sqrt(2.0) * math.exp(math.lgamma((n + 1) / 2.0) - math.lgamma(n / 2.0))
    return {
        "weights": w,
        "mu": int(pos.sum()),
        "mueff": mueff,
        "cc": cc,
        "c1": c1,
        "cmu": cmu,
        "cs": cs,
        "damps": damps,
        "chin": chin,
    }


class BatchCMA:
    """``runs`` CMA-ES runs in ``n`` dimensions with population ``lam``, initial step ``sigma0`` and
    stop tolerance ``tol`` (in units of the function values; tolx is ``tol/10`` in units of x).

    Positions and steps are in the caller's coordinates (for ``mscmaes`` the normalized box
    [0, 1]^n, which the runs may leave); function values are minimized. State, per run ``r``: ``mean`` (R, n), ``sigma`` (R,), covariance ``C`` (R, n, n) and its
    eigendecomposition ``C = B diag(D**2) B^T`` (``B`` (R, n, n), ``D`` (R, n) ascending), paths
    ``ps``, ``pc`` (R, n), generation count ``it`` (R,), best-of-generation history ``hist`` (R, H)
    (a ring, H = floor(10 + 30 n / lam) as cma), flat-fitness count ``flat`` (R,), generators
    ``rngs``. Every run must be started with :meth:`restart` before the first :meth:`ask`.
    """

    def __init__(self, runs: int, n: int, lam: int, sigma0: float, tol: float) -> None:
        self.R, self.n, self.lam, self.sigma0, self.tol = int(runs), int(n), int(lam), float(sigma0), float(tol)
        p = parameters(self.n, self.lam)
        self.w, self.mu, self.mueff = p["weights"], int(p["mu"]), float(p["mueff"])
        self.cc, self.c1, self.cmu, self.cs, self.damps, self.chin = (
            float(p[k]) for k in ("cc", "c1", "cmu", "cs", "damps", "chin")
        )
        self.H = int(10 + 30 * self.n / self.lam)
        R, n = self.R, self.n
        self.mean, self.ps, self.pc = np.zeros((R, n)), np.zeros((R, n)), np.zeros((R, n))
        self.sigma, self.D = np.full(R, self.sigma0), np.ones((R, n))
        self.C, self.B = np.tile(np.eye(n), (R, 1, 1)), np.tile(np.eye(n), (R, 1, 1))
        self.it, self.flat = np.zeros(R, dtype=np.int64), np.zeros(R, dtype=np.int64)
        self.hist = np.zeros((R, self.H))
        self.Y = np.zeros((R, self.lam, n))  # the last steps asked, in units of sigma
        self.rngs: list[np.random.Generator | None] = [None] * R
        self.C0 = np.exp((1e-4 / n) * np.arange(n))  # cma's initial variances (distinct: unique eigenvectors)

    def restart(self, r: int, x0: np.ndarray, rng: np.random.Generator) -> None:
        """Run ``r`` afresh at ``x0`` (n,), sampling from ``rng``: sigma0, C ~ I (:attr:`C0`), zero paths and history."""
        self.mean[r], self.sigma[r], self.rngs[r] = x0, self.sigma0, rng
        self.C[r], self.B[r], self.D[r] = np.diag(self.C0), np.eye(self.n), np.sqrt(self.C0)
        self.ps[r], self.pc[r], self.it[r], self.flat[r] = 0.0, 0.0, 0, 0

    def ask(self) -> np.ndarray:
        """All runs' candidates, ``(R * lam, n)``, run by run: ``mean_r + sigma_r B_r diag(D_r) z``, z ~ N(0, I)."""
        Z = np.stack([g.standard_normal((self.lam, self.n)) for g in self.rngs])
        self.Y = (Z * self.D[:, None, :]) @ self.B.transpose(0, 2, 1)
        return (self.mean[:, None, :] + self.sigma[:, None, None] * self.Y).reshape(-1, self.n)

    def _inv_sqrt(self, V: np.ndarray) -> np.ndarray:
        """C^(-1/2) applied to row vectors ``V`` (R, k, n) of each run."""
        return ((V @ self.B) / self.D[:, None, :]) @ self.B.transpose(0, 2, 1)

    def tell(self, F: np.ndarray) -> np.ndarray:
        """Update every run from the values ``F`` (R * lam,) of the last :meth:`ask`'s candidates
        (same order); return the runs that meet a stop test, a boolean mask (R,)."""
        R, n, lam, mu = self.R, self.n, self.lam, self.mu
        F = np.array(F, dtype=float).reshape(R, lam)
        bad = np.isnan(F)
        if bad.any():  # as cma: a NaN value counts as the median of the others
            F[bad] = np.broadcast_to(np.nanmedian(F, axis=1, keepdims=True), F.shape)[bad]
        order = np.argsort(F, axis=1, kind="stable")
        Fs = np.take_along_axis(F, order, axis=1)
        Ys = np.take_along_axis(self.Y, order[:, :, None], axis=1)  # (R, lam, n), best first
        self.it += 1
        yw = self.w[:mu] @ Ys[:, :mu]  # (R, n): the mean's step over sigma
        self.mean += self.sigma[:, None] * yw
        # step size path and the stall of the rank-one path (C^(-1/2) of the current C, as sampled)
        zw = self._inv_sqrt(yw[:, None, :])[:, 0]
        self.ps = (1.0 - self.cs) * self.ps + math.sqrt(self.cs * (2.0 - self.cs) * self.mueff) * zw
        ps2 = np.sum(self.ps**2, axis=1)
        hsig = (ps2 / (1.0 - (1.0 - self.cs) ** (2 * self.it)) / n - 1.0 < 1.0 + 4.0 / (n + 1)).astype(float)
        self.pc = (1.0 - self.cc) * self.pc + (hsig * math.sqrt(self.cc * (2.0 - self.cc) * self.mueff))[:, None] * yw
        # covariance: rank-one + rank-mu with negative weights rescaled to Mahalanobis length sqrt(n)
        c1a = self.c1 * (1.0 - (1.0 - hsig**2) * self.cc * (2.0 - self.cc))
        wc = np.tile(self.cmu * self.w, (R, 1))
        neg = self.w < 0
        if neg.any():
            norms = np.sqrt(
                np.sum(((Ys[:, neg] @ self.B) / self.D[:, None, :]) ** 2, axis=2)
            )  # (R, #neg): |C^(-1/2) y|
            wc[:, neg] *= n / (norms + 1e-9) ** 2
        decay = 1.0 - c1a - self.cmu * float(self.w.sum())
        self.C *= decay[:, None, None]
        self.C += self.c1 * self.pc[:, :, None] * self.pc[:, None, :]
        self.C += (Ys.transpose(0, 2, 1) * wc[:, None, :]) @ Ys
        self.sigma *= np.exp(np.clip(self.cs / self.damps * (np.sqrt(ps2) / self.chin - 1.0), -1.0, 1.0))
        self.C = (self.C + self.C.transpose(0, 2, 1)) / 2.0
        D2, self.B = np.linalg.eigh(self.C)
        self.D = np.sqrt(np.maximum(D2, 1e-300))
        # best-of-generation history, a ring of H; the first generation fills it (so max/min see only real values)
        first = self.it == 1
        self.hist[first] = Fs[first, :1]
        self.hist[np.arange(R), (self.it - 1) % self.H] = Fs[:, 0]
        return self._stop(Fs)

    def _stop(self, Fs: np.ndarray) -> np.ndarray:
        """cma's stop tests (see the module docstring) after a tell; ``Fs`` (R, lam) sorted values."""
        tol, R = self.tol, self.R
        hist_range = self.hist.max(axis=1) - self.hist.min(axis=1)
        stop = (Fs[:, -1] - Fs[:, 0] < tol) & (hist_range < tol)  # tolfun
        stop |= (np.minimum(self.it, self.H) > 9) & (hist_range < tol)  # tolfunhist
        sd = self.sigma[:, None] * np.sqrt(np.diagonal(self.C, axis1=1, axis2=2))  # (R, n) standard deviations
        stop |= np.all(sd < 0.1 * tol, axis=1) & np.all(
            self.sigma[:, None] * self.pc < 0.1 * tol, axis=1
        )  # tolx (as cma: pc signed)
        stop |= np.any(sd > self.sigma0 * TOLFACUPX, axis=1)  # tolfacupx
        stop |= np.any(self.mean == self.mean + 0.2 * sd, axis=1)  # noeffectcoord
        i = self.it % self.n
        axis = self.B[np.arange(R), :, i] * (0.1 * self.sigma * self.D[np.arange(R), i])[:, None]
        stop |= np.all(self.mean == self.mean + axis, axis=1)  # noeffectaxis
        stop |= self.D[:, -1] > TOLCONDITIONCOV**0.5 * self.D[:, 0]  # tolconditioncov
        self.flat = np.where(Fs[:, 0] < Fs[:, int(0.75 * self.lam)], 0, self.flat + 1)
        return stop | (self.flat > 1)  # tolflatfitness
