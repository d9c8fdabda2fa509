"""From the drill tip to the pedicle: the probability that a screw breaches (model §22).

* :mod:`~arcube.pedicles.geometry`: each screw's pedicle at its isthmus (22.1) and the breach test, its direction and
  grade (22.3);
* :mod:`~arcube.pedicles.sources`: what moves the screw there (22.2): the built or calibrated robot, the registration,
  the deflection; the reference one sample at a time and the batched path;
* :mod:`~arcube.pedicles.monte_carlo`: the Monte Carlo and its results (22.4);
* :mod:`~arcube.pedicles.settings`: :class:`BreachSettings`;
* :mod:`~arcube.pedicles.first_order`: the first-order P(breach) and what it takes to reach a target (the inverse
  questions);
* :mod:`~arcube.pedicles.run`: :func:`breach`, the computation of ``arcube breach`` for a robot as docked
  (:func:`arcube.breach` finds the docking at the patient first: :mod:`arcube.design_job.at_patient`);
* :mod:`~arcube.pedicles.output`: its folder and files, and the screws as 3D Slicer markups.
"""

from arcube.pedicles.monte_carlo import BREACH_COLUMNS, BreachResult
from arcube.pedicles.run import breach
from arcube.pedicles.settings import BreachSettings

__all__ = ["BREACH_COLUMNS", "BreachResult", "BreachSettings", "breach"]
