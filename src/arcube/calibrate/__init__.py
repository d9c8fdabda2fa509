"""Calibration of a built robot from tracker measurements (model §21).

* :func:`poses`: which poses to measure (21.3): candidates around the plan, greedy D-optimal choice,
  O1 and condition number against a random choice -> :class:`PoseSelection` (and the poses CSV);
* :func:`simulate`: a robot built to a tolerance class, measured at the poses with tracker noise
  -> :class:`Simulation` (and the measurement CSV), with the real robot's deviations as ground truth;
* :func:`identify`: the real parameters and zero offsets from measurements (21.2, 21.4) -> :class:`Calibration`
  (and the folder design.json, calibration.json, residuals.csv, calibration.html).

```python
import arcube, arcube.calibrate as cal
plan = arcube.select(arcube.load_trajectories("reference"), side="R")
chosen = cal.poses("design.json", plan, "+,+,+,-", out="poses.csv")
sim = cal.simulate("design.json", "poses.csv", out="measurements.csv")
result = cal.identify("design.json", "measurements.csv", "+,+,+,-", trajectories=plan, out="calibration")
result.design, result.q0_deg          # the calibrated design (27,) and zero offsets (5,) deg
```

The modules: :mod:`~arcube.calibrate.measurements` (the CSV), :mod:`~arcube.calibrate.model` (unknowns,
residuals, Jacobian), :mod:`~arcube.calibrate.identifiability` (QR with pivoting, O1),
:mod:`~arcube.calibrate.budget` (the calibrated robot's accuracy budget), :mod:`~arcube.calibrate.design_file`
(the calibrated design.json), :mod:`~arcube.calibrate.settings`.
"""

from __future__ import annotations

from arcube.calibrate.identify import identify
from arcube.calibrate.poses import PoseSelection, poses
from arcube.calibrate.result import Calibration
from arcube.calibrate.settings import IdentifySettings, PoseSettings, SimulateSettings
from arcube.calibrate.simulate import Simulation, simulate

__all__ = [
    "Calibration",
    "IdentifySettings",
    "PoseSelection",
    "PoseSettings",
    "SimulateSettings",
    "Simulation",
    "identify",
    "poses",
    "simulate",
]
