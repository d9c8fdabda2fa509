"""The result of an identification (model §21.4): :class:`Calibration`, and what it writes.

Residual figures: per measurement, the tip residual |E_meas - E_model| (mm, 3-D) and the axis residual
angle(e_meas, e_model) (deg). Their RMS over a set of rows is sqrt(mean of the squares): at the noise
level it is sqrt(3) sigma_E for the tip (three axes of noise sigma_E) and sqrt(2) sigma_e for the axis
(two directions perpendicular to it), which calibration.json states beside them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.calibrate.budget import CalibratedBudget
from arcube.calibrate.design_file import StartDesign, calibrated_dict
from arcube.model.design import Design
from arcube.calibrate.identifiability import Identifiability
from arcube.calibrate.measurements import Measurements
from arcube.calibrate.model import (
    KINDS,
    N_UNKNOWNS,
    UNKNOWN_UNITS,
    UNKNOWNS,
    with_unknowns,
)
from arcube.calibrate.settings import IdentifySettings
from arcube.model.mechanism import format_mode
from arcube.io.json_values import finite


def pose_errors(
    E_meas: ArrayLike, e_meas: ArrayLike, E_model: ArrayLike, e_model: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(|E_meas - E_model| mm, angle(e_meas, e_model) deg), each ``(...)``; NaN where the model is NaN."""
    dE = np.linalg.norm(np.asarray(E_meas, dtype=float) - np.asarray(E_model, dtype=float), axis=-1)
    a, b = np.asarray(e_meas, dtype=float), np.asarray(e_model, dtype=float)
    ang = np.rad2deg(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))
    return dE, ang


def rms(a: ArrayLike) -> float | None:
    """sqrt(mean(a^2)), None for no values."""
    x = np.asarray(a, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else None


class Residuals(NamedTuple):
    """Per measurement ``(N,)``: tip (mm) and axis (deg) residuals at the nominal and the identified values."""

    E_before_mm: NDArray[np.float64]
    e_before_deg: NDArray[np.float64]
    E_after_mm: NDArray[np.float64]
    e_after_deg: NDArray[np.float64]


@dataclass(frozen=True)
class Calibration:
    """An identification: the calibrated design, every unknown's estimate and sigma, residuals, budget."""

    settings: IdentifySettings
    start: StartDesign  # the nominal design (and the zero offsets it had)
    mode: NDArray[np.float64]  # (4,) working mode
    measurements: Measurements
    fitted: NDArray[np.bool_]  # (N,) True: fitted, False: held out
    assembly: NDArray[np.float64]  # (N, 3) assembly mode of each measurement
    identifiability: Identifiability  # at the nominal values, on the fitted rows
    scale: NDArray[np.float64]  # (31,) typical sizes (mm, deg)
    u_nominal: NDArray[np.float64]  # (31,) nominal values of the unknowns (mm, deg)
    u_identified: NDArray[np.float64]  # (31,)
    covariance: NDArray[np.float64]  # (31, 31) of the identified values (mm, deg); 0 for the non-identifiable
    sigma_hat: float  # sqrt(residual variance per degree of freedom): ~1 at the tracker's noise level
    dof: int  # 5 N_fit - identified unknowns
    residuals: Residuals
    o1: float  # Borm and Menq's O1 of the fitted rows (identifiable unknowns, nominal values)
    condition_number: float
    n_model: int  # unknowns the model can identify near these readings (the too-few check)
    solver: dict[str, Any]
    budget: CalibratedBudget | None  # the calibrated robot's accuracy budget (None: no point reached)

    @property
    def design(self) -> NDArray[np.float64]:
        """The calibrated design ``(27,)`` (mm, deg): identified parameters, d_z as given."""
        return with_unknowns(self.start.vector, self.u_identified)[0]

    @property
    def q0_deg(self) -> NDArray[np.float64]:
        """The identified zero offsets ``(5,)`` deg, joints rho_x, rho_y, rho_z, delta_x, delta_y."""
        return self.u_identified[26:].copy()

    @property
    def sigma(self) -> NDArray[np.float64]:
        """``(31,)`` standard deviation of each identified value (mm, deg); NaN where not identifiable."""
        return np.where(self.identifiability.identifiable, np.sqrt(np.maximum(np.diag(self.covariance), 0.0)), np.nan)

    def calibrated_design(self) -> Design:
        """The calibrated design as every command reads it: the identified parameters with the zero
        offsets (``q0_deg``), the mode and the input's c_z (what ``design.json`` holds)."""
        return Design.from_dict(self.design_json())

    def design_json(self) -> dict[str, Any]:
        """The object of design.json (27 parameters, q0_* deg, mode, c_z when the input had one, and the docking it
        was measured at when the input said: patient, side, plan_digest)."""
        return calibrated_dict(self.design, self.q0_deg, self.mode, self.start.c_z, self.start.labels)

    def unknown_rows(self) -> list[dict[str, Any]]:
        """One row per unknown: name, kind, unit, scale, nominal, identified, deviation, sigma, identifiable, pivot,
        confounded_with (names and coefficients in design units: a deviation du of this unknown looks like
        coefficient x du of that one)."""
        ident, sig = self.identifiability, self.sigma
        rows = []
        for k in range(N_UNKNOWNS):
            conf = ident.confounded_with(k, self.scale)
            rows.append(
                {
                    "name": UNKNOWNS[k],
                    "kind": KINDS[k],
                    "unit": UNKNOWN_UNITS[k],
                    "scale": float(self.scale[k]),
                    "nominal": float(self.u_nominal[k]),
                    "identified": float(self.u_identified[k]),
                    "deviation": float(self.u_identified[k] - self.u_nominal[k]),
                    "sigma": None if math.isnan(sig[k]) else float(sig[k]),
                    "identifiable": bool(ident.identifiable[k]),
                    "pivot": float(ident.pivot[k]),
                    "confounded_with": [{"name": UNKNOWNS[i], "coefficient": c} for i, c in conf],
                }
            )
        return rows

    def residual_rms(self) -> dict[str, Any]:
        """RMS of the tip (mm) and axis (deg) residuals, before (nominal) and after, on fitted and held-out rows."""
        r, s = self.residuals, self.settings
        out: dict[str, Any] = {}
        for name, rows in (("fitted", self.fitted), ("held_out", ~self.fitted)):
            out[name] = {
                "rows": int(rows.sum()),
                "E_rms_mm_before": rms(r.E_before_mm[rows]),
                "E_rms_mm": rms(r.E_after_mm[rows]),
                "e_rms_deg_before": rms(r.e_before_deg[rows]),
                "e_rms_deg": rms(r.e_after_deg[rows]),
            }
        out["noise"] = {
            "E_rms_mm": math.sqrt(3.0) * s.sigma_mm,
            "e_rms_deg": math.sqrt(2.0) * s.sigma_deg,
            "note": "the RMS residuals at the tracker's noise level: sqrt(3) sigma_E (3-D) and sqrt(2) sigma_e",
        }
        return out

    def to_json(self) -> dict[str, Any]:
        """The object of calibration.json (non-finite numbers as null)."""
        m = self.measurements
        not_ident = [u["name"] for u in self.unknown_rows() if not u["identifiable"]]
        data = {
            "mode": format_mode(self.mode),
            "settings": self.settings.model_dump(),
            "measurements": {
                "source": m.source,
                "rows": len(m),
                "fitted": int(self.fitted.sum()),
                "held_out": int((~self.fitted).sum()),
            },
            "unknowns": self.unknown_rows(),
            "not_identifiable": not_ident,
            "identifiable_count": int(self.identifiability.rank),
            "model_identifiable_count": self.n_model,
            "residuals": self.residual_rms(),
            "sigma_hat": self.sigma_hat,
            "degrees_of_freedom": self.dof,
            "observability": {"O1": self.o1, "condition_number": self.condition_number},
            "solver": self.solver,
            "budget": None if self.budget is None else self.budget.to_json(),
            "design": self.design_json(),
        }
        return finite(data)
