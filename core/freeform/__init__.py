"""Freeform modules with one connector (FreeBOT, SnailBot) in MuJoCo (FreeSN paper 2.1, 4.1).

* :mod:`.mujoco` -- what every MuJoCo freeform world shares: the ground, switched
  equality constraints, seeded sensor noise, headings;
* :mod:`.world` -- the world built with ``MjSpec``: shells, connectors on motor-driven
  joints about the parent's centre, docks and flows as switched welds, suckers;
* :mod:`.driver` -- the :class:`~msrr.core.driver.Driver` a robot registers as ``mujoco``;
* :mod:`.recognition` -- the recognizer (module reports only) and the controllers.

Importing this package imports ``mujoco``: robot plugins import it inside their hooks.
"""

from .driver import FreeformDriver
from .recognition import (
    ContactController,
    ContactRecognizer,
    common_turn,
    flow_direction,
    goal_side,
    links_of,
    module_headings,
)
from .world import (
    ConstraintEvent,
    FreeformOptions,
    FreeformWorld,
    ModuleDesign,
    ModuleReport,
    place,
)

__all__ = [
    "ConstraintEvent",
    "ContactController",
    "ContactRecognizer",
    "FreeformDriver",
    "FreeformOptions",
    "FreeformWorld",
    "ModuleDesign",
    "ModuleReport",
    "common_turn",
    "flow_direction",
    "goal_side",
    "links_of",
    "module_headings",
    "place",
]
