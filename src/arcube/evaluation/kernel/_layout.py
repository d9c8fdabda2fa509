"""Constants shared by the kernel's modules: array layouts, failure codes, numeric constants."""

from __future__ import annotations

import math

import numpy as np

from arcube.evaluation.reference import _EXCESS_CAP, FAILURES

PI = math.pi
TWO_PI = 2.0 * math.pi
CAP = float(_EXCESS_CAP)
BIG = float(np.finfo(np.float64).max)
INF = math.inf
NAN = math.nan

CODE_SINGULAR = FAILURES.index("singular/J_LV") + 1  # 8 .. 14 in JACOBIAN_NAMES order
CODE_Z_DYAD = FAILURES.index("guard/z_dyad") + 1
CODE_RHO = FAILURES.index("guard/rho_max") + 1
CODE_TRANS = FAILURES.index("guard/transmission") + 1
CODE_KAPPA = FAILURES.index("guard/kappa_max") + 1
CODE_SAM = FAILURES.index("guard/single_assembly_mode") + 1
CODE_PATIENT = FAILURES.index("collision/patient") + 1
CODE_SELF = FAILURES.index("collision/self") + 1
assert FAILURES[:7] == ("TLS/x", "TLS/y", "TLS/z", "RTS/x", "RTS/y", "TMS/x", "TMS/y")

# Layout of the per-design geometry rows built by ``_geometry`` (mm, rad, trig of the angles).
G_M, G_F, G_P, G_D, G_C, G_T, G_R, G_O = 0, 3, 6, 9, 12, 14, 16, 17
G_SA, G_CA, G_CB, G_SB = 19, 21, 23, 25
G_ROT = 27  # 9 entries of the mounting rotation R, row-major (MODEL.md 13.1)
G_L = 36  # tool offset L, mm (MODEL.md 13.2)
G_FLAT = 37  # 1.0 where R = I exactly (the stages then see E - m unrotated, bit for bit)
N_GEO = 38

# Layout of the option vector built by ``_option_vector``.
O_ZDYAD, O_CZ, O_RHO_ON, O_RHO, O_TR_ON, O_TR, O_KM_ON, O_KM, O_SAM, O_EXACT = range(10)
O_DO_SELF, O_ANAT, O_CLR_ON, O_CLR, O_SELF_ON, O_SELF, O_LM, O_DO_CLR = range(10, 18)  # body clearances, MODEL.md 14
O_PERF = 18  # 12 entries: encoder (5, rad), thrust, lateral force (N), stiffness (5, N·mm/rad); MODEL.md 15
O_PERF_ON = 30  # 1.0: compute the metrics of MODEL.md 15
O_CMIN_EXACT = 31  # 1.0: summaries need the exact smallest clearance, not only the guard's decision
N_OPT = 32

# Layout of the per-design summary rows.
S_NBAD, S_RF, S_ETAG, S_VIOL, S_DMIN, S_DMEAN, S_DMAX, S_CMIN, S_SMIN = range(9)
S_PERF = 9  # 6 maxima: tip, lateral, axial, axis error, torque, deflection (MODEL.md 15.5)
N_SUMM = 15

# Layout of the per-point extra rows (body clearances).
X_CLR, X_PART, X_SELF = range(3)
X_PERF = 3  # 7 entries: kernel._performance.N_PERF (MODEL.md 15)
N_EXTRA = 10

CHUNK = 64
"""Points per tile when a few designs are split over threads."""
