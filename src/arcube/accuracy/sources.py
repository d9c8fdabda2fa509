"""The error sources of model §20.1: names, units, kinds, and each one's tolerance for a design.

The n = 41 sources, in :data:`SOURCE_NAMES` order (the order of every ``(..., n)`` array of
:mod:`arcube.accuracy`):

* the design parameters that move the tool, in :data:`arcube.model.design.PARAM_NAMES` order
  (d_z does not, and has no source): the docking m_x m_y m_z; the 13 lengths f_u, p_u, d_x, d_y,
  c_x, c_y, t_x, t_y, r; the 6 angles o_u, alpha_u, beta_u; the docking mount_rx .. mount_rz; L;
* ``q0_<joint>``: the joint zero offsets (once per built robot);
* ``encoder_<joint>`` and ``backlash_<joint>``: at every pose;

with joints rho_x rho_y rho_z delta_x delta_y (:data:`JOINTS`). A tolerance T is in mm for the lengths,
L and m, in degrees for every angle (o, alpha, beta, mount and the joints' sources).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.iso import angular_tolerance, linear_tolerance
from arcube.model.design import INDEX, PARAM_NAMES, full_params

JOINTS: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated joints (the columns of J_E, model §15.1)."""

LENGTHS: tuple[str, ...] = tuple("f_x f_y f_z p_x p_y p_z d_x d_y c_x c_y t_x t_y r L".split())
"""The group ``lengths``: the 13 lengths that move the tip, and the tool offset L (ISO 2768-1 linear)."""
ANGLES: tuple[str, ...] = ("o_x", "o_y", "alpha_x", "alpha_y", "beta_x", "beta_y")
"""The group ``angles``: ISO 2768-1 angular, with r as the shorter leg."""
DOCKING_MM: tuple[str, ...] = ("m_x", "m_y", "m_z")
DOCKING_DEG: tuple[str, ...] = ("mount_rx", "mount_ry", "mount_rz")
PARAM_SOURCES: tuple[str, ...] = tuple(n for n in PARAM_NAMES if n in {*LENGTHS, *ANGLES, *DOCKING_MM, *DOCKING_DEG})
"""The 26 design parameters that move the tool, in design order."""
JOINT_KINDS: tuple[str, ...] = ("q0", "encoder", "backlash")
SOURCE_NAMES: tuple[str, ...] = (*PARAM_SOURCES, *(f"{kind}_{j}" for kind in JOINT_KINDS for j in JOINTS))
"""Every error source, in the order of the arrays of :mod:`arcube.accuracy`."""
N_SOURCES = len(SOURCE_NAMES)
GROUPS: dict[str, tuple[str, ...]] = {
    "lengths": LENGTHS,
    "angles": ANGLES,
    **{kind: tuple(f"{kind}_{j}" for j in JOINTS) for kind in JOINT_KINDS},
}
"""Names a tolerance override may give for several sources at once: ``lengths``, ``angles``, and ``q0``,
``encoder``, ``backlash`` (that source of all five joints, deg)."""

_DEG_NAMES = frozenset({*ANGLES, *DOCKING_DEG})
UNITS: tuple[str, ...] = tuple("mm" if n in PARAM_SOURCES and n not in _DEG_NAMES else "deg" for n in SOURCE_NAMES)
"""Unit of each source's tolerance (and of its deviation)."""
IS_ANGLE: NDArray[np.bool_] = np.array([u == "deg" for u in UNITS])

PARAM_COLUMN: NDArray[np.intp] = np.array([INDEX.get(n, -1) for n in SOURCE_NAMES])
"""Index into the 27 design parameters of each source (-1 for the joints' sources)."""
JOINT_COLUMN: NDArray[np.intp] = np.array(
    [JOINTS.index(n.split("_", 1)[1]) if n not in INDEX else -1 for n in SOURCE_NAMES]
)
"""Index into the 5 joints of each joint source (-1 for the parameters)."""
PER_ROBOT: NDArray[np.bool_] = np.array([not n.startswith(("encoder_", "backlash_")) for n in SOURCE_NAMES])
"""Sources drawn once per built robot (parameters, docking, zero offsets); the others afresh at every pose."""


def resolve_overrides(tol: Mapping[str, float]) -> dict[str, float]:
    """Per-source tolerances from a mapping of source or group names (a group first, then single
    names over it, whatever the mapping's order). Names must be known (checked by the settings)."""
    out: dict[str, float] = {}
    for name, value in tol.items():
        if name in GROUPS:
            out.update({n: float(value) for n in GROUPS[name]})
    out.update({name: float(value) for name, value in tol.items() if name not in GROUPS})
    return out


def class_unused(tol: Mapping[str, float]) -> bool:
    """Whether the overrides ``tol`` set every source a tolerance class sets (the :data:`LENGTHS` and
    :data:`ANGLES`): the class then changes nothing (:func:`tolerances`)."""
    return set(LENGTHS) | set(ANGLES) <= set(resolve_overrides(tol))


def tolerances(
    params: ArrayLike,
    tolerance_class: str = "m",
    tol: Mapping[str, float] | None = None,
    q0_deg: float = 0.1,
    encoder_deg: float = 0.01,
    backlash_arcmin: float = 1.0,
    docking_mm: float = 0.0,
    docking_deg: float = 0.0,
) -> NDArray[np.float64]:
    """Each source's tolerance T ``(..., n)`` (mm or deg, :data:`UNITS`) for designs ``(..., 27)`` (mm, deg).

    Lengths: ISO 2768-1 linear of the nominal length in ``tolerance_class`` (:mod:`arcube.accuracy.iso`);
    angles: ISO 2768-1 angular with the design's r as the shorter leg; the joints and the docking from
    the scalar arguments (backlash given in arcmin); then ``tol`` (mm or deg, by source or group) over all.
    """
    x = full_params(params)
    T = np.zeros(x.shape[:-1] + (N_SOURCES,))
    r = x[..., INDEX["r"]]
    for i, name in enumerate(SOURCE_NAMES):
        if name in LENGTHS:
            T[..., i] = linear_tolerance(x[..., INDEX[name]], tolerance_class)
        elif name in ANGLES:
            T[..., i] = angular_tolerance(r, tolerance_class)
        elif name in DOCKING_MM:
            T[..., i] = docking_mm
        elif name in DOCKING_DEG:
            T[..., i] = docking_deg
        else:
            kind = name.split("_", 1)[0]
            T[..., i] = {"q0": q0_deg, "encoder": encoder_deg, "backlash": backlash_arcmin / 60.0}[kind]
    for name, value in resolve_overrides(tol or {}).items():
        T[..., SOURCE_NAMES.index(name)] = value
    return T


def sigmas(T: ArrayLike, distribution: str) -> NDArray[np.float64]:
    """Standard deviations of the sources: T/sqrt(3) (``uniform`` on [-T, T]) or T/3 (``normal``), model §20.1."""
    return np.asarray(T, dtype=float) / (np.sqrt(3.0) if distribution == "uniform" else 3.0)
