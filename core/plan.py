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
import math
import os
import re
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from itertools import pairwise
from typing import Annotated, Literal

from pydantic import AllowInfNan, Field, Strict

from .configuration import Configuration
from .errors import ConfigurationError
from .files import Coordinate, Cost, Number, StrictModel, atomic_write_text, parse_model, read_json
from .io import ConfigurationFile, configuration_from_model, configuration_to_model
from .kinematics import KinematicTree, KinematicTreeFile
from .robot import Robot, Violation, check_structure
from .scenario import MAX_DISTANCE, MAX_LOOPS, MAX_TIME

__all__ = ["STRUT_ENDS", "Action", "ActionType", "BehaviorCall", "CommandGain",
           "ConnectionChange", "ConnectionKey", "Plan", "behavior_runs", "check_chain", "check_plan",
           "connection_key", "join_plans", "links", "load_plan", "natural_key", "save_plan"]


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
    BEHAVIOR = "behavior"


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
    def ends(self) -> tuple[tuple[str, str], tuple[str, str]]:
        """Its two ``(module, port)`` ends (``""`` for no port) in natural order
        (:func:`natural_key`): the order every listing of the connection uses."""
        first, second = sorted(((self.source, self.source_port or ""),
                                (self.target, self.target_port or "")),
                               key=lambda end: (natural_key(end[0]), natural_key(end[1])))
        return first, second

    @property
    def label(self) -> str:
        """The connection's one name: its :attr:`ends`, module id then port, joined by
        ``-``: ``3T-8B`` whichever end a planner or driver names first, ``N1p2-S4a`` for a
        FreeSN strut end ``a`` on node ``N1``."""
        return "-".join(module + port for module, port in self.ends)

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


@dataclass(frozen=True)
class CommandGain:
    """One module command of a mapping behavior: ``value = sum(gains[p] * params[p])``.

    Attributes:
        module: module id (the library's reference ids in a library, the system's in a
            plan).
        command: controller command name (``"wheel_speed"`` [rad/s]).
        gains: ``(parameter name, gain)`` pairs.
        connector: for an edge module, ``"source"`` or ``"target"`` end of its edge.
    """

    module: str
    command: str
    gains: tuple[tuple[str, float], ...]
    connector: Literal["source", "target"] | None = None

    def value(self, parameters: Mapping[str, float]) -> float:
        """The command value for the given parameter values (missing ones count 0)."""
        return sum(g * float(parameters.get(p, 0.0)) for p, g in self.gains)

    @property
    def key(self) -> str:
        """The name the value travels under in ``ModuleCommand.wheels``: the connector's
        end (``"a"`` the source end of an edge module, ``"b"`` its target end, as in
        :data:`STRUT_ENDS`), else the command's name."""
        if self.connector is None:
            return self.command
        return STRUT_ENDS[0 if self.connector == "source" else 1]


@dataclass(frozen=True)
class BehaviorCall:
    """A behavior an action runs (FreeSN paper, sections 4.3 and 6.3).

    A *mapping* behavior is one :attr:`ActionType.BEHAVIOR` action: every tick for
    ``duration`` seconds of driver time (or until the system's centre moved
    ``distance``) the executor sends each :class:`CommandGain`'s value for
    ``parameters`` while holding the action's target shape. A *sequence* behavior is a
    run of ordinary actions (moving, mostly), one loop after the other, each carrying
    the call with its ``loop`` number; with ``distance`` the executor skips the loops
    left once the centre has moved that far.

    Attributes:
        name: the behavior's label (``"wheeled-move"``).
        kind: ``"sequence"`` or ``"mapping"``.
        parameters: parameter name -> value (``speed`` [m/s], ``yaw_rate`` [rad/s]).
        commands: a mapping behavior's linear map, in the system's ids.
        duration: how long a mapping behavior runs [s of driver time].
        loops: loops of a sequence behavior in the plan.
        loop: which loop this action belongs to (from 0).
        distance: the behavior ends once the system's centre moved this far [m].
        direction: the commanded direction of travel in the action target's frame
            (unit, 3 numbers), for the heading error; ``None`` when not known.
    """

    name: str
    kind: Literal["sequence", "mapping"]
    parameters: Mapping[str, float] = field(default_factory=dict)
    commands: tuple[CommandGain, ...] = ()
    duration: float | None = None
    loops: int = 1
    loop: int = 0
    distance: float | None = None
    direction: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        for what, value in (("duration", self.duration), ("distance", self.distance)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigurationError(f"behavior {self.name}: {what} must be a finite "
                                         f"number > 0, got {value!r}", field=what)
        if self.kind == "mapping" and self.duration is None and self.distance is None:
            raise ConfigurationError(f"behavior {self.name}: a mapping behavior needs a "
                                     "duration or a distance", field="duration")
        if self.loops < 1 or not 0 <= self.loop < self.loops:
            raise ConfigurationError(f"behavior {self.name}: loop {self.loop} of "
                                     f"{self.loops}", field="loops")

    def __str__(self) -> str:
        params = ", ".join(f"{k}={v:g}" for k, v in self.parameters.items())
        return f"{self.name}({params})"


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
        behavior: the behavior this action runs (a ``BEHAVIOR`` action) or belongs to (a
            step of a sequence behavior), else ``None``.
        reaches: the name of a goal of the run this action ends at (a scenario stage's
            goal: the executor reports the shape error there); ``""`` for steps between.
        retrieved: where a retrieved step comes from, for the recording (``"S6N3-2.1
            <- S6N3-1.3; N1=n7, ..."``); ``""`` when planned otherwise.
    """

    type: ActionType
    target: Configuration
    modules: tuple[str, ...] = ()
    changes: tuple[ConnectionChange, ...] = ()
    goals: dict[str, list[float]] = field(default_factory=dict)
    cost: float = 0.0
    kinematic_tree: KinematicTree | None = None
    note: str = ""
    behavior: BehaviorCall | None = None
    reaches: str = ""
    retrieved: str = ""

    @property
    def label(self) -> str:
        """The action's one name in run output, plan files and the viewer: ``dock 3T-8B``,
        ``undock 3T-8B``, ``undock 5T-7B; dock 6T-7B`` (a flow or parallel step: broken
        first, as executed), ``move 2, 5``, ``behavior wheeled-move(speed=0.05)``;
        connections by :attr:`ConnectionChange.label`."""
        if self.type is ActionType.BEHAVIOR and self.behavior is not None:
            return f"behavior {self.behavior}"
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


def behavior_runs(actions: Sequence[Action]) -> list[range]:
    """The runs of behaviors in ``actions``, as index ranges: a mapping behavior's one
    action, or a sequence behavior's loops in a row (a new run begins where the behavior
    changes, or its loop number goes back)."""
    runs: list[range] = []
    first: int | None = None
    for index, action in enumerate(actions):
        call = action.behavior
        before = actions[index - 1].behavior if index else None
        starts = call is not None and (before is None or before.name != call.name
                                       or call.kind == "mapping" or before.loop > call.loop)
        if first is not None and (call is None or starts):
            runs.append(range(first, index))
            first = None
        if starts:
            first = index
    if first is not None:
        runs.append(range(first, len(actions)))
    return runs


def join_plans(plans: Sequence[Plan]) -> Plan:
    """One plan that runs ``plans`` one after the other (a scenario's stages): the first
    one's start and mapping, the last one's goal, every action in order, the notes
    kept, the stats summed, the planner names joined (``"library"``, ``"library+mcs"``).

    Raises:
        ConfigurationError: no plans, plans of different robots, or a plan that does not
            start with the modules the previous one ended with.
    """
    if not plans:
        raise ConfigurationError("no plans to join")
    for before, after in pairwise(plans):
        if after.robot != before.robot:
            raise ConfigurationError(f"cannot join a plan for {after.robot!r} to one for "
                                     f"{before.robot!r}")
        if after.start.modules() != before.goal.modules():
            raise ConfigurationError("a stage starts with other modules than the one before "
                                     "ends with")
    stats: dict[str, float] = {}
    for plan in plans:
        for key, value in plan.stats.items():
            stats[key] = stats.get(key, 0.0) + value
    names = list(dict.fromkeys(p.planner for p in plans))
    return Plan(robot=plans[0].robot, planner="+".join(names), start=plans[0].start,
                goal=plans[-1].goal, actions=[a for p in plans for a in p.actions],
                mapping=dict(plans[0].mapping), notes=[n for p in plans for n in p.notes],
                stats=stats)


# -- file format ------------------------------------------------------------------------


MAX_ACTIONS = 100_000
"""Most actions a plan file may hold (a thousand loops of a long sequence behavior fit)."""


class ChangeModel(StrictModel):
    source: str
    target: str
    source_port: str | None = None
    target_port: str | None = None
    edge_id: str | None = None


class CommandGainModel(StrictModel):
    module: str = Field(min_length=1)
    command: str = Field(min_length=1)
    gains: dict[str, Number]
    connector: Literal["source", "target"] | None = None


class BehaviorModel(StrictModel):
    """A :class:`BehaviorCall` in a plan file."""

    name: str = Field(min_length=1)
    kind: Literal["sequence", "mapping"]
    parameters: dict[str, Number] = {}
    commands: list[CommandGainModel] = []
    duration: Annotated[float, Strict(), AllowInfNan(False), Field(gt=0, le=MAX_TIME)] \
        | None = None
    loops: Annotated[int, Strict(), Field(ge=1, le=MAX_LOOPS)] = 1
    loop: Annotated[int, Strict(), Field(ge=0, lt=MAX_LOOPS)] = 0
    distance: Annotated[float, Strict(), AllowInfNan(False), Field(gt=0, le=MAX_DISTANCE)] \
        | None = None
    direction: Annotated[list[Number], Field(min_length=3, max_length=3)] | None = None


class ActionModel(StrictModel):
    type: ActionType
    target: ConfigurationFile
    modules: list[str] = []
    changes: list[ChangeModel] = []
    goals: dict[str, list[Coordinate]] = {}
    cost: Cost = 0.0
    kinematic_tree: KinematicTreeFile | None = None
    note: str = ""
    behavior: BehaviorModel | None = None
    reaches: str = ""
    retrieved: str = ""


class PlanFile(StrictModel):
    """A plan file (``platform plan --json``; read back with :func:`load_plan`)."""

    schema_version: Annotated[int, Strict()] = Field(1, ge=1, le=1)
    robot: str = Field(min_length=1)
    planner: str
    start: ConfigurationFile
    goal: ConfigurationFile
    actions: list[ActionModel] = Field(max_length=MAX_ACTIONS)
    mapping: dict[str, str] = {}
    notes: list[str] = []
    stats: dict[str, Number] = {}


def _behavior_model(call: BehaviorCall | None) -> BehaviorModel | None:
    if call is None:
        return None
    return BehaviorModel(
        name=call.name, kind=call.kind, parameters=dict(call.parameters),
        commands=[CommandGainModel(module=c.module, command=c.command, gains=dict(c.gains),
                                   connector=c.connector) for c in call.commands],
        duration=call.duration, loops=call.loops, loop=call.loop, distance=call.distance,
        direction=None if call.direction is None else list(call.direction))


def _behavior_call(model: BehaviorModel | None, source: str | None, field: str
                   ) -> BehaviorCall | None:
    if model is None:
        return None
    try:
        return BehaviorCall(
            name=model.name, kind=model.kind, parameters=dict(model.parameters),
            commands=tuple(CommandGain(c.module, c.command, tuple(c.gains.items()), c.connector)
                           for c in model.commands),
            duration=model.duration, loops=model.loops, loop=model.loop,
            distance=model.distance,
            direction=None if model.direction is None else
            (model.direction[0], model.direction[1], model.direction[2]))
    except ConfigurationError as exc:
        raise ConfigurationError(exc.message, source=source,
                                 field=f"{field}.{exc.field}" if exc.field else field) from None


def _tree_model(tree: KinematicTree | None) -> KinematicTreeFile | None:
    return None if tree is None else KinematicTreeFile.model_validate(tree.to_dict())


def plan_to_model(plan: Plan) -> PlanFile:
    return PlanFile(
        robot=plan.robot, planner=plan.planner,
        start=configuration_to_model(plan.start), goal=configuration_to_model(plan.goal),
        actions=[ActionModel(type=a.type, target=configuration_to_model(a.target),
                             modules=list(a.modules),
                             changes=[ChangeModel(**c.__dict__) for c in a.changes],
                             goals=a.goals, cost=a.cost,
                             kinematic_tree=_tree_model(a.kinematic_tree), note=a.note,
                             behavior=_behavior_model(a.behavior), reaches=a.reaches,
                             retrieved=a.retrieved)
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
    """The ids an action names exist in its target (vertices, or edges that are modules)."""
    target = set(action.target.vertices()) | set(action.target.edge_ids())
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
    for j, command in enumerate(action.behavior.commands if action.behavior else ()):
        if command.module not in target:
            raise ConfigurationError(f"module {command.module!r} is not in the action's "
                                     "target", source=source,
                                     field=f"actions[{i}].behavior.commands[{j}]")


def _tree(model: KinematicTreeFile | None, robot: str, modes: Mapping[str, type],
          source: str | None, field: str) -> KinematicTree | None:
    if model is None:
        return None
    try:
        tree = KinematicTree.from_dict(model.model_dump(mode="json", exclude_none=True),
                                       modes=modes, source=source)
    except ConfigurationError as exc:
        raise ConfigurationError(exc.message, source=source,
                                 field=f"{field}.{exc.field}" if exc.field else field) from None
    if tree.configuration.robot != robot:
        raise ConfigurationError(f"a tree of robot {tree.configuration.robot!r} in a plan for "
                                 f"{robot!r}", source=source, field=f"{field}.robot")
    return tree


def plan_from_model(model: PlanFile, source: str | None = None,
                    modes: Mapping[str, type] | None = None) -> Plan:
    """A :class:`Plan` from its file model; every configuration names the plan's robot,
    every id an action names is in its target; errors name ``source`` and the field.

    Args:
        model: the parsed file.
        source: file name for error messages.
        modes: the robot's joint modes (``Robot.joint_modes``), to read the actions'
            kinematic trees back as :class:`~msrr.core.kinematics.KinematicTree` s.
    """
    actions = []
    for i, a in enumerate(model.actions):
        where = f"actions[{i}]"
        action = Action(type=a.type,
                        target=_configuration(a.target, model.robot, source, f"{where}.target"),
                        modules=tuple(a.modules),
                        changes=tuple(ConnectionChange(**c.model_dump()) for c in a.changes),
                        goals=a.goals, cost=a.cost,
                        kinematic_tree=_tree(a.kinematic_tree, model.robot, modes or {}, source,
                                             f"{where}.kinematic_tree"),
                        note=a.note,
                        behavior=_behavior_call(a.behavior, source, f"{where}.behavior"),
                        reaches=a.reaches, retrieved=a.retrieved)
        if action.type is ActionType.BEHAVIOR and action.behavior is None:
            raise ConfigurationError("a behavior action names no behavior", source=source,
                                     field=f"{where}.behavior")
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
    """Validate ``plan`` whole against ``robot``: its start and goal follow every rule of
    the robot; every action target has only the robot's module kinds, ports and legal
    port pairs (an intermediate configuration may break a topology rule on purpose,
    e.g. while split); and the actions follow one another from the start to the goal
    (:func:`check_chain`).

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
        found = check_structure(action.target, robot.spec) + _port_pairs(action.target, robot)
        if found:
            raise ConfigurationError(f"{found[0].where}: {found[0].message}",
                                     field=f"actions[{i}].target")
    check_chain(plan)


def _port_pairs(config: Configuration, robot: Robot) -> list[Violation]:
    """The connections of ``config`` whose port pair the robot's rules refuse (a step
    may break a topology rule on purpose, never a port pair)."""
    found = []
    for edge in config.edges():
        ports = edge.ports or (None, None)
        if not robot.rules.ports_compatible(config.kind_of(edge.source), ports[0],
                                            config.kind_of(edge.target), ports[1]):
            found.append(Violation(f"connection {edge.id}", f"illegal port pair "
                                   f"{edge.source}{ports[0] or ''}-{edge.target}{ports[1] or ''}"))
    return found


def _link_changes(before: Configuration, after: Configuration
                  ) -> tuple[set[ConnectionKey], set[ConnectionKey]]:
    """The links (:func:`links`) ``after`` has that ``before`` lacks, and those it lost."""
    have = Counter(key for key, _ in links(before))
    want = Counter(key for key, _ in links(after))
    return set(want - have), set(have - want)


def _names(keys: set[ConnectionKey]) -> str:
    labels = sorted("-".join(f"{m}{p or ''}" for m, p in sorted(key, key=lambda e: (
        natural_key(e[0]), e[1] or ""))) for key in keys)
    return ", ".join(labels) or "none"


_KINDS: dict[ActionType, Callable[[int, int], bool]] = {
    ActionType.MOVING: lambda made, broken: not made and not broken,
    ActionType.BEHAVIOR: lambda made, broken: not made and not broken,
    ActionType.CONNECTION: lambda made, broken: made == 1 and not broken,
    ActionType.DISCONNECTION: lambda made, broken: broken == 1 and not made,
    ActionType.PARALLEL_DISCONNECTION: lambda made, broken: broken > 1 and not made,
    ActionType.FLOW: lambda made, broken: made == 1 and broken == 1,
    ActionType.PARALLEL_CONNECTION: lambda made, broken: made >= 1 and made + broken > 1,
}
"""Which counts of links made and broken each action type may have (section 4.1; a flow
is one of each, of one module: :func:`msrr.core.actions.flow_move` has the exact rule,
which the executor applies)."""


def check_chain(plan: Plan) -> None:
    """Validate that ``plan``'s actions follow one another: each action's target has the
    modules of the step before (the start for the first), its type and ``changes`` are
    the links that step makes and breaks, its ``modules`` name every module its changes
    and goals name, no action repeats the one before it, and the last target is the
    plan's goal (its modules and links).

    Raises:
        ConfigurationError: naming the field (``actions[3].changes``, ``goal``...).
    """
    before, said = plan.start, "the start"
    for i, action in enumerate(plan.actions):
        where = f"actions[{i}]"
        _same_modules(before, action.target, said, f"{where}.target")
        made, broken = _link_changes(before, action.target)
        if not _KINDS[action.type](len(made), len(broken)):
            raise ConfigurationError(
                f"a {action.type.value} action, but from {said} its target makes "
                f"{_names(made)} and breaks {_names(broken)}", field=f"{where}.type")
        planned = {c.key for c in action.changes}
        if planned != made | broken and (planned or action.type is not ActionType.FLOW):
            raise ConfigurationError(
                f"are {_names(planned)}, but from {said} its target makes {_names(made)} "
                f"and breaks {_names(broken)}", field=f"{where}.changes")
        acting = {m for c in action.changes for m in (c.source, c.target)} | set(action.goals)
        missing = sorted(acting - set(action.modules), key=natural_key)
        if missing:
            raise ConfigurationError(f"leaves out {', '.join(missing)}, which the action's "
                                     "changes or goals name", field=f"{where}.modules")
        if i and _repeats(action, plan.actions[i - 1]):
            raise ConfigurationError("repeats the action before it", field=where)
        before, said = action.target, f"{where}.target"
    _same_modules(before, plan.goal, said, "goal")
    made, broken = _link_changes(before, plan.goal)
    if made or broken:
        raise ConfigurationError(f"is not where the actions end: {said} lacks {_names(made)} "
                                 f"and has {_names(broken)} besides", field="goal")


def _same_modules(before: Configuration, after: Configuration, said: str, field: str) -> None:
    have, want = before.modules(), after.modules()
    if have != want:
        extra = sorted(set(want) - set(have), key=natural_key)
        gone = sorted(set(have) - set(want), key=natural_key)
        kinds = sorted((m for m in set(have) & set(want) if have[m] != want[m]), key=natural_key)
        parts = [f"{what} {', '.join(ids)}" for what, ids in (
            ("modules not in " + said + ":", extra), ("lacks", gone),
            ("other module kinds of", kinds)) if ids]
        raise ConfigurationError(f"has other modules than {said} ({'; '.join(parts)})",
                                 field=field)


def _repeats(action: Action, before: Action) -> bool:
    """Whether ``action`` is ``before`` again (a copied step: nothing left to do)."""
    if (action.type, action.modules, action.changes, action.goals, action.behavior,
            action.reaches) != (before.type, before.modules, before.changes, before.goals,
                                before.behavior, before.reaches):
        return False
    return configuration_to_model(action.target) == configuration_to_model(before.target)


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
    model = parse_model(PlanFile, read_json(path), str(path))
    if robot is not None and not isinstance(robot, Robot):
        robot = robot(model.robot)
    plan = plan_from_model(model, str(path), None if robot is None else robot.joint_modes)
    if robot is not None:
        try:
            check_plan(plan, robot)
        except ConfigurationError as exc:
            raise exc.at(str(path)) from None
    return plan
