"""A tiny robot defined in the tests, so core tests need no built-in robot plugin.

``tiny``: one module kind ``cube`` (a 0.4 x 0.2 x 0.1 m box) with an active port
``T`` (+x) and a passive port ``B`` (-x); only T-B connections, each port used once.
Its simulation is :class:`PointDriver`: modules are points on the x axis moving at
their commanded speed, and two armed ports latch when their modules are within
``reach`` of each other. :class:`LinePlanner` plans any start -> goal of the same
modules: undock what the goal lacks, move each new child next to its parent, dock.

``with installed(folder):`` registers the robot as an inline plugin (scenario
``swap`` written into ``folder``) and unregisters it afterwards. Not a test module.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from msrr.core import (
    Configuration,
    DockingRules,
    ModuleKind,
    PortSpec,
    RobotSpec,
    Scenario,
    Violation,
    hookimpl,
    plugins,
    save_configuration,
)
from msrr.core.control import Control
from msrr.core.driver import Driver, ModuleCommand, Observation, Pose
from msrr.core.events import Phase, Run
from msrr.core.hookspecs import Register
from msrr.core.kinematics.node import FixedNode, KinematicNode
from msrr.core.plan import Action, ActionType, ConnectionChange, Plan
from msrr.core.robot import Robot, port_reuse_violations

NAME = "tiny"
CUBE = ModuleKind(
    name="cube", symbol="C", role="vertex",
    ports=(PortSpec("T", "active", (1.0, 0.0, 0.0)), PortSpec("B", "passive", (-1.0, 0.0, 0.0))),
    geometry={"length": 0.4, "width": 0.2, "height": 0.1},
)
SPEC = RobotSpec(NAME, "Tiny test robot", (CUBE,), description="cubes docking T to B")


class TinyRules(DockingRules):
    """T docks to B only; a port holds one connection."""

    robot = NAME

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return (source_port, target_port) == ("T", "B")

    def check_topology(self, config: Configuration) -> list[Violation]:
        return port_reuse_violations(config)


ROBOT = Robot(SPEC, TinyRules(), {"fixed": FixedNode})


class PointDriver(Driver):
    """Modules are points on a line moving at their commanded speed; docks latch when
    commanded and the two modules are within ``reach`` of each other."""

    name = "points"
    description = "points on a line"

    def __init__(self, reach: float = 1.05, **options: Any):
        self.reach = reach
        self.connected = False
        self.x: dict[str, float] = {}
        self.speed: dict[str, float] = {}
        self.links: set[frozenset[tuple[str, str]]] = set()
        self.armed: set[tuple[str, str]] = set()
        self.t = 0.0

    @property
    def is_connected(self) -> bool:
        return self.connected

    def connect(self) -> None:
        self.connected = True

    def disconnect(self) -> None:
        self.connected = False

    def reset(self, start: Configuration) -> None:
        self.x = {m: float(i) for i, m in enumerate(start.vertices())}
        self.links = {frozenset({(e.source, e.ports[0]), (e.target, e.ports[1])})
                      for e in start.edges()}
        self.t = 0.0

    def get_observation(self) -> Observation:
        sensors: dict[str, dict] = {m: {} for m in self.x}
        for link in self.links:
            (a, fa), (b, fb) = sorted(link)
            sensors[a][fa] = (b, fb)
            sensors[b][fb] = (a, fa)
        # tracked like hardware with a pose sensor: no witness, the judge reads these
        return Observation(self.t, sensors,
                           tracked={m: Pose.planar(x, 0.0, 0.0) for m, x in self.x.items()})

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        self.speed = {m: c.wheels.get("v", 0.0) for m, c in commands.items()}
        self.armed = {(m, f) for m, c in commands.items() for f in c.dock}
        for m, c in commands.items():
            self.links = {k for k in self.links if not any((m, f) in k for f in c.undock)}

    def step(self, dt: float) -> None:
        for m, v in self.speed.items():
            self.x[m] += v * dt
        for a, fa in self.armed:
            for b, fb in self.armed:
                if a < b and abs(self.x[a] - self.x[b]) <= self.reach:
                    self.links.add(frozenset({(a, fa), (b, fb)}))
        self.t += dt

    @property
    def time(self) -> float:
        return self.t


class LinkRecognizer:
    """Latched ports to a configuration: each latched T-B pair is a connection T -> B."""

    name = "links"
    description = "latched ports to a configuration"

    def recognize(self, sensors: Mapping[str, Any], *, seed: int = 0) -> Configuration:
        config = Configuration(NAME)
        for m in sensors:
            config.add_module(m, CUBE.name)
        seen = set()
        for a, faces in sensors.items():
            for fa, (b, fb) in faces.items():
                key = frozenset({(a, fa), (b, fb)})
                if key not in seen:
                    seen.add(key)
                    source, target = ((a, fa), (b, fb)) if fa == "T" else ((b, fb), (a, fa))
                    config.connect(source[0], target[0], ports=(source[1], target[1]))
        return config


class GoalController:
    """Drives each goal module at up to 1 m/s toward its goal x."""

    name = "goal"
    description = "straight to the goal"

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        pass

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        commands, errors = {}, {}
        for m, goal in action.goals.items():
            error = goal[0] - float(observation.tracked[m].position[0])
            errors[m] = abs(error)
            step = max(-1.0, min(1.0, error * 10))
            commands[m] = ModuleCommand(wheels={"v": step if abs(error) > 1e-3 else 0.0})
        return Control(commands, errors, reached=all(e <= 1e-3 for e in errors.values()))


class LinePlanner:
    """Undock every connection the goal lacks, then for each new connection move the
    child to 1 m in front of its parent (where :class:`PointDriver` placed the modules
    at ``reset``: x = index in ``start.vertices()``) and dock."""

    name = "line"
    description = "undock, move next to the parent, dock"

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        have = {(e.source, e.target, e.ports) for e in start.edges()}
        want = {(e.source, e.target, e.ports) for e in goal.edges()}
        x = {m: float(i) for i, m in enumerate(start.vertices())}
        current = start.copy()
        actions = []
        for e in start.edges():
            if (e.source, e.target, e.ports) not in want:
                current.disconnect(e.id)
                actions.append(Action(ActionType.DISCONNECTION, current.copy(),
                                      (e.source, e.target),
                                      (ConnectionChange(e.source, e.target, *e.ports),)))
        for e in goal.edges():
            if (e.source, e.target, e.ports) in have:
                continue
            x[e.target] = x[e.source] + 1.0
            actions.append(Action(ActionType.MOVING, current.copy(), (e.target,),
                                  goals={e.target: [x[e.target], 0.0, 0.0]}))
            current.connect(e.source, e.target, ports=e.ports)
            actions.append(Action(ActionType.CONNECTION, current.copy(), (e.source, e.target),
                                  (ConnectionChange(e.source, e.target, *e.ports),)))
        return Plan(NAME, self.name, start, goal, actions)


class Hinge(FixedNode):
    """A joint mode for the registrar test (behaves as a fixed node)."""

    name = "tiny_hinge"


def chain(*links: tuple[str, str], modules: str = "abc", name: str = "") -> Configuration:
    """Cubes ``modules`` with a T -> B connection per ``(parent, child)`` link."""
    config = Configuration(NAME, name=name)
    for m in modules:
        config.add_module(m, CUBE.name)
    for parent, child in links:
        config.connect(parent, child, ports=("T", "B"))
    return config


def swap_plan(goal_x: float = 2.0) -> Plan:
    """a-b docked, c apart: undock a-b, move c to ``goal_x`` next to b, dock b-c."""
    plan = LinePlanner().plan(chain(("a", "b")), chain(("b", "c")))
    moving = plan.actions[1]
    plan.actions[1] = replace(moving, goals={"c": [goal_x, 0.0, 0.0]})
    return plan


def make_run(plan: Plan, **kwargs: Any) -> Run:
    return Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points", **kwargs)


class TinyPlugin:
    """The hook implementations of the tiny robot (an inline plugin)."""

    def __init__(self, folder: Path | None = None):
        self.scenarios: list[Scenario] = []
        if folder is not None:
            start, goal = folder / "start.json", folder / "goal.json"
            save_configuration(chain(("a", "b"), name="ab"), start)
            save_configuration(chain(("b", "c"), name="bc"), goal)
            self.scenarios.append(Scenario("swap", "a-b to b-c", start, goal, default=True))

    @hookimpl
    def msrr_robot(self) -> RobotSpec:
        return SPEC

    @hookimpl
    def msrr_docking_rules(self, robot: str) -> DockingRules | None:
        return TinyRules() if robot == NAME else None

    @hookimpl
    def msrr_kinematic_nodes(self, robot: str, register: Register[type[KinematicNode]]) -> None:
        if robot == NAME:
            register(Hinge)

    @hookimpl
    def msrr_controllers(self, robot: str, register: Register[GoalController]) -> None:
        if robot == NAME:
            register(GoalController())

    @hookimpl
    def msrr_recognizers(self, robot: str, register: Register[LinkRecognizer]) -> None:
        if robot == NAME:
            register(LinkRecognizer())

    @hookimpl
    def msrr_planners(self, robot: str, register: Register[LinePlanner]) -> None:
        if robot == NAME:
            register(LinePlanner())

    @hookimpl
    def msrr_drivers(self, robot: str, register: Register[type[PointDriver]]) -> None:
        if robot == NAME:
            register(PointDriver)

    @hookimpl
    def msrr_scenarios(self, robot: str, register: Register[Scenario]) -> None:
        if robot == NAME:
            for scenario in self.scenarios:
                register(scenario)


@contextmanager
def installed(folder: Path | None = None) -> Iterator[TinyPlugin]:
    """The tiny robot registered as a plugin for the ``with`` block."""
    with plugins.temporary(TinyPlugin(folder), "tiny-robot") as plugin:
        yield plugin
