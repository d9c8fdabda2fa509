"""A calibrated design's file (MODEL.md 21.4) until :class:`arcube.Design` reads it itself.

``design.json`` of ``arcube calibrate identify``: one flat JSON object with

* the 27 parameter names of :data:`arcube.model.design.PARAM_NAMES` (mm, deg), the identified values;
* ``q0_rho_x``, ``q0_rho_y``, ``q0_rho_z``, ``q0_delta_x``, ``q0_delta_y``: the identified joint zero
  offsets dq0 (deg): the real joint angle is the encoder's reading plus q0, so the IK of a calibrated
  design subtracts q0 from its joint angles before the controller commands them;
* ``mode``: the working mode the calibration used (``"+,+,+,-"``);
* ``c_z``: the z dyad's second link (mm), only when the input design had one (it does not move the
  tool and is not identified: copied).

:func:`load_design` reads any design a calibration starts from (a :class:`Design`, a preset, 27
numbers, a plain design JSON, or a calibrated one); :func:`read_calibrated` is the small reader the
integrator replaces by ``Design``'s own.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.sources import JOINTS
from arcube.errors import InputError
from arcube.io.files import atomic_write_text
from arcube.io.inputs import load_json, short_repr
from arcube.model.design import PRESETS, Design
from arcube.model.mechanism import DEFAULT_MODE, format_mode, parse_mode

Q0_KEYS: tuple[str, ...] = tuple(f"q0_{j}" for j in JOINTS)
"""The zero-offset keys of a calibrated design (deg), joint order rho_x, rho_y, rho_z, delta_x, delta_y."""
_EXTRA_KEYS = frozenset({*Q0_KEYS, "mode", "c_z", "placements"})


@dataclass(frozen=True)
class StartDesign:
    """A design a calibration works from: the 27 parameters, and what a calibrated file adds."""

    design: Design
    q0_deg: NDArray[np.float64]  # (5,) zero offsets, deg (0 for an uncalibrated design)
    c_z: float | None  # the z dyad's second link, mm, when the file had one
    mode: str | None  # the working mode the file records, if any
    calibrated: bool  # the file held q0_* keys

    @property
    def vector(self) -> NDArray[np.float64]:
        """The 27 parameters ``(27,)`` (mm, deg)."""
        return self.design.to_vector()


def _number(value: Any, key: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{source}: {key} is not a number ({short_repr(value)})")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{source}: {key} is not finite ({short_repr(value)})")
    return v


def _from_mapping(data: dict[str, Any], source: str) -> StartDesign:
    design = Design.from_dict({k: v for k, v in data.items() if k not in _EXTRA_KEYS}, source=source)
    present = [k for k in Q0_KEYS if k in data]
    if present and len(present) != len(Q0_KEYS):
        missing = ", ".join(k for k in Q0_KEYS if k not in data)
        raise InputError(f"{source}: a calibrated design needs all five zero offsets; missing {missing}")
    q0 = np.array([_number(data[k], k, source) for k in Q0_KEYS]) if present else np.zeros(5)
    if np.any(np.abs(q0) > 180.0):
        raise InputError(f"{source}: a zero offset must lie within +-180 deg, got {q0.tolist()}")
    c_z = None
    if "c_z" in data and data["c_z"] is not None:
        c_z = _number(data["c_z"], "c_z", source)
        if c_z <= 0.0:
            raise InputError(f"{source}: c_z must be a positive length (mm), got {c_z:g}")
    mode = None
    if data.get("mode") is not None:
        if not isinstance(data["mode"], str):
            raise InputError(f"{source}: mode must be text such as \"+,+,+,-\", got {short_repr(data['mode'])}")
        try:
            mode = format_mode(parse_mode(data["mode"]))
        except ValueError as exc:
            raise InputError(f"{source}: {exc}") from None
    return StartDesign(design, q0, c_z, mode, bool(present))


def load_design(spec: Any) -> StartDesign:
    """The design a calibration starts from: a :class:`StartDesign`, a :class:`Design`, a preset name, a
    design JSON path (plain or calibrated), or 27 (23) numbers (mm, deg). InputError naming the file or
    ``design`` otherwise."""
    if isinstance(spec, StartDesign):
        return spec
    if isinstance(spec, (str, os.PathLike)) and not (isinstance(spec, str) and spec in PRESETS):
        path = Path(spec)
        data = load_json(path)
        if not isinstance(data, dict):
            raise InputError(f"{path}: a design file must hold one JSON object keyed by parameter names")
        return _from_mapping(data, str(path))
    return StartDesign(Design.coerce(spec), np.zeros(5), None, None, False)


def calibrated_dict(design: ArrayLike, q0_deg: ArrayLike, mode: ArrayLike | str, c_z: float | None = None) -> dict[str, Any]:
    """The object of a calibrated ``design.json``: 27 parameters, ``q0_*`` (deg), ``mode``, and ``c_z`` if given."""
    d = Design.from_vector(design).to_dict()
    q0 = np.asarray(q0_deg, dtype=float).reshape(5)
    d.update({k: float(v) for k, v in zip(Q0_KEYS, q0)})
    d["mode"] = mode if isinstance(mode, str) else format_mode(mode)
    if c_z is not None:
        d["c_z"] = float(c_z)
    return d


def write_calibrated(path: str | os.PathLike[str], design: ArrayLike, q0_deg: ArrayLike, mode: ArrayLike | str,
                     c_z: float | None = None) -> None:  # fmt: skip
    """Write a calibrated ``design.json`` atomically (:func:`calibrated_dict`)."""
    atomic_write_text(path, json.dumps(calibrated_dict(design, q0_deg, mode, c_z), indent=2) + "\n")


def read_calibrated(path: str | os.PathLike[str]) -> tuple[Design, NDArray[np.float64]]:
    """(design, q0 ``(5,)`` deg) of a calibrated ``design.json`` (q0 = 0 for a plain design file)."""
    start = load_design(Path(path))
    return start.design, start.q0_deg


def design_digest(design: ArrayLike, q0_deg: ArrayLike) -> str:
    """16 hex digits of the SHA-256 of the 27 parameters and the 5 zero offsets (full precision): the
    ``design`` column of a poses file, which :func:`arcube.calibrate.simulate` checks against its design.
    ``c_z`` and the mode are not part of it (they do not move the tool for given joint angles)."""
    values = [*np.asarray(design, dtype=float).reshape(-1), *np.asarray(q0_deg, dtype=float).reshape(-1)]
    text = ",".join(repr(float(v) + 0.0) for v in values)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def signs_of(mode: Any, fallback: str | None = None) -> NDArray[np.float64]:
    """Four signs ``(4,)`` from ``"+,+,+,-"``, four numbers +-1, or None (``fallback``, else +,+,+,+)."""
    if mode is None:
        return parse_mode(fallback) if fallback else DEFAULT_MODE.copy()
    if isinstance(mode, str):
        try:
            return parse_mode(mode)
        except ValueError as exc:
            raise InputError.of("mode", str(exc)) from None
    try:
        s = np.asarray(mode, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError.of("mode", "must be four signs such as \"+,+,+,-\"") from None
    if s.shape != (4,) or not np.all(np.abs(s) == 1.0):
        raise InputError.of("mode", f"must be four signs +1/-1, got {s.tolist()}")
    return s


__all__ = ["Q0_KEYS", "StartDesign", "calibrated_dict", "design_digest", "load_design", "read_calibrated", "signs_of", "write_calibrated"]
