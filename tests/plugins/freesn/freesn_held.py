"""A FreeSN structure held in shape by its controller, its wheels driven (the node-wheel
tests' loop)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand, Observation
from msrr.core.shape import skeletal_errors
from msrr.plugins.freesn.sim.controller import FreeSNController

WHEELS_FROM = 10
"""The tick from which the wheels run (1 s at 10 Hz: the shape settles first)."""


def held_commands(controller: FreeSNController, start: Configuration,
                  observation: Observation, wheels: Mapping[str, Mapping[str, float]],
                  tick: int, yaw: float | None) -> tuple[dict[str, ModuleCommand], float]:
    """The commands that hold ``start`` at ``tick``, ``wheels`` (module -> connector ->
    speed) added from :data:`WHEELS_FROM` on, and the yaw they turn it by: eq. 8's onto
    the first recognition (``yaw`` None at the first tick)."""
    if yaw is None:
        yaw = skeletal_errors(controller._recognizer.recognize(observation.sensors), start)[2]
    commands = controller.commands(start, observation, yaw=yaw)
    if tick >= WHEELS_FROM:
        commands.update({m: replace(commands[m], wheels=dict(w)) for m, w in wheels.items()})
    return commands, yaw
