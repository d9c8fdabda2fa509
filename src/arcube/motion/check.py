"""The continuous check of model §17.2, NumPy reference: is a state of the program allowed?

A state is a pose (E, e) on a line segment, or a joint vector q = (rho_x, rho_y, rho_z, delta_x,
delta_y) (rad) in a transit, whose pose is the forward kinematics of q in the program's assembly
mode (the first state's signs of H_x, H_y and det[x_beta, y_beta, e]). At a state:

1. the inverse kinematics solves the pose in the design's working mode (failures as
   :data:`arcube.evaluation.reference.FAILURES` names them: ``TLS/x``, ``TMS/y``, ``singular/...``);
   for a joint state, q also assembles (``FK/assembly``) and the IK of its pose gives q back
   (``IK/working_mode``: else q is in another working mode); with the design's own c_z (model §19.2)
   the z dyad closes (``guard/z_dyad``), and the body's ``zdyad`` is the closed dyad D_z -> J_z -> Q_z;
2. the assembly signs are the program's (``guard/assembly_mode``): no Type-2 singularity is crossed;
3. eta_L <= kappa_max (``guard/kappa_max``);
4. the body (model §14.1, without the tool) clears the anatomy by c_min (``collision/patient``)
   and itself by c_self (``collision/self``);
5. in transit only, the tool (segment E -> H, radius rho_t) clears the anatomy by >= 0
   (``collision/tool``).

Clearances are those of :mod:`arcube.evaluation.clearance` (the reference's functions, axes sampled
every ``step`` mm). ``margin`` (mm) is added to every clearance limit: the planner checks coarser
states (:data:`PLANNING_RESOLUTION_MM` apart, axes every :data:`PLANNING_STEP_MM`) against limits
raised to match (:meth:`Checker.coarse`), so what it accepts passes the fine check too (a distance is
1-Lipschitz).

**Compiled** (``engine="numba"``): the condition numbers and both body clearances come from the
kernel (:func:`arcube.evaluation.kernel.evaluate_task_numba`); the IK's branch and assembly signs,
the tool clearance and the points that measure the resolution stay NumPy (cheap next to the
clearances). eta_L and the self clearance equal the reference's to rounding. The kernel's body
clearance is a branch-and-bound minimum at most ``TOL_MM`` (0.1 mm) above the exact one, so the
check takes it less ``TOL_MM``: a lower bound, where the reference's samples every 0.25 mm give an
upper bound; the compiled check is the stricter, by at most both. Calls of fewer than 16 states use
the reference (the kernel's per-call set-up costs more than it saves there).

:func:`refine` samples a path so that no point of the body or the tool moves more than
:data:`~arcube.motion.limits.RESOLUTION_MM` between two consecutive checked states (model §17.2).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.evaluation.clearance import SAMPLE_STEP_MM, Distance, anatomy_clearance, self_clearance
from arcube.evaluation.envelope_clearance import envelope_clearance
from arcube.evaluation.indices import JACOBIAN_NAMES, condition_numbers
from arcube.model.body import BodyParts, body_parts, great_circle, mechanism_points
from arcube.model.mechanism import forward_kinematics, inverse_kinematics
from arcube.options import Body, Guards, Options, Outputs
from arcube.motion.limits import RESOLUTION_MM, ProgramLimits

__all__ = ["Checker", "PLANNING_RESOLUTION_MM", "StateChecks", "displacement", "refine"]

PLANNING_RESOLUTION_MM = 2.0
"""The planner's states: no body or tool point moves more than this between two of them (at most;
see :meth:`Checker.coarse`), and its samples along the body's axes (the reference: 0.25 mm)."""
_Q_TOL = 1e-7
"""rad: a joint state and the IK of its pose agree to this (else it is in another working mode)."""
_KERNEL_MIN_STATES = 16
"""With ``engine="numba"``, fewer states per call are checked by the reference: the kernel's per-call set-up
costs more than it saves there (one state per call, e.g. OMPL's validity checks: measured by
benchmarks/bench_program.py)."""
_STAGES = (("TLS", "xyz", "tls_arg"), ("RTS", "xy", "rts_arg"), ("TMS", "xy", "tms_arg"))


class StateChecks(NamedTuple):
    """The check of n states; every field has n rows (NaN where a value does not exist)."""

    ok: NDArray[np.bool_]  # (n,)
    reason: NDArray[np.object_]  # (n,) the first constraint that fails ('' where ok)
    E: NDArray[np.float64]  # (n, 3) drill tip, R_w, mm
    e: NDArray[np.float64]  # (n, 3) drill axis
    q: NDArray[np.float64]  # (n, 5) the IK's joints in the working mode, rad
    assembly: NDArray[np.float64]  # (n, 3) signs of H_x, H_y, det[x_b, y_b, e]
    eta: NDArray[np.float64]  # (n,) eta_L (inf at a singularity)
    clearance: NDArray[np.float64]  # (n,) body to anatomy, mm (NaN without anatomy)
    tool_clearance: NDArray[np.float64]  # (n,) tool to anatomy, mm (NaN without anatomy or off the transits)
    self_clearance: NDArray[np.float64]  # (n,) mm
    envelope_clearance: NDArray[np.float64]  # (n,) body to the envelope of model §19.5, mm (NaN without an envelope)
    points: NDArray[np.float64]  # (n, K, 3) body and tool points, for the resolution of 17.2

    def take(self, index: ArrayLike) -> StateChecks:
        """The states at ``index``."""
        return StateChecks(*(f[index] for f in self))

    @staticmethod
    def concat(parts: list[StateChecks]) -> StateChecks:
        """The states of ``parts``, one after another."""
        return StateChecks(*(np.concatenate(fields, axis=0) for fields in zip(*parts)))

    def describe(self, i: int, limits: ProgramLimits) -> str:
        """``collision/patient at E = (x, y, z) mm (clearance 1.2 mm < 5)``: state i's failure, one line."""
        reason = str(self.reason[i])
        where = (
            "E = (" + ", ".join(f"{v:.2f}" for v in self.E[i]) + ") mm"
            if np.all(np.isfinite(self.E[i]))
            else "this joint state"
        )
        detail = {
            "guard/kappa_max": f"eta_L {self.eta[i]:.4g} > {limits.kappa_max:g}",
            "guard/z_dyad": "the z dyad (d_z, c_z) cannot span D_z -> Q_z",
            "collision/patient": f"clearance {self.clearance[i]:.3g} mm < {limits.clearance:g}",
            "collision/self": f"self clearance {self.self_clearance[i]:.3g} mm < {limits.self_clearance:g}",
            "collision/tool": f"tool clearance {self.tool_clearance[i]:.3g} mm < 0",
            "collision/envelope": f"envelope clearance {self.envelope_clearance[i]:.3g} mm < {limits.envelope_clearance:g}",
        }.get(reason)
        return f"{reason} at {where}" + (f" ({detail})" if detail else "")


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class Checker:
    """The constraints of model §17.2 for one design, working mode and anatomy.

    ``assembly`` (3,) is the program's assembly mode (None: not checked, and :meth:`joints` refuses
    to run; the caller fixes it from the program's first state). ``step`` and ``margin`` as in the
    module docstring.
    """

    def __init__(
        self,
        params: ArrayLike,
        mode: ArrayLike,
        limits: ProgramLimits,
        body: Body = Body(),
        distance: Distance | None = None,
        assembly: ArrayLike | None = None,
        *,
        step: float = SAMPLE_STEP_MM,
        margin: float = 0.0,
        engine: str = "numpy",
        envelope: Any = None,
        c_z: float | None = None,
    ) -> None:
        if engine not in ("numpy", "numba"):
            raise ValueError(f"engine must be numpy or numba, got {engine!r}")
        self.engine = engine
        self.c_z = None if c_z is None else float(c_z)  # the design's own z dyad (model §19.2): closed at every state
        self.params = np.asarray(params, dtype=float)
        self.mode = np.asarray(mode, dtype=float)
        self.limits, self.body, self.distance, self.envelope = limits, body, distance, envelope
        self.assembly = None if assembly is None else np.asarray(assembly, dtype=float)
        self.step, self.margin = float(step), float(margin)
        self.resolution = RESOLUTION_MM  # no body or tool point moves more than this between two checked states
        self.calls = 0  # states checked so far

    def coarse(self, ends: StateChecks | None = None) -> Checker:
        """The planner's checker: states ``resolution`` mm apart, axes sampled every ``resolution`` mm, and
        every clearance limit raised by ``resolution`` (half a state's move, half a sample step; for the
        self clearance, two parts each moving half a state's move). The resolution is
        :data:`PLANNING_RESOLUTION_MM`, or less when the transit's two ends (``ends``, checked finely)
        are closer to a limit, down to 17.2's own 0.5 mm."""
        res = PLANNING_RESOLUTION_MM
        if ends is not None:
            lim = self.limits
            slack = [ends.self_clearance - lim.self_clearance]
            if self.distance is not None:
                slack += [ends.clearance - lim.clearance, ends.tool_clearance]
            if self.envelope is not None:
                slack += [ends.envelope_clearance - lim.envelope_clearance]
            least = float(np.nanmin(np.concatenate(slack)))
            res = float(np.clip(0.9 * least, RESOLUTION_MM, PLANNING_RESOLUTION_MM))
        out = Checker(
            self.params,
            self.mode,
            self.limits,
            self.body,
            self.distance,
            self.assembly,
            step=res,
            margin=res,
            engine=self.engine,
            envelope=self.envelope,
            c_z=self.c_z,
        )
        out.resolution = res
        return out

    def poses(self, E: ArrayLike, e: ArrayLike, tool: bool = False) -> StateChecks:
        """Check poses (E ``(n, 3)``, unit e ``(n, 3)`` or ``(3,)``); the tool too where ``tool``."""
        E = np.atleast_2d(np.asarray(E, dtype=float))
        e = np.broadcast_to(np.asarray(e, dtype=float), E.shape)
        n = len(E)
        self.calls += n
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = inverse_kinematics(self.params, E, e, self.mode)
            mp = mechanism_points(self.params, E, e, c_z=self.c_z, motor_length=self.body.motor_length, sol=sol)
            clear = tool_clear = env = np.full(n, np.nan)
            if self.engine == "numba" and n >= _KERNEL_MIN_STATES:
                kappa, clear_k, selfc, env = self._compiled(E, e)
                clear = clear if self.distance is None else clear_k
            else:
                kappa = condition_numbers(sol, self.params)
                parts = body_parts(mp, self.body.radii)
                selfc = self_clearance(parts)
                if self.distance is not None:
                    clear = self._body_clearance(parts)
                if self.envelope is not None:
                    env = envelope_clearance(parts, self.envelope).clearance
            eta = np.max(np.where(np.isnan(kappa), np.inf, kappa), axis=-1)
            if self.distance is not None:
                if tool:
                    tool_clear = self._tool_clearance(mp.E, mp.H)
        q = np.concatenate([sol.rho, sol.delta], axis=-1)
        asm = sol.assembly
        reason = np.full(n, "", dtype=object)
        lim, m = self.limits, self.margin
        checks: list[tuple[str, NDArray[np.bool_]]] = []
        for name, legs, field in _STAGES:
            arg = getattr(sol, field)
            checks += [(f"{name}/{leg}", ~(np.abs(arg[..., i]) <= 1.0)) for i, leg in enumerate(legs)]
        checks += [(f"singular/{name}", ~np.isfinite(kappa[..., i])) for i, name in enumerate(JACOBIAN_NAMES)]
        if self.c_z is not None:  # model §19.2: a z leg that can be assembled, at every state
            checks.append(("guard/z_dyad", ~np.asarray(mp.z_closes)))
        checks += [
            (
                "guard/assembly_mode",
                np.any(asm != self.assembly, axis=-1) if self.assembly is not None else np.zeros(n, bool),
            ),
            ("guard/kappa_max", ~(eta <= lim.kappa_max)),
            ("collision/self", ~(selfc >= lim.self_clearance + m)),
        ]
        if self.envelope is not None:  # model §19.5, checked after the body's own clearances
            checks.append(("collision/envelope", ~(env >= lim.envelope_clearance + m)))
        if self.distance is not None:
            checks.insert(-1, ("collision/patient", ~(clear >= lim.clearance + m)))
            if tool:
                checks.append(("collision/tool", ~(tool_clear >= m)))
        for name, failed in reversed(checks):
            reason = np.where(failed, name, reason)
        points = np.concatenate(
            [
                mp.P,
                mp.D,
                mp.Q,
                mp.K,
                mp.T,
                mp.J_z[:, None],
                mp.B,
                mp.H[:, None],
                mp.arc_alpha.reshape(n, -1, 3),
                mp.arc_beta.reshape(n, -1, 3),
                mp.E[:, None],
                mp.drill_end[:, None],
            ],
            axis=1,
        )
        return StateChecks(reason == "", reason, mp.E, mp.e, q, asm, eta, clear, tool_clear, selfc, env, points)

    def _compiled(self, E: NDArray[np.float64], e: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """(kappa ``(n, 7)``, clearance ``(n,)``, self clearance ``(n,)``, envelope clearance ``(n,)``) of poses
        from the compiled kernel."""
        from arcube.evaluation.kernel import evaluate_task_numba
        from arcube.evaluation.kernel._clearance import TOL_MM

        outputs = Outputs(clearances=True, anatomy_clearance=self.distance is not None, tip_metrics=False)
        guards = Guards() if self.c_z is None else Guards(c_z=self.c_z)  # the body's z dyad is the design's
        ok = np.all(np.isfinite(E), axis=-1) & np.all(np.isfinite(e), axis=-1)
        kappa, clear, selfc, env = (
            np.full((len(E), 7), np.nan),
            np.full(len(E), np.nan),
            np.full(len(E), np.nan),
            np.full(len(E), np.nan),
        )
        if ok.any():
            pts = evaluate_task_numba(
                self.params,
                E[ok],
                e[ok],
                self.mode,
                Options(guards=guards, body=self.body, outputs=outputs),
                anatomy=self.distance,
                envelope=self.envelope,
            ).points
            kappa[ok], clear[ok], selfc[ok] = pts.kappa, pts.clearance_mm - TOL_MM, pts.self_clearance_mm
            if (
                self.envelope is not None
            ):  # a skin mesh is searched as the anatomy is: its tolerance below, as the clearance's
                env[ok] = pts.envelope_clearance_mm - (TOL_MM if self.envelope.skin else 0.0)
        return kappa, clear, selfc, env

    def _body_clearance(self, parts: BodyParts) -> NDArray[np.float64]:
        """The body's clearance to the anatomy: the reference's :func:`anatomy_clearance` at the default
        step; at a coarser step (the planner) the same samples (every ``step`` mm along each axis, both ends)
        in one batched lookup, which is much faster for a few states."""
        if self.step == SAMPLE_STEP_MM:
            return anatomy_clearance(parts, self.distance, self.step)[0]  # type: ignore[arg-type]
        seg = parts.segments  # (n, S, 2, 3)
        k = (
            max(
                int(
                    np.ceil(
                        np.nanmax(np.linalg.norm(seg[..., 1, :] - seg[..., 0, :], axis=-1), initial=0.0) / self.step
                    )
                ),
                1,
            )
            + 1
        )
        f = np.linspace(0.0, 1.0, k)[:, None]
        seg_pts = seg[..., None, 0, :] + f * (seg[..., None, 1, :] - seg[..., None, 0, :])  # (n, S, k, 3)
        ends = parts.arc_ends
        angle = np.arccos(np.clip(np.sum(ends[..., 0, :] * ends[..., 1, :], axis=-1), -1.0, 1.0))
        ka = max(int(np.ceil(np.nanmax(parts.arc_radius[..., None] * angle, initial=0.0) / self.step)), 1) + 1
        arc_pts = parts.arc_centre[:, None, None, :] + parts.arc_radius[:, None, None, None] * great_circle(
            ends[..., 0, :], ends[..., 1, :], ka
        )
        n = len(seg)
        sizes = (seg_pts.shape[1] * k, parts.spheres.shape[1], arc_pts.shape[1] * ka)
        pts = np.concatenate([seg_pts.reshape(n, -1, 3), parts.spheres, arc_pts.reshape(n, -1, 3)], axis=1)
        bad = ~np.all(np.isfinite(pts), axis=-1)
        d = np.where(bad, np.nan, self.distance(np.where(bad[..., None], 0.0, pts)))  # type: ignore[misc]
        a, b = sizes[0], sizes[0] + sizes[1]
        per = np.concatenate(
            [d[:, :a].reshape(n, -1, k).min(axis=-1), d[:, a:b], d[:, b:].reshape(n, -1, ka).min(axis=-1)], axis=1
        )
        return np.min(per - parts.radius, axis=-1)

    def _tool_clearance(self, E: NDArray[np.float64], H: NDArray[np.float64]) -> NDArray[np.float64]:
        """Smallest distance of the tool's axis E -> H (sampled every ``step`` mm) to the anatomy, minus rho_t."""
        length = np.nanmax(np.linalg.norm(H - E, axis=-1), initial=0.0)
        k = max(int(np.ceil(length / self.step)), 1) + 1
        frac = np.linspace(0.0, 1.0, k)
        pts = E[:, None, :] + frac[None, :, None] * (H - E)[:, None, :]
        bad = ~np.all(np.isfinite(pts), axis=-1)
        d = self.distance(np.where(bad[..., None], 0.0, pts))  # type: ignore[misc]
        return np.min(np.where(bad, np.nan, d), axis=-1) - self.limits.tool_radius

    def pose_of(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """(E, e, assembles) of joint states q ``(n, 5)`` rad, by the FK in the program's assembly mode."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        with np.errstate(invalid="ignore", divide="ignore"):
            fk = forward_kinematics(self.params, q[:, :3], q[:, 3:], self.assembly)
        return fk.E, fk.e, fk.valid & np.all(np.isfinite(fk.E), axis=-1)

    def joints(self, q: ArrayLike, tool: bool = True) -> StateChecks:
        """Check joint states q ``(n, 5)`` rad: FK -> pose -> :meth:`poses`, then the IK must give q back."""
        if self.assembly is None:
            raise ValueError("the program's assembly mode is not fixed yet: check a pose first")
        q = np.atleast_2d(np.asarray(q, dtype=float))
        E, e, valid = self.pose_of(q)
        E = np.where(valid[:, None], E, np.nan)
        e = np.where(valid[:, None], _unit(np.where(valid[:, None], e, 1.0)), np.nan)
        out = self.poses(E, e, tool)
        diff = np.abs(out.q - q)
        diff[:, 3:] = np.abs(np.angle(np.exp(1j * (out.q[:, 3:] - q[:, 3:]))))  # delta modulo 2 pi
        same = np.all(diff <= _Q_TOL, axis=-1)
        reason = np.where(~valid, "FK/assembly", np.where(out.ok & ~same, "IK/working_mode", out.reason))
        return out._replace(ok=reason == "", reason=reason.astype(object), q=np.where(valid[:, None], q, np.nan))


def displacement(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n - 1,)``: the largest move of a body or tool point between consecutive states (NaN points ignored)."""
    d = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    return np.max(np.where(np.isfinite(d), d, 0.0), axis=-1) if len(d) else np.zeros(0)


def refine(
    evaluate: Callable[[NDArray[np.float64]], StateChecks],
    s0: float,
    s1: float,
    limit: float = RESOLUTION_MM,
    n0: int = 9,
    stop_on_failure: bool = False,
    max_states: int = 200_000,
) -> tuple[NDArray[np.float64], StateChecks]:
    """States s in [s0, s1] of a path so close that no body or tool point moves more than ``limit``
    between two of them; ``evaluate(s)`` checks a batch. Intervals that move more are split
    (into as many equal parts as their move needs) until none does.

    With ``stop_on_failure`` the refinement stops at the first round that finds a failing state.
    Returns the sorted s and their checks.
    """
    s = np.linspace(s0, s1, max(n0, 2))
    checks = evaluate(s)
    while True:
        if stop_on_failure and not checks.ok.all():
            return s, checks
        move = displacement(checks.points)
        over = np.flatnonzero(move > limit)
        if not len(over):
            return s, checks
        if len(s) > max_states:
            raise RuntimeError(
                f"refine: more than {max_states} states needed (a point moves {move.max():.3g} mm per state)"
            )
        parts = np.ceil(move[over] / limit * 1.05).astype(int)  # a little more: the move is not exactly linear in s
        new = np.concatenate([s[i] + (s[i + 1] - s[i]) * np.arange(1, k) / k for i, k in zip(over, parts)])
        added = evaluate(new)
        s_all = np.concatenate([s, new])
        order = np.argsort(s_all, kind="stable")
        s, checks = s_all[order], StateChecks.concat([checks, added]).take(order)
