"""A simulation model of any design: the mechanism as MuJoCo MJCF (XML), assembled at one task point.

:func:`export_mjcf` writes one body per rigid link of MODEL.md 3-6 and 14.1, joined by hinges at the
model's joint points and about the model's axes (mechanism axes turned into the patient frame by the
mounting rotation R, MODEL.md 13), with the three loops of the mechanism closed by ``<connect>``
equality constraints. Lengths are in mm, angles in rad, masses in kg (links of density 1e-6 kg/mm^3,
about water), time in s; gravity is -9810 mm/s^2 along z of the patient frame (posterior is up with
the patient prone).

Body tree (every body frame is parallel to the patient frame in the assembled pose; hinge angle =
the model's angle, thanks to each hinge's ``ref``)::

    base (static: frame links O -> P_u, actuators at P_u)
    |- crank_u          hinge rho_u   at P_u about -v_u  (u = x, y, z; positive rho turns about -v, MODEL.md 3.1)
    |  `- knee_u        hinge kappa_u at D_u about +v_u  (passive, kappa_u = rho_u: keeps the distal chain planar)
    |     |- input_u    hinge delta_u at D_u about u     (u = x, y; n(delta) from -w toward +v, MODEL.md 4.1)
    |     |  `- coupler_u  hinge gamma_u at K_u about u  (passive: coupler direction minus delta_u)
    |     `- zdyad_d    hinge zdyad_D at D_z about z_m   (z leg only, MODEL.md 6; angle of J_z - D_z from x_m)
    |        `- zdyad_c hinge zdyad_J at J_z about z_m   (relative angle of Q_z - J_z to J_z - D_z)
    |           `- platform  hinge zdyad_Q at Q_z about z_m  (carries Q_x, Q_y, Q_z and the centre C)
    |              `- output_u  hinge sigma_u at Q_u about u  (four-bar output t_u, MODEL.md 4.1; u = x, y)
    |                 `- alpha_u  (welded to output_u: the TMS output and the RTS input are one link, 5.1)
    |                    `- beta_u  hinge tau_u at B_u = C + r u_beta about u_beta (passive, dihedral angle)
    |                       `- drill (welded to beta_x only): sites ``tip`` at E and ``holder`` at H = C + r e

Loop closures (``<equality>``, each a ``connect``: a point of body1, given by ``anchor``, held on the
same point of body2, which the compiler takes from the assembled pose; the sites of the same names
mark the points):

* ``close_T_u`` and ``close_T_u_axis`` (u = x, y): the coupler_u's tip onto the output_u's tip, at T_u
  and at T_u + a û (a = :data:`PIN_MM`): two points on the hinge axis make the revolute joint at T_u
  (a single point would leave the platform free to turn about ŵ_u);
* ``close_H``: the distal spherical link beta_y onto the drill at H. Both bodies already turn about
  C (every spherical axis passes through C), so one common point H makes the hinge about e.

17 hinges, 12 independent constraint equations (15 rows, 3 redundant): 5 degrees of freedom,
driven by the five position actuators ``rho_x, rho_y, rho_z, delta_x, delta_y`` (targets in rad,
the model's angles; stiffness :data:`KP`, with the damping :data:`KV` on the actuated joints). The
keyframe ``assembled`` holds the pose and the actuator targets at ``at``; load it
(``mujoco.mj_resetDataKeyframe(model, data, 0)``) before simulating, because MuJoCo starts with every
control at 0. No geom collides (contype 0); the anatomy, when given, is drawn only.

Accuracy (tests/test_mjcf.py): with every hinge set from the IK, MuJoCo's forward kinematics puts the
tip on E and every closure at rest to ~1e-12 mm; driven by the five actuators with gravity off, the
tip settles on E to ~1e-5..1e-2 mm within 0.3 s per point. With gravity on, the finite servo
stiffness and the soft constraints let the mechanism sag by a few tenths of a millimetre.

Long module: one MJCF body-tree builder, with the docstring that documents the body tree and its loop closures.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.model import frames
from arcube.model.body import U_HAT, V_HAT, W_HAT, BodyRadii, mechanism_points
from arcube.model.design import Design, unpack
from arcube.model.mechanism import format_mode, inverse_kinematics, parse_mode

__all__ = [
    "ACTUATED",
    "JOINT_NAMES",
    "export_mjcf",
    "joint_values",
    "z_dyad_range",
]

ACTUATED: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated hinges (and their position actuators), in the order of MODEL.md 7.4."""

JOINT_NAMES: tuple[str, ...] = (
    "rho_x", "kappa_x", "delta_x", "gamma_x",
    "rho_y", "kappa_y", "delta_y", "gamma_y",
    "rho_z", "kappa_z", "zdyad_D", "zdyad_J", "zdyad_Q",
    "sigma_x", "tau_x", "sigma_y", "tau_y",
)  # fmt: skip
"""Every hinge of the exported model, in the order of ``qpos`` (depth-first body tree)."""

PIN_MM = 100.0
"""Distance between the two points of a hinge closure along its axis (close_T_u, close_T_u_axis), mm: the
wider apart, the stiffer MuJoCo's soft constraint holds the hinge's direction."""

KP = 1.0e8
"""Stiffness of the position actuators, kg mm^2 / s^2 per rad (= 100 N m/rad)."""
KV = 1.0e6
"""Damping of the actuated joints, kg mm^2 / s per rad (= 1 N m s/rad): the servo's velocity gain."""

_COLORS = {
    "base": "0.35 0.35 0.40 1", "actuator": "0.15 0.15 0.18 1", "tls": "0.30 0.45 0.75 1",
    "tms": "0.90 0.55 0.15 1", "zdyad": "0.60 0.40 0.80 1", "platform": "0.80 0.80 0.30 1",
    "rts": "0.25 0.70 0.40 1", "tool": "0.85 0.85 0.90 1", "motor": "0.20 0.20 0.25 1",
    "anatomy": "0.95 0.85 0.75 0.35",
}  # fmt: skip


_FLOAT_MAX = float(np.finfo(float).max)


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles into (-pi, pi]."""
    return -np.remainder(np.pi - a, 2.0 * np.pi) + np.pi


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sum(a * b, axis=-1)


def _params(design: Design | ArrayLike) -> NDArray[np.float64]:
    return Design.coerce(design).to_vector()


def _signs(mode: str | ArrayLike) -> NDArray[np.float64]:
    if isinstance(mode, str):
        try:
            return parse_mode(mode)
        except ValueError as exc:
            problem = str(exc).removeprefix("working mode ")  # "must be four signs ..., got '...'"
            raise InputError.of("mode", problem) from None
    return np.asarray(mode, dtype=float)


def _axes_world(params: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(û, v̂, ŵ) of legs x, y, z in R_w, each ``(3 legs, 3)``, and R ``(3, 3)`` (one design)."""
    R = frames.mount_rotation(unpack(params))
    return U_HAT @ R.T, V_HAT @ R.T, W_HAT @ R.T, R


def joint_values(
    design: Design | ArrayLike, E: ArrayLike, e: ArrayLike, mode: str | ArrayLike = "+,+,+,+", *, c_z: float | None = None,
) -> dict[str, NDArray[np.float64]]:  # fmt: skip
    """Every hinge angle of the exported model (rad) at poses (E, e) in R_w, from the IK; each ``(...)``.

    Keys are :data:`JOINT_NAMES`. Actuated hinges are the model's rho_u, delta_u; ``sigma_u`` is the
    model's sigma_u; ``kappa_u`` = rho_u (the knee that keeps the planar chain parallel); ``gamma_u``
    is the coupler's angle minus delta_u (about û); ``tau_u`` the dihedral angle at u_beta from the
    great circle toward û to the one toward e (about u_beta); ``zdyad_D`` the angle of J_z - D_z from
    x_m toward y_m, ``zdyad_J`` that of Q_z - J_z minus it, ``zdyad_Q`` minus the angle of Q_z - J_z.
    NaN where the IK (or the z dyad) has no solution. One design, poses broadcast.
    """
    params = _params(design)
    signs = _signs(mode)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, signs)
        mp = mechanism_points(params, E, e, signs, c_z=c_z, sol=sol)
    U, V, W, R = _axes_world(params)
    out: dict[str, NDArray[np.float64]] = {}
    for i, u in enumerate("xyz"):
        out[f"rho_{u}"] = sol.rho[..., i]
        out[f"kappa_{u}"] = sol.rho[..., i]
    ub_w = sol.u_beta @ R.T  # (..., 2, 3)
    for i, u in enumerate("xy"):
        out[f"delta_{u}"] = sol.delta[..., i]
        ct = mp.T[..., i, :] - mp.K[..., i, :]
        phi = np.arctan2(_dot(ct, V[i]), -_dot(ct, W[i]))
        out[f"gamma_{u}"] = _wrap(phi - sol.delta[..., i])
        out[f"sigma_{u}"] = sol.sigma[..., i]
        ub = ub_w[..., i, :]
        a = U[i] - _dot(U[i], ub)[..., None] * ub
        b = mp.e - _dot(mp.e, ub)[..., None] * ub
        out[f"tau_{u}"] = np.arctan2(_dot(np.cross(a, b), ub), _dot(a, b))
    xm, ym = R[:, 0], R[:, 1]
    dj = mp.J_z - mp.D[..., 2, :]
    jq = mp.Q[..., 2, :] - mp.J_z
    phi1 = np.arctan2(_dot(dj, ym), _dot(dj, xm))
    phi2 = np.arctan2(_dot(jq, ym), _dot(jq, xm))
    out["zdyad_D"] = phi1
    out["zdyad_J"] = _wrap(phi2 - phi1)
    out["zdyad_Q"] = _wrap(-phi2)
    return {name: np.asarray(out[name], dtype=float) for name in JOINT_NAMES}


def z_dyad_range(L_z: ArrayLike, d_z: float) -> tuple[float, float]:
    """The c_z range [lo, hi] (mm) that closes the z dyad at every span L_z = |Q_z - D_z| (MODEL.md 6):
    the intersection of [|L_z - d_z|, L_z + d_z]; empty (lo > hi) when no c_z can."""
    L = np.asarray(L_z, dtype=float).reshape(-1)
    return float(np.max(np.abs(L - d_z))), float(np.min(L + d_z))


@dataclass(frozen=True)
class _Plan:
    E: NDArray[np.float64]  # (P, 3)
    e: NDArray[np.float64]
    ids: tuple[str, ...]
    trajectory: NDArray[np.intp]
    k: NDArray[np.intp]
    n_points: int


def _plan(plan: Any, points: int) -> _Plan:
    from arcube.evaluation.task import build_task
    from arcube.io import TrajectorySet
    from arcube.evaluation.result import load_trajectory_set

    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
        raise InputError.of("points", f"must be an integer of at least 2 (both ends of a trajectory), got {short_repr(points)}")
    if plan is None:
        plan = "reference"
    ts = plan if isinstance(plan, TrajectorySet) else load_trajectory_set(os.fspath(plan), int(points))
    if len(ts.ids) == 0:
        raise InputError("the plan has no trajectories")
    task = build_task(ts.entry, ts.target, int(points), ids=ts.ids)
    return _Plan(task.E, task.e, tuple(task.ids), task.trajectory, task.k, int(points))


def _resolve_point(plan: _Plan, at: str | tuple[Any, int] | None) -> int:
    """Index into the plan's points of ``at`` = ``"ID:K"`` (or ``(id, k)``); None: first point."""
    if at is None:
        return 0
    if isinstance(at, str):
        tid, sep, ktext = at.strip().rpartition(":")
        if not sep or not tid:
            raise InputError.of("at", f"{short_repr(at)}: expected ID:K, a trajectory id and a sample index, e.g. '1:0'")
        try:
            k = int(ktext)
        except ValueError:
            raise InputError.of("at", f"{short_repr(at)}: the sample index K must be an integer, got {short_repr(ktext)}") from None
    else:
        tid, k = str(at[0]), int(at[1])
    if tid not in plan.ids:
        shown = ", ".join(plan.ids[:12]) + (", ..." if len(plan.ids) > 12 else "")
        raise InputError.of("at", f"{tid}:{k}: no trajectory with id {short_repr(tid)} in the plan (ids: {shown})")
    if not 0 <= k < plan.n_points:
        raise InputError.of("at", f"{tid}:{k}: sample index k must lie in 0..{plan.n_points - 1} (points={plan.n_points})")
    t = plan.ids.index(tid)
    return int(np.flatnonzero((plan.trajectory == t) & (plan.k == k))[0])


def _no_ik_reason(sol: Any) -> str:
    parts, undefined = [], []
    for stage, arg, legs in (("TLS", sol.tls_arg, "xyz"), ("RTS", sol.rts_arg, "xy"), ("TMS", sol.tms_arg, "xy")):
        for leg, a in zip(legs, np.asarray(arg, dtype=float).reshape(-1)):
            if math.isfinite(a) and abs(a) > 1.0:
                parts.append(f"{stage} {leg} out of reach (|arg| = {abs(a):.3g} > 1)")
            elif not math.isfinite(a):
                undefined.append(f"{stage} {leg}")
    # a NaN argument follows from an earlier stage's failure; name it only when nothing else failed
    return ", ".join(parts or undefined) or "a stage has no finite solution"


# ------------------------------------------------------------------------------------------ XML building


def _num(x: float) -> str:
    v = float(x) + 0.0
    if not math.isfinite(v):
        raise InputError("MJCF export: a computed position is not finite (degenerate pose)")
    return repr(v)


def _vec(v: ArrayLike) -> str:
    return " ".join(_num(x) for x in np.asarray(v, dtype=float).reshape(-1))


class _Body:
    """A body built in the assembled pose: frame parallel to the patient frame, origin at ``origin`` (R_w)."""

    def __init__(self, parent_el: ET.Element, name: str, origin: NDArray[np.float64], parent_origin: NDArray[np.float64] | None):
        self.origin = np.asarray(origin, dtype=float)
        attrs = {"name": name}
        if parent_origin is not None:
            attrs["pos"] = _vec(self.origin - parent_origin)
        self.el = ET.SubElement(parent_el, "body", attrs)
        self.name = name
        self.registry: dict[str, _Body] = {name: self}

    def child(self, name: str, origin: NDArray[np.float64]) -> _Body:
        body = _Body(self.el, name, origin, self.origin)
        body.registry = self.registry  # one name -> body map for the whole tree
        self.registry[name] = body
        return body

    def local(self, p: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(p, dtype=float) - self.origin

    def hinge(self, name: str, point: ArrayLike, axis: ArrayLike, ref: float, cls: str) -> None:
        ax = np.asarray(axis, dtype=float)
        ax = ax / np.linalg.norm(ax)
        ET.SubElement(self.el, "joint", {"name": name, "class": cls, "type": "hinge", "pos": _vec(self.local(point)), "axis": _vec(ax), "ref": _num(ref)})

    def capsule(self, name: str, a: ArrayLike, b: ArrayLike, radius: float, color: str) -> None:
        pa, pb = self.local(a), self.local(b)
        if np.linalg.norm(pb - pa) < 1e-6:
            self.sphere(name, a, radius, color)
            return
        ET.SubElement(self.el, "geom", {"name": name, "type": "capsule", "fromto": _vec(np.concatenate([pa, pb])), "size": _num(radius), "rgba": _COLORS[color]})

    def sphere(self, name: str, p: ArrayLike, radius: float, color: str) -> None:
        ET.SubElement(self.el, "geom", {"name": name, "type": "sphere", "pos": _vec(self.local(p)), "size": _num(radius), "rgba": _COLORS[color]})

    def polyline(self, name: str, pts: NDArray[np.float64], radius: float, color: str) -> None:
        for j in range(len(pts) - 1):
            self.capsule(f"{name}_{j}", pts[j], pts[j + 1], radius, color)

    def site(self, name: str, p: ArrayLike, zaxis: ArrayLike | None = None, size: float = 2.0, group: int | None = None) -> None:
        attrs = {"name": name, "pos": _vec(self.local(p)), "size": _num(size)}
        if group is not None:
            attrs["group"] = str(group)
        if zaxis is not None:
            attrs["zaxis"] = _vec(zaxis)
        ET.SubElement(self.el, "site", attrs)


def _mesh_items(anatomy: Any) -> list[Any]:
    if anatomy is None:
        return []
    meshes = getattr(anatomy, "meshes", anatomy)  # an arcube Anatomy, or a sequence of trimesh meshes
    if hasattr(meshes, "vertices") and hasattr(meshes, "faces"):
        meshes = [meshes]
    items = list(meshes)
    for i, m in enumerate(items):
        if not (hasattr(m, "vertices") and hasattr(m, "faces")):
            raise InputError(f"anatomy item {i}: not a triangle mesh (needs vertices and faces)")
    return items


def export_mjcf(
    design: Design | ArrayLike,
    plan: Any = None,
    *,
    at: str | tuple[Any, int] | None = None,
    points: int = 30,
    mode: str | ArrayLike = "+,+,+,+",
    c_z: float | None = None,
    radii: BodyRadii = BodyRadii(),
    anatomy: Any = None,
) -> str:
    """The MJCF XML (a string) of ``design`` assembled at one point of ``plan``; see the module docstring.

    Parameters
    ----------
    design : a :class:`Design` or a ``(27,)`` / ``(23,)`` vector (mm, deg).
    plan : a :class:`~arcube.io.TrajectorySet`, a path that :func:`arcube.load_trajectories` reads, or
        None / ``"reference"`` (the bundled reference patient); sampled at ``points`` per trajectory.
    at : ``"ID:K"``, trajectory id and sample index k; default the first point of the plan that the
        design reaches (trajectory order, then k).
    mode : working mode, ``"+,+,+,+"`` or four signs (MODEL.md 4.3, 5.3).
    c_z : second link of the z-leg dyad (mm); default d_z (MODEL.md 6). The dyad must close at every
        point of the plan where the IK has a solution, else :class:`InputError` names the c_z range
        that would (the intersection of [|L_z - d_z|, L_z + d_z]) or says that none can.
    radii : body radii of MODEL.md 14.1 (links, actuators, drill motor radius and length).
    anatomy : None, an :class:`~arcube.evaluation.anatomy.Anatomy` or trimesh meshes (patient frame, mm),
        written as static, non-colliding mesh geoms.

    Raises :class:`InputError` for a bad ``at``, no IK solution at ``at``, or a z dyad that cannot close.
    """
    params = _params(design)
    Design.from_vector(params)  # validates (InputError)
    signs = _signs(mode)
    if not isinstance(radii, BodyRadii):
        raise InputError.of("radii", "must be an arcube.model.body.BodyRadii")
    g = unpack(params)
    d_z = float(g.d[2])
    if c_z is not None and not (isinstance(c_z, (int, float)) and 0.0 < c_z <= _FLOAT_MAX):  # finite, > 0
        raise InputError.of("c_z", f"must be a finite number of mm > 0, got {short_repr(c_z)}")
    cz = d_z if c_z is None else float(c_z)
    pl = _plan(plan, points)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, pl.E, pl.e, signs)
    ok = np.all(np.isfinite(np.concatenate([sol.rho, sol.delta, sol.sigma], axis=-1)), axis=-1)
    if at is None and not ok.any():
        one = inverse_kinematics(params, pl.E[0], pl.e[0], signs)
        raise InputError(
            f"the design reaches no point of the plan in mode {format_mode(signs)} (at trajectory "
            f"{pl.ids[0]}, k=0: {_no_ik_reason(one)}); pick another mode, design or plan"
        )
    idx = int(np.flatnonzero(ok)[0]) if at is None else _resolve_point(pl, at)
    where = f"trajectory {pl.ids[pl.trajectory[idx]]}, k={int(pl.k[idx])}"
    if not ok[idx]:
        one = inverse_kinematics(params, pl.E[idx], pl.e[idx], signs)
        raise InputError(
            f"the design has no IK solution at {where} in mode {format_mode(signs)}: {_no_ik_reason(one)}; "
            "pick another point (at), mode or design"
        )
    # z dyad (MODEL.md 6) at every point of the plan that the IK solves: D_z and Q_z lie in one plane z_m = const.
    mp_all = mechanism_points(params, pl.E[ok], pl.e[ok], signs, c_z=cz)
    L_z = np.linalg.norm(mp_all.Q[:, 2, :] - mp_all.D[:, 2, :], axis=-1)
    lo, hi = z_dyad_range(L_z, d_z)
    if not lo <= cz <= hi:
        bad = int(np.sum((L_z > d_z + cz) | (L_z < abs(d_z - cz))))
        head = (f"the z-leg dyad (d_z = {d_z:.4g} mm, c_z = {cz:.4g} mm) cannot close at {bad} of {len(L_z)} "
                f"solvable points of the plan (|Q_z - D_z| spans {L_z.min():.1f}-{L_z.max():.1f} mm)")  # fmt: skip
        if lo <= hi:  # the message leads with the parameter to change (the CLI puts its flag there)
            raise InputError.of("c_z", f"in [{lo:.2f}, {hi:.2f}] mm closes the z-leg dyad at every point: {head}")
        raise InputError(f"{head}; no c_z closes it at every point (it would need c_z >= {lo:.1f} and <= {hi:.1f} mm): change d_z or the placement")

    return _build_xml(params, pl.E[idx], pl.e[idx], signs, cz, radii, _mesh_items(anatomy), where)


def _build_xml(params: NDArray[np.float64], E: NDArray[np.float64], e: NDArray[np.float64], signs: NDArray[np.float64],
               c_z: float, radii: BodyRadii, meshes: list[Any], where: str) -> str:  # fmt: skip
    g = unpack(params)
    mp = mechanism_points(params, E, e, signs, c_z=c_z, motor_length=radii.motor_length, arc_samples=9)
    q = {k: float(v) for k, v in joint_values(params, E, e, signs, c_z=c_z).items()}
    U, V, W, R = _axes_world(params)
    zm = R[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, signs)
    ub = sol.u_beta @ R.T  # (2, 3) in R_w
    rl, ra = radii.link, radii.actuator
    O, P, D, Q, K, T, B = mp.O, mp.P, mp.D, mp.Q, mp.K, mp.T, mp.B
    C, H, Ew, ew, Jz = mp.C, mp.H, mp.E, mp.e, mp.J_z

    root = ET.Element("mujoco", {"model": "arcube"})
    ET.SubElement(root, "compiler", {"angle": "radian", "autolimits": "true"})
    opt = ET.SubElement(root, "option", {"timestep": "0.001", "integrator": "implicitfast", "gravity": "0 0 -9810"})
    ET.SubElement(opt, "flag", {"contact": "disable"})
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", {"offwidth": "1280", "offheight": "960"})
    ET.SubElement(vis, "map", {"znear": "0.001", "zfar": "50"})
    ET.SubElement(vis, "scale", {"framelength": "0.3", "framewidth": "0.02", "jointlength": "0.3", "jointwidth": "0.03"})
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", {"contype": "0", "conaffinity": "0", "density": "1e-6", "group": "1"})
    ET.SubElement(default, "site", {"group": "3", "rgba": "1 0.2 0.2 1"})
    active = ET.SubElement(default, "default", {"class": "active"})
    ET.SubElement(active, "joint", {"damping": _num(KV), "armature": "100"})
    passive = ET.SubElement(default, "default", {"class": "passive"})
    ET.SubElement(passive, "joint", {"damping": "1", "armature": "1"})
    ET.SubElement(default, "equality", {"solref": "0.002 1"})

    asset = ET.SubElement(root, "asset")
    ET.SubElement(asset, "texture", {"name": "sky", "type": "skybox", "builtin": "gradient", "rgb1": "0.55 0.65 0.75", "rgb2": "0.05 0.05 0.08", "width": "256", "height": "256"})
    if meshes:
        for i, m in enumerate(meshes):
            v = np.asarray(m.vertices, dtype=float)
            f = np.asarray(m.faces, dtype=np.int64)
            ET.SubElement(asset, "mesh", {"name": f"anatomy_{i}", "inertia": "shell",
                                          "vertex": " ".join(_num(x) for x in v.reshape(-1)),
                                          "face": " ".join(str(int(x)) for x in f.reshape(-1))})  # fmt: skip

    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", {"name": "top", "pos": _vec(C + np.array([0.0, 0.0, 1500.0])), "dir": "0 0 -1", "directional": "true"})
    for i in range(len(meshes)):
        ET.SubElement(world, "geom", {"name": f"anatomy_{i}", "type": "mesh", "mesh": f"anatomy_{i}", "rgba": _COLORS["anatomy"], "group": "2", "mass": "0"})

    base = _Body(world, "base", O, np.zeros(3))
    bodies = base.registry  # every body by name, shared down the tree
    base.site("O", O)
    for i, u in enumerate("xyz"):
        base.capsule(f"frame_{u}", O, P[i], rl, "base")
        base.sphere(f"actuator_P_{u}", P[i], ra, "actuator")
        base.site(f"P_{u}", P[i])

    platform: _Body | None = None
    for i, u in enumerate("xyz"):
        crank = base.child(f"crank_{u}", P[i])
        crank.hinge(f"rho_{u}", P[i], -V[i], q[f"rho_{u}"], "active")
        crank.capsule(f"crank_{u}", P[i], D[i], rl, "tls")
        knee = crank.child(f"knee_{u}", D[i])
        knee.hinge(f"kappa_{u}", D[i], V[i], q[f"kappa_{u}"], "passive")
        knee.site(f"D_{u}", D[i])
        if u in "xy":
            knee.sphere(f"actuator_D_{u}", D[i], ra, "actuator")
            inp = knee.child(f"input_{u}", D[i])
            inp.hinge(f"delta_{u}", D[i], U[i], q[f"delta_{u}"], "active")
            inp.capsule(f"input_{u}", D[i], K[i], rl, "tms")
            inp.site(f"K_{u}", K[i])
            cpl = inp.child(f"coupler_{u}", K[i])
            cpl.hinge(f"gamma_{u}", K[i], U[i], q[f"gamma_{u}"], "passive")
            cpl.capsule(f"coupler_{u}", K[i], T[i], rl, "tms")
            cpl.site(f"coupler_{u}_T", T[i])
            cpl.site(f"coupler_{u}_T_axis", T[i] + PIN_MM * U[i], group=4)
        else:
            knee.sphere("joint_D_z", D[i], 1.5 * rl, "tls")
            dz = knee.child("zdyad_d", D[i])
            dz.hinge("zdyad_D", D[i], zm, q["zdyad_D"], "passive")
            dz.capsule("zdyad_d", D[i], Jz, rl, "zdyad")
            dz.site("J_z", Jz)
            cz = dz.child("zdyad_c", Jz)
            cz.hinge("zdyad_J", Jz, zm, q["zdyad_J"], "passive")
            cz.capsule("zdyad_c", Jz, Q[2], rl, "zdyad")
            platform = cz.child("platform", C)
            platform.hinge("zdyad_Q", Q[2], zm, q["zdyad_Q"], "passive")
    assert platform is not None
    for a, b in ((0, 1), (1, 2), (2, 0)):
        platform.capsule(f"platform_{'xyz'[a]}{'xyz'[b]}", Q[a], Q[b], rl, "platform")
    platform.site("C", C)
    for i, u in enumerate("xyz"):
        platform.site(f"Q_{u}", Q[i])

    for i, u in enumerate("xy"):
        out = platform.child(f"output_{u}", Q[i])
        out.hinge(f"sigma_{u}", Q[i], U[i], q[f"sigma_{u}"], "passive")
        out.capsule(f"output_{u}", Q[i], T[i], rl, "tms")
        out.site(f"output_{u}_T", T[i])
        out.site(f"output_{u}_T_axis", T[i] + PIN_MM * U[i], group=4)
        alpha = out.child(f"alpha_{u}", C)  # welded: the four-bar output and the proximal spherical link are one link
        alpha.polyline(f"spherical_alpha_{u}", mp.arc_alpha[i], rl, "rts")
        alpha.site(f"B_{u}", B[i])
        beta = alpha.child(f"beta_{u}", B[i])
        beta.hinge(f"tau_{u}", B[i], ub[i], q[f"tau_{u}"], "passive")
        beta.polyline(f"spherical_beta_{u}", mp.arc_beta[i], rl, "rts")
        if u == "x":
            drill = beta.child("drill", Ew)  # welded to beta_x: the drill holder
            drill.capsule("tool", Ew, H, max(0.25 * rl, 1.0), "tool")
            drill.capsule("drill_motor", H, mp.drill_end, radii.motor, "motor")
            drill.site("tip", Ew, zaxis=ew)
            drill.site("holder", H, zaxis=ew)
            drill.site("C_drill", C)
        else:
            beta.site("beta_y_H", H)

    # connect = body1's anchor (local) and, computed by the compiler in the assembled pose, the same point of body2
    eq = ET.SubElement(root, "equality")
    for i, u in enumerate("xy"):
        cpl, out = bodies[f"coupler_{u}"], bodies[f"output_{u}"]
        ET.SubElement(eq, "connect", {"name": f"close_T_{u}", "body1": cpl.name, "body2": out.name, "anchor": _vec(cpl.local(T[i]))})
        ET.SubElement(eq, "connect", {"name": f"close_T_{u}_axis", "body1": cpl.name, "body2": out.name,
                                      "anchor": _vec(cpl.local(T[i] + PIN_MM * U[i]))})  # fmt: skip
    ET.SubElement(eq, "connect", {"name": "close_H", "body1": "beta_y", "body2": "drill", "anchor": _vec(bodies["beta_y"].local(H))})

    act = ET.SubElement(root, "actuator")
    for name in ACTUATED:
        ET.SubElement(act, "position", {"name": name, "joint": name, "kp": _num(KP)})

    sensor = ET.SubElement(root, "sensor")
    ET.SubElement(sensor, "framepos", {"name": "tip_pos", "objtype": "site", "objname": "tip"})
    ET.SubElement(sensor, "framezaxis", {"name": "drill_axis", "objtype": "site", "objname": "tip"})

    keys = ET.SubElement(root, "keyframe")
    ET.SubElement(keys, "key", {"name": "assembled", "qpos": " ".join(_num(q[n]) for n in JOINT_NAMES),
                                "ctrl": " ".join(_num(q[n]) for n in ACTUATED)})  # fmt: skip

    ET.indent(root, space="  ")
    d = Design.from_vector(params).to_dict()
    header = (
        f" arcube MJCF export: AR-CUBE assembled at {where}, mode {format_mode(signs)}, c_z = {c_z:.6g} mm.\n"
        "     Units: mm, rad, kg, s. Load the keyframe 'assembled' before simulating (MuJoCo starts with ctrl = 0).\n"
        f"     Design: {', '.join(f'{k}={v:.6g}' for k, v in d.items())} "
    )
    return "<!--" + header + "-->\n" + ET.tostring(root, encoding="unicode") + "\n"
