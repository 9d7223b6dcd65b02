"""Named runs that ``platform run --robot ROBOT --scenario NAME`` starts.

A scenario starts from a configuration in the system's own ids and goes through
*stages*: its ``goal`` (if any) is the first, then each of ``stages`` in order -- another
goal configuration, or a behavior of the robot's library run for a duration, a number
of loops or a distance. ``platform run`` plans every stage at prepare time, stage ``i``
from where stage ``i - 1`` ends (in the system's ids), and joins the plans into one
(:func:`msrr.core.plan.join_plans`), so the executor, ``plan.json``, the progress bar
and the summary see one list of actions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from .errors import ConfigurationError

__all__ = ["MAX_DISTANCE", "MAX_LOOPS", "MAX_TIME", "Scenario", "Stage"]

MAX_LOOPS = 1000
"""Most loops of a sequence behavior a stage may ask for (each loop is planned as its
actions, so the plan, its file and the run grow with it)."""

MAX_TIME = 7 * 24 * 3600.0
"""Longest duration a stage may ask for [s of driver time]: a week."""

MAX_DISTANCE = 10_000.0
"""Longest distance a behavior may be asked to cover [m]."""


@dataclass(frozen=True)
class Stage:
    """One stage of a scenario: reach a goal configuration, or run a behavior.

    Attributes:
        goal: path to a goal configuration file (its ids need not be the system's: the
            planner matches it).
        behavior: name of a behavior of the robot's library (``"wheeled-move"``); the
            planner retrieves the path to its start configuration, then runs it.
        parameters: a mapping behavior's parameter values (``(("speed", 0.05),)`` [m/s]).
        duration: how long a mapping behavior runs [s of driver time], at most
            :data:`MAX_TIME`.
        loops: how many times a sequence behavior runs (at most, with ``distance``), at
            most :data:`MAX_LOOPS`.
        distance: the behavior stops once the system's centre moved this far [m], at
            most :data:`MAX_DISTANCE`.
        name: how the stage's goal is called in the summary; default the goal file's
            configuration name or the behavior's.
        joint_mode: the joint mode a goal stage's moves run in (one of the robot's, such
            as SnailBot's ``sucker_revolute``): each moving action the planner left
            without a kinematic tree gets that mode's default tree; ``""``: the
            robot's default mode.
    """

    goal: Path | None = None
    behavior: str | None = None
    parameters: tuple[tuple[str, float], ...] = ()
    duration: float | None = None
    loops: int | None = None
    distance: float | None = None
    name: str = ""
    joint_mode: str = ""

    def __post_init__(self) -> None:
        if (self.goal is None) == (self.behavior is None):
            raise ConfigurationError("a stage has either a goal or a behavior")
        for what, value, high in (("duration", self.duration, MAX_TIME),
                                  ("distance", self.distance, MAX_DISTANCE)):
            if value is not None and not (math.isfinite(value) and 0 < value <= high):
                raise ConfigurationError(f"must be a number in (0, {high:g}], got {value!r}",
                                         field=what)
        if self.loops is not None and (isinstance(self.loops, bool) or not isinstance(
                self.loops, int) or not 1 <= self.loops <= MAX_LOOPS):
            raise ConfigurationError(f"must be a whole number in [1, {MAX_LOOPS}], got "
                                     f"{self.loops!r}", field="loops")
        for key, value in self.parameters:
            if not math.isfinite(value):
                raise ConfigurationError(f"must be finite, got {value!r}", field=key)

    def __str__(self) -> str:
        if self.goal is not None:
            return self.name or self.goal.stem
        params = ", ".join(f"{k}={v:g}" for k, v in self.parameters)
        return f"{self.behavior}({params})"


@dataclass(frozen=True)
class Scenario:
    """A start configuration, what to reach from it, and the words to describe it.

    Attributes:
        name: identifier on the command line (``"cross-probe"``).
        description: one line for tables and progress output.
        start: path to the start configuration file.
        goal: path to the goal configuration file (the first stage), or ``None`` when
            the scenario begins with a behavior stage.
        default: whether ``platform run --robot ROBOT`` runs this one.
        stages: what follows the goal, in order.
    """

    name: str
    description: str
    start: Path
    goal: Path | None = None
    default: bool = False
    stages: tuple[Stage, ...] = ()

    def __post_init__(self) -> None:
        if self.goal is None and not self.stages:
            raise ConfigurationError(f"scenario {self.name!r} has neither a goal nor stages")

    @classmethod
    def through(cls, name: str, description: str, start: Path, *goals: Path) -> Scenario:
        """A scenario from ``start`` through goal configuration files, one stage each,
        in order (at least one)."""
        return cls(name=name, description=description, start=start, goal=goals[0],
                   stages=tuple(Stage(goal=g) for g in goals[1:]))

    def all_stages(self) -> tuple[Stage, ...]:
        """The goal (as a stage, when there is one) then :attr:`stages`."""
        first = () if self.goal is None else (Stage(goal=self.goal),)
        return first + self.stages
