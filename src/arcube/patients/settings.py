"""Settings of the segmentation path (issue 33), for the generated CLI: which segments to keep, and the
format of a virtual patient's default anatomy.

* :class:`SegmentSelection` (``--segments NAME|VALUE[,...]``): passed as ``segments=`` to
  :func:`arcube.evaluation.anatomy.load_anatomy` / ``resolve_anatomy`` wherever an anatomy is read.
* :class:`PatientAnatomyFormat` (``--anatomy-format``, ``--anatomy-spacing-mm``): passed to
  :func:`arcube.patients.cohort.write_patients` as ``anatomy_format=`` and ``anatomy_spacing_mm=``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field

from arcube.errors import InputError
from arcube.io.segmentations import parse_segments
from arcube.options import Settings

__all__ = ["PatientAnatomyFormat", "SegmentSelection", "Segments"]


def _segments(value: Any) -> tuple[str, ...] | None:
    try:
        return parse_segments(value)
    except InputError:  # the settings error names the field and the value itself
        raise ValueError("must be names or label values separated by commas, none empty") from None


Segments = Annotated[tuple[str, ...] | None, BeforeValidator(_segments)]
"""Segment names or label values (``"C3,C4"``, ``["C3", 4]``), or None: every segment with a voxel."""


class SegmentSelection(Settings):
    """Which segments of segmentation anatomy files (``.seg.nrrd``, ``.nrrd``, ``.nii``, ``.nii.gz``) to keep."""

    segments: Segments = None
    """Segments of segmentation files to keep: names or label values, comma-separated (C3,C4,skin or 3,4); default every segment with a voxel."""


class PatientAnatomyFormat(Settings):
    """The file format of each virtual patient's default anatomy (model §14.2)."""

    anatomy_format: Literal["stl", "seg.nrrd", "nii.gz"] = "stl"
    """Default anatomy file: stl (patient frame), seg.nrrd (3D Slicer segmentation, LPS) or nii.gz (NIfTI label map, RAS)."""
    anatomy_spacing_mm: float = Field(default=0.5, gt=0, allow_inf_nan=False)
    """Voxel size of a seg.nrrd or nii.gz default anatomy, mm."""
