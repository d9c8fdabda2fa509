"""The 27 design parameters of the AR-CUBE: the paper's 23 (model §2), then the mounting
rotation and the tool offset (model §13.3): ``mount_rx, mount_ry, mount_rz`` (deg) and ``L`` (mm).

Long module: the parameters, their checks and :class:`Design`'s JSON form are one contract, the design file.

Two layers, as in spatialmath:

* the plain-array layer: a design is a float array of shape ``(..., 27)`` in the order of
  :data:`PARAM_NAMES`, lengths in mm and angles in degrees (the units of files and users); a
  ``(..., 23)`` array is the paper's design, the four additions at 0;
  :func:`unpack` turns it into :class:`Geometry`, named arrays with angles in radians, which is
  what the stage modules consume;
* :class:`Design`, a small validated container for one design with JSON I/O.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.io.inputs import COORDINATE_LIMIT_MM, load_json, short_repr
from arcube.model.modes import format_mode, parse_mode

PARAM_NAMES: tuple[str, ...] = (
    "m_x",
    "m_y",
    "m_z",
    "f_x",
    "f_y",
    "f_z",
    "p_x",
    "p_y",
    "p_z",
    "d_x",
    "d_y",
    "d_z",
    "c_x",
    "c_y",
    "t_x",
    "t_y",
    "r",
    "o_x",
    "o_y",
    "alpha_x",
    "alpha_y",
    "beta_x",
    "beta_y",
    "mount_rx",
    "mount_ry",
    "mount_rz",
    "L",
)
"""Code order of the 27 parameters (model §2 and 13.3)."""

SLICES: dict[str, slice | int] = {
    "m": slice(0, 3),
    "f": slice(3, 6),
    "p": slice(6, 9),
    "d": slice(9, 12),
    "c": slice(12, 14),
    "t": slice(14, 16),
    "r": 16,
    "o": slice(17, 19),
    "alpha": slice(19, 21),
    "beta": slice(21, 23),
    "mount": slice(23, 26),
    "L": 26,
}
"""The one parameter layout: where each :class:`Geometry` field sits on the last axis of a design
array, i.e. the :data:`PARAM_NAMES` ``<key>_*`` (an int: the one scalar parameter ``<key>``).
``x[..., SLICES["p"]]`` is ``(..., 3)``, ``x[..., SLICES["r"]]`` is ``(...)``."""
ANGLE_GROUPS: frozenset[str] = frozenset({"o", "alpha", "beta", "mount"})
"""The :data:`SLICES` keys in degrees in a design array (radians in :class:`Geometry`)."""

N_PARAMS = len(PARAM_NAMES)
N_PAPER = 23
PAPER_NAMES: tuple[str, ...] = PARAM_NAMES[:N_PAPER]
"""The paper's 23 parameters (model §2); ``--free all`` frees these."""
MOUNT_NAMES: tuple[str, ...] = ("mount_rx", "mount_ry", "mount_rz")
ADDED_NAMES: tuple[str, ...] = (*MOUNT_NAMES, "L")
"""The four additions of model §13; 0 when a design file omits them (the paper)."""
INDEX: dict[str, int] = {name: i for i, name in enumerate(PARAM_NAMES)}
PLACEMENT: tuple[str, ...] = ("m_x", "m_y", "m_z", *MOUNT_NAMES)
"""A docking's own parameters (model §19.1): where the base is clamped and how it is turned."""
ROBOT_NAMES: tuple[str, ...] = (*(n for n in PARAM_NAMES if n not in PLACEMENT), "c_z")
"""The robot's 22 parameters (model §19.1): the 27 but the docking's six, then c_z."""

ANGLE_NAMES: frozenset[str] = frozenset({"o_x", "o_y", "alpha_x", "alpha_y", "beta_x", "beta_y", *MOUNT_NAMES})
POSITION_NAMES: frozenset[str] = frozenset({"m_x", "m_y", "m_z"})
LENGTH_NAMES: frozenset[str] = frozenset(PARAM_NAMES) - ANGLE_NAMES - POSITION_NAMES - {"L"}
"""Link lengths: must be strictly positive (L, the tool offset, may be 0)."""

UNITS: dict[str, str] = {n: ("deg" if n in ANGLE_NAMES else "mm") for n in PARAM_NAMES}

MAX_LENGTH_MM = 2000.0
"""Longest link, tool offset L or z-dyad link c_z, mm. The robot stands beside an operating table (about 0.6 m
wide) and reaches a neck; its default search bounds stop at 250 mm (model §12.1) and the z dyad's at 500 mm. 2 m is
longer than any such robot's link, so a longer one is a unit mistake (um read as mm) or a typo, which would only
produce meaningless numbers downstream."""
MAX_POSITION_MM = COORDINATE_LIMIT_MM
"""Largest |m_x|, |m_y|, |m_z| (the base, patient frame, mm): within the coordinate range of every file read
(:data:`arcube.io.inputs.COORDINATE_LIMIT_MM`, 100 m), as the plan's points are."""

PAPER_TABLE2: dict[str, float] = {
    "m_x": 31.8694,
    "m_y": 11.9589,
    "m_z": 192.0769,
    "f_x": 123.1147,
    "f_y": 116.9719,
    "f_z": 56.7787,
    "p_x": 134.099,
    "p_y": 149.9886,
    "p_z": 99.8766,
    "d_x": 79.2596,
    "d_y": 99.9402,
    "d_z": 53.5671,
    "c_x": 139.8911,
    "c_y": 106.8319,
    "t_x": 70.9301,
    "t_y": 65.3946,
    "r": 70.4466,
    "o_x": -19.2229,
    "o_y": 43.2917,
    "alpha_x": 52.6402,
    "alpha_y": 66.446,
    "beta_x": 50.0038,
    "beta_y": 62.1208,
    "mount_rx": 0.0,
    "mount_ry": 0.0,
    "mount_rz": 0.0,
    "L": 0.0,
}
"""The paper's Table 2 (the optimum it reports)."""

PRESETS: dict[str, dict[str, float]] = {"paper": PAPER_TABLE2}


@dataclass(frozen=True)
class Geometry:
    """Named view of design arrays, angles in radians. Every field broadcasts over ``...``.

    Per-leg fields are stacked on the last axis in leg order x, y, z (or x, y for the two
    legs that have a four-bar and a spherical link).
    """

    m: NDArray[np.float64]  # (..., 3) mm, origin of R_m in R_w
    f: NDArray[np.float64]  # (..., 3) mm, frame links
    p: NDArray[np.float64]  # (..., 3) mm, cranks
    d: NDArray[np.float64]  # (..., 3) mm, TMS input links (x, y) and z-dyad first link
    c: NDArray[np.float64]  # (..., 2) mm, TMS couplers
    t: NDArray[np.float64]  # (..., 2) mm, TMS output links
    r: NDArray[np.float64]  # (...,)  mm, RTS radius
    o: NDArray[np.float64]  # (..., 2) rad, transmitting offsets
    alpha: NDArray[np.float64]  # (..., 2) rad, proximal spherical links
    beta: NDArray[np.float64]  # (..., 2) rad, distal spherical links
    mount: NDArray[np.float64]  # (..., 3) rad, mounting rotation angles (rx, ry, rz), model §13.1
    L: NDArray[np.float64]  # (...,) mm, tool offset from the drill tip E to the centre C, model §13.2


def full_params(params: ArrayLike) -> NDArray[np.float64]:
    """Design arrays ``(..., 23)`` or ``(..., 27)`` as ``(..., 27)`` (the four additions 0 when absent)."""
    x = np.asarray(params, dtype=float)
    if x.shape[-1:] == (N_PAPER,):
        return np.concatenate([x, np.zeros(x.shape[:-1] + (N_PARAMS - N_PAPER,))], axis=-1)
    if x.shape[-1:] != (N_PARAMS,):
        raise ValueError(f"design array must have last axis {N_PARAMS} (or {N_PAPER}), got shape {x.shape}")
    return x


def unpack(params: ArrayLike) -> Geometry:
    """Split a design array ``(..., 27)`` or ``(..., 23)`` (mm, deg) into a :class:`Geometry` (mm, rad)."""
    x = full_params(params)
    fields = {key: x[..., at] for key, at in SLICES.items()}
    return Geometry(**{key: np.deg2rad(v) if key in ANGLE_GROUPS else v for key, v in fields.items()})


def validate_values(values: Mapping[str, Any], source: str = "design") -> dict[str, float]:
    """Check a name -> value mapping: the 23 names of model §2 (the four of 13.3 are optional, 0 when absent; but the
    three mounting angles come together, and with L), finite numbers, positive lengths, L >= 0, mounting angles
    within ±360 deg.

    Returns the values as floats in :data:`PARAM_NAMES` order. Raises :class:`InputError` with
    a one-line message naming ``source`` and the first problem found.
    """
    if not isinstance(values, Mapping):
        raise InputError(f"{source}: expected a mapping of parameter names to values, got {type(values).__name__}")
    unknown = [k for k in values if k not in INDEX]
    if unknown:
        raise InputError(
            f"{source}: unknown parameter {short_repr(unknown[0])} (expected the 27 names of model §2 and 13.3: {', '.join(PARAM_NAMES)})"
        )
    mounted = [n for n in MOUNT_NAMES if n in values]
    if mounted and len(mounted) < len(MOUNT_NAMES):  # a partial group is a mistake, not a rotation about fewer axes
        raise InputError(
            f"{source}: the mounting rotation needs all of {', '.join(MOUNT_NAMES)}; missing "
            f"{', '.join(n for n in MOUNT_NAMES if n not in values)} (a paper-style design gives none of them)"
        )
    if mounted and "L" not in values:
        raise InputError(
            f"{source}: a mounted design needs its tool offset L (mm): the tip is L from the spherical stage's centre"
        )
    values = {**{n: 0.0 for n in ADDED_NAMES}, **values}
    missing = [n for n in PARAM_NAMES if n not in values]
    if missing:
        raise InputError(f"{source}: missing parameter(s) {', '.join(missing)}")
    out: dict[str, float] = {}
    for name in PARAM_NAMES:
        raw = values[name]
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise InputError(f"{source}: parameter {name} is not a number ({short_repr(raw)})")
        try:
            val = float(raw)
        except OverflowError:  # an int beyond the float range
            raise InputError(f"{source}: parameter {name} is out of range ({short_repr(raw)})") from None
        if not math.isfinite(val):
            raise InputError(f"{source}: parameter {name} is not finite ({short_repr(raw)})")
        if name in LENGTH_NAMES and val <= 0.0:
            raise InputError(f"{source}: length {name} must be positive, got {val:g} mm")
        if (name in LENGTH_NAMES or name == "L") and val > MAX_LENGTH_MM:
            raise InputError(
                f"{source}: length {name} must be at most {MAX_LENGTH_MM:g} mm (no link of a robot beside a patient is "
                f"longer; a unit mistake?), got {val:g} mm"
            )
        if name in POSITION_NAMES and abs(val) > MAX_POSITION_MM:
            raise InputError(f"{source}: position {name} must lie within ±{MAX_POSITION_MM:g} mm, got {val:g} mm")
        if name.startswith(("alpha_", "beta_")) and not 0.0 < val < 180.0:
            raise InputError(f"{source}: spherical link angle {name} must lie in (0, 180) deg, got {val:g}")
        if name in MOUNT_NAMES and abs(val) > 360.0:  # the same rotation mod 360, but no one writes it so: a typo
            raise InputError(f"{source}: mounting angle {name} must lie within ±360 deg, got {val:g}")
        if name == "L" and val < 0.0:
            raise InputError(f"{source}: tool offset L must be >= 0 mm, got {val:g}")
        out[name] = val
    return out


ACTUATED: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated joints, in the order of joint vectors."""
Q0_KEYS: tuple[str, ...] = tuple(f"q0_{j}" for j in ACTUATED)
"""The keys of a calibrated design's joint zero offsets in a design file (deg, model §21.4)."""
EXTRA_KEYS: tuple[str, ...] = ("c_z", "mode", "zdyad_elbow", *Q0_KEYS)
ROBOT_FIELDS = ("c_z", "dockings", "zdyad_elbow")
"""The fields by which a design file describes a built robot (model §19.1), which must then carry its ``mode``."""
"""What a design file may carry beside the 27 parameters (see :class:`Design`)."""
_LISTS = ("placements", "dockings")
"""Lists a run or design job writes beside a design (each patient's or docking's placement): not part of it."""
LABEL_KEYS: tuple[str, ...] = ("patient", "side", "plan_digest")
"""What a docking file says about itself (whose docking, which side): checked, not part of the design."""


def check_labels(values: Mapping[str, Any], source: str) -> None:
    """InputError unless a docking file's ``patient`` is text and its ``side`` R or L (both optional)."""
    patient, side = values.get("patient"), values.get("side")
    if patient is not None and (not isinstance(patient, str) or not patient.strip()):
        raise InputError(f"{source}: patient must be the docking's patient name (text), got {short_repr(patient)}")
    if side is not None and side not in ("R", "L"):
        raise InputError(f'{source}: side must be "R" or "L", got {short_repr(side)}')


def _extra_number(value: Any, key: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{source}: {key} is not a number ({short_repr(value)})")
    try:
        v = float(value)
    except OverflowError:
        raise InputError(f"{source}: {key} is out of range ({short_repr(value)})") from None
    if not math.isfinite(v):
        raise InputError(f"{source}: {key} is not finite ({short_repr(value)})")
    return v


def check_extras(c_z: Any, mode: Any, q0_deg: Any, zdyad_elbow: Any, source: str = "design") -> tuple[Any, ...]:
    """(c_z, mode, q0_deg, zdyad_elbow) of a design, checked and normalised (InputError naming ``source``)."""
    if c_z is not None:
        c_z = _extra_number(c_z, "c_z", source)
        if not 0.0 < c_z <= MAX_LENGTH_MM:
            raise InputError(
                f"{source}: c_z (the z dyad's second link) must be a positive length of at most {MAX_LENGTH_MM:g} mm, "
                f"got {c_z:g} mm"
            )
    if mode is not None:
        if not isinstance(mode, str):
            raise InputError(f'{source}: mode must be text such as "+,+,+,-", got {short_repr(mode)}')
        try:
            mode = format_mode(parse_mode(mode))
        except ValueError as exc:
            raise InputError(f"{source}: {exc}") from None
    if q0_deg is not None:
        q0 = tuple(_extra_number(v, k, source) for k, v in zip(Q0_KEYS, q0_deg))
        if len(q0) != len(Q0_KEYS) or len(tuple(q0_deg)) != len(Q0_KEYS):
            raise InputError(f"{source}: a calibrated design needs five zero offsets ({', '.join(Q0_KEYS)})")
        if any(abs(v) > 180.0 for v in q0):
            raise InputError(f"{source}: a zero offset must lie within +-180 deg, got {list(q0)}")
        q0_deg = q0
    if zdyad_elbow is None or isinstance(zdyad_elbow, bool) or zdyad_elbow not in (1, -1, 1.0, -1.0):
        raise InputError(
            f"{source}: zdyad_elbow must be +1 or -1 (the side of the z dyad's elbow, model §19.1), got {short_repr(zdyad_elbow)}"
        )
    return c_z, mode, q0_deg, float(zdyad_elbow)


@dataclass(frozen=True)
class Design:
    """One validated design: 27 values in mm and degrees, in :data:`PARAM_NAMES` order, and what a
    design file records beside them:

    * ``c_z``: the z dyad's second link (mm, model §19.1); None: c_z = d_z (model §6), as every
      file written before c_z became a parameter;
    * ``mode``: the working mode the design was made for (``"+,+,-,+"``); commands use it when no mode
      is given; None: not recorded (``+,+,+,+`` then, the paper's);
    * ``q0_deg``: a calibrated design's joint zero offsets (deg, model §21.4), which the controller's
      joint angles subtract; None: not calibrated (all 0);
    * ``zdyad_elbow``: the side of the z dyad's elbow, +1 (model §14.1's) or -1 (19.1).
    """

    values: tuple[float, ...]
    c_z: float | None = None
    mode: str | None = None
    q0_deg: tuple[float, ...] | None = None
    zdyad_elbow: float = 1.0

    def __post_init__(self) -> None:
        if len(self.values) == N_PAPER:
            object.__setattr__(self, "values", tuple(self.values) + (0.0,) * (N_PARAMS - N_PAPER))
        if len(self.values) != N_PARAMS:
            raise InputError(f"design: expected {N_PARAMS} values (or the paper's {N_PAPER}), got {len(self.values)}")
        validate_values(dict(zip(PARAM_NAMES, self.values)))
        c_z, mode, q0, elbow = check_extras(self.c_z, self.mode, self.q0_deg, self.zdyad_elbow)
        for name, value in (("c_z", c_z), ("mode", mode), ("q0_deg", q0), ("zdyad_elbow", elbow)):
            object.__setattr__(self, name, value)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any], source: str = "design") -> Design:
        """Build from a flat name -> value mapping (validated): the 27 parameters, and the keys of
        :data:`EXTRA_KEYS` when present (lists of placements or dockings beside them are skipped)."""
        if not isinstance(values, Mapping):
            raise InputError(f"{source}: expected a mapping of parameter names to values, got {type(values).__name__}")
        params = {k: v for k, v in values.items() if k not in EXTRA_KEYS and k not in _LISTS and k not in LABEL_KEYS}
        if (
            isinstance(values.get("dockings"), list) and "m_x" not in values
        ):  # model §19.1: a robot without its placements
            raise InputError(
                f"{source}: one robot at {len(values['dockings'])} dockings, no placement of its own: give one docking's "
                "design (dockings/<patient>_<side>/design.json beside it), or the side whose docking to use"
            )
        check_labels(values, source)
        checked = validate_values(params, source)
        present = [k for k in Q0_KEYS if k in values]
        if present and len(present) != len(Q0_KEYS):
            raise InputError(
                f"{source}: a calibrated design needs all five zero offsets; missing {', '.join(k for k in Q0_KEYS if k not in values)}"
            )
        q0 = [values[k] for k in Q0_KEYS] if present else None
        extras = check_extras(values.get("c_z"), values.get("mode"), q0, values.get("zdyad_elbow", 1.0), source)
        return cls(tuple(checked[n] for n in PARAM_NAMES), *extras)

    @classmethod
    def from_vector(cls, vector: ArrayLike) -> Design:
        """Build from a length-27 (or the paper's 23) vector in :data:`PARAM_NAMES` order (mm, deg)."""
        try:
            v = np.asarray(vector, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                f"design: the vector must hold numbers (mm, deg) ({' '.join(str(exc).split())[:120]})"
            ) from None
        return cls(tuple(float(a) for a in v))

    @classmethod
    def coerce(cls, design: Any) -> Design:
        """A :class:`Design` from what a caller may give: a Design, a preset name or a design JSON path,
        or a vector of 27 (or 23) numbers; InputError naming ``design`` otherwise."""
        if isinstance(design, Design):
            return design
        if isinstance(design, (str, os.PathLike)):
            return cls.load(os.fspath(design))
        if isinstance(design, (bytes, dict)) or design is None:
            raise InputError.of(
                "design",
                f"must be a Design, a preset name, a design JSON path or 27 numbers, got {type(design).__name__}",
            )
        return cls.from_vector(design)

    @classmethod
    def preset(cls, name: str) -> Design:
        """A named preset; ``paper`` is Table 2."""
        if name not in PRESETS:
            raise InputError(f"unknown design preset {name!r} (known: {', '.join(PRESETS)})")
        return cls.from_dict(PRESETS[name], source=f"preset {name}")

    @classmethod
    def from_json(cls, path: str | os.PathLike[str]) -> Design:
        """Read a flat JSON object keyed by the parameter names and :data:`EXTRA_KEYS` (a ``placements``
        or ``dockings`` list beside them, as runs and design jobs write them, is not part of the design)."""
        p = Path(path)
        # a regular file of at most 64 MiB, UTF-8 or UTF-16/32 with a BOM, JSON nested <= 64 levels
        data = load_json(p)
        if not isinstance(data, dict):
            raise InputError(f"{p}: a design file must hold one JSON object keyed by parameter names")
        return cls.from_dict(data, source=str(p))

    @classmethod
    def paper(cls) -> Design:
        """The paper's optimum (Table 2)."""
        return cls.preset("paper")

    @classmethod
    def load(cls, spec: str | os.PathLike[str]) -> Design:
        """A preset name (``paper``) or a path to a design JSON file."""
        if isinstance(spec, str) and spec in PRESETS:
            return cls.preset(spec)
        if isinstance(spec, str) and not os.path.lexists(spec) and not os.path.splitext(spec)[1]:
            raise InputError(f"{spec}: no such file, and not a preset (presets: {', '.join(PRESETS)})")
        design = cls.from_json(spec)
        if design.mode is None:  # a robot is built in one working mode: a file that describes a robot says which
            data = load_json(Path(spec))
            robot = [k for k in ROBOT_FIELDS if k in data]
            if robot:
                raise InputError(
                    f"{spec}: mode: missing; a robot file (it has {', '.join(robot)}) must carry its working mode, "
                    'e.g. "mode": "+,+,-,+" (its design job\'s summary.json says which)'
                )
        return design

    def to_dict(self) -> dict[str, float]:
        """The 27 parameters: flat name -> value mapping (mm, deg), in code order."""
        return dict(zip(PARAM_NAMES, self.values))

    def to_file_dict(self) -> dict[str, Any]:
        """What a design file holds: the 27 parameters, then ``c_z``, ``mode``, ``zdyad_elbow`` (when not
        +1) and ``q0_*`` where the design has them."""
        out: dict[str, Any] = dict(self.to_dict())
        if self.c_z is not None:
            out["c_z"] = self.c_z
        if self.mode is not None:
            out["mode"] = self.mode
        if self.zdyad_elbow != 1.0:
            out["zdyad_elbow"] = int(self.zdyad_elbow)
        if self.q0_deg is not None:
            out.update(zip(Q0_KEYS, self.q0_deg))
        return out

    @property
    def c_z_mm(self) -> float:
        """The z dyad's second link in mm: ``c_z``, else d_z (model §6)."""
        return float(self["d_z"]) if self.c_z is None else float(self.c_z)

    @property
    def q0(self) -> NDArray[np.float64]:
        """The joint zero offsets ``(5,)`` in deg (0 for a design that is not calibrated)."""
        return np.zeros(len(ACTUATED)) if self.q0_deg is None else np.array(self.q0_deg, dtype=float)

    def with_extras(self, **extras: Any) -> Design:
        """A copy with ``c_z``, ``mode``, ``q0_deg`` or ``zdyad_elbow`` changed (checked)."""
        unknown = set(extras) - {"c_z", "mode", "q0_deg", "zdyad_elbow"}
        if unknown:
            raise InputError(f"design: unknown field {sorted(unknown)[0]!r} (c_z, mode, q0_deg, zdyad_elbow)")
        return dataclasses.replace(self, **extras)

    def to_vector(self) -> NDArray[np.float64]:
        """The 27 values as a float array (mm, deg), for optimizers and batch evaluation."""
        return np.array(self.values, dtype=float)

    def to_json(self, path: str | os.PathLike[str]) -> None:
        """Write the flat JSON object (:meth:`to_file_dict`) atomically (temporary file, then rename)."""
        atomic_write_text(path, json.dumps(self.to_file_dict(), indent=2) + "\n")

    def replace(self, **changes: float) -> Design:
        """A copy with some parameters changed (``c_z``, ``mode``, ``q0_deg``, ``zdyad_elbow`` kept)."""
        d = self.to_dict()
        for k, v in changes.items():
            if k not in INDEX:
                raise InputError(f"design: unknown parameter {k!r}")
            d[k] = v
        return dataclasses.replace(
            Design.from_dict(d), c_z=self.c_z, mode=self.mode, q0_deg=self.q0_deg, zdyad_elbow=self.zdyad_elbow
        )

    def __getitem__(self, name: str) -> float:
        return self.values[INDEX[name]]
