"""Hook implementations of the generic runtime: what every described robot gets.

Registered through the entry-point group like any plugin. Every hook is ``trylast``: a
fallback, after the robot's own items and any other plugin's, and an item of the same
name from anyone else wins over it. The items are built from the robot's description
(:func:`msrr.core.plugins.describe`); this module imports the runtime inside the hooks,
so loading it costs nothing on ``--help``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..hookspecs import hookimpl

if TYPE_CHECKING:
    from ..capabilities import Controller, DriverFactory, Planner, Recognizer
    from ..hookspecs import Register

__all__ = ["msrr_controllers", "msrr_drivers", "msrr_planners", "msrr_recognizers"]


@hookimpl(trylast=True)
def msrr_planners(robot: str, register: Register[Planner]) -> None:
    from .. import plugins
    from .planner import GenericPlanner

    register(GenericPlanner(plugins.describe(robot)))


@hookimpl(trylast=True)
def msrr_drivers(robot: str, register: Register[DriverFactory]) -> None:
    from .. import plugins
    from ..bodies import has_bodies
    from .driver import KinematicDriverFactory

    spec = plugins.robot(robot)
    register(KinematicDriverFactory(spec))
    if has_bodies(spec):
        from .physics import PhysicsDriverFactory  # MuJoCo: only for robots with bodies

        register(PhysicsDriverFactory(spec))


@hookimpl(trylast=True)
def msrr_recognizers(robot: str, register: Register[Recognizer]) -> None:
    from .. import plugins
    from .recognizer import LatchRecognizer

    register(LatchRecognizer(plugins.robot(robot)))


@hookimpl(trylast=True)
def msrr_controllers(robot: str, register: Register[Controller]) -> None:
    from .. import plugins
    from ..bodies import has_bodies
    from .controller import LatchController

    spec = plugins.robot(robot)
    register(LatchController(spec))
    if has_bodies(spec):
        from .drive import DriveController

        register(DriveController(spec))
