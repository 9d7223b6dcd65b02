"""The generic runtime: what every robot gets from its description alone.

A plugin that describes only its module kinds, ports and docking rules can run
``platform run --robot ROBOT --from A --to B``: the runtime's own plugin
(:mod:`msrr.core.generic.plugin`, ``trylast`` hooks) registers these items for every
robot, after the robot's own, so a robot's own planner, driver, recognizer and
controller come first and override them, and ``--planner generic`` / ``--driver
kinematic`` pick them by name.

* :class:`GenericPlanner` (``generic``) -- exact A* over dock/undock steps, small systems;
* :class:`KinematicDriverFactory` (``kinematic``) -- an ideal world, no physics model;
* :class:`LatchRecognizer` (``latches``) -- the configuration from latched ports;
* :class:`LatchController` (``latches``) -- carries modules into place and docks them.

Every item has ``generic = True``; ``platform robots`` marks them so.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

if TYPE_CHECKING:
    from .controller import LatchController
    from .driver import KinematicDriver, KinematicDriverFactory
    from .planner import MAX_EXPANSIONS, MAX_MODULES, MAX_PORTS, GenericPlanner
    from .readings import Latch, ModuleReading
    from .recognizer import LatchRecognizer

_EXPORTS = {  # name -> submodule that defines it
    "LatchController": "controller",
    "KinematicDriver": "driver",
    "KinematicDriverFactory": "driver",
    "Latch": "readings",
    "ModuleReading": "readings",
    "MAX_EXPANSIONS": "planner",
    "MAX_MODULES": "planner",
    "MAX_PORTS": "planner",
    "GenericPlanner": "planner",
    "LatchRecognizer": "recognizer",
}

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
    "is_generic",
]


def is_generic(item: object) -> bool:
    """Whether ``item`` comes from the generic runtime (not from the robot's plugin)."""
    return getattr(item, "generic", False) is True


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
