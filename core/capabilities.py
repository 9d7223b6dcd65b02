"""Protocols of the things plugins register through the capability hooks.

One place for "what does ``register(item)`` accept" per capability hook:

==========================  ===================================================
hook                        registered item
==========================  ===================================================
``msrr_kinematic_nodes``    a :class:`~msrr.core.kinematics.node.KinematicNode` subclass
``msrr_controllers``        a :class:`Controller`
``msrr_recognizers``        a :class:`Recognizer`
``msrr_planners``           a :class:`Planner`
``msrr_drivers``            a :class:`DriverFactory`
``msrr_scenarios``          a :class:`~msrr.core.scenario.Scenario`
==========================  ===================================================

Each has a ``name`` (its key in ``platform robots`` and on the command line) and a
one-line ``description``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from .configuration import Configuration
from .control import Controller
from .driver import DriverFactory
from .errors import UnknownNameError
from .plan import Plan
from .robot import Robot

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = ["BehaviorPlanner", "Capabilities", "Controller", "DriverFactory", "Planner",
           "Recognizer"]


@runtime_checkable
class Planner(Protocol):
    """Turns a start and a goal configuration into a :class:`~msrr.core.plan.Plan`."""

    name: str
    description: str

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """Plan from ``start`` to ``goal`` (both in their own ids).

        Raises:
            PlanningError: the goal cannot be reached (module counts differ, illegal goal).
        """
        ...


@runtime_checkable
class BehaviorPlanner(Planner, Protocol):
    """A planner that also plans behaviors of the robot's library (``platform run
    --behavior NAME``): the path to the behavior's start configuration, then the
    behavior itself (FreeSN paper, sections 4.3 and 6.3)."""

    def plan_behavior(self, start: Configuration, behavior: str, *,
                      parameters: Mapping[str, float] | None = None,
                      duration: float | None = None, loops: int | None = None,
                      distance: float | None = None, seed: int = 0) -> Plan:
        """Plan from ``start`` to the behavior's start, then ``ActionType.BEHAVIOR``
        action (mapping behaviors) or the behavior's loops (sequence behaviors).

        Raises:
            PlanningError: no such behavior, or its start cannot be reached.
        """
        ...


@runtime_checkable
class Recognizer(Protocol):
    """Turns what a driver senses into the current :class:`Configuration`."""

    name: str
    description: str

    def recognize(self, sensors: Mapping[str, Any], *, seed: int = 0) -> Configuration:
        """The configuration that ``sensors`` (:attr:`Observation.sensors
        <msrr.core.driver.Observation.sensors>`, per module id) shows, in the modules'
        own ids."""
        ...


@dataclass(frozen=True)
class Capabilities:
    """Everything one robot has, resolved once from the plugins and handed down (the
    layers below the application wing never ask the plugin host).

    Each mapping is by name, in order: the first item is the default.

    Attributes:
        robot: spec, docking rules and joint modes.
        controllers, recognizers, planners, drivers, scenarios: the registered items.
        libraries: behavior library files (``msrr_libraries``).
    """

    robot: Robot
    controllers: Mapping[str, Controller]
    recognizers: Mapping[str, Recognizer]
    planners: Mapping[str, Planner]
    drivers: Mapping[str, DriverFactory]
    scenarios: Mapping[str, Scenario]
    libraries: tuple[Path, ...] = ()

    @property
    def name(self) -> str:
        """The robot's name."""
        return self.robot.spec.name

    def controller(self, name: str | None = None) -> Controller:
        """Controller ``name``, or the default (raises :class:`UnknownNameError`)."""
        return pick(self.controllers, "controller", self.name, name)

    def recognizer(self, name: str | None = None) -> Recognizer:
        """Recognizer ``name``, or the default (raises :class:`UnknownNameError`)."""
        return pick(self.recognizers, "recognizer", self.name, name)

    def planner(self, name: str | None = None) -> Planner:
        """Planner ``name``, or the default (raises :class:`UnknownNameError`)."""
        return pick(self.planners, "planner", self.name, name)

    def driver(self, name: str | None = None) -> DriverFactory:
        """Driver ``name``, or the default (raises :class:`UnknownNameError`)."""
        return pick(self.drivers, "driver", self.name, name)

    def behavior_planner(self, preferred: Planner | None = None) -> BehaviorPlanner:
        """``preferred`` if it plans behaviors, else the robot's first planner that does.

        Raises:
            UnknownNameError: no planner of the robot plans behaviors.
        """
        for candidate in (preferred, *self.planners.values()):
            if isinstance(candidate, BehaviorPlanner):
                return candidate
        raise UnknownNameError(f"planner of behaviors for robot {self.name!r} (one that "
                               "ships a behavior library)", "(default)", self.planners)


def pick(items: Mapping[str, Any], what: str, robot: str, name: str | None) -> Any:
    """Item ``name`` of ``items``, or the first (the default) when ``name`` is None.

    Raises:
        UnknownNameError: no such item (listing the known ones), or none at all.
    """
    if name is None:
        if not items:
            raise UnknownNameError(f"{what} for robot {robot!r}", "(default)", ())
        return next(iter(items.values()))
    try:
        return items[name]
    except KeyError:
        raise UnknownNameError(f"{what} for robot {robot!r}", name, items) from None
