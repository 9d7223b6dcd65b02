"""The freeform family: modules with one connector that docks anywhere on another module
(FreeBOT, SnailBot; FreeSN paper, sections 2.1, 4.1), and the MuJoCo world every freeform
robot's simulation stands on.

* :mod:`.miso` -- MISO connection planning (the ``miso`` and ``miso-exact`` planners)
  between configurations of any pieces, under the robot's rules; pure: numpy and scipy,
  no simulator;
* :mod:`.design` -- a single-connector robot's description (:func:`freeform_robot`,
  read from its ``robot.json``) and its module's design in the simulator
  (:class:`ModuleDesign`);
* :mod:`.plugin` -- :class:`FreeformPlugin`, the hook implementations of a
  single-connector robot, built from its description, joint modes, module design and
  scenarios; imports nothing heavy, so a robot's plugin module stays cheap to load;
* :mod:`.mujoco` -- what every MuJoCo freeform world shares (FreeSN's too): the step
  loop, switched weld equalities for docking, the ground, seeded sensor noise, headings
  (:class:`MujocoWorld`), and the driver over such a world (:class:`MujocoDriver`);
* :mod:`.world` -- the world of single-connector modules built with ``MjSpec``: shells,
  connectors on motor-driven joints about the parent's centre, docks and flows as
  switched welds, suckers;
* :mod:`.driver` -- the :class:`~msrr.core.driver.Driver` a robot registers as ``mujoco``;
* :mod:`.recognition` -- the recognizer (module reports only) and the controllers.

The names below are imported on first use (PEP 562): ``import msrr.core.freeform`` and
the planner import no simulator; the world, driver and recognition modules import
``mujoco``.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .design import ModuleDesign, freeform_robot, read_freeform_robot
    from .driver import FreeformDriver, FreeformDriverFactory
    from .layout import place
    from .miso import MisoLimits, MisoPlanner, plan_miso
    from .mujoco import MujocoOptions, MujocoWorld, SensorNoise, Switches
    from .mujoco_driver import MujocoDriver
    from .plugin import FreeformPlugin
    from .recognition import (
        ContactController,
        ContactRecognizer,
        anchors,
        bend_error,
        bend_errors,
        common_turn,
        flow_direction,
        goal_side,
        links_of,
        module_headings,
    )
    from .world import ConstraintEvent, FreeformOptions, FreeformWorld, ModuleReport

_WHERE = {
    "ConstraintEvent": "world",
    "ContactController": "recognition",
    "ContactRecognizer": "recognition",
    "FreeformDriver": "driver",
    "FreeformDriverFactory": "driver",
    "FreeformOptions": "world",
    "FreeformPlugin": "plugin",
    "FreeformWorld": "world",
    "MisoLimits": "miso",
    "MisoPlanner": "miso",
    "ModuleDesign": "design",
    "ModuleReport": "world",
    "MujocoDriver": "mujoco_driver",
    "MujocoOptions": "mujoco",
    "MujocoWorld": "mujoco",
    "SensorNoise": "mujoco",
    "Switches": "mujoco",
    "anchors": "recognition",
    "bend_error": "recognition",
    "bend_errors": "recognition",
    "common_turn": "recognition",
    "flow_direction": "recognition",
    "freeform_robot": "design",
    "goal_side": "recognition",
    "links_of": "recognition",
    "module_headings": "recognition",
    "place": "layout",
    "plan_miso": "miso",
    "read_freeform_robot": "design",
}
"""Public name -> the submodule that defines it."""

__all__ = [
    "ConstraintEvent",
    "ContactController",
    "ContactRecognizer",
    "FreeformDriver",
    "FreeformDriverFactory",
    "FreeformOptions",
    "FreeformPlugin",
    "FreeformWorld",
    "MisoLimits",
    "MisoPlanner",
    "ModuleDesign",
    "ModuleReport",
    "MujocoDriver",
    "MujocoOptions",
    "MujocoWorld",
    "SensorNoise",
    "Switches",
    "anchors",
    "bend_error",
    "bend_errors",
    "common_turn",
    "flow_direction",
    "freeform_robot",
    "goal_side",
    "links_of",
    "module_headings",
    "place",
    "plan_miso",
    "read_freeform_robot",
]


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first use (PEP 562)."""
    try:
        module = _WHERE[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_WHERE})
