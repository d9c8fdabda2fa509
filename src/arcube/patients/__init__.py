"""Virtual patients built from published cervical morphometry (``shared/data/MORPHOMETRY.md``).

:mod:`arcube.patients.virtual` draws the parameters, builds the bilateral C3-C7 trajectories and
checks them (MORPHOMETRY.md section 4).
"""

from __future__ import annotations

# The package's names are those of arcube.patients.virtual, listed once there.
from arcube.patients.virtual import *  # noqa: F403
from arcube.patients.virtual import __all__  # noqa: F401
