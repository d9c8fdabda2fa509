"""The summaries of a design job and of ``arcube dock`` (their summary.json) as typed objects
(:class:`~arcube.summary.Summary`): :class:`DesignSummary`, :class:`DockSummary`."""

from __future__ import annotations

from typing import Any

from arcube.optimization.run_results import RunSummary
from arcube.summary import Summary

__all__ = ["DesignSummary", "DockSummary"]


class DesignSummary(RunSummary):
    """The summary of ``arcube design`` (its summary.json, ``DesignResult.summary``): the chosen seed's run summary
    (:class:`~arcube.optimization.run_results.RunSummary`'s fields, but its files, tasks, objectives, limits and
    sessions) and the job's verdict, robot, dockings and coverage."""

    meets_requirements: bool
    """Whether the chosen robot meets every requirement at every docking."""
    objective: str
    docking_mode: str | None
    """The dockings (model §19): per-side, per-patient, or None (one placement)."""
    missed: list[str]
    """The requirements missed somewhere."""
    missed_at: dict[str, str]
    """Each missed requirement -> the docking where it is tightest."""
    robot: dict[str, float]
    """The chosen robot's parameters (mm, deg) with its c_z."""
    dockings: list[dict[str, Any]]
    """One entry per docking: who, met, the figures of model §19.4's table, binding requirement (with its margin and
    ``binding_violation``), folder."""
    requirements: list[dict[str, Any]]
    """requirements.csv's rows."""
    accuracy: dict[str, Any]
    """The accuracy as built (model §20) of the docking where it is worst."""
    training: dict[str, Any]
    """The coverage of the dockings the robot was designed on (met / all, the Wilson interval)."""
    held_out: dict[str, Any] | None
    """The same on a held-out cohort (``--validate``)."""
    breach: dict[str, Any]
    """The breach figures (model §22) of the docking where it is most likely."""
    redocked: list[str]
    """The dockings docked anew after the search."""
    search_verdict_agreement: float | None
    """Of the dockings the search called feasible (every docking of every seed), the fraction the re-check met at the
    search's own placement (plan's points, approach lines, program built); None when the search called none feasible."""
    seeds_served: dict[str, int]
    """Each seed's dockings served once re-checked, docked anew where needed and programmed (the robot kept serves the
    most, then has the smallest worst eta_G)."""


class DockSummary(Summary):
    """The summary of ``arcube dock`` (its summary.json, ``DockResult.summary``): the robot, each side's docking, the
    coverage with its 95 % Wilson interval (model §19.6)."""

    format: str
    format_version: int
    robot_file: str
    """The robot as given (a design job's design.json or a docking file)."""
    robot: dict[str, float]
    """The robot's 22 parameters (mm, deg), unchanged at every docking."""
    mode: str
    zdyad_elbow: int
    c_z_assumed: bool
    """Whether the robot's c_z was not in its file (then d_z)."""
    dockings: list[dict[str, Any]]
    """One entry per side: who, met, missed, binding requirement and margin (``binding``, ``binding_margin``,
    ``binding_unit``, ``binding_where``, and ``binding_violation``: the normalized violation of model §16 by which it was
    chosen, :func:`~arcube.design_job.coverage.binding_row`), the placement, the search's figures."""
    coverage: float
    """Sides served / sides."""
    coverage_low: float
    coverage_high: float
    sides: int
    met: int
    """Sides served."""
    settings: dict[str, Any]
    """The docking's own settings (seed, starts, evaluations, requirements, tolerance class, points, standoff)."""
    wall_s: float
