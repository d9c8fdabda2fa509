"""A calibrated design's file (model §21.4), read and written by :class:`arcube.Design` itself.

``design.json`` of ``arcube calibrate identify``: one flat JSON object with

* the 27 parameter names of :data:`arcube.model.design.PARAM_NAMES` (mm, deg), the identified values;
* ``q0_rho_x``, ``q0_rho_y``, ``q0_rho_z``, ``q0_delta_x``, ``q0_delta_y``: the identified joint zero
  offsets dq0 (deg): the real joint angle is the encoder's reading plus q0, so the IK of a calibrated
  design subtracts q0 from its joint angles before the controller commands them;
* ``mode``: the working mode the calibration used (``"+,+,+,-"``);
* ``c_z``: the z dyad's second link (mm), only when the input design had one (it does not move the
  tool and is not identified: copied);
* ``patient``, ``side`` and ``plan_digest``: whose docking the robot was measured at, when the input design says
  (a docking file, or a robot's ``design.json`` with a side): a calibration holds at that docking only, and
  ``arcube breach`` refuses it on another side or another patient's plan.

:func:`load_design` reads any design a calibration starts from (a :class:`Design`, a preset, 27
numbers, a plain design JSON, or a calibrated one).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.coerce import mode_signs
from arcube.io.files import atomic_write_text
from arcube.model.design import Q0_KEYS, Design
from arcube.model.modes import format_mode


@dataclass(frozen=True)
class StartDesign:
    """A design a calibration works from: the 27 parameters, and what a calibrated file adds."""

    design: Design
    q0_deg: NDArray[np.float64]  # (5,) zero offsets, deg (0 for an uncalibrated design)
    c_z: float | None  # the z dyad's second link, mm, when the file had one
    mode: str | None  # the working mode the file records, if any
    calibrated: bool  # the file held q0_* keys
    labels: dict[str, Any] = field(default_factory=dict)  # patient, side, plan_digest: the docking measured at

    @property
    def vector(self) -> NDArray[np.float64]:
        """The 27 parameters ``(27,)`` (mm, deg)."""
        return self.design.to_vector()


def load_design(spec: Any) -> StartDesign:
    """The design a calibration starts from: a :class:`StartDesign`, a :class:`Design`, a preset name, a
    design JSON path (plain or calibrated: :meth:`Design.from_json` reads its ``q0_*``, ``mode`` and
    ``c_z``), or 27 (23) numbers (mm, deg). InputError naming the file or ``design`` otherwise."""
    if isinstance(spec, StartDesign):
        return spec
    d = Design.coerce(spec)
    return StartDesign(d, d.q0, d.c_z, d.mode, d.q0_deg is not None, file_labels(spec))


def file_labels(spec: Any) -> dict[str, Any]:
    """The docking a design file says it is (``patient``, ``side``, ``plan_digest``: :data:`LABEL_KEYS`), {} for
    anything else."""
    from arcube.io.inputs import load_json
    from arcube.model.design import LABEL_KEYS

    if not isinstance(spec, (str, os.PathLike)) or Path(spec).suffix.lower() != ".json" or not Path(spec).is_file():
        return {}
    data = load_json(Path(spec))
    return {k: data[k] for k in LABEL_KEYS if isinstance(data, dict) and data.get(k) is not None}


def calibrated_dict(
    design: ArrayLike,
    q0_deg: ArrayLike,
    mode: ArrayLike | str,
    c_z: float | None = None,
    labels: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The object of a calibrated ``design.json``: 27 parameters, ``q0_*`` (deg), ``mode``, ``c_z`` if given, and the
    docking's ``labels`` (patient, side, plan_digest) if given."""
    q0 = tuple(float(v) for v in np.asarray(q0_deg, dtype=float).reshape(5))
    text = mode if isinstance(mode, str) else format_mode(mode)
    return {**Design.from_vector(design).with_extras(q0_deg=q0, mode=text, c_z=c_z).to_file_dict(), **(labels or {})}


def write_calibrated(
    path: str | os.PathLike[str], design: ArrayLike, q0_deg: ArrayLike, mode: ArrayLike | str, c_z: float | None = None
) -> None:
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
    return mode_signs(fallback or DEFAULT_MODE_TEXT if mode is None else mode)


__all__ = [
    "Q0_KEYS",
    "StartDesign",
    "calibrated_dict",
    "design_digest",
    "file_labels",
    "load_design",
    "read_calibrated",
    "signs_of",
    "write_calibrated",
]
