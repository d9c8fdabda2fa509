"""What a design becomes outside arcube: joint-space trajectories for a controller
(:mod:`arcube.export.joints`), a MuJoCo model (:mod:`arcube.export.mjcf`, its hinge angles in
:mod:`arcube.export.angles`, its masses in :mod:`arcube.export.inertia`) and the MuJoCo replay of a
drilling program (:mod:`arcube.export.replay`)."""

from __future__ import annotations
