"""Putting a program together (model §17): lines, transits, order, rows and summary.

1. Every trajectory's line S_j -> A_j -> B_j is checked at 17.2's resolution (the tool exempt); a
   failing state is an error naming the segment (approach or drill) and the constraint.
2. The assembly mode is that of the first trajectory's standoff; every state must keep it.
3. Order: ``given``, or the shortest (:mod:`arcube.motion.order`) over transit times, starting from
   a proxy for every pair (the timed straight joint move, unchecked) and replacing it by the real
   duration of each transit the current best order uses, until that order's transits are all real.
4. Transits (:mod:`arcube.motion.transit`) and line pieces are timed and sampled
   (:mod:`arcube.motion.sampling`); the rows go one after another on one grid of step dt.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arcube.errors import InputError
from arcube.evaluation.standoff import standoff_points
from arcube.io.trajectories import TrajectorySet
from arcube.model.design import Design
from arcube.model.mechanism import format_mode
from arcube.evaluation.mass_bodies import MassModel
from arcube.evaluation.masses import moving_mass_kg
from arcube.options import Body, Loads
from arcube.motion.check import Checker, StateChecks
from arcube.motion.dynamics import program_torques
from arcube.motion.limits import RESOLUTION_MM, Planner, ProgramLimits
from arcube.motion.motors import motor_figures
from arcube.motion.order import EXACT_MAX, path_cost, shortest_order
from arcube.motion.output import JOINTS, Program
from arcube.motion.rows import check_total
from arcube.motion.sampling import cruise_problem, sample_piece
from arcube.motion.segments import Line, Piece, line_piece, polyline_fn
from arcube.motion.timing import TimingError, time_optimal
from arcube.motion.transit import Transit, transit

__all__ = ["build_program"]

_IK = ("TLS/", "RTS/", "TMS/", "singular/", "FK/", "IK/")


def _blocked(segment: str, checks: StateChecks, i: int, limits: ProgramLimits, mode: str) -> str:
    text = f"{segment} blocked: {checks.describe(i, limits)}"
    if str(checks.reason[i]).startswith(_IK):
        text += f" (the design does not reach this pose in working mode {mode})"
    return text


def _lines(ts: TrajectorySet, anatomy: Any, limits: ProgramLimits) -> list[Line]:
    A, B = np.asarray(ts.entry, float), np.asarray(ts.target, float)
    S, depth = standoff_points(A, B, anatomy, limits.standoff_mm)
    e = (A - B) / np.linalg.norm(A - B, axis=1, keepdims=True)
    return [
        Line(str(ts.ids[i]), S[i], A[i], B[i], e[i], float(depth[i]), float(np.linalg.norm(A[i] - B[i])))
        for i in range(len(A))
    ]


def _near(q_from: NDArray[np.float64], q_to: NDArray[np.float64]) -> NDArray[np.float64]:
    """q_to with each delta turned by a multiple of 2 pi to lie within pi of q_from's."""
    out = q_to.copy()
    out[3:] = q_from[3:] + np.angle(np.exp(1j * (q_to[3:] - q_from[3:])))
    return out


def _proxy(q_a: NDArray[np.float64], q_b: NDArray[np.float64], checker: Checker, limits: ProgramLimits) -> float:
    """The timed straight joint move from q_a to q_b (not checked): the order's first guess of a transit."""
    fn, knots = polyline_fn(np.stack([q_a, q_b]))
    if knots[-1] <= 1e-12:
        return 0.0
    grid = np.linspace(0.0, knots[-1], 33)
    E = checker.pose_of(fn(grid, 0))[0]
    gain = np.linalg.norm(np.gradient(E, grid, axis=0), axis=-1)
    speed = limits.max_tip_speed if np.all(np.isfinite(gain)) else None
    try:
        return time_optimal(fn, grid, limits.qd_max, limits.qdd_max, speed, gain if speed else None).duration
    except TimingError:
        return math.inf


class _Builder:
    def __init__(
        self,
        design: Design,
        ts: TrajectorySet,
        anatomy: Any,
        mode: NDArray[np.float64],
        limits: ProgramLimits,
        body: Body,
        planner: Planner,
        log: Callable[[str], None],
        engine: str = "numpy",
        envelope: Any = None,
    ) -> None:
        self.ts, self.limits, self.planner, self.log, self.design = ts, limits, planner, log, design
        self.mode, self.mode_text = mode, format_mode(mode)
        self.lines = _lines(ts, anatomy, limits)
        self.anatomy_source = None if anatomy is None else str(anatomy.source)
        distance = None if anatomy is None else anatomy.distance
        self.checker = Checker(
            design.to_vector(), mode, limits, body, distance, engine=engine, envelope=envelope, c_z=design.c_z
        )
        self.envelope_source = None if envelope is None else envelope.source
        self.transits: dict[tuple[int, int], tuple[Transit, list[dict[str, Any]], float]] = {}

    def check_lines(self) -> None:
        first = self.lines[0]
        c0 = self.checker.poses(first.S[None], first.e)
        if not c0.ok[0]:
            raise InputError(_blocked(f"approach {first.tid}", c0, 0, self.limits, self.mode_text))
        self.checker.assembly = c0.assembly[0].copy()
        for line in self.lines:
            checks = line.check(self.checker)
            if not checks.ok.all():
                i = int(np.flatnonzero(~checks.ok)[0])
                seg = "approach" if line.s[i] < line.depth else "drill"
                raise InputError(_blocked(f"{seg} {line.tid}", checks, i, self.limits, self.mode_text))

    def line_rows(self, line: Line) -> list[tuple[Piece, dict[str, Any]]]:
        lim, p = self.limits, self.checker.params
        pieces = [
            line_piece("approach", line, 0.0, line.depth, lim.approach_speed, p, self.mode),
            line_piece("drill", line, line.depth, line.total, lim.feed, p, self.mode),
            line_piece("retract", line, line.total, 0.0, lim.retract_speed, p, self.mode),
        ]
        out = []
        for piece in pieces:
            problem = cruise_problem(piece, lim)
            if problem:
                raise InputError(f"{piece.kind} {line.tid}: {problem}")
            try:
                out.append((piece, sample_piece(piece, lim, line=True)))
            except TimingError as exc:
                raise InputError(f"{piece.kind} {line.tid}: {exc}") from None
        return out

    def q_standoff(self, j: int) -> NDArray[np.float64]:
        return self.lines[j].checks.q[0]  # type: ignore[union-attr]

    def transit(self, a: int, b: int) -> tuple[Transit, list[dict[str, Any]], float]:
        if (a, b) not in self.transits:
            la, lb = self.lines[a], self.lines[b]
            label = f"{la.tid}->{lb.tid}"
            q_a = self.q_standoff(a)
            tr = transit(
                label, q_a, _near(q_a, self.q_standoff(b)), self.checker, self.limits.max_tip_speed, self.planner
            )
            rows: list[dict[str, Any]] = []
            duration = 0.0 if tr.method == "none" else math.inf
            if tr.pieces:
                try:
                    rows = [sample_piece(piece, self.limits, line=False) for piece in tr.pieces]
                    duration = sum(r["t"][-1] for r in rows)
                except TimingError as exc:
                    tr.pieces, tr.method = [], f"blocked (timing: {exc})"
            self.log(
                f"transit {la.tid} -> {lb.tid}: {tr.method}"
                + (f", {duration:.2f} s" if math.isfinite(duration) else "")
            )
            self.transits[(a, b)] = (tr, rows, duration)
        return self.transits[(a, b)]

    def blocked_message(self, a: int, b: int) -> str:
        tr = self.transits[(a, b)][0]
        head = f"transit {self.lines[a].tid} -> {self.lines[b].tid} blocked: "
        if tr.blocked is None:
            return head + f"the straight move passes but cannot be timed ({tr.method})"
        text = head + f"{tr.blocked.describe(tr.blocked_index, self.limits)} on the straight move in joint space"
        if tr.method.startswith("blocked (timing"):
            return text + f"; the planned path cannot be timed ({tr.method[9:-1]})"
        return (
            text
            + f", and OMPL RRTConnect found no way around within {self.planner.time_s:g} s (seed {self.planner.seed})"
        )

    def choose_order(self, order: str) -> tuple[list[int], str]:
        n = len(self.lines)
        if order == "given" or n == 1:
            seq = list(range(n))
            order = "given" if order == "given" else "single trajectory"
            for a, b in zip(seq[:-1], seq[1:]):
                if not math.isfinite(self.transit(a, b)[2]):
                    raise InputError(self.blocked_message(a, b))
            return seq, order
        q = [self.q_standoff(j) for j in range(n)]
        cost = np.zeros((n, n))
        for a in range(n):
            for b in range(a + 1, n):
                cost[a, b] = cost[b, a] = _proxy(q[a], _near(q[a], q[b]), self.checker, self.limits)
        last_blocked = None
        for _ in range(n * n + 1):
            seq, exact = shortest_order(cost)
            todo = [(a, b) for a, b in zip(seq[:-1], seq[1:]) if (a, b) not in self.transits]
            if not todo and math.isfinite(path_cost(seq, cost)):
                break
            if not todo:
                raise InputError(
                    self.blocked_message(*last_blocked) if last_blocked else "no order of the trajectories can be run"
                )
            for a, b in todo:
                cost[a, b] = self.transit(a, b)[2]
                if self.transits[(a, b)][0].method == "straight" and (b, a) not in self.transits:
                    cost[b, a] = cost[a, b]  # the same states backwards: a better guess than the proxy
                if not math.isfinite(cost[a, b]):
                    last_blocked = (a, b)
        method = (
            "shortest (exact: dynamic programming over subsets)"
            if exact
            else f"shortest (heuristic beyond {EXACT_MAX}: nearest neighbour + 2-opt)"
        )
        return seq, method


def _extreme(values: list[tuple[NDArray[np.float64], str]], smallest: bool) -> tuple[float, str | None]:
    best, where = (math.inf if smallest else -math.inf), None
    for v, label in values:
        v = v[np.isfinite(v)]
        if len(v):
            x = float(v.min() if smallest else v.max())
            if (x < best) if smallest else (x > best):
                best, where = x, label
    return (best, where) if where is not None else (math.nan, None)


def build_program(
    design: Design,
    ts: TrajectorySet,
    anatomy: Any,
    mode: NDArray[np.float64],
    order: str,
    limits: ProgramLimits,
    body: Body,
    planner: Planner,
    log: Callable[[str], None] | None = None,
    masses: MassModel | None = None,
    loads: Loads | None = None,
    engine: str = "numpy",
    envelope: Any = None,
) -> Program:
    """The program of ``design`` for the plan ``ts`` (model §17); InputError naming the segment if none exists.

    With ``masses`` (model §18.1) the rows get the actuator torques of 18.2 and the summary the motor
    figures of 18.3 (``loads``: the drilling thrust and lateral bound of 15.3, default :class:`Loads`).
    ``engine``: ``numpy`` or ``numba``, the continuous check's (:class:`~arcube.motion.check.Checker`).
    ``envelope``: the envelope of the whole patient (model §19.5) the body clears by ``limits.envelope_clearance``
    everywhere, or None.
    """
    b = _Builder(design, ts, anatomy, mode, limits, body, planner, log or (lambda _: None), engine, envelope)
    b.check_lines()
    seq, order_method = b.choose_order(order)
    blocks: list[tuple[str, str, dict[str, Any]]] = []  # (segment, trajectory label, rows)
    per_traj, transits = [], []
    checked: list[tuple[StateChecks, str, bool]] = [(line.checks, line.tid, False) for line in b.lines]  # type: ignore[misc]
    for pos, j in enumerate(seq):
        line = b.lines[j]
        info: dict[str, Any] = {
            "trajectory": line.tid,
            "level": ts.levels[j],
            "side": ts.sides[j],
            "standoff_mm": line.depth,
            "exit_depth_mm": line.depth - limits.standoff_mm,
            "drilled_mm": line.length,
        }
        for piece, rows in b.line_rows(line):
            blocks.append((piece.kind, line.tid, rows))
            info[f"{piece.kind}_s"] = float(rows["t"][-1])
            check_total(limits, sum(len(r["t"]) for _, _, r in blocks), piece.kind)
        per_traj.append(info)
        if pos + 1 < len(seq):
            tr, rows_list, duration = b.transit(j, seq[pos + 1])
            label = f"{line.tid}->{b.lines[seq[pos + 1]].tid}"
            transits.append(
                {
                    "from": line.tid,
                    "to": b.lines[seq[pos + 1]].tid,
                    "duration_s": duration,
                    "method": tr.method,
                    "waypoints": tr.waypoints,
                    "pieces": len(tr.pieces),
                    "planner_s": tr.planner_s,
                    "straight_blocked_by": None if tr.blocked is None else str(tr.blocked.reason[tr.blocked_index]),
                }
            )
            blocks += [("transit", label, rows) for rows in rows_list]
            check_total(limits, sum(len(r["t"]) for _, _, r in blocks), "transit")
            checked += [(piece.checks, label, True) for piece in tr.pieces]
    prog = _program(b, seq, order_method, blocks, per_traj, transits, checked)
    prog = dataclasses.replace(
        prog, summary={**prog.summary, "clearances_along_time": clearances_along_time(prog, b.checker)}
    )
    return prog if masses is None else with_torques(prog, b.checker.params, b.mode, masses, loads or Loads())


SERIES_ROWS = 2000
"""At most this many rows (evenly spaced, the last included) carry the clearances along time."""


def clearances_along_time(prog: Program, checker: Checker) -> dict[str, list[float | None]]:
    """The body, tool and self clearances (mm) at up to :data:`SERIES_ROWS` rows of ``prog``, for the report's
    plot over time (the tool's in transits only, NaN elsewhere; the body's NaN without anatomy). The
    constraints themselves are checked on the finer states of 17.2; these rows only draw them."""
    n = len(prog.t_s)
    idx = np.unique(np.append(np.arange(0, n, max(1, math.ceil(n / SERIES_ROWS))), n - 1))
    transit = prog.segment[idx] == "transit"
    clear, tool, selfc = (np.full(len(idx), np.nan) for _ in range(3))
    for mask, with_tool in ((transit, True), (~transit, False)):
        if mask.any():
            c = checker.poses(prog.E[idx[mask]], prog.e[idx[mask]], tool=with_tool)
            clear[mask], tool[mask], selfc[mask] = c.clearance, c.tool_clearance, c.self_clearance
    as_list = lambda a: [float(v) if math.isfinite(v) else None for v in a]  # noqa: E731
    return {
        "t_s": as_list(prog.t_s[idx]),
        "clearance_mm": as_list(clear),
        "tool_clearance_mm": as_list(tool),
        "self_clearance_mm": as_list(selfc),
    }


def with_torques(
    prog: Program, params: NDArray[np.float64], mode: NDArray[np.float64], masses: MassModel, loads: Loads
) -> Program:
    """``prog`` with its actuator torques per row (18.2) and its motor figures (18.3) in the summary."""
    tq = program_torques(
        params,
        prog.E,
        prog.e,
        mode,
        float(prog.summary["dt_s"]),
        prog.segment == "drill",
        masses,
        loads.thrust_N,
        loads.lateral_force_N,
    )
    summary = dict(prog.summary)
    summary["motors"] = motor_figures(prog.t_s, np.radians(prog.q_dot_deg), tq, JOINTS)
    summary["masses"] = {**dataclasses.asdict(masses), "moving_mass_kg": float(moving_mass_kg(params, masses))}
    summary["loads"] = {"thrust_N": loads.thrust_N, "lateral_force_N": loads.lateral_force_N}
    return dataclasses.replace(prog, tau_Nm=tq.tau_Nm, summary=summary)


def _program(
    b: _Builder,
    seq: list[int],
    order_method: str,
    blocks: list[tuple[str, str, dict[str, Any]]],
    per_traj: list[dict[str, Any]],
    transits: list[dict[str, Any]],
    checked: list[tuple[StateChecks, str, bool]],
) -> Program:
    lim = b.limits
    parts: dict[str, list[Any]] = {k: [] for k in ("E", "e", "q", "qd", "seg", "traj")}
    step = 0
    starts = []
    for i, (seg, label, rows) in enumerate(blocks):
        # a piece's last row is the next one's first: it belongs to the piece that ends there, so that every segment
        # ends exactly where it should (the approach at A, the drill at B, the retract at the standoff)
        first = 0 if i == 0 else 1
        n = len(rows["t"]) - first
        starts.append(step)
        for k in ("E", "e", "q", "qd"):
            parts[k].append(rows[k][first:])
        parts["seg"] += [seg] * n
        parts["traj"] += [label] * n
        step += len(rows["t"]) - 1
    q = np.concatenate(parts["q"])
    q[:, 3:] = np.unwrap(q[:, 3:], axis=0)
    qd = np.concatenate(parts["qd"])
    t = np.arange(len(q)) * lim.dt
    seg = np.array(parts["seg"])
    total = float(t[-1])
    times = {
        k: float(np.sum(np.diff(t)[seg[1:] == k])) for k in ("approach", "drill", "retract", "transit")
    }  # a step is its end row's
    kinds = [blk[0] for blk in blocks]
    traj_starts = [starts[i] * lim.dt for i, k in enumerate(kinds) if k == "approach"]
    for info, start in zip(per_traj, traj_starts):
        info["start_s"] = start
    tr_starts = [
        starts[i] * lim.dt for i, k in enumerate(kinds) if k == "transit" and (i == 0 or kinds[i - 1] != "transit")
    ]
    for info, start in zip(transits, tr_starts):
        info["start_s"] = start
    E = np.concatenate(parts["E"])
    accel = np.abs(np.diff(qd, axis=0)) / lim.dt
    in_transit = seg == "transit"
    tip = np.linalg.norm(np.diff(E, axis=0), axis=-1) / lim.dt
    clear = _extreme([(c.clearance, lab) for c, lab, _ in checked], True)
    tool = _extreme([(c.tool_clearance, lab) for c, lab, is_tr in checked if is_tr], True)
    selfc = _extreme([(c.self_clearance, lab) for c, lab, _ in checked], True)
    envc = _extreme([(c.envelope_clearance, lab) for c, lab, _ in checked], True)
    eta = _extreme([(c.eta, lab) for c, lab, _ in checked], False)
    summary: dict[str, Any] = {
        "order": [b.lines[j].tid for j in seq],
        "order_method": order_method,
        "total_s": total,
        "drilling_s": times["drill"],
        "approach_s": times["approach"],
        "retract_s": times["retract"],
        "transit_s": times["transit"],
        "rows": len(t),
        "dt_s": lim.dt,
        "mode": b.mode_text,
        "assembly_signs": [int(v) for v in b.checker.assembly],  # type: ignore[union-attr]
        "trajectories": per_traj,
        "transits": transits,
        "clearance_min_mm": clear[0],
        "clearance_min_at": clear[1],
        "tool_clearance_min_mm": tool[0],
        "tool_clearance_min_at": tool[1],
        "self_clearance_min_mm": selfc[0],
        "self_clearance_min_at": selfc[1],
        "eta_L_max": eta[0],
        "eta_L_max_at": eta[1],
        **(
            {"envelope_clearance_min_mm": envc[0], "envelope_clearance_min_at": envc[1], "envelope": b.envelope_source}
            if b.envelope_source is not None
            else {}
        ),
        "joint_speed_max_deg_s": {j: float(np.degrees(np.max(np.abs(qd[:, i])))) for i, j in enumerate(JOINTS)},
        "joint_accel_max_deg_s2": {
            j: float(np.degrees(np.max(accel[:, i], initial=0.0))) for i, j in enumerate(JOINTS)
        },
        "tip_speed_max_transit_mm_s": float(np.max(tip[in_transit[:-1] & in_transit[1:]], initial=0.0)),
        "checked_states": int(b.checker.calls),
        "resolution_mm": RESOLUTION_MM,
        "check_engine": b.checker.engine,
        "timing": "toppra (TOPP-RA, time-optimal on the checked grid; rows verified, retimed if a limit is exceeded)",
        "limits": lim.model_dump(),
        "planner": {"name": "OMPL RRTConnect + PathSimplifier", **b.planner.model_dump()},
        "anatomy": b.anatomy_source,
        "plan": b.ts.source,
        "design": b.design.to_file_dict(),
        "body": b.checker.body.model_dump(),
    }
    q_deg = np.degrees(q)
    if b.design.q0_deg is not None:  # model §21.4: a calibrated design commands IK - q0 (the encoders then read it)
        q_deg = q_deg - b.design.q0
        summary["q0_deg"] = dict(zip(JOINTS, b.design.q0.tolist()))
    return Program(t, seg, np.array(parts["traj"]), E, np.concatenate(parts["e"]), q_deg, np.degrees(qd), summary)
