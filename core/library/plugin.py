"""Hook implementation of the library planner: any robot with behavior libraries gets it.

A robot that registers library files (``msrr_libraries``) gets the ``library`` planner
(:class:`~msrr.core.library.planner.LibraryPlanner`: match, shortest action path, remap;
behaviors with ``platform run --behavior``). Registered through the entry-point group
like any plugin; an ordinary implementation, so it comes after the robot's own planners
and before the generic runtime's ``trylast`` fallback.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..hookspecs import hookimpl

if TYPE_CHECKING:
    from ..capabilities import Planner
    from ..hookspecs import Register

__all__ = ["msrr_planners"]


@hookimpl
def msrr_planners(robot: str, register: Register[Planner]) -> None:
    from .. import plugins

    paths = plugins.libraries(robot)
    if paths:
        from .planner import LibraryPlanner

        register(LibraryPlanner(plugins.describe(robot), paths))
