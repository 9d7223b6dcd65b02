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
from typing import Any, Protocol, runtime_checkable

from .configuration import Configuration
from .control import Controller
from .driver import DriverFactory
from .plan import Plan

__all__ = ["BehaviorPlanner", "Controller", "DriverFactory", "Planner", "Recognizer"]


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
