"""Design optimization of the AR-CUBE (model §12) on top of pymoo.

* :mod:`arcube.optimization.problem`: variables, bounds, fixing, objectives and the graded constraint;
  one batch call of the core model per population (per task);
* :mod:`arcube.optimization.algorithms`: the pymoo algorithms (ga, de, cmaes, nsga2) and terminations;
* :mod:`arcube.optimization.lean`: drop-ins for pymoo's per-individual bookkeeping (same results, faster);
* :mod:`arcube.optimization.run`: run folder, history, executors, the run loop;
* :mod:`arcube.optimization.checkpoint`: the evaluation log, checkpoints and their replay (resume);
* :mod:`arcube.cli.optimize`: the ``optimize`` and ``resume`` commands.
"""

from __future__ import annotations

from arcube.optimization.problem import DEFAULT_BOUNDS, FitnessModel, TaskData, VariableSpace

__all__ = ["DEFAULT_BOUNDS", "FitnessModel", "TaskData", "VariableSpace"]
