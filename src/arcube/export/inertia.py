"""Masses and inertias of the exported MuJoCo bodies, from the mass model of model §18.1.

Each MuJoCo body of :mod:`arcube.export.mjcf` carries the sum of the 18.1 bodies
(:data:`arcube.evaluation.mass_bodies.BODY_NAMES`) rigidly attached to it:

* ``crank_u`` (u = x, y, z), ``input_u``, ``coupler_u``, ``output_u`` (u = x, y), ``zdyad_d``,
  ``zdyad_c``: the 18.1 link of the same name;
* ``knee_u`` (u = x, y): ``actuator_D_u``, the point mass at D_u (where its geom is drawn);
* ``platform``: ``platform_xy``, ``platform_yz``, ``platform_zx``;
* ``alpha_u``, ``beta_u``: the 12 chords ``spherical_alpha_u/k``, ``spherical_beta_u/k``;
* ``drill``: ``drill_motor``.

A rod of mass m from a to b: centre of mass (a + b)/2, inertia m l^2/12 (I - d d^T) about it (d the
unit direction, l the length; 0 along the rod, 18.1); the drill motor adds m rho_m^2/4 (I - e e^T)
across its axis, and nothing along it: its spin about e is the spindle's, not counted in 18.2, so
MuJoCo's kinetic energy is 18.2's T but for the hinges' armature (rotor inertia the exporter adds for
numerical stability: 1e-4 kg m^2 on the actuated hinges, 1e-6 on the passive ones). A point mass has no inertia of its own. A body's inertia is the
sum over its parts about their common centre of mass (parallel-axis theorem), in the patient frame's
axes: the exporter builds every body frame parallel to it.

The mass model's geometry follows the exported body: :func:`mass_model_for` takes the link radius,
the motor radius and length from the export's radii and c_z from the export, the material, the
actuator and motor masses and gravity from ``masses``. MuJoCo rejects a moving body whose mass or a
principal moment of inertia is below 1e-15 (mjMINVAL), e.g. ``knee_z`` (no part of 18.1) or a single
rod (no inertia along itself): the exporter sets the compiler's ``boundmass`` and ``boundinertia``
to :data:`MASS_FLOOR_KG` and :data:`INERTIA_FLOOR_KG_MM2`, far below any 18.1 figure (their weight
moves a gravity torque by < 1e-8 N m).

Units: kg, mm, kg mm^2 (the MJCF's units), positions in the patient frame R_w.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from arcube.arrays import Floats
from arcube.errors import InputError
from arcube.evaluation.mass_bodies import BODY_NAMES, MOTOR, MassModel, bodies_of_solution
from arcube.model.body import BodyRadii
from arcube.model.mechanism import inverse_kinematics
from arcube.options import Options

__all__ = [
    "BODY_OF",
    "INERTIA_FLOOR_KG_MM2",
    "MASS_FLOOR_KG",
    "Inertial",
    "body_inertials",
    "mass_model_for",
    "principal_axes",
]

MASS_FLOOR_KG = 1.0e-6
"""Smallest mass MuJoCo gets for a moving body (compiler ``boundmass``), kg."""
INERTIA_FLOOR_KG_MM2 = 1.0e-6
"""Smallest principal moment MuJoCo gets for a moving body (compiler ``boundinertia``), kg mm^2."""


def _mujoco_body(name: str) -> str:
    base = name.split("/")[0]
    if base.startswith("spherical_"):
        return base.removeprefix("spherical_")  # spherical_alpha_x -> alpha_x
    if base.startswith("platform_"):
        return "platform"
    if base.startswith("actuator_D_"):
        return "knee_" + base[-1]
    if base == "drill_motor":
        return "drill"
    return base


BODY_OF: dict[str, str] = {name: _mujoco_body(name) for name in BODY_NAMES}
"""18.1 body name -> the MuJoCo body that carries it (module docstring)."""


@dataclass(frozen=True)
class Inertial:
    """One MuJoCo body's mass (kg), centre of mass ``com`` ``(3,)`` (R_w, mm) and inertia tensor
    ``inertia`` ``(3, 3)`` about the centre of mass, in R_w's axes (kg mm^2)."""

    mass: float
    com: Floats
    inertia: Floats


def mass_model_for(masses: MassModel | Options | None, radii: BodyRadii, c_z: float) -> MassModel:
    """The 18.1 mass model of an export: ``masses`` (default ``Options()``) with the exported geometry
    (link radius, motor radius and length of ``radii``; the z dyad's c_z, mm)."""
    if masses is not None and not isinstance(masses, (MassModel, Options)):
        raise InputError.of(
            "masses", f"must be an arcube.options.Options, a MassModel or None, got {type(masses).__name__}"
        )
    model = MassModel.of(masses)
    return dataclasses.replace(
        model,
        link_radius_mm=float(radii.link),
        motor_radius_mm=float(radii.motor),
        motor_length_mm=float(radii.motor_length),
        c_z_mm=float(c_z),
    )


def body_inertials(
    params: Floats,
    E: Floats,
    e: Floats,
    signs: Floats,
    model: MassModel,
) -> dict[str, Inertial]:
    """The :class:`Inertial` of every MuJoCo body that carries a part of 18.1, at the pose (E, e) ``(3,)``
    (R_w, mm) of one design ``(27,)`` in working mode ``signs`` ``(4,)``; keyed by MuJoCo body name.

    Raises :class:`InputError` where the IK (or the forward Jacobian that 18.1's bodies need) fails.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, signs)
        b = bodies_of_solution(sol, params, model)
    if not np.all(np.isfinite(b.ends)):
        raise InputError(
            "MJCF export: the mass model has no finite body positions at the assembled pose (singular pose)"
        )
    out: dict[str, Inertial] = {}
    for body in dict.fromkeys(BODY_OF.values()):
        parts = [i for i, name in enumerate(BODY_NAMES) if BODY_OF[name] == body]
        m = b.mass[parts]
        a, c = b.ends[parts, 0, :], b.ends[parts, 1, :]
        com_parts = 0.5 * (a + c)
        total = float(m.sum())
        com = (m[:, None] * com_parts).sum(axis=0) / total if total > 0.0 else com_parts.mean(axis=0)
        inertia = np.zeros((3, 3))
        for k, i in enumerate(parts):
            d = c[k] - a[k]
            inertia += (
                m[k] / 12.0 * (float(d @ d) * np.eye(3) - np.outer(d, d))
            )  # rod: m l^2/12 (I - d d^T), l d = b - a
            r = com_parts[k] - com
            inertia += m[k] * (float(r @ r) * np.eye(3) - np.outer(r, r))  # parallel axes
            if i == MOTOR:
                axis = d / np.linalg.norm(d)
                inertia += float(b.radial_inertia) * (np.eye(3) - np.outer(axis, axis))
        out[body] = Inertial(total, com, 0.5 * (inertia + inertia.T))
    return out


def principal_axes(inertia: Floats) -> tuple[Floats, Floats]:
    """The principal moments ``(3,)`` (>= 0, kg mm^2) and axes ``(3, 3)`` (columns, a right-handed
    rotation) of a symmetric inertia tensor ``(3, 3)``: inertia = axes diag(moments) axes^T.

    A flat body (the chords of one spherical link lie in one plane) has C = A + B exactly, which
    rounding (also MuJoCo's, of the axes) can break; MuJoCo rejects A + B < C, so all three moments are
    raised by the deficit (if any) plus 1e-10 of the largest: a relative change of ~1e-10.
    """
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    moments = np.maximum(moments, 0.0)
    deficit = max(float(np.max(2.0 * moments - moments.sum())), 0.0)  # max_k  m_k - (sum of the other two)
    return moments + deficit + 1e-10 * float(moments.max()), axes
