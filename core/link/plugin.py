"""Hook implementation of the link driver: every robot can run on real modules.

Registered through the entry-point group like any plugin. The link speaks to the modules
that the robot's other drivers simulate, so it comes after all of them: the hook is a
wrapper, and it registers once every other implementation has (after ``yield``). Its
recognizer, controller and goal layout are those of the robot's default driver, the
first one registered.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import TYPE_CHECKING

from ..hookspecs import hookimpl

if TYPE_CHECKING:
    from ..capabilities import DriverFactory
    from ..hookspecs import Register

__all__ = ["msrr_drivers"]


@hookimpl(wrapper=True)
def msrr_drivers(robot: str, register: Register[DriverFactory]
                 ) -> Generator[None, list[None], list[None]]:
    answers = yield
    from .. import plugins
    from .driver import LinkDriverFactory

    register(LinkDriverFactory(plugins.robot(robot), next(iter(register.registered), None)))
    return answers
