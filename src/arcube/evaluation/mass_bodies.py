"""The robot's moving bodies for model §18.1: masses, end points and their joint Jacobians.

Every moving body is a uniform **rod** between two end points a, b (a point mass has a = b) plus, for
the drill motor only, the extra inertia of its radius. In :data:`BODY_NAMES` order (65 bodies):

* 14 links of 14.1: ``crank_u`` P_u -> D_u (u = x, y, z), ``input_u`` D_u -> K_u, ``coupler_u``
  K_u -> T_u, ``output_u`` Q_u -> T_u (u = x, y), the z dyad ``zdyad_d`` D_z -> J_z and ``zdyad_c``
  J_z -> Q_z, the platform triangle Q_x -> Q_y -> Q_z -> Q_x;
* the spherical links as 12 chords each (``spherical_alpha_u/k``: C + r û -> C + r u_beta,
  ``spherical_beta_u/k``: C + r u_beta -> C + r e, k = 0..11, equal angles along the great circle);
* the delta actuators ``actuator_D_u`` (u = x, y), point masses at D_u;
* ``drill_motor``: a solid cylinder from H = C + r e to H + L_m e, radius rho_m.

Links are thin-walled tubes (outer radius rho_l = ``Body.link_radius``, wall w): mass = lambda x
length, lambda = rho_mat pi (rho_l^2 - (rho_l - w)^2), the radii converted mm -> m, so lambda is in
kg/mm. Every length is fixed by the design: the cranks, four-bar links and dyad links are design
parameters (c_z = ``Guards.c_z``, d_z when None, model §6), each platform side is |r x̂ - r ŷ| = r sqrt 2,
and each chord of a spherical link spans 1/12 of the arc angle alpha_u or beta_u (the IK puts u_beta
exactly alpha_u from û and beta_u from e; 0 < alpha, beta < 180 deg assumed), so it is 2 r sin(phi/24).

**Where the z dyad does not close** (the paper never checks it; ``z_dyad`` is off by default,
model §6) [resolution of an ambiguity]: both dyad rods become the straight segment D_z -> Q_z that
14.1 draws there, still with the masses lambda d_z and lambda c_z of the links one would build, so the
dyad's mass sits at the midpoint of D_z Q_z. Where it closes, the elbow J_z is 14.1's (elbow sign +1).
Exactly at the dyad's own singularity (J_z - D_z parallel to Q_z - J_z) the elbow's rate is infinite
and the Jacobians there are NaN.

Jacobians (the "exact route" of model §18.2 for every body): from the forward Jacobian of 15.1 in
R_w, J_E and J_e ``(..., 3, 5)``, the centre moves with J_C = J_E + L J_e (C = E + L e). Every point
then moves by a rule of its own body, with the actuator rates q_dot = (rho_x, rho_y, rho_z, delta_x,
delta_y) and the passive RTS/TMS angle rate sigma_dot_u:

* D_u: the crank turns about -v̂_u (model §3.1): dD_u = rho_dot_u (-v̂_u) x (D_u - P_u); P_u is fixed;
* K_u: the input link turns about û_u relative to the crank: dK_u = dD_u + delta_dot_u û_u x (K_u - D_u);
* Q_u: the platform translates: dQ_u = dC;
* T_u: the output link turns about û_u with sigma_u: dT_u = dC + sigma_dot_u û_u x (T_u - Q_u);
* u_beta: it turns about û_u with sigma_u (5.1): du_beta = sigma_dot_u û_u x u_beta, where Gamma_u =
  u_beta . e - cos beta_u = 0 gives sigma_dot_u = -(u_beta . e_dot) / J_AS,u, J_AS,u = (û x u_beta) . e;
* the arcs' points C + r (a_k v1 + b_k v2) (slerp between the unit vectors v1, v2 of the arc, fixed
  coefficients since its angle is fixed) move with dC + r (a_k dv1 + b_k dv2), with de = J_e q_dot;
* H + s e (the holder, the motor's ends): dC + s de;
* J_z: the planar dyad closes, (J - D).dJ = (J - D).dD, (J - Q).dJ = (J - Q).dQ, ẑ_m.dJ = ẑ_m.dQ
  (3x3 solve per point).

Units: lengths mm, masses kg, Jacobians mm/rad, in the patient frame R_w. Shapes broadcast over the
leading axes of the IK solution ``(...)``, e.g. designs x points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.evaluation.performance import jacobians_of_solution
from arcube.io.inputs import short_repr
from arcube.model import frames
from arcube.model.body import FOUR_BAR_PARTS, U_HAT, V_HAT, Z_ELBOW_SIGN, mechanism_points
from arcube.model.design import unpack
from arcube.model.mechanism import IKSolution
from arcube.options import Body, Masses, Options

N_CHORDS = 12
"""Chords per spherical link (model §18.1)."""
_LINKS = (
    "crank_x",
    "crank_y",
    "crank_z",
    *FOUR_BAR_PARTS,
    "zdyad_d",
    "zdyad_c",
    "platform_xy",
    "platform_yz",
    "platform_zx",
)
_ARC_NAMES = tuple(f"spherical_{kind}_{u}/{k}" for kind in ("alpha", "beta") for u in "xy" for k in range(N_CHORDS))
BODY_NAMES: tuple[str, ...] = (*_LINKS, *_ARC_NAMES, "actuator_D_x", "actuator_D_y", "drill_motor")
"""The 65 moving bodies, in the order of every body axis."""
N_BODIES = len(BODY_NAMES)
MOTOR = N_BODIES - 1


_BODY, _MASSES = Body(), Masses()
"""The defaults of model §14.1 and 18.1, as the settings declare them."""


@dataclass(frozen=True)
class MassModel:
    """The plain-value mass model (model §18.1) the functions take; :meth:`of` reads it from Options.

    Unlike :class:`arcube.options.Masses`, a zero density is allowed here (massless links, for tests
    and for isolating one kind of body). Gravity is in m/s^2 in the patient frame R_w.
    """

    link_radius_mm: float = _BODY.link_radius
    wall_mm: float = _MASSES.wall_mm
    density_kg_m3: float = _MASSES.density_kg_m3
    m_delta_kg: float = _MASSES.m_delta_kg
    m_motor_kg: float = _MASSES.m_motor_kg
    motor_radius_mm: float = _BODY.motor_radius
    motor_length_mm: float = _BODY.motor_length
    gravity: tuple[float, float, float] = _MASSES.gravity
    c_z_mm: float | None = None  # second z-dyad link; None: c_z = d_z (model §6)
    z_elbow: float = Z_ELBOW_SIGN

    def __post_init__(self) -> None:
        for name in ("link_radius_mm", "wall_mm", "motor_radius_mm", "motor_length_mm"):
            _check(self, name, lambda v: v > 0.0, "> 0")
        for name in ("density_kg_m3", "m_delta_kg", "m_motor_kg"):
            _check(self, name, lambda v: v >= 0.0, ">= 0")
        if self.c_z_mm is not None:
            _check(self, "c_z_mm", lambda v: v > 0.0, "> 0")
        if self.wall_mm >= self.link_radius_mm:
            raise InputError.of(
                "MassModel.wall_mm", f"must be < link_radius_mm ({self.link_radius_mm:g}), got {self.wall_mm:g}"
            )
        g = self.gravity
        if not (
            isinstance(g, (tuple, list))
            and len(g) == 3
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in g)
        ):
            raise InputError.of("MassModel.gravity", f"must be three finite numbers (m/s^2), got {short_repr(g)}")

    @classmethod
    def of(cls, options: Options | MassModel | None = None) -> MassModel:
        """The mass model of ``options`` (``Options.masses``, ``Options.body``, ``Options.guards.c_z``)."""
        if isinstance(options, MassModel):
            return options
        o = Options() if options is None else options
        m, b = o.masses, o.body
        return cls(
            b.link_radius,
            m.wall_mm,
            m.density_kg_m3,
            m.m_delta_kg,
            m.m_motor_kg,
            b.motor_radius,
            b.motor_length,
            tuple(float(v) for v in m.gravity),
            o.guards.c_z,
        )

    @property
    def lambda_kg_per_mm(self) -> float:
        """Mass per length of a link tube: rho_mat pi (rho_l^2 - (rho_l - w)^2), in kg/mm."""
        ro, ri = self.link_radius_mm * 1e-3, (self.link_radius_mm - self.wall_mm) * 1e-3
        return self.density_kg_m3 * math.pi * (ro * ro - ri * ri) * 1e-3


def _check(obj: MassModel, name: str, ok, text: str) -> None:  # type: ignore[no-untyped-def]
    v = getattr(obj, name)
    if not (isinstance(v, (int, float)) and math.isfinite(v) and ok(v)):
        raise InputError.of(f"MassModel.{name}", f"must be a finite number {text}, got {short_repr(v)}")


def _chord_lengths(params: ArrayLike, model: MassModel, c_z: ArrayLike | None = None) -> NDArray[np.float64]:
    """``(..., 62)``: the length (mm) of every rod of the links and arcs, fixed by the design; ``c_z``: each
    design's own z-dyad link (mm, broadcasting as ``params[..., 0]``), else the model's (d_z when None)."""
    g = unpack(params)
    lead = np.shape(g.r)
    if c_z is not None:
        c_z = np.asarray(c_z, dtype=float)
    elif model.c_z_mm is None:
        c_z = g.d[..., 2]
    else:
        c_z = np.full(lead, float(model.c_z_mm))
    side = np.sqrt(2.0) * g.r
    arcs = [2.0 * g.r[..., None] * np.sin(phi / (2 * N_CHORDS)) for phi in (g.alpha, g.beta)]  # (..., 2) each
    links = [
        *np.moveaxis(g.p, -1, 0),
        g.d[..., 0],
        g.d[..., 1],
        g.c[..., 0],
        g.c[..., 1],
        g.t[..., 0],
        g.t[..., 1],
        g.d[..., 2],
        c_z,
        side,
        side,
        side,
    ]
    chords = [np.repeat(a[..., i, None], N_CHORDS, axis=-1) for a in arcs for i in range(2)]
    return np.concatenate([np.stack(np.broadcast_arrays(*links), axis=-1), *chords], axis=-1)


def body_masses_kg(
    params: ArrayLike, options: Options | MassModel | None = None, c_z: ArrayLike | None = None
) -> NDArray[np.float64]:
    """``(..., 65)`` the mass (kg) of every body in :data:`BODY_NAMES` order, per design ``(..., 27)``;
    ``c_z`` ``(...)``: each design's own z-dyad link (mm; None: the model's)."""
    model = MassModel.of(options)
    rods = model.lambda_kg_per_mm * _chord_lengths(params, model, c_z)
    lead = rods.shape[:-1]
    tail = np.broadcast_to(np.array([model.m_delta_kg, model.m_delta_kg, model.m_motor_kg]), lead + (3,))
    return np.concatenate([rods, tail], axis=-1)


class Bodies(NamedTuple):
    """The moving bodies at poses, in R_w: rods from a to b (a = b for a point mass: the delta actuators), each with
    its centre of mass at (a + b)/2; the drill motor a solid cylinder (its extra inertia ``radial_inertia``). The
    ends and their Jacobians are NaN where the IK (or the forward Jacobian) fails."""

    mass: NDArray[np.float64]
    """``(..., 65)`` each body's mass, kg, in :data:`BODY_NAMES` order."""
    ends: NDArray[np.float64]
    """``(..., 65, 2, 3)`` its end points a, b, mm."""
    J_ends: NDArray[np.float64]
    """``(..., 65, 2, 3, 5)`` their Jacobians (da = J_a q_dot), mm/rad."""
    radial_inertia: NDArray[np.float64]
    """``(...)`` the drill motor's inertia beyond a thin rod's, m rho_m^2 / 4 about axes across e, kg mm^2 (its spin
    about e, m rho_m^2 / 2, is the spindle's and is not counted, model §18.2)."""

    @property
    def com(self) -> NDArray[np.float64]:
        """``(..., 65, 3)`` centres of mass, mm."""
        return 0.5 * (self.ends[..., 0, :] + self.ends[..., 1, :])

    @property
    def J_com(self) -> NDArray[np.float64]:
        """``(..., 65, 3, 5)`` Jacobians of the centres of mass, mm/rad."""
        return 0.5 * (self.J_ends[..., 0, :, :] + self.J_ends[..., 1, :, :])


def slerp_coefficients(phi: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(a_k, b_k) ``(..., 13)`` with sample k = a_k v1 + b_k v2 on the arc of angle phi from v1 to v2."""
    s = np.linspace(0.0, 1.0, N_CHORDS + 1)
    ph = phi[..., None]
    return np.sin((1.0 - s) * ph) / np.sin(ph), np.sin(s * ph) / np.sin(ph)


def _outer(vec: NDArray[np.float64], row: NDArray[np.float64]) -> NDArray[np.float64]:
    """vec ``(..., 3)`` times row ``(..., 5)`` -> ``(..., 3, 5)``."""
    return vec[..., :, None] * row[..., None, :]


def bodies_of_solution(
    sol: IKSolution,
    params: ArrayLike,
    options: Options | MassModel | None = None,
    jacobians: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    c_z: ArrayLike | None = None,
) -> Bodies:
    """The moving bodies (model §18.1) at the poses of an IK solution, with their Jacobians.

    ``jacobians`` = (J_E, J_e) of :func:`arcube.evaluation.performance.jacobians_of_solution` if at hand;
    ``c_z``: each design's own z-dyad link (mm, broadcasting as ``params[..., 0]``; None: the model's).
    """
    model = MassModel.of(options)
    g = unpack(params)
    J_E, J_e = jacobians_of_solution(sol, params) if jacobians is None else jacobians
    mp = mechanism_points(
        params,
        sol.E_m,
        sol.e,
        c_z=model.c_z_mm if c_z is None else c_z,
        z_elbow=model.z_elbow,
        motor_length=model.motor_length_mm,
        arc_samples=2,
        sol=sol,
    )  # the chords' points are built below
    lead = np.broadcast_shapes(mp.C.shape[:-1], J_E.shape[:-2])
    L = np.broadcast_to(g.L, lead)[..., None, None]
    J_C = J_E + L * J_e
    R = np.broadcast_to(frames.mount_rotation(g), lead + (3, 3))
    u_hat = np.einsum("...ij,uj->...ui", R, U_HAT)  # (..., 3 legs, 3) in R_w
    v_hat = np.einsum("...ij,uj->...ui", R, V_HAT)
    C, e, r = mp.C, mp.e, mp.r[..., None, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        ub = (mp.B - C[..., None, :]) / r  # (..., 2, 3) u_beta in R_w
        j_as = np.sum(np.cross(u_hat[..., :2, :], ub) * e[..., None, :], axis=-1)
        J_sigma = -np.einsum("...ui,...ij->...uj", ub, J_e) / j_as[..., None]  # (..., 2, 5)
    eye5 = np.eye(5)
    # TLS and TMS joint points (see the module docstring).
    J_D = _outer(np.cross(-v_hat, mp.D - mp.P), np.ones(5)) * eye5[:3, None, :]  # (..., 3, 3, 5): column rho_u only
    J_K = (
        J_D[..., :2, :, :]
        + _outer(np.cross(u_hat[..., :2, :], mp.K - mp.D[..., :2, :]), np.ones(5)) * eye5[3:, None, :]
    )
    J_Q = np.broadcast_to(J_C[..., None, :, :], lead + (3, 3, 5))
    J_T = J_Q[..., :2, :, :] + _outer(np.cross(u_hat[..., :2, :], mp.T - mp.Q[..., :2, :]), J_sigma)
    J_ub = _outer(np.cross(u_hat[..., :2, :], ub), J_sigma)  # (..., 2, 3, 5)
    # z dyad: the elbow J_z and its rate where the dyad closes.
    Dz, Qz, J_Dz, J_Qz = mp.D[..., 2, :], mp.Q[..., 2, :], J_D[..., 2, :, :], J_Q[..., 2, :, :]
    closes = np.broadcast_to(mp.z_closes, lead)
    Jz, J_Jz = _elbow(mp.J_z, Dz, Qz, J_Dz, J_Qz, u_hat[..., 2, :], closes)
    # the spherical links: 13 samples each, as slerp between fixed unit vectors with fixed coefficients.
    arc_pts, arc_J = [], []
    for kind, phi in (("alpha", g.alpha), ("beta", g.beta)):
        a, b = slerp_coefficients(np.broadcast_to(phi, lead + (2,)))  # (..., 2, 13)
        if kind == "alpha":
            v1, v2, J1, J2 = u_hat[..., :2, :], ub, np.zeros(lead + (2, 3, 5)), J_ub
        else:
            v1, v2, J1 = ub, np.broadcast_to(e[..., None, :], lead + (2, 3)), J_ub
            J2 = np.broadcast_to(J_e[..., None, :, :], lead + (2, 3, 5))
        X = C[..., None, None, :] + r[..., None] * (a[..., None] * v1[..., None, :] + b[..., None] * v2[..., None, :])
        JX = J_C[..., None, None, :, :] + r[..., None, None] * (
            a[..., None, None] * J1[..., None, :, :] + b[..., None, None] * J2[..., None, :, :]
        )
        arc_pts.append(np.stack([X[..., :-1, :], X[..., 1:, :]], axis=-2).reshape(lead + (2 * N_CHORDS, 2, 3)))
        arc_J.append(np.stack([JX[..., :-1, :, :], JX[..., 1:, :, :]], axis=-3).reshape(lead + (2 * N_CHORDS, 2, 3, 5)))
    J_H = J_C + mp.r[..., None, None] * J_e
    J_M = J_H + model.motor_length_mm * J_e
    # z dyad: D_z -> J_z -> Q_z where it closes; else both rods on D_z -> Q_z (module docstring).
    op = ~closes[..., None]
    z_ends = [
        (Dz, np.where(op, Qz, Jz), J_Dz, np.where(op[..., None], J_Qz, J_Jz)),
        (np.where(op, Dz, Jz), Qz, np.where(op[..., None], J_Dz, J_Jz), J_Qz),
    ]
    Pz = np.zeros(lead + (3, 5))
    pairs = [
        *((mp.P[..., u, :], mp.D[..., u, :], Pz, J_D[..., u, :, :]) for u in range(3)),
        *((mp.D[..., u, :], mp.K[..., u, :], J_D[..., u, :, :], J_K[..., u, :, :]) for u in range(2)),
        *((mp.K[..., u, :], mp.T[..., u, :], J_K[..., u, :, :], J_T[..., u, :, :]) for u in range(2)),
        *((mp.Q[..., u, :], mp.T[..., u, :], J_Q[..., u, :, :], J_T[..., u, :, :]) for u in range(2)),
        *z_ends,
        *((mp.Q[..., u, :], mp.Q[..., (u + 1) % 3, :], J_C, J_C) for u in range(3)),
        *((mp.D[..., u, :], mp.D[..., u, :], J_D[..., u, :, :], J_D[..., u, :, :]) for u in range(2)),
        (mp.H, mp.drill_end, J_H, J_M),
    ]
    ends = np.stack([np.stack(np.broadcast_arrays(a, b), axis=-2) for a, b, _, _ in pairs], axis=-3)
    J_ends = np.stack([np.stack(np.broadcast_arrays(Ja, Jb), axis=-3) for _, _, Ja, Jb in pairs], axis=-4)
    # BODY_NAMES order: the 14 links, the 48 chords, the two delta actuators, the motor.
    ends = np.concatenate([ends[..., :14, :, :], *arc_pts, ends[..., 14:, :, :]], axis=-3)
    J_ends = np.concatenate([J_ends[..., :14, :, :, :], *arc_J, J_ends[..., 14:, :, :, :]], axis=-4)
    bad = ~np.all(np.isfinite(J_E), axis=(-2, -1))
    ends = np.where(bad[..., None, None, None], np.nan, ends)
    J_ends = np.where(bad[..., None, None, None, None], np.nan, J_ends)
    mass = np.broadcast_to(body_masses_kg(params, model, c_z), lead + (N_BODIES,))
    radial = np.broadcast_to(model.m_motor_kg * model.motor_radius_mm**2 / 4.0, lead)
    return Bodies(mass=mass, ends=ends, J_ends=J_ends, radial_inertia=radial)


def _elbow(
    J: NDArray[np.float64],
    D: NDArray[np.float64],
    Q: NDArray[np.float64],
    J_D: NDArray[np.float64],
    J_Q: NDArray[np.float64],
    axis: NDArray[np.float64],
    closes: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The z-dyad elbow J ``(..., 3)`` and its Jacobian ``(..., 3, 5)`` from the dyad's closure (module
    docstring); NaN where the dyad does not close or sits at its own singularity."""
    M = np.stack(np.broadcast_arrays(J - D, J - Q, axis), axis=-2)  # (..., 3, 3)
    rhs = np.stack(
        [
            np.einsum("...i,...ij->...j", J - D, J_D),
            np.einsum("...i,...ij->...j", J - Q, J_Q),
            np.einsum("...i,...ij->...j", axis, J_Q),
        ],
        axis=-2,
    )
    ok = closes & np.all(np.isfinite(M), axis=(-2, -1)) & np.all(np.isfinite(rhs), axis=(-2, -1))
    M_safe = np.where(ok[..., None, None], M, np.eye(3))
    ok &= np.abs(np.linalg.det(M_safe)) > 0.0
    J_J = np.linalg.solve(np.where(ok[..., None, None], M_safe, np.eye(3)), np.where(ok[..., None, None], rhs, 0.0))
    return J, np.where(ok[..., None, None], J_J, np.nan)
