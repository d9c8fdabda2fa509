"""Constants shared by the kernel's modules: the layouts of its float rows, failure codes, numbers.

Every row the kernel hands around is a float64 vector of named blocks laid end to end, declared
once here as ``(name, width)`` entries. A :class:`Layout` turns the entries into offsets, and each
offset is also a module constant ``<PREFIX>_<NAME>`` (the name upper-cased, e.g. ``G_SIN_ALPHA``,
``S_ETA_G``, ``X_TORQUE_ACTUATOR``), which the compiled code reads: Numba freezes module-level
ints into the machine code.

* ``G_*``: :data:`GEOMETRY`, one design's geometry row (built by ``kernel._geometry``), ``N_GEO``;
* ``O_*``: :data:`OPTIONS`, the option vector (built by ``kernel._option_vector``), ``N_OPT``;
* ``S_*``: :data:`SUMMARY`, one design's summary row: one column per field of
  :class:`~arcube.evaluation.reference.TaskResults` after ``w_G``, and ``n_bad`` for ``w_G``, ``N_SUMM``;
* ``X_*``: :data:`EXTRA`, one point's extra row: one column per field of
  :class:`~arcube.evaluation.reference.PointResults` without an array of its own, ``N_EXTRA``.

So a new result field gets its column, and ``kernel.evaluate_task_numba`` packs it, without an edit
here; the compiled code then has to fill it (tests/test_kernel.py compares every field with the
reference, and fails on a field it has no tolerance for).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from arcube.evaluation.performance import MAXIMUM_FIELDS
from arcube.evaluation.reference import FAILURES, GRADE_SCALES, IK_FAILURES, PointResults, TaskResults
from arcube.model.design import SLICES

PI = math.pi
TWO_PI = 2.0 * math.pi
BIG = float(np.finfo(np.float64).max)
INF = math.inf
NAN = math.nan
EXCESS_CAP = 10.0
"""Cap on one argument's excess in the graded violation (model §12.2), as the reference's
``_EXCESS_CAP`` (tests/test_kernel_layout.py holds the two equal)."""

GRADE_Z_DYAD = GRADE_SCALES["z_dyad"]
GRADE_RHO = GRADE_SCALES["rho_max"]  # rad
GRADE_SINE = GRADE_SCALES["transmission"]
GRADE_CLEARANCE = GRADE_SCALES["clearance"]  # mm
GRADE_ENVELOPE = GRADE_SCALES["envelope"]  # mm
"""The scales S of model §16's guard terms min(s / S, 1), the reference's ``GRADE_SCALES``."""
CODE_IK_LAST = IK_FAILURES
"""Failure codes 1 .. CODE_IK_LAST: the inverse kinematics fails (a stage, or eta_L = inf; model §16)."""

CODE_SINGULAR = FAILURES.index("singular/J_LV") + 1  # 8 .. 14 in JACOBIAN_NAMES order
CODE_Z_DYAD = FAILURES.index("guard/z_dyad") + 1
CODE_RHO = FAILURES.index("guard/rho_max") + 1
CODE_TRANS = FAILURES.index("guard/transmission") + 1
CODE_KAPPA = FAILURES.index("guard/kappa_max") + 1
CODE_SAM = FAILURES.index("guard/single_assembly_mode") + 1
CODE_PATIENT = FAILURES.index("collision/patient") + 1
CODE_SELF = FAILURES.index("collision/self") + 1
CODE_ENVELOPE = FAILURES.index("collision/envelope") + 1
assert FAILURES[:7] == ("TLS/x", "TLS/y", "TLS/z", "RTS/x", "RTS/y", "TMS/x", "TMS/y")
assert CODE_IK_LAST == CODE_SINGULAR + 6 == CODE_Z_DYAD - 1

CHUNK = 64
"""Points per tile when a few designs are split over threads."""


class Layout:
    """Named blocks laid end to end in a float64 row: ``offset[name]``, ``width[name]``, ``size``."""

    def __init__(self, prefix: str, entries: Iterable[tuple[str, int]]) -> None:
        self.prefix = prefix
        self.entries: tuple[tuple[str, int], ...] = tuple(entries)
        self.offset: dict[str, int] = {}
        self.width: dict[str, int] = {}
        at = 0
        for name, width in self.entries:
            if name in self.offset or width < 1:
                raise ValueError(f"layout {prefix}: {name!r} repeated or of width {width}")
            self.offset[name] = at
            self.width[name] = width
            at += width
        self.size = at

    @property
    def names(self) -> tuple[str, ...]:
        """The block names, in row order."""
        return tuple(name for name, _ in self.entries)

    def constants(self) -> dict[str, int]:
        """``{"<PREFIX>_<NAME>": offset}`` of every block (the name upper-cased)."""
        out = {f"{self.prefix}_{name.upper()}": at for name, at in self.offset.items()}
        if len(out) != len(self.offset):
            raise ValueError(f"layout {self.prefix}: names that differ only in case")
        return out


def _width(at: slice | int) -> int:
    return 1 if isinstance(at, int) else at.stop - at.start


GEOMETRY = Layout(
    "G",
    (
        *((key, _width(SLICES[key])) for key in ("m", "f", "p", "d", "c", "t", "r")),  # mm, as in the design array
        ("o", _width(SLICES["o"])),  # transmitting offsets, rad
        ("sin_alpha", _width(SLICES["alpha"])),
        ("cos_alpha", _width(SLICES["alpha"])),
        ("cos_beta", _width(SLICES["beta"])),
        ("sin_beta", _width(SLICES["beta"])),
        ("rot", 9),  # the mounting rotation R, row-major (model §13.1)
        ("L", 1),  # tool offset, mm (model §13.2)
        ("flat", 1),  # 1.0 where R = I exactly (the stages then see E - m unrotated, bit for bit)
        # the spherical links as 12 chords each (model §18.1), in the order alpha_x, alpha_y, beta_x, beta_y:
        ("arc_chord", 4),  # sin(phi / 24): a chord is 2 r sin(phi / 24) long
        ("arc_a", 4),
        ("arc_b", 4),  # sum over the chords of the slerp coefficients of their midpoints (kernel._masses)
        ("c_z", 1),  # the z dyad's second link, mm: the design's own (model §19.1); NaN: Guards.c_z's, else d_z
    ),
)
"""One design's geometry row ``(N_GEO,)``: mm, rad and the trig of the spherical angles."""

OPTIONS = Layout(
    "O",
    (
        # guards (model §8.2, 14.3); an optional threshold is a pair <name>_on (1.0: active), <name>
        ("z_dyad", 1),
        ("c_z", 1),  # c_z in mm, NaN: c_z = d_z (a design's own c_z, in its geometry row, comes first)
        ("rho_max_on", 1),
        ("rho_max", 1),  # rad
        ("transmission_on", 1),
        ("transmission", 1),  # sine of the smallest transmission angle
        ("kappa_max_on", 1),
        ("kappa_max", 1),
        ("single_assembly_mode", 1),
        ("clearance_on", 1),
        ("clearance", 1),  # mm
        ("self_clearance_on", 1),
        ("self_clearance", 1),  # mm
        ("envelope_on", 1),
        ("envelope", 1),  # mm, the clearance to the envelope of the whole patient (model §19.5)
        # body (model §14.1)
        ("motor_length", 1),  # mm
        # loads (model §15)
        ("encoder", 5),  # rad, per actuator
        ("thrust", 1),
        ("lateral_force", 1),  # N
        ("stiffness", 5),  # N·mm/rad, per actuator
        # masses (model §18.1)
        ("link_mass", 1),  # kg/mm, lambda of a link's tube
        ("m_delta", 1),
        ("m_motor", 1),  # kg
        ("gravity", 3),  # m/s^2, patient frame
        # what to compute (1.0: yes)
        ("exact", 1),
        ("do_clearance", 1),
        ("do_self_clearance", 1),
        ("tip_metrics", 1),
        ("clearance_min_exact", 1),
        ("holding_torque", 1),  # with tip_metrics: the holding torque of model §18.2
        ("do_envelope", 1),  # the clearance to the envelope (model §19.5), given one
    ),
)
"""The option vector ``(N_OPT,)``: the settings as numbers, thresholds as the reference compares them."""

assert TaskResults._fields[:2] == ("points", "w_G")
SUMMARY_FIELDS: tuple[str, ...] = ("n_bad", *TaskResults._fields[2:])
"""Columns of a summary row: the number of failing points (w_G is n_bad == 0), then the TaskResults fields."""
SUMMARY = Layout("S", ((name, 1) for name in SUMMARY_FIELDS))
"""One design's summary row ``(N_SUMM,)``."""

POINT_ARRAYS: tuple[str, ...] = (
    "reachable",
    "failure",
    "kappa",
    "eta_L",
    "dexterity_pct",
    "excess",
    "rho",
    "delta",
    "sigma",
)
"""PointResults fields with arrays of their own in the kernel (``reachable`` is failure == 0)."""
EXTRA_FIELDS: tuple[str, ...] = tuple(name for name in PointResults._fields if name not in POINT_ARRAYS)
"""Columns of an extra row: every other PointResults field (the guard grade, model §16; body clearances, 14.3;
tip metrics, 15)."""
EXTRA = Layout("X", ((name, 1) for name in EXTRA_FIELDS))
"""One point's extra row ``(N_EXTRA,)``; integer fields (parts, actuators) held as floats."""

for _row in (GEOMETRY, OPTIONS, SUMMARY, EXTRA):
    globals().update(_row.constants())
del _row
N_GEO, N_OPT, N_SUMM, N_EXTRA = GEOMETRY.size, OPTIONS.size, SUMMARY.size, EXTRA.size

METRIC_COLUMNS = np.array([EXTRA.offset[name] for name in MAXIMUM_FIELDS], dtype=np.int64)
"""Extra columns of the tip metrics of model §15 and the holding torque of 18.2 that have a maximum (all but
the actuators)."""
MAXIMA = np.array(
    [(SUMMARY.offset[name.rsplit("_", 1)[0] + "_max"], EXTRA.offset[name]) for name in MAXIMUM_FIELDS], dtype=np.int64
)
"""(summary column, extra column) of each maximum over the reachable points (model §15.5, 18.2), ``(7, 2)``."""
