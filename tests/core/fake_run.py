"""A tiny in-memory robot for executor and timeline tests (not a test module)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from msrr.core import Configuration
from msrr.core.control import Control
from msrr.core.driver import Driver, ModuleCommand, Observation, Pose
from msrr.core.events import Phase, Run
from msrr.core.plan import Action, ActionType, ConnectionChange, Plan


class PointDriver(Driver):
    """Modules are points on a line moving at their commanded speed; docks latch when
    commanded and the two modules are within ``reach`` of each other."""

    name = "points"
    description = "points on a line"

    def __init__(self, reach: float = 1.05):
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
        sensors = {m: {} for m in self.x}
        for link in self.links:
            (a, fa), (b, fb) = sorted(link)
            sensors[a][fa] = (b, fb)
            sensors[b][fb] = (a, fa)
        return Observation(self.t, {m: Pose.planar(x, 0.0, 0.0) for m, x in self.x.items()},
                           sensors)

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
    name = "links"
    description = "face links to a configuration"

    def recognize(self, observation: Any, *, seed: int = 0) -> Configuration:
        config = Configuration("mmrp")
        for m in observation:
            config.add_module(m, "mmrp")
        seen = set()
        for a, faces in observation.items():
            for fa, (b, fb) in faces.items():
                key = frozenset({(a, fa), (b, fb)})
                if key not in seen:
                    seen.add(key)
                    config.connect(a, b, ports=(fa, fb))
        return config


class GoalController:
    """Drives each goal module at 1 m/s toward its goal x."""

    name = "goal"
    description = "straight to the goal"

    def begin(self, action: Action, phase: Phase, observation: Observation) -> None:
        pass

    def control(self, action: Action, phase: Phase, observation: Observation) -> Control:
        commands, errors = {}, {}
        for m, goal in action.goals.items():
            error = goal[0] - float(observation.poses[m].position[0])
            errors[m] = abs(error)
            step = max(-1.0, min(1.0, error * 10))
            commands[m] = ModuleCommand(wheels={"v": step if abs(error) > 1e-3 else 0.0})
        return Control(commands, errors, reached=all(e <= 1e-3 for e in errors.values()))


def three(*links: tuple[str, str, str, str]) -> Configuration:
    return LinkRecognizer().recognize(
        {m: {} for m in "abc"} | _faces(links))


def _faces(links: tuple[tuple[str, str, str, str], ...]) -> dict[str, dict]:
    out: dict[str, dict] = {m: {} for m in "abc"}
    for a, fa, b, fb in links:
        out[a][fa] = (b, fb)
        out[b][fb] = (a, fa)
    return out


def swap_plan(goal_x: float = 2.0) -> Plan:
    """a-b docked, c apart: undock a-b, move c next to b, dock b-c."""
    start = three(("a", "T", "b", "B"))
    free = three()
    goal = three(("b", "T", "c", "B"))
    actions = [
        Action(ActionType.DISCONNECTION, free, ("a", "b"),
               (ConnectionChange("a", "b", "T", "B"),)),
        Action(ActionType.MOVING, free, ("c",), goals={"c": [goal_x, 0.0, 0.0]}),
        Action(ActionType.CONNECTION, goal, ("b", "c"),
               (ConnectionChange("b", "c", "T", "B"),)),
    ]
    return Plan("mmrp", "hand", start, goal, actions)


def make_run(plan: Plan, **kwargs: Any) -> Run:
    return Run(robot="mmrp", scenario="test", plan=plan, driver="points", **kwargs)
