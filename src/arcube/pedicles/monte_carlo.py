"""The Monte Carlo of breaches (model §22.4): N samples, each a built robot, a registration and the deflection.

Per screw: P(breach) with its 95 % Wilson interval, P by direction (medial, lateral, cranial, caudal), P(major), the
p95 of the offset |delta| at the isthmus, and P(breach) with each source alone (the other two at 0), computed on the
same draws, and the source that decides the screw (``deciding_source``: the one whose P alone is largest; on a tie, the
one whose offsets fill the most of the room on average). Per level and side the largest P(breach); per docking the
largest and the expected number of breached screws, sum_j P_j. ``breach_probability``: the largest P(breach) over the
screws that are not too wide; ``too_wide``: the others (P = 1 by geometry).

One truth per screw: a screw the robot does not reach at its docking (the design job's verdict for its trajectory, the
guards included, model §16-17, or no inverse kinematics at its isthmus) is not drilled by it: it has no P(breach) at
all (NaN, empty cells), its ``status`` is ``not_reached``, and the summary counts it apart. A screw wider than its
pedicle is ``screw_too_wide``; every other screw is ``assessed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.summary import Summary
from arcube.pedicles.geometry import DIRECTIONS, Pedicles, classify
from arcube.pedicles.sources import (
    Draws,
    RobotModel,
    deflection,
    draw,
    registration,
    robot_displacements,
    robot_displacements_reference,
)

__all__ = ["BREACH_COLUMNS", "SOURCES", "STATUSES", "BreachResult", "BreachSummary", "monte_carlo", "wilson"]

BREACH_COLUMNS = (
    "trajectory",
    "level",
    "side",
    "width_mm",
    "height_mm",
    "isthmus_depth_mm",
    "screw_mm",
    "room_mm",
    "too_wide",
    "p_breach",
    "p_breach_low",
    "p_breach_high",
    "p_medial",
    "p_lateral",
    "p_cranial",
    "p_caudal",
    "p_major",
    "offset_p95_mm",
    "p_robot_alone",
    "p_registration_alone",
    "p_deflection_alone",
)
"""The columns of breach.csv, one row per screw in the plan's order (then :data:`MORE_COLUMNS`)."""
MORE_COLUMNS = ("room_height_mm", "docking", "reached", "status", "deciding_source", "p_first_order")
"""breach.csv's columns after :data:`BREACH_COLUMNS`."""
SOURCES = ("robot", "registration", "deflection")
"""The error sources of model §22.2, in the order of ``p_alone``'s columns."""
STATUSES = ("assessed", "not_reached", "screw_too_wide")
"""A screw's ``status``: its P(breach) computed; not reached by the robot at its docking (no P); wider than its pedicle
(P = 1 by geometry)."""
Z95 = 1.959963984540054


def wilson(k: NDArray[np.float64] | float, n: int, z: float = Z95) -> tuple[Any, Any]:
    """The 95 % Wilson score interval (low, high) of a proportion k/n, elementwise; exactly 0 (1) at k = 0 (k = n)."""
    k_a = np.asarray(k, dtype=float)
    p = k_a / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return np.where(k_a == 0, 0.0, np.maximum(centre - half, 0.0)), np.where(
        k_a == n, 1.0, np.minimum(centre + half, 1.0)
    )


class BreachSummary(Summary):
    """The summary of a breach computation (``BreachResult.summary()``, the ``summary.json`` of ``arcube breach``,
    model §22)."""

    breach_probability: float | None
    """The largest probability that a screw leaves its pedicle, over the reached screws not wider than their pedicle;
    1 when every reached screw is too wide; None only when no screw is reached."""
    worst_screw: str | None
    """The trajectory where it is largest."""
    deciding_source: str | None
    """What decides the worst screw: robot, registration or deflection (None for a too-wide screw: its geometry)."""
    screws: int
    """Screws in the plan."""
    reached: int
    """Screws the robot reaches at its docking (assessed or too wide)."""
    too_wide: list[str]
    """Screws wider than their pedicle (they always breach)."""
    not_reached: list[str]
    """Trajectories the robot does not reach at its docking (the design job's verdict): no P(breach)."""
    expected_breaches: float
    """Sum of the probabilities over the reached screws."""
    what_it_takes: list[dict[str, Any]]
    """Per level (then ``all``): what brings its worst screw to the target P (what_it_takes.csv)."""
    per_level_side: dict[str, float]
    """The largest probability per level and side (``"C3 R"``)."""
    per_docking: dict[str, dict[str, Any]]
    """Per docking: its largest probability, its expected breaches, its screws."""
    samples: int
    settings: dict[str, Any]


@dataclass(frozen=True)
class BreachResult:
    """The breach Monte Carlo of one plan: per-screw arrays ``(J,)`` and the settings it ran with."""

    pedicles: Pedicles
    docking: tuple[str, ...]  # (J,) the docking of each screw (its side, or "both")
    samples: int
    reached: NDArray[np.bool_]  # the design job's verdict at the docking and the nominal IK at the isthmus (else no P)
    p_breach: NDArray[np.float64]
    p_direction: NDArray[np.float64]  # (J, 4) medial, lateral, cranial, caudal
    p_major: NDArray[np.float64]
    offset_p95_mm: NDArray[np.float64]
    p_alone: NDArray[np.float64]  # (J, 3) robot, registration, deflection
    offsets: NDArray[np.float64] = field(repr=False)  # (N, J, 2) the combined offsets, for the pictures
    settings: dict[str, Any] = field(default_factory=dict)
    deciding: tuple[str, ...] = ()  # (J,) the deciding source of each assessed screw, "" for the others
    p_first_order: NDArray[np.float64] | None = (
        None  # (J,) the first-order P (pedicles.first_order), NaN if not reached
    )
    takes: tuple[dict[str, Any], ...] = ()  # what it takes to reach the target (pedicles.first_order.what_it_takes)
    plan: Any = field(default=None, repr=False)  # the TrajectorySet of the screws (for the markups), when known

    @property
    def status(self) -> tuple[str, ...]:
        """(J,) each screw's :data:`STATUSES` entry."""
        wide = self.pedicles.too_wide
        return tuple(
            "not_reached" if not self.reached[j] else "screw_too_wide" if wide[j] else "assessed"
            for j in range(len(self.pedicles.ids))
        )

    @property
    def interval(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The 95 % Wilson interval of each P(breach)."""
        return wilson(np.round(self.p_breach * self.samples), self.samples)

    def rows(self) -> list[dict[str, Any]]:
        """One dict per screw with :data:`BREACH_COLUMNS` (and ``room_height_mm``, ``docking``, ``reached``); NaN where
        a figure is not defined (the direction, grade and offsets of a too-wide screw)."""
        p, (low, high), room, wide = self.pedicles, self.interval, self.pedicles.room, self.pedicles.too_wide
        status, deciding = self.status, self.deciding or ("",) * len(p.ids)
        out = []
        for j in range(len(p.ids)):
            nan_if_wide = lambda v: math.nan if wide[j] or not self.reached[j] else float(v)  # noqa: E731 - one screw's rule
            if not self.reached[j]:
                low[j] = high[j] = math.nan
            out.append(
                {
                    "trajectory": p.ids[j],
                    "level": p.levels[j],
                    "side": p.sides[j],
                    "width_mm": float(p.width[j]),
                    "height_mm": float(p.height[j]),
                    "isthmus_depth_mm": float(p.depth[j]),
                    "screw_mm": float(p.screw[j]),
                    "room_mm": float(room[j, 0]),
                    "too_wide": bool(wide[j]),
                    "p_breach": float(self.p_breach[j]),
                    "p_breach_low": float(low[j]),
                    "p_breach_high": float(high[j]),
                    **{f"p_{name}": nan_if_wide(self.p_direction[j, k]) for k, name in enumerate(DIRECTIONS)},
                    "p_major": nan_if_wide(self.p_major[j]),
                    "offset_p95_mm": nan_if_wide(self.offset_p95_mm[j]),
                    "p_robot_alone": nan_if_wide(self.p_alone[j, 0]),
                    "p_registration_alone": nan_if_wide(self.p_alone[j, 1]),
                    "p_deflection_alone": nan_if_wide(self.p_alone[j, 2]),
                    "room_height_mm": float(room[j, 1]),
                    "docking": self.docking[j],
                    "reached": bool(self.reached[j]),
                    "status": status[j],
                    "deciding_source": deciding[j],
                    "p_first_order": math.nan
                    if self.p_first_order is None or not self.reached[j]
                    else float(self.p_first_order[j]),
                }
            )
        return out

    def summary(self) -> BreachSummary:
        """``breach_probability`` (the largest P over the reached screws that are not too wide; 1 when every reached
        screw is too wide), its screw and deciding source, ``too_wide`` and ``not_reached`` (their ids), the largest P
        per level and side, per docking the largest and the expected breaches, and the settings. Screws not reached
        count in ``screws`` and ``not_reached`` only."""
        p, reached = self.pedicles, np.asarray(self.reached, dtype=bool)
        wide = p.too_wide & reached
        fit = ~p.too_wide & reached
        if fit.any():
            worst: int | None = int(np.argmax(np.where(fit, self.p_breach, -1.0)))
        else:  # every reached screw is too wide (P = 1 by geometry), or none is reached
            worst = int(np.argmax(wide)) if wide.any() else None
        per_level: dict[str, float] = {}
        for j in np.flatnonzero(reached):
            key = f"{p.levels[j]} {p.sides[j]}"
            per_level[key] = max(per_level.get(key, 0.0), float(self.p_breach[j]))
        per_docking = {}
        for name in dict.fromkeys(self.docking):
            mine = np.array([d == name for d in self.docking])
            per_docking[name] = {
                "breach_probability": float(np.max(self.p_breach[mine & fit]))
                if (mine & fit).any()
                else (1.0 if (mine & wide).any() else None),
                "expected_breaches": float(np.sum(self.p_breach[mine & reached])),
                "screws": int(mine.sum()),
                "not_reached": int((mine & ~reached).sum()),
            }
        deciding = self.deciding or ("",) * len(p.ids)
        return BreachSummary(
            breach_probability=None if worst is None else float(self.p_breach[worst]),
            worst_screw=None if worst is None else p.ids[worst],
            deciding_source=(deciding[worst] or None) if worst is not None else None,
            screws=len(p.ids),
            reached=int(reached.sum()),
            too_wide=[p.ids[j] for j in np.flatnonzero(wide)],
            not_reached=[p.ids[j] for j in np.flatnonzero(~reached)],
            expected_breaches=float(np.sum(self.p_breach[reached])),
            what_it_takes=[dict(r) for r in self.takes],
            per_level_side=per_level,
            per_docking=per_docking,
            samples=self.samples,
            settings=self.settings,
        )


def _stats(offsets: NDArray[np.float64], p: Pedicles) -> tuple[NDArray[np.float64], ...]:
    """(P(breach), P by direction (J, 4), P(major)) of offsets ``(N, J, 2)``."""
    breach, direction, major = classify(offsets, p)
    p_dir = np.stack([np.mean(direction == k, axis=0) for k in range(len(DIRECTIONS))], axis=-1)
    return np.mean(breach, axis=0), p_dir, np.mean(major, axis=0)


def monte_carlo(
    robot: RobotModel,
    p: Pedicles,
    docking: tuple[str, ...],
    *,
    samples: int,
    seed: int,
    registration_mm: float,
    registration_deg: float,
    thrust_N: float,
    stiffness_Nm_per_rad: Any,
    reference: bool = False,
    settings: dict[str, Any] | None = None,
    verdict: NDArray[np.bool_] | None = None,
) -> BreachResult:
    """Run the Monte Carlo (module docstring) on the screws ``p``; ``docking`` ``(J,)`` names each screw's docking (one
    registration per docking, about the centroid of its screws' entries). ``reference``: the robot's displacements
    one sample at a time (:func:`~arcube.pedicles.sources.robot_displacements_reference`), else all at once.
    ``verdict`` ``(J,)``: the design job's verdict of each screw's trajectory at its docking (None: every one reached);
    a screw it refuses, or whose isthmus pose the nominal robot cannot take, gets no figures (NaN)."""
    e = -p.u
    names = list(dict.fromkeys(docking))
    index = np.array([names.index(d) for d in docking], dtype=np.intp)
    entries = p.isthmus - p.depth[:, None] * p.u
    centres = np.array([entries[index == k].mean(axis=0) for k in range(len(names))])
    draws: Draws = draw(
        np.random.default_rng(seed), robot, samples, len(p.ids), len(names), registration_mm, registration_deg
    )
    robot_d = (robot_displacements_reference if reference else robot_displacements)(robot, p.isthmus, e, draws)
    reached = ~np.any(np.isnan(robot_d[0]), axis=-1) if samples else np.ones(len(p.ids), bool)
    if verdict is not None:
        reached = reached & np.asarray(verdict, dtype=bool).reshape(len(p.ids))
    robot_d = np.where(
        np.isnan(robot_d), np.inf, robot_d
    )  # a screw the robot does not reach is not drilled where planned
    reg_d = registration(draws, p.isthmus, index, centres)
    # an unassembled or unreached screw's offset is not finite (inf x 0 gives NaN): classify() counts it a breach
    with np.errstate(invalid="ignore", over="ignore"):
        defl_d = np.nan_to_num(deflection(robot, p.isthmus, e, thrust_N, stiffness_Nm_per_rad), nan=np.inf)[None]
        offsets = p.offsets(robot_d + reg_d + defl_d)
    with np.errstate(invalid="ignore", over="ignore"):
        p_breach, p_dir, p_major = _stats(offsets, p)
        alone = np.stack(
            [_stats(p.offsets(d), p)[0] for d in (robot_d, reg_d, np.broadcast_to(defl_d, robot_d.shape))], axis=-1
        )
        size = np.nan_to_num(np.linalg.norm(offsets, axis=-1), nan=np.inf)  # not finite: beyond any room
    from arcube.accuracy.monte_carlo import percentiles

    p95 = percentiles(size, [95.0], axis=0)[0]
    with np.errstate(invalid="ignore", over="ignore"):
        per_source = [p.offsets(d) for d in (robot_d, reg_d, np.broadcast_to(defl_d, robot_d.shape))]
    deciding = _deciding(alone, per_source, p, reached)
    gone = ~reached  # one truth per screw: what the robot does not drill has no figures
    p_breach, p_major, p95 = (np.where(gone, np.nan, a) for a in (p_breach, p_major, p95))
    p_dir, alone = (np.where(gone[:, None], np.nan, a) for a in (p_dir, alone))
    return BreachResult(
        p, tuple(docking), samples, reached, p_breach, p_dir, p_major, p95, alone, offsets, settings or {}, deciding
    )


def _deciding(
    alone: NDArray[np.float64], offsets: list[NDArray[np.float64]], p: Pedicles, reached: NDArray[np.bool_]
) -> tuple[str, ...]:
    """(J,) the source (:data:`SOURCES`) whose P(breach) alone ``alone`` ``(J, 3)`` is largest at each assessed screw;
    a tie (every source alone 0, say) goes to the source whose offsets ``(N, J, 2)`` fill the most of the room on
    average, mean (delta_w/a')^2 + (delta_h/b')^2 (the last is the first: robot). "" for a screw not assessed."""
    room = np.where(p.too_wide[:, None], 1.0, p.room)
    with np.errstate(invalid="ignore", over="ignore"):
        fill = np.stack(
            [np.nan_to_num(np.mean(np.sum((o / room) ** 2, axis=-1), axis=0), nan=np.inf) for o in offsets], axis=-1
        )
    out = []
    for j in range(len(p.ids)):
        if not reached[j] or p.too_wide[j]:
            out.append("")
            continue
        keys = [(float(alone[j, k]), float(fill[j, k]), -k) for k in range(len(SOURCES))]
        out.append(SOURCES[-max(keys)[2]])
    return tuple(out)
