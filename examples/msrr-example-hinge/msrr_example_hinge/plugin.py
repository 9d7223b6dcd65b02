"""The hinge robot: modules with a head and a tail port that dock head-to-tail into chains."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from msrr.core import (
    Body,
    DockingRules,
    Hinge,
    ModuleKind,
    PortSpec,
    RobotSpec,
    Scenario,
    Violation,
    hookimpl,
)
from msrr.core.hookspecs import Register
from msrr.core.robot import port_reuse_violations

if TYPE_CHECKING:  # annotations only: configurations import numpy and networkx
    from msrr.core import Configuration

CONFIGS = Path(__file__).parent / "configs"

HINGE = ModuleKind(
    name="hinge",
    symbol="H",
    role="vertex",
    ports=(PortSpec("head", "active", (1.0, 0.0, 0.0), position=(0.095, 0.0, 0.0)),
           PortSpec("tail", "passive", (-1.0, 0.0, 0.0), position=(-0.095, 0.0, 0.0))),
    body=Body(shape="box", size=(0.1, 0.03, 0.03), mass=0.2, friction=0.3),  # [m], [kg]
    hinge=Hinge(port="head", axis=(0.0, 0.0, 1.0), torque=1.0, limit=2.0),
    description="a link with a revolute hinge at its head port",
)

SPEC = RobotSpec(
    name="hinge",
    title="Hinge chain (example)",
    module_kinds=(HINGE,),
    description="Example third-party robot: hinge modules dock head-to-tail into chains.",
)


@hookimpl
def msrr_robot() -> RobotSpec | None:
    return SPEC


class HingeRules(DockingRules):
    """A head docks only to a tail; each port once; one connected chain (or ring)."""

    robot = "hinge"

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return {source_port, target_port} == {"head", "tail"}

    def check_topology(self, config: Configuration) -> list[Violation]:
        split = [] if config.is_connected() else [
            Violation("connections", "the hinges must form one chain or ring")]
        return port_reuse_violations(config) + split


@hookimpl
def msrr_docking_rules(robot: str) -> DockingRules | None:
    return HingeRules() if robot == SPEC.name else None


@hookimpl
def msrr_scenarios(robot: str, register: Register[Scenario]) -> None:
    if robot == SPEC.name:
        register(Scenario("reverse", "reverse a chain of three hinges",
                          CONFIGS / "chain3.json", CONFIGS / "chain3-reversed.json",
                          default=True))
        register(Scenario("fold", "a chain of four folds until its ends dock (physics)",
                          CONFIGS / "chain4.json", CONFIGS / "ring4.json"))
