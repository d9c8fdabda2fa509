"""The optimizer's variables: the default bounds of model §12.1 and 13.3, the free parameters
(``free``: names and the groups ``all`` and ``mount``) and bound overrides (``bounds``), parsed and checked."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from arcube.errors import InputError
from arcube.model.design import (
    ANGLE_NAMES,
    INDEX,
    LENGTH_NAMES,
    MAX_LENGTH_MM,
    MAX_POSITION_MM,
    MOUNT_NAMES,
    PAPER_NAMES,
    PARAM_NAMES,
    POSITION_NAMES,
)

__all__ = ["C_Z", "C_Z_BOUNDS", "DEFAULT_BOUNDS", "FREE_GROUPS", "parse_bounds", "parse_free", "resolve_bounds"]

_B_M, _B_F, _B_L, _B_R, _B_O, _B_A = (
    (-400.0, 400.0),
    (20.0, 250.0),
    (30.0, 200.0),
    (50.0, 80.0),
    (-270.0, 270.0),
    (30.0, 90.0),
)
DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "m_x": _B_M,
    "m_y": _B_M,
    "m_z": _B_M,
    "f_x": _B_F,
    "f_y": _B_F,
    "f_z": _B_F,
    "p_x": _B_L,
    "p_y": _B_L,
    "p_z": _B_L,
    "d_x": _B_L,
    "d_y": _B_L,
    "d_z": _B_L,
    "c_x": _B_L,
    "c_y": _B_L,
    "t_x": _B_L,
    "t_y": _B_L,
    "r": _B_R,
    "o_x": _B_O,
    "o_y": _B_O,
    "alpha_x": _B_A,
    "alpha_y": _B_A,
    "beta_x": _B_A,
    "beta_y": _B_A,
    "mount_rx": (-180.0, 180.0),
    "mount_ry": (-180.0, 180.0),
    "mount_rz": (-180.0, 180.0),
    "L": (0.0, 200.0),
}
"""model §12.1 and 13.3 default bounds (mm, deg)."""
C_Z = "c_z"
"""The z dyad's second link (model §19.1): a free parameter beside the 27 (``free=...,c_z``), in no design vector."""
C_Z_BOUNDS: tuple[float, float] = (20.0, 500.0)
"""Its default bounds, mm (model §19.1)."""
FREE_GROUPS: dict[str, tuple[str, ...]] = {"all": PAPER_NAMES, "mount": MOUNT_NAMES}
"""Group words of ``free``: ``all`` (the paper's 23) and ``mount`` (the three mounting angles)."""


def parse_free(spec: str | Sequence[str]) -> tuple[str, ...]:
    """Parameter names and group words (``all``: the paper's 23, ``mount``: the three mounting
    angles), as a list or comma-separated text (``"all,mount,L"``) -> names in PARAM_NAMES order,
    then ``c_z`` (model §19.1) when named."""
    text = spec if isinstance(spec, str) else ",".join(str(s) for s in spec)
    items = [s.strip() for s in text.strip().split(",")]
    if not items or any(not n for n in items):
        raise InputError.of("RunSettings.free", f"{text!r}: expected parameter names or the groups 'all' and 'mount'")
    names: set[str] = set()
    for item in items:
        if item.lower() in FREE_GROUPS:
            names.update(FREE_GROUPS[item.lower()])
        elif item in INDEX or item == C_Z:
            names.add(item)
        else:
            raise InputError.of(
                "RunSettings.free",
                f"has an unknown parameter {item!r} (groups: all, mount; names: {', '.join(PARAM_NAMES)}, {C_Z})",
            )
    return tuple(n for n in (*PARAM_NAMES, C_Z) if n in names)


def parse_bounds(spec: str | Mapping[str, Sequence[float]] | None) -> dict[str, tuple[float, float]]:
    """Bound overrides ``{name: (lo, hi)}``, or their text form ``'p_x=30:250,r=50:90'``; checked."""
    out: dict[str, tuple[float, float]] = {}
    if not spec:
        return out
    if isinstance(spec, (list, tuple)) and all(isinstance(s, str) for s in spec):
        spec = ",".join(spec)  # the command line's repeated NAME=LO:HI items
    items: list[tuple[str, Any]]
    if isinstance(spec, str):
        items = []
        for item in spec.split(","):
            name, sep, rng = item.partition("=")
            lo_s, sep2, hi_s = rng.partition(":")
            if not sep or not sep2:
                raise InputError.of(
                    "RunSettings.bounds",
                    f"item {item.strip()!r}: expected NAME=LO:HI with NAME one of the 27 parameters",
                )
            try:
                items.append((name.strip(), (float(lo_s), float(hi_s))))
            except ValueError:
                raise InputError.of("RunSettings.bounds", f"item {item.strip()!r}: LO and HI must be numbers") from None
    else:
        items = list(dict(spec).items())
    for name, pair in items:
        if name not in INDEX and name != C_Z:
            raise InputError.of("RunSettings.bounds", f"{name!r}: not one of the 27 parameters or {C_Z}")
        if name in out:  # the last copy would win without a word
            raise InputError.of("RunSettings.bounds", f"{name}: given twice")
        try:
            lo, hi = (float(v) for v in pair)
        except (TypeError, ValueError):
            raise InputError.of("RunSettings.bounds", f"{name}: expected two numbers (lo, hi), got {pair!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError.of("RunSettings.bounds", f"{name}={lo!r}:{hi!r}: need finite lo < hi")
        if (name in LENGTH_NAMES or name == C_Z) and lo <= 0.0:
            raise InputError.of("RunSettings.bounds", f"{name}: a length needs a lower bound > 0, got {lo:g}")
        if (name in LENGTH_NAMES or name in (C_Z, "L")) and hi > MAX_LENGTH_MM:  # as a design file's lengths
            raise InputError.of(
                "RunSettings.bounds", f"{name}: a length needs an upper bound <= {MAX_LENGTH_MM:g} mm, got {hi:g}"
            )
        if name in POSITION_NAMES and not (-MAX_POSITION_MM <= lo and hi <= MAX_POSITION_MM):
            raise InputError.of(
                "RunSettings.bounds", f"{name}: the base position must stay within ±{MAX_POSITION_MM:g} mm"
            )
        if name in MOUNT_NAMES and not (-360.0 <= lo and hi <= 360.0):  # as a design file's (one turn either way)
            raise InputError.of("RunSettings.bounds", f"{name}: mounting angles must stay within ±360 deg")
        if name == "L" and lo < 0.0:
            raise InputError.of("RunSettings.bounds", f"L: the tool offset needs a lower bound >= 0, got {lo:g}")
        if name in ANGLE_NAMES and name.startswith(("alpha", "beta")) and not (0.0 < lo and hi < 180.0):
            raise InputError.of("RunSettings.bounds", f"{name}: spherical link angles must stay within (0, 180) deg")
        out[name] = (lo, hi)
    return out


def resolve_bounds(
    overrides: Mapping[str, tuple[float, float]] | None = None, c_z: bool = False
) -> dict[str, tuple[float, float]]:
    """DEFAULT_BOUNDS updated with ``overrides``; with ``c_z`` (a free c_z) also c_z's (:data:`C_Z_BOUNDS` unless overridden)."""
    return {**DEFAULT_BOUNDS, **({C_Z: C_Z_BOUNDS} if c_z else {}), **(overrides or {})}
