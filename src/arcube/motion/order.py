"""The order of the trajectories (model §17.1): the shortest total time, or the plan's own.

The approach, drill and retract of every trajectory take the same time in any order, so the
shortest program is the shortest open path through the standoffs: a travelling-salesman path with
free ends over the transit times. :func:`shortest_order` solves it exactly by dynamic programming
over subsets (Held-Karp: O(2^T T^2) in time, O(2^T T) memory) for up to :data:`EXACT_MAX`
trajectories; beyond, nearest neighbour from every start then 2-opt (not guaranteed optimal).

Transit times are not known before a transit is planned. The caller starts from a proxy for every
pair (the timed straight move in joint space, unchecked), replaces it with the real duration of
every transit it plans (or inf if blocked), and solves again until the best order uses only
transits whose time is real (:func:`arcube.motion.assemble` does this).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["EXACT_MAX", "path_cost", "shortest_order"]

EXACT_MAX = 13
"""Up to this many trajectories the order is exact (Held-Karp)."""


def path_cost(order: list[int], cost: NDArray[np.float64]) -> float:
    """Sum of the transit times along ``order``."""
    return float(sum(cost[a, b] for a, b in zip(order[:-1], order[1:])))


def shortest_order(cost: NDArray[np.float64]) -> tuple[list[int], bool]:
    """(order, exact): the visiting order with the smallest sum of ``cost[a, b]`` (T x T, inf = blocked)."""
    n = len(cost)
    if n <= 1:
        return list(range(n)), True
    order, exact = (_held_karp(cost), True) if n <= EXACT_MAX else (_heuristic(cost), False)
    if order[0] > order[-1] and path_cost(order[::-1], cost) <= path_cost(order, cost):
        order = order[::-1]  # of two equal orders, the one that starts earlier in the plan
    return order, exact


def _held_karp(cost: NDArray[np.float64]) -> list[int]:
    n = len(cost)
    full = 1 << n
    best = np.full((full, n), np.inf)
    parent = np.full((full, n), -1, dtype=np.int64)
    for j in range(n):
        best[1 << j, j] = 0.0
    bits = np.array([1 << j for j in range(n)])
    for mask in range(1, full):
        row = best[mask]
        if not np.isfinite(row).any():
            continue
        out = np.flatnonzero((mask & bits) == 0)  # the next trajectory: one not visited yet
        if not len(out):
            continue
        # arriving at k from any last j in mask: row[j] + cost[j, k]
        total = row[:, None] + cost[:, out]  # (n, len(out))
        j_best = np.argmin(total, axis=0)
        value = total[j_best, np.arange(len(out))]
        for k, v, j in zip(out, value, j_best):
            m2 = mask | (1 << k)
            if v < best[m2, k]:
                best[m2, k], parent[m2, k] = v, j
    last = int(np.argmin(best[full - 1]))
    order, mask = [last], full - 1
    while parent[mask, order[-1]] >= 0:
        prev = int(parent[mask, order[-1]])
        mask ^= 1 << order[-1]
        order.append(prev)
    return order[::-1]


def _heuristic(cost: NDArray[np.float64]) -> list[int]:
    n = len(cost)
    best_order, best_value = list(range(n)), np.inf
    for start in range(n):
        order, left = [start], set(range(n)) - {start}
        while left:
            nxt = min(left, key=lambda k: cost[order[-1], k])
            order.append(nxt)
            left.discard(nxt)
        order = _two_opt(order, cost)
        value = path_cost(order, cost)
        if value < best_value:
            best_order, best_value = order, value
    return best_order


def _two_opt(order: list[int], cost: NDArray[np.float64]) -> list[int]:
    improved = True
    while improved:
        improved = False
        for i in range(0, len(order) - 1):
            for k in range(i + 1, len(order)):
                candidate = order[:i] + order[i : k + 1][::-1] + order[k + 1 :]
                if path_cost(candidate, cost) < path_cost(order, cost) - 1e-12:
                    order, improved = candidate, True
    return order
