"""Plans: the sequence of actions a planner hands to the executor.

Everything in a plan is in the *system's own* module ids (mappings are applied once,
by the planner or at library retrieval), so the executor never sees a reference id.

Action types follow the FreeSN paper, section 4.1: *moving* (vectors change, the
topology does not), *connection* and *disconnection* (one connection made or
broken; MMRP's dock and undock), *flow* (a leaf module leaves its parent for a
neighbour of the parent, disconnection and connection at once; defined in
:mod:`msrr.core.actions`), and *parallel* connection/disconnection (several at once).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Annotated, Any

from pydantic import Field, Strict

from .configuration import Configuration
from .errors import ConfigurationError
from .files import Coordinate, Cost, Number, StrictModel, atomic_write_text, parse_model, read_json
from .io import ConfigurationFile, configuration_from_model, configuration_to_model
from .robot import Robot, check_structure

__all__ = ["STRUT_ENDS", "Action", "ActionType", "ConnectionChange", "ConnectionKey", "Plan",
           "check_plan", "connection_key", "links", "load_plan", "natural_key", "save_plan"]


class ActionType(StrEnum):
    """Kinds of action (FreeSN paper section 4.1), detected by :func:`msrr.core.actions.classify`.

    A step that breaks some connections and makes others (not a flow) is a
    ``PARALLEL_CONNECTION``: disconnections first, then connections. ``FLOW``: one
    leaf module moves its one connection from its parent to a neighbour of the parent
    (:func:`msrr.core.actions.flow_move` has the exact rule).
    """

    MOVING = "moving"
    CONNECTION = "connection"
    DISCONNECTION = "disconnection"
    FLOW = "flow"
    PARALLEL_CONNECTION = "parallel_connection"
    PARALLEL_DISCONNECTION = "parallel_disconnection"


ConnectionKey = frozenset[tuple[str, str | None]]
"""The direction-free identity of a connection: its two ``(module, port)`` ends."""


def connection_key(source: str, target: str, source_port: str | None = None,
                   target_port: str | None = None) -> ConnectionKey:
    """The direction-free identity of a connection: its two ``(module, port)`` ends."""
    return frozenset({(source, source_port), (target, target_port)})


def natural_key(text: str) -> tuple[str | int, ...]:
    """Sort key of an id with its digit runs compared as numbers (``"2" < "10"``,
    ``"S2" < "S10"``): even positions hold text, odd positions numbers."""
    return tuple(int(part) if i % 2 else part for i, part in enumerate(re.split(r"(\d+)", text)))


@dataclass(frozen=True)
class ConnectionChange:
    """One connection made or broken: ``connect(source source_port, target target_port)``.

    Its one name everywhere a user reads it (run output, plan files, the viewer) is
    :attr:`label`; ``str(change)`` is that label.
    """

    source: str
    target: str
    source_port: str | None = None
    target_port: str | None = None
    edge_id: str | None = None

    @property
    def key(self) -> ConnectionKey:
        """Its direction-free identity (:func:`connection_key`)."""
        return connection_key(self.source, self.target, self.source_port, self.target_port)

    @property
    def label(self) -> str:
        """The connection's one name: its two ends, module id then port, in natural
        order (:func:`natural_key`) joined by ``-``: ``3T-8B`` whichever end a planner or
        driver names first, ``N1p2-S4a`` for a FreeSN strut end ``a`` on node ``N1``."""
        ends = sorted(((self.source, self.source_port or ""), (self.target, self.target_port or "")),
                      key=lambda end: (natural_key(end[0]), natural_key(end[1])))
        return "-".join(module + port for module, port in ends)

    def __str__(self) -> str:
        return self.label


STRUT_ENDS = ("a", "b")
"""Names of the source and target end of a connection that is a module."""


def links(config: Configuration) -> list[tuple[ConnectionKey, ConnectionChange]]:
    """Every physical link of ``config`` with its direction-free key.

    A connection between two modules is one link; a connection that is itself a
    module (a FreeSN strut) is one link per end resting on a module,
    ``{(strut, end), (module, port)}``; an end at a virtual vertex (a free connector)
    is no link.
    """
    found = []
    for edge in config.edges():
        ports = edge.ports or (None, None)
        if edge.kind is None:
            if not (config.is_virtual(edge.source) or config.is_virtual(edge.target)):
                found.append((connection_key(edge.source, edge.target, ports[0], ports[1]),
                              ConnectionChange(edge.source, edge.target, ports[0], ports[1],
                                               edge.id)))
            continue
        for end, vertex, port in zip(STRUT_ENDS, (edge.source, edge.target), ports, strict=True):
            if not config.is_virtual(vertex):
                found.append((connection_key(edge.id, vertex, end, port),
                              ConnectionChange(edge.id, vertex, end, port, edge.id)))
    return found


@dataclass
class Action:
    """One step of a plan.

    Attributes:
        type: the action type.
        target: the configuration the system should be in when the action is done.
        modules: ids of the modules that act.
        changes: connections made (connection types) or broken (disconnection types).
        goals: per-module goal pose for moving actions, ``{id: [x, y, yaw]}`` in
            [m, m, rad] for planar robots (MMRP), empty when ``target`` says it all.
        cost: motion cost of the step (library edge cost, or path length [m]).
        kinematic_tree: the tree that executes the step (freeform robots), if any.
        note: one line for logs ("free module 7 to the slot of 5").
    """

    type: ActionType
    target: Configuration
    modules: tuple[str, ...] = ()
    changes: tuple[ConnectionChange, ...] = ()
    goals: dict[str, list[float]] = field(default_factory=dict)
    cost: float = 0.0
    kinematic_tree: Any | None = None
    note: str = ""

    @property
    def label(self) -> str:
        """The action's one name in run output, plan files and the viewer: ``dock 3T-8B``,
        ``undock 3T-8B``, ``undock 5T-7B; dock 6T-7B`` (a flow or parallel step: broken
        first, as executed), ``move 2, 5``; connections by :attr:`ConnectionChange.label`."""
        if not self.changes:
            return f"move {', '.join(self.modules)}".strip()
        made = set(self.made())
        broken = [c.label for c in self.changes if c not in made]
        docked = [c.label for c in self.changes if c in made]
        return "; ".join(f"{verb} {', '.join(names)}"
                         for verb, names in (("undock", broken), ("dock", docked)) if names)

    def __str__(self) -> str:
        return self.label

    def made(self) -> tuple[ConnectionChange, ...]:
        """The changes that are connections of ``target`` (connections made)."""
        keys = {key for key, _ in links(self.target)}
        return tuple(c for c in self.changes if c.key in keys)

    def broken(self) -> tuple[ConnectionChange, ...]:
        """The changes that are not connections of ``target`` (connections broken)."""
        keys = {key for key, _ in links(self.target)}
        return tuple(c for c in self.changes if c.key not in keys)


@dataclass
class Plan:
    """The actions that take ``start`` to ``goal``, and what the planner knows about them.

    Attributes:
        robot: the robot's name.
        planner: name of the planner that made it.
        start: the configuration the plan starts from.
        goal: the configuration it reaches (in the system's ids).
        actions: the steps, in executable order.
        mapping: module mapping from the start's ids to the goal file's ids, if any.
        notes: remarks a user should read (fallbacks taken, approximations).
        stats: numbers the planner measured (time [ms], counts).
    """

    robot: str
    planner: str
    start: Configuration
    goal: Configuration
    actions: list[Action]
    mapping: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def docks(self) -> int:
        """Connections the actions make (a flow's and a reconnection's included)."""
        return sum(len(a.made()) for a in self.actions)

    @property
    def undocks(self) -> int:
        """Connections the actions break (a flow's and a reconnection's included)."""
        return sum(len(a.broken()) for a in self.actions)

    @property
    def flows(self) -> int:
        """Flow actions (each also one dock and one undock)."""
        return sum(1 for a in self.actions if a.type is ActionType.FLOW)


# -- file format ------------------------------------------------------------------------


class ChangeModel(StrictModel):
    source: str
    target: str
    source_port: str | None = None
    target_port: str | None = None
    edge_id: str | None = None


class ActionModel(StrictModel):
    type: ActionType
    target: ConfigurationFile
    modules: list[str] = []
    changes: list[ChangeModel] = []
    goals: dict[str, list[Coordinate]] = {}
    cost: Cost = 0.0
    kinematic_tree: dict[str, Any] | None = None
    note: str = ""


class PlanFile(StrictModel):
    """A plan file (``platform plan --json``; read back with :func:`load_plan`)."""

    schema_version: Annotated[int, Strict()] = Field(1, ge=1, le=1)
    robot: str = Field(min_length=1)
    planner: str
    start: ConfigurationFile
    goal: ConfigurationFile
    actions: list[ActionModel]
    mapping: dict[str, str] = {}
    notes: list[str] = []
    stats: dict[str, Number] = {}


def plan_to_model(plan: Plan) -> PlanFile:
    def tree(action: Action) -> Any:
        t = action.kinematic_tree
        return t.to_dict() if hasattr(t, "to_dict") else t

    return PlanFile(
        robot=plan.robot, planner=plan.planner,
        start=configuration_to_model(plan.start), goal=configuration_to_model(plan.goal),
        actions=[ActionModel(type=a.type, target=configuration_to_model(a.target),
                             modules=list(a.modules),
                             changes=[ChangeModel(**c.__dict__) for c in a.changes],
                             goals=a.goals, cost=a.cost, kinematic_tree=tree(a), note=a.note)
                 for a in plan.actions],
        mapping=plan.mapping, notes=plan.notes, stats=plan.stats,
    )


def _configuration(model: ConfigurationFile, robot: str, source: str | None, field: str
                   ) -> Configuration:
    try:
        config = configuration_from_model(model)
    except ConfigurationError as exc:
        raise ConfigurationError(exc.message, source=source,
                                 field=f"{field}.{exc.field}" if exc.field else field) from None
    if config.robot != robot:
        raise ConfigurationError(f"a configuration of robot {config.robot!r} in a plan for "
                                 f"{robot!r}", source=source, field=f"{field}.robot")
    return config


def _check_action(action: Action, i: int, source: str | None) -> None:
    """The ids an action names exist in its target."""
    target = action.target
    for j, module in enumerate(action.modules):
        if module not in target:
            raise ConfigurationError(f"module {module!r} is not in the action's target",
                                     source=source, field=f"actions[{i}].modules[{j}]")
    for module in action.goals:
        if module not in target:
            raise ConfigurationError(f"module {module!r} is not in the action's target",
                                     source=source, field=f"actions[{i}].goals")
    for j, change in enumerate(action.changes):
        for end in (change.source, change.target):
            if end not in target:
                raise ConfigurationError(f"module {end!r} is not in the action's target",
                                         source=source, field=f"actions[{i}].changes[{j}]")


def plan_from_model(model: PlanFile, source: str | None = None) -> Plan:
    """A :class:`Plan` from its file model; every configuration names the plan's robot,
    every id an action names is in its target; errors name ``source`` and the field."""
    actions = []
    for i, a in enumerate(model.actions):
        action = Action(type=a.type,
                        target=_configuration(a.target, model.robot, source,
                                              f"actions[{i}].target"),
                        modules=tuple(a.modules),
                        changes=tuple(ConnectionChange(**c.model_dump()) for c in a.changes),
                        goals=a.goals, cost=a.cost, kinematic_tree=a.kinematic_tree, note=a.note)
        _check_action(action, i, source)
        actions.append(action)
    start = _configuration(model.start, model.robot, source, "start")
    goal = _configuration(model.goal, model.robot, source, "goal")
    for module in model.mapping:
        if module not in start:
            raise ConfigurationError(f"module {module!r} is not in the start",
                                     source=source, field="mapping")
    return Plan(robot=model.robot, planner=model.planner, start=start, goal=goal,
                actions=actions, mapping=model.mapping, notes=model.notes, stats=model.stats)


def check_plan(plan: Plan, robot: Robot) -> None:
    """Validate ``plan`` against ``robot``: its start and goal follow every rule of the
    robot; every action target has only the robot's module kinds and ports (an
    intermediate configuration may break a topology rule on purpose, e.g. while split).

    Raises:
        ConfigurationError: naming the field (``start``, ``actions[3].target``...).
    """
    if plan.robot != robot.name:
        raise ConfigurationError(f"is a plan for robot {plan.robot!r}, not {robot.name!r}",
                                 field="robot")
    for where, config in (("start", plan.start), ("goal", plan.goal)):
        found = robot.violations(config)
        if found:
            raise ConfigurationError(f"{found[0].where}: {found[0].message}", field=where)
    for i, action in enumerate(plan.actions):
        found = check_structure(action.target, robot.spec)
        if found:
            raise ConfigurationError(f"{found[0].where}: {found[0].message}",
                                     field=f"actions[{i}].target")


def save_plan(plan: Plan, path: str | os.PathLike[str]) -> None:
    """Write ``plan`` as JSON, atomically."""
    data = plan_to_model(plan).model_dump(mode="json", exclude_none=True)
    atomic_write_text(path, json.dumps(data, indent=2) + "\n")


def load_plan(path: str | os.PathLike[str],
              robot: Robot | Callable[[str], Robot] | None = None) -> Plan:
    """Read a plan file and, when ``robot`` is given, validate it (:func:`check_plan`).

    ``robot`` may be a function giving the robot of the name the file holds, as
    :func:`msrr.core.plugins.load_plan` passes.

    Raises:
        ConfigurationError: a bad file, field or id, or a broken rule of ``robot``;
            naming the file and the field.
    """
    plan = plan_from_model(parse_model(PlanFile, read_json(path), str(path)), str(path))
    if robot is not None and not isinstance(robot, Robot):
        robot = robot(plan.robot)
    if robot is not None:
        try:
            check_plan(plan, robot)
        except ConfigurationError as exc:
            raise exc.at(str(path)) from None
    return plan
