"""The named groups the kernel's functions hand one another instead of long lists of scalars and arrays.

Numba passes a namedtuple as a struct and compiles ``s.pcr0`` to a read of one of its fields, so a group
costs nothing at run time and one definition here replaces the lists each callee and call site repeated.

* :class:`RTS`, :class:`TLS`, :class:`TMS`: one point's stage values (model §3-7, mechanism coordinates)
  that the per-point pass (``_points``) hands to the condition numbers, the local guards, the body
  (``_body``), the tip metrics (``_performance``) and the holding torque (``_masses``). :class:`RTS`
  depends on the drill direction only and is kept over a run of equal directions;
* :class:`Inputs` and :class:`Rows`: what the driver (``_driver``) hands to each design's pass and
  summaries.

Every group is flat (no tuple inside): Numba's parallel loops pass a tuple's items as separate arguments,
one level deep only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class RTS(NamedTuple):
    """The RTS IK at one drill direction (``_points._rts_direction``), mechanism axes."""

    em0: float  # the drill axis e
    em1: float
    em2: float
    sig0: float  # sigma_x, sigma_y (rad)
    sig1: float
    arg0: float  # the arguments of their acos (|.| > 1: no solution)
    arg1: float
    ss0: float  # sin, cos of sigma_x, then of sigma_y
    cs0: float
    ss1: float
    cs1: float
    jas0: float  # the J_AS diagonal
    jas1: float
    det: float  # det[x_b, y_b, e]
    kAS: float  # kappa(J_AS), kappa(J_AP)
    kAP: float
    xb0: float  # u_beta of leg x (x_beta), then of leg y (y_beta)
    xb1: float
    xb2: float
    yb0: float
    yb1: float
    yb2: float


class TLS(NamedTuple):
    """The TLS IK (Eq 1) at one point: the centre C and its three legs, mechanism coordinates."""

    C0: float  # the centre C of the spherical stage (mm)
    C1: float
    C2: float
    rho0: float  # rho_x, rho_y, rho_z (rad; NaN unless asked for)
    rho1: float
    rho2: float
    cr0: float  # cos, sin of rho_x, then of rho_y and rho_z
    sr0: float
    cr1: float
    sr1: float
    cr2: float
    sr2: float
    pcr0: float  # p_u cos rho_u: the J_LV diagonal but for its sign
    pcr1: float
    pcr2: float


class TMS(NamedTuple):
    """The TMS IK (Eq 3) at one point, legs x and y: cos, sin of delta and the Jacobian terms (``_stages._tms_leg``)."""

    cd0: float
    sd0: float
    cd1: float
    sd1: float
    F0: float
    F1: float
    G0: float
    G1: float
    D0: float  # a_v
    D1: float
    E0: float  # a_w
    E1: float
    H0: float
    H1: float


class Inputs(NamedTuple):
    """What every design's pass reads (``_points._design_points``): the designs, the task's points, the options."""

    geometry: np.ndarray  # (D, N_GEO) geometry rows
    modes: np.ndarray  # (D, 4) working modes
    E: np.ndarray  # (P, 3) mm
    e: np.ndarray  # (P, 3) unit
    same_e: np.ndarray  # (P,) bool: e[k] equals e[k - 1] bitwise
    opt: np.ndarray  # (N_OPT,) the option vector
    full: bool  # the per-point details are wanted


class Rows(NamedTuple):
    """One design's per-point rows (P,), as ``_points._design_points`` and ``_summary._finalize`` fill them."""

    failure: np.ndarray  # int16 failure code
    eta: np.ndarray  # eta_raw, then eta_L
    excess: np.ndarray  # the IK domain excess of model §12.2
    assembly: np.ndarray  # int8 assembly mode
    dexterity: np.ndarray  # 100 / eta_L (%)
    extra: np.ndarray  # (P, N_EXTRA)
