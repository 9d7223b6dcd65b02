"""Protocols of the things plugins register through the capability hooks.

A planner, recognizer, controller or driver factory is any object with these
attributes; ``name`` is its key in ``platform robots`` and on the command line.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from .configuration import Configuration
from .plan import Plan

__all__ = ["Planner", "Recognizer"]


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
class Recognizer(Protocol):
    """Turns what a driver observes into the current :class:`Configuration`."""

    name: str
    description: str

    def recognize(self, observation: Any, *, seed: int = 0) -> Configuration:
        """The configuration that ``observation`` shows, in the modules' own ids."""
        ...
