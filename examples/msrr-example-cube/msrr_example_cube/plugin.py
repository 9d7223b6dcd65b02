"""The cube robot: wheeled cubes with a docking face on each side, described only.

Everything else -- planner, MuJoCo world, recognizer, controller -- comes from the
platform's generic runtime, built from this description.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from msrr.core import (
    Body,
    DockingRules,
    ModuleKind,
    PortSpec,
    RobotDefaults,
    RobotSpec,
    Scenario,
    ShapeTolerance,
    Violation,
    Wheels,
    hookimpl,
)
from msrr.core.hookspecs import Register
from msrr.core.robot import port_reuse_violations

if TYPE_CHECKING:  # annotations only: configurations import numpy and networkx
    from msrr.core import Configuration

CONFIGS = Path(__file__).parent / "configs"

CUBE = ModuleKind(
    name="cube",
    symbol="C",
    role="vertex",
    ports=(PortSpec("E", "neutral", (1.0, 0.0, 0.0)), PortSpec("N", "neutral", (0.0, 1.0, 0.0)),
           PortSpec("W", "neutral", (-1.0, 0.0, 0.0)), PortSpec("S", "neutral", (0.0, -1.0, 0.0))),
    body=Body(shape="box", size=(0.1, 0.1, 0.08), mass=0.4),
    wheels=Wheels(radius=0.02, track=0.07, speed=0.15, torque=0.3),
    description="a wheeled cube with a magnetic docking face on each side",
)

SPEC = RobotSpec(
    name="cube",
    title="Wheeled cube (example)",
    module_kinds=(CUBE,),
    description="Example third-party robot: wheeled cubes that dock face to face on the floor.",
    defaults=RobotDefaults(planar=True,
                           shape_tolerance=ShapeTolerance(position=0.02, heading=0.1)),
)


@hookimpl
def msrr_robot() -> RobotSpec | None:
    return SPEC


class CubeRules(DockingRules):
    """Any face docks to any face; each face once."""

    robot = "cube"

    def check_topology(self, config: Configuration) -> list[Violation]:
        return port_reuse_violations(config)


@hookimpl
def msrr_docking_rules(robot: str) -> DockingRules | None:
    return CubeRules() if robot == SPEC.name else None


@hookimpl
def msrr_scenarios(robot: str, register: Register[Scenario]) -> None:
    if robot == SPEC.name:
        register(Scenario("line-l", "a line of four cubes becomes an L",
                          CONFIGS / "line4.json", CONFIGS / "l4.json", default=True))
        register(Scenario("l-t", "the L becomes a T", CONFIGS / "l4.json", CONFIGS / "t4.json"))
