"""A simulation model of any design: the mechanism as MuJoCo MJCF (XML), assembled at one task point.

:func:`export_mjcf` writes one body per rigid link of model §3-6 and 14.1, joined by hinges at the
model's joint points and about the model's axes (mechanism axes turned into the patient frame by the
mounting rotation R, model §13), with the three loops of the mechanism closed by ``<connect>``
equality constraints. Lengths are in mm, angles in rad, masses in kg, inertias in kg mm^2, time in s,
forces in kg mm/s^2 (1 N m of torque = 1e6 kg mm^2/s^2). Masses and inertias are those of model §18.1
(``masses``, :mod:`arcube.export.inertia`: each body carries the 18.1 parts rigidly attached to it; the
geoms are drawn only); gravity is the mass model's, m/s^2 x 1000, in the patient frame, which is the
model's world frame (default (0, 0, -9810) mm/s^2: posterior is up with the patient prone).

Body tree (every body frame is parallel to the patient frame in the assembled pose; hinge angle =
the model's angle, thanks to each hinge's ``ref``)::

    base (static: frame links O -> P_u, actuators at P_u)
    |- crank_u          hinge rho_u   at P_u about -v_u  (u = x, y, z; positive rho turns about -v, model §3.1)
    |  `- knee_u        hinge kappa_u at D_u about +v_u  (passive, kappa_u = rho_u: keeps the distal chain planar)
    |     |- input_u    hinge delta_u at D_u about u     (u = x, y; n(delta) from -w toward +v, model §4.1)
    |     |  `- coupler_u  hinge gamma_u at K_u about u  (passive: coupler direction minus delta_u)
    |     `- zdyad_d    hinge zdyad_D at D_z about z_m   (z leg only, model §6; angle of J_z - D_z from x_m)
    |        `- zdyad_c hinge zdyad_J at J_z about z_m   (relative angle of Q_z - J_z to J_z - D_z)
    |           `- platform  hinge zdyad_Q at Q_z about z_m  (carries Q_x, Q_y, Q_z and the centre C)
    |              `- output_u  hinge sigma_u at Q_u about u  (four-bar output t_u, model §4.1; u = x, y)
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

The loop closures are near-rigid (:data:`SOLIMP`): MuJoCo's default soft constraints would let the
weight of the links sag the tip by 0.3-30 mm. A closed loop also means that an actuator's holding
torque is not its own entry of ``qfrc_inverse`` (MuJoCo treats the loops as cut): it is G^T
qfrc_bias at rest, with G ``(17, 5)`` the hinge rates per actuator rate (the null space of the
closures' Jacobian), which equals :func:`arcube.evaluation.masses.gravity_torque_Nm`.

Accuracy (tests/test_mjcf.py): with every hinge set from the IK, MuJoCo's forward kinematics puts the
tip on E and every closure at rest to ~1e-12 mm; driven by the five actuators with gravity off, the
tip settles on E to ~1e-3 mm within 0.3 s per point. With gravity on, the position servos alone
(100 N m/rad) let the tip sag by about a millimetre; with the gravity torques of model §18.2 as a
feed-forward (ctrl = q + tau / KP) it stays within ~0.01 mm.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from arcube.arrays import Floats
from arcube.errors import InputError, RenamedWarning
from arcube.evaluation.mass_bodies import MassModel
from arcube.coerce import design_mode
from arcube.export.angles import ACTUATED, JOINT_NAMES, axes_world, joint_values, z_dyad_range
from arcube.export.inertia import INERTIA_FLOOR_KG_MM2, MASS_FLOOR_KG, body_inertials, mass_model_for
from arcube.export.plan_point import no_ik_reason, plan_points, resolve_point
from arcube.export.xmltree import COLORS, XmlBody, mesh_items, num, vec
from arcube.io.inputs import short_repr
from arcube.model.body import mechanism_points
from arcube.model.design import MAX_LENGTH_MM, Design, unpack
from arcube.model.mechanism import format_mode, inverse_kinematics
from arcube.options import Options, request_options
from arcube.request import Request
from arcube.validation import caller_stacklevel

__all__ = [
    "ACTUATED",
    "JOINT_NAMES",
    "KP",
    "KV",
    "ExportedRobot",
    "check_z_dyad",
    "checked_inputs",
    "design_with_c_z",
    "export_masses",
    "export_mjcf",
    "joint_values",
    "model_xml",
    "z_dyad_range",
]

PIN_MM = 100.0
"""Distance between the two points of a hinge closure along its axis (close_T_u, close_T_u_axis), mm: the
wider apart, the stiffer MuJoCo's soft constraint holds the hinge's direction."""

KP = 1.0e8
"""Stiffness of the position actuators, kg mm^2 / s^2 per rad (= 100 N m/rad)."""
KV = 3.0e6
"""Damping of the actuated joints, kg mm^2 / s per rad (= 3 N m s/rad): the servo's velocity gain (about
critical damping of KP against the 18.1 masses: the tip settles fastest, tests/test_mjcf.py)."""
SOLREF = "0.002 1"
"""``solref`` of the loop closures: time constant 2 ms, critical damping."""
SOLIMP = "0.9999 0.9999 0.001 0.5 2"
"""``solimp`` of the loop closures: impedance 0.9999 (MuJoCo's largest) at any violation, near-rigid, so
that the closures carry the links' weight without sagging (MuJoCo issues 1818, 701, 278)."""

_FLOAT_MAX = float(np.finfo(float).max)
_SELECTION = ("side", "levels", "ids", "transform", "anatomy_frame", "segments", "table_z")
"""What a Request given to :func:`export_mjcf` holds that its keywords do not: they are resolved with the request."""


def export_mjcf(
    design: Design | ArrayLike | Request,
    plan: Any = None,
    *,
    at: str | tuple[Any, int] | None = None,
    points: int = 30,
    mode: str | ArrayLike | None = None,
    c_z: float | None = None,
    options: Options | None = None,
    anatomy: Any = None,
    masses: bool | None = None,
    envelope: Any = None,
    **changes: Any,
) -> str:
    """The MJCF XML (a string) of ``design`` assembled at one point of ``plan``; see the module docstring.

    Parameters
    ----------
    design : a :class:`Design` or a ``(27,)`` / ``(23,)`` vector (mm, deg); or an :class:`arcube.Request` (its plan
        and selection, mode, points, options, anatomy and envelope, resolved as :func:`arcube.evaluate` resolves
        them; the keywords it holds then stay unset).
    plan : a :class:`~arcube.io.TrajectorySet`, a path that :func:`arcube.load_trajectories` reads, or
        None / ``"reference"`` (the bundled reference patient); sampled at ``points`` per trajectory.
    at : ``"ID:K"``, trajectory id and sample index k; default the first point of the plan that the
        design reaches (trajectory order, then k).
    mode : working mode, ``"+,+,+,+"`` or four signs (model §4.3, 5.3); None: the design's own, else ``+,+,+,+``.
    c_z : deprecated (one release, with a :class:`~arcube.errors.RenamedWarning`): the z-leg dyad's second link is
        the design's own, :attr:`Design.c_z` (``design.with_extras(c_z=...)``), else d_z (model §6, 19.1). The dyad
        must close at every point of the plan where the IK has a solution, else :class:`InputError` names the c_z
        range that would (the intersection of [|L_z - d_z|, L_z + d_z]) or says that none can.
    options : the :class:`arcube.Options` of the robot: its body radii (model §14.1) and its mass model
        (18.1: every body's mass and inertia and the model's gravity, :mod:`arcube.export.inertia`);
        ``**changes``: its settings by name (``link_radius=6``, ``wall=1.5``).
    anatomy : None, an :class:`~arcube.evaluation.anatomy.Anatomy` or trimesh meshes (patient frame, mm),
        written as static, non-colliding mesh geoms.
    masses : None: the mass model of ``options`` (a massless model when its links are too thin for the
        default wall and no masses were given); False: a massless model; True: required.
    envelope : the envelope of the whole patient and the table (model §19.5) to draw: an Envelope, or
        ``"default"`` / mesh files placed on ``plan`` (give the whole plan: its landmarks are the patient's).

    Raises :class:`InputError` for a bad ``at``, no IK solution at ``at``, or a z dyad that cannot close.
    """
    if isinstance(design, Request):  # its plan selected, its anatomy and envelope placed, as evaluate resolves them
        req = Request.of(locals(), export_mjcf, taken=_SELECTION)
        r = req.resolve()
        design, plan, mode, anatomy, envelope = r.design, r.plan, r.signs, r.anatomy, r.envelope
        points, options = req.points, req.options
    opts = request_options(options, **changes)
    robot = checked_inputs(with_c_z(design, c_z, "export_mjcf"), mode)
    params, signs, cz = robot
    pl = plan_points(plan, points)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, pl.E, pl.e, signs)
    ok = np.all(np.isfinite(np.concatenate([sol.rho, sol.delta, sol.sigma], axis=-1)), axis=-1)
    if at is None and not ok.any():
        one = inverse_kinematics(params, pl.E[0], pl.e[0], signs)
        raise InputError(
            f"the design reaches no point of the plan in mode {format_mode(signs)} (at trajectory "
            f"{pl.ids[0]}, k=0: {no_ik_reason(one)}); pick another mode, design or plan"
        )
    idx = int(np.flatnonzero(ok)[0]) if at is None else resolve_point(pl, at)
    where = f"trajectory {pl.ids[pl.trajectory[idx]]}, k={int(pl.k[idx])}"
    if not ok[idx]:
        one = inverse_kinematics(params, pl.E[idx], pl.e[idx], signs)
        raise InputError.of(
            "at",
            f"{short_repr(at)}: the design has no IK solution at {where} in mode {format_mode(signs)}: "
            f"{no_ik_reason(one)}; pick another point, mode or design",
        )
    check_z_dyad(params, pl.E[ok], pl.e[ok], signs, cz, "solvable points of the plan")
    if envelope is not None and not hasattr(envelope, "boxes"):
        from arcube.evaluation.envelope import resolve_envelope
        from arcube.io.load import load_plan

        envelope = resolve_envelope(
            envelope,
            load_plan("reference" if plan is None else plan),
            anatomy if hasattr(anatomy, "distance") else None,
        )
    return model_xml(robot, pl.E[idx], pl.e[idx], anatomy, where, options=opts, masses=masses, envelope=envelope)


def export_masses(options: Options, masses: bool | None) -> MassModel:
    """The mass model of an export: ``options``' (model §18.1) when it applies
    (:meth:`arcube.Options.mass_model_on`), else a massless model (the links' geometry only)."""
    if options.mass_model_on(masses):
        return MassModel.of(options)
    link = options.body.link_radius
    return MassModel(link_radius_mm=link, wall_mm=link / 2, density_kg_m3=0.0, m_delta_kg=0.0, m_motor_kg=0.0)


def with_c_z(design: Design | ArrayLike, c_z: Any, function: str) -> Design | ArrayLike:
    """``design`` with the c_z given by the deprecated keyword of ``function`` (None: ``design`` as given). c_z's one
    home is the design (:attr:`Design.c_z`, model §19.1); the keyword is taken for one release, with a
    :class:`~arcube.errors.RenamedWarning`. InputError naming ``c_z`` unless a finite length > 0 mm."""
    if c_z is None:
        return design
    warnings.warn(
        f"{function}(c_z=...) is now the design's c_z: give design.with_extras(c_z=...) (the keyword goes in the next release)",
        RenamedWarning,
        stacklevel=caller_stacklevel(),
    )
    return design_with_c_z(design, c_z)


def design_with_c_z(design: Design | ArrayLike, c_z: Any) -> Design:
    """``design`` (a Design, preset, file or vector) with c_z (mm, model §19.1) set: an export's ``--c-z``.
    InputError naming ``c_z`` unless a length > 0 mm and at most :data:`arcube.model.design.MAX_LENGTH_MM`."""
    if isinstance(c_z, bool) or not (isinstance(c_z, (int, float)) and 0.0 < c_z <= MAX_LENGTH_MM):
        most = (
            f" and at most {MAX_LENGTH_MM:g} (a link of the robot)" if isinstance(c_z, (int, float)) and c_z > 0 else ""
        )
        raise InputError.of("c_z", f"must be a finite number of mm > 0{most}, got {short_repr(c_z)}")
    return Design.coerce(design).with_extras(c_z=float(c_z))


class ExportedRobot(NamedTuple):
    """The robot an export draws, checked (:func:`checked_inputs`)."""

    params: Floats
    """Design vector ``(27,)`` (mm, deg)."""
    signs: Floats
    """Working mode ``(4,)``, signs."""
    c_z: float
    """The z dyad's link, mm: the design's (model §19.1), else d_z (model §6)."""


def checked_inputs(design: Design | ArrayLike, mode: str | ArrayLike | None) -> ExportedRobot:
    """The robot of an export; InputError on bad input. ``mode`` None: the design's own."""
    d = Design.coerce(design)  # a design file keeps its c_z and mode (a vector has neither); validates (InputError)
    params = d.to_vector()
    return ExportedRobot(params, design_mode(d, mode), float(unpack(params).d[2]) if d.c_z is None else float(d.c_z))


def check_z_dyad(
    params: Floats,
    E: Floats,
    e: Floats,
    signs: Floats,
    c_z: float,
    what: str,
) -> None:
    """InputError unless the z dyad (model §6; D_z and Q_z lie in one plane z_m = const) closes with c_z (mm)
    at every pose (E, e) ``(P, 3)``; the message names the c_z range that would, or says that none can."""
    d_z = float(unpack(params).d[2])
    mp_all = mechanism_points(params, E, e, signs, c_z=c_z)
    L_z = np.linalg.norm(mp_all.Q[:, 2, :] - mp_all.D[:, 2, :], axis=-1)
    lo, hi = z_dyad_range(L_z, d_z)
    if not lo <= c_z <= hi:
        bad = int(np.sum((L_z > d_z + c_z) | (L_z < abs(d_z - c_z))))
        head = (
            f"the z-leg dyad (d_z = {d_z:.4g} mm, c_z = {c_z:.4g} mm) cannot close at {bad} of {len(L_z)} "
            f"{what} (|Q_z - D_z| spans {L_z.min():.1f}-{L_z.max():.1f} mm)"
        )
        if lo <= hi:  # the message leads with the parameter to change (the CLI puts its flag there)
            raise InputError.of("c_z", f"in [{lo:.2f}, {hi:.2f}] mm closes the z-leg dyad at every point: {head}")
        raise InputError(
            f"{head}; no c_z closes it at every point (it would need c_z >= {lo:.1f} and <= {hi:.1f} mm): change d_z or the placement"
        )


def model_xml(
    robot: ExportedRobot,
    E: Floats,
    e: Floats,
    anatomy: Any,
    where: str,
    *,
    options: Options,
    masses: bool | None,
    actuated: dict[str, float] | None = None,
    note: str = "",
    envelope: Any = None,
) -> str:
    """The MJCF text assembled at the pose (E, e) ``(3,)``, R_w; inputs checked by the caller (:func:`export_mjcf`).

    ``options``: the body radii and masses (:func:`export_masses` of ``masses``); ``actuated``: angles (rad) of
    actuated hinges to use instead of the IK's (each congruent to it mod 2 pi: a program may turn delta by whole
    turns); ``note``: one more line of the header comment; ``envelope``:
    the envelope of the whole patient (model §19.5), drawn (:func:`envelope_geoms`).
    """
    params, signs, c_z = robot
    radii = options.body.radii
    model = mass_model_for(export_masses(options, masses), radii, c_z)
    meshes = mesh_items(anatomy)
    mp = mechanism_points(params, E, e, signs, c_z=c_z, motor_length=radii.motor_length, arc_samples=9)
    q = {k: float(v) for k, v in joint_values(params, E, e, signs, c_z=c_z).items()} | (actuated or {})
    inertials = body_inertials(params, E, e, signs, model)
    U, V, W, R = axes_world(params)
    zm = R[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, signs)
    ub = sol.u_beta @ R.T  # (2, 3) in R_w
    rl, ra = radii.link, radii.actuator
    O, P, D, Q, K, T, B = mp.O, mp.P, mp.D, mp.Q, mp.K, mp.T, mp.B
    C, H, Ew, ew, Jz = mp.C, mp.H, mp.E, mp.e, mp.J_z

    root = ET.Element("mujoco", {"model": "arcube"})
    ET.SubElement(
        root,
        "compiler",
        {
            "angle": "radian",
            "autolimits": "true",
            "inertiafromgeom": "false",
            "boundmass": num(MASS_FLOOR_KG),
            "boundinertia": num(INERTIA_FLOOR_KG_MM2),
        },
    )
    gravity = vec(1000.0 * np.asarray(model.gravity, dtype=float))  # m/s^2 -> mm/s^2, patient frame = model frame
    opt = ET.SubElement(root, "option", {"timestep": "0.001", "integrator": "implicitfast", "gravity": gravity})
    ET.SubElement(opt, "flag", {"contact": "disable"})
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", {"offwidth": "1280", "offheight": "960"})
    ET.SubElement(vis, "map", {"znear": "0.001", "zfar": "50"})
    ET.SubElement(
        vis, "scale", {"framelength": "0.3", "framewidth": "0.02", "jointlength": "0.3", "jointwidth": "0.03"}
    )
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", {"contype": "0", "conaffinity": "0", "group": "1"})
    ET.SubElement(default, "site", {"group": "3", "rgba": "1 0.2 0.2 1"})
    active = ET.SubElement(default, "default", {"class": "active"})
    ET.SubElement(active, "joint", {"damping": num(KV), "armature": "100"})
    passive = ET.SubElement(default, "default", {"class": "passive"})
    ET.SubElement(passive, "joint", {"damping": "1", "armature": "1"})
    ET.SubElement(default, "equality", {"solref": SOLREF, "solimp": SOLIMP})

    asset = ET.SubElement(root, "asset")
    ET.SubElement(
        asset,
        "texture",
        {
            "name": "sky",
            "type": "skybox",
            "builtin": "gradient",
            "rgb1": "0.55 0.65 0.75",
            "rgb2": "0.05 0.05 0.08",
            "width": "256",
            "height": "256",
        },
    )
    if meshes:
        for i, m in enumerate(meshes):
            v = np.asarray(m.vertices, dtype=float)
            f = np.asarray(m.faces, dtype=np.int64)
            ET.SubElement(
                asset,
                "mesh",
                {
                    "name": f"anatomy_{i}",
                    "inertia": "shell",
                    "vertex": " ".join(num(x) for x in v.reshape(-1)),
                    "face": " ".join(str(int(x)) for x in f.reshape(-1)),
                },
            )

    world = ET.SubElement(root, "worldbody")
    ET.SubElement(
        world,
        "light",
        {"name": "top", "pos": vec(C + np.array([0.0, 0.0, 1500.0])), "dir": "0 0 -1", "directional": "true"},
    )
    for i in range(len(meshes)):
        ET.SubElement(
            world,
            "geom",
            {
                "name": f"anatomy_{i}",
                "type": "mesh",
                "mesh": f"anatomy_{i}",
                "rgba": COLORS["anatomy"],
                "group": "2",
                "mass": "0",
            },
        )

    base = XmlBody(world, "base", O, np.zeros(3))
    bodies = base.registry  # every body by name, shared down the tree
    base.site("O", O)
    for i, u in enumerate("xyz"):
        base.capsule(f"frame_{u}", O, P[i], rl, "base")
        base.sphere(f"actuator_P_{u}", P[i], ra, "actuator")
        base.site(f"P_{u}", P[i])

    platform: XmlBody | None = None
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

    for name, part in inertials.items():
        bodies[name].inertial(part)

    # connect = body1's anchor (local) and, computed by the compiler in the assembled pose, the same point of body2
    eq = ET.SubElement(root, "equality")
    for i, u in enumerate("xy"):
        cpl, out = bodies[f"coupler_{u}"], bodies[f"output_{u}"]
        ET.SubElement(
            eq,
            "connect",
            {"name": f"close_T_{u}", "body1": cpl.name, "body2": out.name, "anchor": vec(cpl.local(T[i]))},
        )
        ET.SubElement(
            eq,
            "connect",
            {
                "name": f"close_T_{u}_axis",
                "body1": cpl.name,
                "body2": out.name,
                "anchor": vec(cpl.local(T[i] + PIN_MM * U[i])),
            },
        )
    ET.SubElement(
        eq,
        "connect",
        {"name": "close_H", "body1": "beta_y", "body2": "drill", "anchor": vec(bodies["beta_y"].local(H))},
    )

    act = ET.SubElement(root, "actuator")
    for name in ACTUATED:
        ET.SubElement(act, "position", {"name": name, "joint": name, "kp": num(KP)})

    sensor = ET.SubElement(root, "sensor")
    ET.SubElement(sensor, "framepos", {"name": "tip_pos", "objtype": "site", "objname": "tip"})
    ET.SubElement(sensor, "framezaxis", {"name": "drill_axis", "objtype": "site", "objname": "tip"})

    keys = ET.SubElement(root, "keyframe")
    ET.SubElement(
        keys,
        "key",
        {
            "name": "assembled",
            "qpos": " ".join(num(q[n]) for n in JOINT_NAMES),
            "ctrl": " ".join(num(q[n]) for n in ACTUATED),
        },
    )

    if envelope is not None:
        envelope_geoms(root, envelope)
    ET.indent(root, space="  ")
    d = Design.from_vector(params).to_dict()
    header = (
        f" arcube MJCF export: AR-CUBE assembled at {where}, mode {format_mode(signs)}, c_z = {c_z:.6g} mm.\n"
        "     Units: mm, rad, kg, s. Load the keyframe 'assembled' before simulating (MuJoCo starts with ctrl = 0).\n"
        f"     Design: {', '.join(f'{k}={v:.6g}' for k, v in d.items())}\n"
        f"     Masses (model §18.1): moving mass {sum(p.mass for p in inertials.values()):.6g} kg, gravity {gravity} mm/s^2. "
        + (f"\n     {note} " if note else "")
    )
    return "<!--" + header + "-->\n" + ET.tostring(root, encoding="unicode") + "\n"


def envelope_geoms(root: ET.Element, envelope: Any) -> None:
    """Draw the envelope of model §19.5 in the model's world (``root``), faint and not colliding (group 3): each
    rounded box as the box of its half extents plus its radius (the rounded box's bounding box: a drawing,
    not the distance the design is checked with), the table as a slab under its plane, a skin mesh as meshes."""
    world, asset = root.find("worldbody"), root.find("asset")
    drawn = {"rgba": COLORS["envelope"], "group": "3", "contype": "0", "conaffinity": "0", "mass": "0"}
    for name, box in zip(envelope.names, envelope.boxes):
        half = box[3:6] + box[6]
        ET.SubElement(
            world,
            "geom",
            {
                "name": f"envelope_{name}",
                "type": "box",
                "pos": vec(box[:3]),
                "size": vec(half),
                **drawn,
            },
        )
    for i, m in enumerate(envelope.skin):
        ET.SubElement(
            asset,
            "mesh",
            {
                "name": f"envelope_skin_{i}",
                "vertex": " ".join(num(x) for x in np.asarray(m.vertices, float).reshape(-1)),
                "face": " ".join(str(int(x)) for x in np.asarray(m.faces, np.int64).reshape(-1)),
            },
        )
        ET.SubElement(
            world,
            "geom",
            {
                "name": f"envelope_skin_{i}",
                "type": "mesh",
                "mesh": f"envelope_skin_{i}",
                **drawn,
            },
        )
    if envelope.table_z is not None:
        ET.SubElement(
            world,
            "geom",
            {
                "name": "envelope_table",
                "type": "box",
                "pos": vec(np.array([0.0, 0.0, envelope.table_z - 10.0])),
                "size": "1500 1500 10",
                **drawn,
            },
        )
