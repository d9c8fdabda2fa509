"""The mechanism: design parameters, poses, the three stages and the whole AR-CUBE.

* :mod:`arcube.model.design`: the design parameters (model §2), :class:`~arcube.model.design.Design`;
* :mod:`arcube.model.poses`: drill poses (E, e), leg frames, trajectory sampling (model §1);
* :mod:`arcube.model.stages`: TLS (:mod:`~arcube.model.stages.tls`), TMS (:mod:`~arcube.model.stages.tms`),
  RTS (:mod:`~arcube.model.stages.rts`) and the z-leg dyad (:mod:`~arcube.model.stages.zleg`);
* :mod:`arcube.model.mechanism`: inverse and forward kinematics and the velocity model (model §5.5, 7.4).

Every function takes NumPy arrays whose leading axes broadcast (designs, points): lengths in mm,
angles in radians inside the code and degrees in the design container.
"""

from __future__ import annotations
