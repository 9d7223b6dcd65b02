"""One capability of every other kind for the hinge robot: joint mode, planner, driver,
recognizer, controller, command and run listener (section 9 of the plugin guide)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from msrr.core import (
    Action,
    Configuration,
    Control,
    ModuleCommand,
    Observation,
    Phase,
    Plan,
    PlanningError,
    hookimpl,
    save_configuration,
)
from msrr.core.actions import detect_action
from msrr.core.capabilities import Controller, DriverFactory, Planner, Recognizer
from msrr.core.events import ActionStatus, Run, RunResult, Tick, TopologyEvent
from msrr.core.generic import KinematicDriverFactory
from msrr.core.hookspecs import Register

from .plugin import HINGE, SPEC

if TYPE_CHECKING:  # annotations only: the kinematics import scipy
    from msrr.core.kinematics.node import KinematicNode


@hookimpl
def msrr_kinematic_nodes(robot: str, register: Register[type[KinematicNode]]) -> None:
    if robot == SPEC.name:
        from .joints import HingeJoint  # scipy: imported when the robot is resolved

        register(HingeJoint)


class UndockThenDock:
    """Undock what the goal lacks, then dock what it adds: one action per changed link."""

    name = "undock-then-dock"
    description = "undock what the goal lacks, then dock what it adds"

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        if start.modules() != goal.modules():
            raise PlanningError("undock-then-dock keeps module ids: start and goal differ")
        wanted = {(e.source, e.target, e.ports) for e in goal.edges()}
        current, actions = start, []
        for edge in start.edges():
            if (edge.source, edge.target, edge.ports) not in wanted:
                after = current.copy()
                after.disconnect(edge.id)
                actions.append(detect_action(current, after, note=f"undock {edge.id}"))
                current = after
        had = {(e.source, e.target, e.ports) for e in start.edges()}
        for edge in goal.edges():
            if (edge.source, edge.target, edge.ports) not in had:
                after = current.copy()
                after.connect(edge.source, edge.target, ports=edge.ports)
                actions.append(detect_action(current, after, note=f"dock {edge.id}"))
                current = after
        return Plan(SPEC.name, self.name, start, goal, actions)


@hookimpl
def msrr_planners(robot: str, register: Register[Planner]) -> None:
    if robot == SPEC.name:
        register(UndockThenDock())


class FastWorld(KinematicDriverFactory):
    """The kinematic world with modules moving at 2 m/s."""

    name = "fast"
    description = "kinematic world, 2 m/s"

    def __init__(self) -> None:
        super().__init__(SPEC, speed=2.0)


@hookimpl
def msrr_drivers(robot: str, register: Register[DriverFactory]) -> None:
    if robot == SPEC.name:
        register(FastWorld())


class HeadToTail:
    """Latched head-tail pairs as connections from the head's module to the tail's."""

    name = "head-to-tail"
    description = "latched ports, each connection from head to tail"

    def recognize(self, sensors: Mapping[str, Any], *, seed: int = 0) -> Configuration:
        config = Configuration(SPEC.name)
        for module in sensors:
            config.add_module(module, HINGE.name)
        for module, reading in sensors.items():
            for latch in reading.latches:
                ends = {latch.port: module, latch.other_port: latch.other}
                config.connect(ends["head"], ends["tail"], ports=("head", "tail"))
        return config


@hookimpl
def msrr_recognizers(robot: str, register: Register[Recognizer]) -> None:
    if robot == SPEC.name:
        register(HeadToTail())


class Straight:
    """Each module of a moving action straight to its planar goal ``[x, y, yaw]``."""

    name = "straight"
    description = "straight to planar goals"

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        """Nothing to prepare: every tick steers straight at the action's goal."""

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        commands, errors = {}, {}
        if phase is Phase.MOVE:
            for module, (x, y, yaw) in action.goals.items():
                here = observation.tracked[module].position
                errors[module] = float(((here[0] - x) ** 2 + (here[1] - y) ** 2) ** 0.5)
                commands[module] = ModuleCommand(joints={"x": x, "y": y, "yaw": yaw})
        return Control(commands, errors, reached=all(e < 1e-9 for e in errors.values()))


@hookimpl
def msrr_controllers(robot: str, register: Register[Controller]) -> None:
    if robot == SPEC.name:
        register(Straight())


@hookimpl
def msrr_register_commands(cli: click.Group) -> None:
    @cli.command("hinge-chain")
    @click.argument("count", type=int)
    @click.argument("out", type=click.Path(path_type=Path))
    def hinge_chain(count: int, out: Path) -> None:
        """Write a chain of COUNT hinges, head to tail, to OUT."""
        config = Configuration(SPEC.name, name=f"chain{count}")
        for i in range(1, count + 1):
            config.add_module(f"h{i}", HINGE.name)
        for i in range(1, count):
            config.connect(f"h{i}", f"h{i + 1}", ports=("head", "tail"))
        save_configuration(config, out)
        click.echo(f"wrote {out}: {count} hinges")


LOG: list[str] = []
"""What the listener saw, one line per event (ticks counted)."""


@hookimpl
def msrr_on_run_start(run: Run) -> None:
    if run.robot == SPEC.name:
        LOG.append(f"start {run.scenario}: {len(run.plan.actions)} actions")


@hookimpl
def msrr_on_tick(run: Run, tick: Tick) -> None:
    if run.robot == SPEC.name and tick.index == 0:
        LOG.append(f"first tick in phase {tick.phase.value}")


@hookimpl
def msrr_on_action(run: Run, action: Action, status: ActionStatus) -> None:
    if run.robot == SPEC.name and status is ActionStatus.SUCCEEDED:
        LOG.append(f"done {action}")


@hookimpl
def msrr_on_topology_change(run: Run, change: TopologyEvent) -> None:
    if run.robot == SPEC.name:
        LOG.append(f"{change.kind} {change.change}")


@hookimpl
def msrr_on_run_end(run: Run, result: RunResult) -> None:
    if run.robot == SPEC.name:
        LOG.append(f"end: {'success' if result.success else result.reason}")
