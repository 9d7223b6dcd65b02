"""The generic runtime: what every robot gets from its description alone.

A plugin that describes only its module kinds, ports and docking rules can run
``platform run --robot ROBOT --from A --to B``: the plugin host adds these items after
the robot's own (:func:`msrr.core.plugins.resolve` builds the :class:`Robot` they get),
so a robot's own planner, driver, recognizer and controller come first and override
them, and ``--planner generic`` / ``--driver kinematic`` pick them by name.

* :class:`GenericPlanner` (``generic``) -- exact A* over dock/undock steps, small systems;
* :class:`KinematicDriverFactory` (``kinematic``) -- an ideal world, no physics model;
* :class:`LatchRecognizer` (``latches``) -- the configuration from latched ports;
* :class:`LatchController` (``latches``) -- carries modules into place and docks them.

Every item has ``generic = True``; ``platform robots`` marks them so.
"""

from __future__ import annotations

from ..robot import Robot
from .controller import LatchController
from .driver import KinematicDriver, KinematicDriverFactory, Latch, ModuleReading
from .planner import MAX_EXPANSIONS, MAX_MODULES, MAX_PORTS, GenericPlanner
from .recognizer import LatchRecognizer

__all__ = [
    "MAX_EXPANSIONS",
    "MAX_MODULES",
    "MAX_PORTS",
    "GenericPlanner",
    "KinematicDriver",
    "KinematicDriverFactory",
    "Latch",
    "LatchController",
    "LatchRecognizer",
    "ModuleReading",
    "capabilities",
    "is_generic",
]

HOOKS = ("msrr_planners", "msrr_drivers", "msrr_recognizers", "msrr_controllers")
"""The capability hooks the generic runtime answers for every robot."""


def capabilities(hook_name: str, robot: Robot) -> list[object]:
    """The generic items of capability hook ``hook_name`` for ``robot`` (none for others)."""
    if hook_name == "msrr_planners":
        return [GenericPlanner(robot)]
    if hook_name == "msrr_drivers":
        return [KinematicDriverFactory(robot.spec)]
    if hook_name == "msrr_recognizers":
        return [LatchRecognizer(robot.spec)]
    if hook_name == "msrr_controllers":
        return [LatchController(robot.spec)]
    return []


def is_generic(item: object) -> bool:
    """Whether ``item`` comes from the generic runtime (not from the robot's plugin)."""
    return getattr(item, "generic", False) is True
