"""The controller interface: from an action and an observation to module commands.

Controllers are registered through ``msrr_controllers(robot, register)``. The
executor calls :meth:`Controller.begin` when an action (or a retry) enters a phase
and :meth:`Controller.control` once per tick; the controller answers with the
commands, per-module errors and whether the phase's configuration is reached
(reaching detection, FreeSN section 4.1). ``begin`` may say how much driver time the
phase needs (a long drive at the controller's speed); the executor then gives the
attempt that time on top of its timeout, so the timeout bounds the slack, not the work.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from .configuration import Configuration
from .driver import ModuleCommand, Observation
from .events import Phase
from .plan import Action

__all__ = ["Control", "Controller", "StartLayout", "WheelCorrector"]


@dataclass(frozen=True)
class Control:
    """One tick of control.

    Attributes:
        commands: per-module commands (modules not named stop).
        errors: per-module distance to the goal [m].
        reached: the configuration of this phase is reached.
        stalled: why the phase cannot finish, as the controller sees it (a joint that no
            longer moves toward its goal); empty while it can. The executor fails the
            action with it instead of waiting out its timeout.
    """

    commands: Mapping[str, ModuleCommand] = field(default_factory=dict)
    errors: Mapping[str, float] = field(default_factory=dict)
    reached: bool = False
    stalled: str = ""


@runtime_checkable
class Controller(Protocol):
    """Turns actions into module commands, closed-loop."""

    name: str
    description: str

    def begin(self, action: Action, phase: Phase, observation: Observation) -> float | None:
        """Prepare ``phase`` of ``action`` (plan a path, pick an approach side).

        Returns:
            The driver time [s] the phase needs at the controller's own speeds, when it
            knows (``None``: no more than the executor's timeout).
        """
        ...

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        """The commands for this tick of ``phase``."""
        ...


@runtime_checkable
class StartLayout(Protocol):
    """A controller that is told the start configuration before the first action, as a
    lab lays its modules out from the start file (the executor calls :meth:`start` once):
    where separate start pieces lie relative to each other is then known, which no
    report says (freeform modules: :meth:`msrr.core.freeform.travel.Locator.start`)."""

    def start(self, configuration: Configuration) -> None:
        """The run starts from ``configuration``, laid out by the robot's rule."""
        ...


@runtime_checkable
class WheelCorrector(Protocol):
    """A controller that also corrects a mapping behavior's wheel commands from the
    configuration recognized each tick (the executor calls :meth:`correct_wheels` in the
    behavior's phase, before it merges them into the tick's commands): a wheel that sets
    part of the stance, which no joint holds (FreeSN: a node wheel whose node only its own
    strut holds, :func:`msrr.plugins.freesn.sim.controller.lone_wheel_corrections`). A
    controller without it leaves the behavior's commands as they are."""

    def correct_wheels(self, action: Action, configuration: Configuration,
                       wheels: Mapping[str, Mapping[str, float]]
                       ) -> dict[str, dict[str, float]]:
        """``wheels`` (per module, per key: :func:`msrr.core.executor.behavior_commands`)
        as this tick should send them, ``configuration`` recognized now."""
        ...
