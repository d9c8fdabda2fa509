"""arcube: kinematic analysis and dimensional design of the AR-CUBE 3T2R surgical robot."""

from __future__ import annotations

__version__ = "0.1.0"
