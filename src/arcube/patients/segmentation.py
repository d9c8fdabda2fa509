"""Renamed :mod:`arcube.patients.anatomy_segments` in 0.3 (one name, ``segmentations``, for the reader in
:mod:`arcube.io.segmentations`); this name is kept for one release and warns."""

import warnings

from arcube.errors import RenamedWarning
from arcube.patients.anatomy_segments import *  # noqa: F403
from arcube.patients.anatomy_segments import __all__  # noqa: F401

warnings.warn(
    "arcube.patients.segmentation is now arcube.patients.anatomy_segments (the old name goes in the next release)",
    RenamedWarning,
    stacklevel=2,
)
