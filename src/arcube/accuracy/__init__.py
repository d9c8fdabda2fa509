"""The accuracy budget of a built robot (model §20): what a robot made to tolerances really drills.

* :mod:`~arcube.accuracy.iso`: ISO 2768-1 general tolerances (linear, angular);
* :mod:`~arcube.accuracy.sources`: the error sources of 20.1, their names, units and tolerances;
* :mod:`~arcube.accuracy.settings`: :class:`ToleranceSettings` (class, overrides, joints, docking, Monte Carlo);
* :mod:`~arcube.accuracy.first_order`: 20.3, the NumPy reference (zonogon worst cases, RMS, shares);
* :mod:`~arcube.accuracy._kernel`: 20.3 compiled (Numba), and per-point functions for an evaluation kernel;
* :mod:`~arcube.accuracy.monte_carlo`: 20.2 and 20.4, built robots with the exact FK;
* :mod:`~arcube.accuracy.budget`: :func:`budget` -> :class:`ToleranceResult`;
* :mod:`~arcube.accuracy.output`: :func:`write`, the output folder (JSON, CSVs, and the pictures it is given),
  all or nothing; :func:`arcube.report.accuracy.write_budget` writes it with every picture.

```python
from arcube.accuracy import ToleranceSettings, budget
from arcube.report.accuracy import write_budget
result = budget(design, task.E, task.e, "+,+,+,-", ToleranceSettings(tolerance_class="f"), task_ids, task.k)
result.summary["lateral_error_p95_mm"]; write_budget(result, "budget")
```
"""

from __future__ import annotations

from arcube.accuracy.budget import ToleranceResult, budget
from arcube.accuracy.output import write
from arcube.accuracy.settings import ToleranceSettings
from arcube.accuracy.sources import SOURCE_NAMES

__all__ = ["SOURCE_NAMES", "ToleranceResult", "ToleranceSettings", "budget", "write"]
