"""Design optimization of the AR-CUBE (MODEL.md section 12) on top of pymoo.

* :mod:`arcube.optimize.problem`: variables, bounds, fixing, objectives and the graded constraint;
  one batch call of the core model per population (per task);
* :mod:`arcube.optimize.algorithms`: the pymoo algorithms (ga, de, cmaes, nsga2) and terminations;
* :mod:`arcube.optimize.lean`: drop-ins for pymoo's per-individual bookkeeping (same results, faster);
* :mod:`arcube.optimize.run`: run folder, history, executors, the run loop;
* :mod:`arcube.optimize.checkpoint`: the evaluation log, checkpoints and their replay (resume);
* :mod:`arcube.optimize.cli`: the ``optimize`` and ``resume`` commands.
"""

from __future__ import annotations

from arcube.optimize.problem import DEFAULT_BOUNDS, FitnessModel, TaskData, VariableSpace

__all__ = ["DEFAULT_BOUNDS", "FitnessModel", "TaskData", "VariableSpace"]
