"""Virtual patients built from published cervical morphometry (``shared/data/MORPHOMETRY.md``).

:mod:`arcube.patients.virtual` draws the parameters, builds the bilateral C3-C7 trajectories and
checks them (MORPHOMETRY.md section 4).
"""

from __future__ import annotations

from arcube.patients.virtual import (
    LEVELS,
    TECHNIQUES,
    PatientCheck,
    build_patient,
    check_patient,
    draw_parameters,
    format_check,
    generate_patient,
    level_frames,
    write_patient,
)

__all__ = [
    "LEVELS",
    "TECHNIQUES",
    "PatientCheck",
    "build_patient",
    "check_patient",
    "draw_parameters",
    "format_check",
    "generate_patient",
    "level_frames",
    "write_patient",
]
