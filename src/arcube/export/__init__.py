"""What a design becomes outside arcube: joint-space trajectories for a controller
(:mod:`arcube.export.joints`)."""

from __future__ import annotations
