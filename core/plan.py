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

import contextlib
import json
import math
import os
import re
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from itertools import pairwise
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AllowInfNan, BeforeValidator, ConfigDict, Field, Strict

from .configuration import VIRTUAL, Configuration, Edge, unit
from .delta import ConfigurationDelta, DerivedConfiguration, Draft, Vertex, difference
from .errors import ConfigurationError
from .files import (
    Coordinate,
    Cost,
    Number,
    StrictModel,
    atomic_write_text,
    not_boolean,
    parse_model,
    read_json,
)
from .io import (
    ConfigurationFile,
    ConnectionModel,
    ModuleModel,
    configuration_from_model,
    configuration_to_model,
)
from .kinematics import KinematicTree, KinematicTreeFile
from .kinematics.tree_file import TREE_SCHEMA_VERSION, NodeModel
from .robot import Robot, Violation, check_structure
from .scenario import MAX_DISTANCE, MAX_LOOPS, MAX_TIME

__all__ = ["STRUT_ENDS", "WHEEL_SPEED", "Action", "ActionType", "BehaviorCall", "CommandGain",
           "ConnectionChange", "ConnectionKey", "Plan", "behavior_runs", "check_chain",
           "check_plan", "connection_key", "join_plans", "links", "load_plan", "natural_key",
           "parse_plan_file", "save_plan"]


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
WHEEL_SPEED = "wheel_speed"
"""A behavior's wheel command [rad/s]; of a connector, it travels under the end's name."""


def links(config: Configuration, edges: Iterable[Edge] | None = None
          ) -> list[tuple[ConnectionKey, ConnectionChange]]:
    """Every physical link of ``config`` (of ``edges`` of it, when given) with its
    direction-free key.

    A connection between two modules is one link; a connection that is itself a
    module (a FreeSN strut) is one link per end resting on a module,
    ``{(strut, end), (module, port)}``; an end at a virtual vertex (a free connector)
    is no link.
    """
    found = []
    for edge in config.edges() if edges is None else edges:
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


LinkLayout = tuple[frozenset[str], tuple[tuple[str, str, str, str | None, tuple[str, str] | None],
                                         ...]]
"""What a configuration's links depend on (:func:`link_layout`)."""


def link_layout(config: Configuration) -> LinkLayout:
    """What :func:`links` of ``config`` depends on: its virtual vertices and every edge's
    ends, id, kind and ports. Two configurations of one layout have the same links, so
    nothing to make or break between them: a test much cheaper than :func:`links` for a
    configuration recognized again every tick."""
    graph = config.graph
    virtual = frozenset(v for v, kind in graph.nodes(data="kind") if kind == VIRTUAL)
    return virtual, tuple((u, v, key, data["kind"], data["ports"])
                          for u, v, key, data in graph.edges(keys=True, data=True))


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
        """The name the value travels under in ``ModuleCommand.wheels``: for a
        :data:`WHEEL_SPEED` command the connector's end (``"a"`` the source end of an
        edge module, ``"b"`` its target end, as in :data:`STRUT_ENDS`), for another
        command of a connector ``"<end>.<command>"`` (``"b.travel_across"``), else the
        command's name."""
        if self.connector is None:
            return self.command
        end = STRUT_ENDS[0 if self.connector == "source" else 1]
        return end if self.command == WHEEL_SPEED else f"{end}.{self.command}"


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
        drive_root: the node the behavior is driven from (the library's
            :attr:`~msrr.core.library.model.Behavior.drive_root`, in the system's ids);
            ``None``: the joint controller's own choice.
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
    drive_root: str | None = None

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
        keys = self._target_links()
        return tuple(c for c in self.changes if c.key in keys)

    def broken(self) -> tuple[ConnectionChange, ...]:
        """The changes that are not connections of ``target`` (connections broken)."""
        keys = self._target_links()
        return tuple(c for c in self.changes if c.key not in keys)

    def _target_links(self) -> set[ConnectionKey]:
        """The links of ``target`` at the modules the changes name (O(their degree), not
        O(the target): a plan of thousands of actions counts its docks quickly). Read
        off the target's own delta when it is a :class:`DerivedConfiguration` whose
        delta writes or removes every changed connection, without building it (printing
        a 1,000-module plan built a thousand targets)."""
        target = self.target if self.changes else None
        if target is None:
            return set()
        if isinstance(target, DerivedConfiguration) and target.delta is not None:
            known = _delta_links(target.delta, self.changes)
            if known is not None:
                return known
        near = {m for c in self.changes for m in (c.source, c.target)}
        edges = {e.id: e for m in near if m in target.graph for e in target.incident(m)}
        for module in near - edges.keys():  # an edge module (a strut) names itself
            if module not in target.graph:
                with contextlib.suppress(ConfigurationError):
                    edges[module] = target.edge(module)
        return {key for key, _ in links(target, edges.values())}


def _delta_links(delta: ConfigurationDelta, changes: Sequence[ConnectionChange]
                 ) -> set[ConnectionKey] | None:
    """The keys of ``changes`` that are links of the configuration ``delta`` leads to,
    read from ``delta`` alone: a change is a link when the delta writes its connection
    (same id, ends and ports, between modules) and none when the delta removes it and
    writes nothing with its key. None when a change is neither, or the delta changes
    vertices (a vertex's kind decides whether a connection is a link)."""
    if delta.vertices or delta.removed_vertices:
        return None
    written = {e.id: e for e, _ in delta.edges}
    written_keys = {connection_key(e.source, e.target, *(e.ports or (None, None)))
                    for e in written.values()}
    removed = set(delta.removed_edges)
    keys = set()
    for change in changes:
        edge = written.get(change.edge_id or "")
        if edge is not None:
            if edge.kind is not None or connection_key(
                    edge.source, edge.target, *(edge.ports or (None, None))) != change.key:
                return None
            keys.add(change.key)
        elif change.edge_id not in removed or change.key in written_keys:
            return None
    return keys


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


SCHEMA_VERSION = 2
"""The plan file format written: the start whole, every later configuration as its
changes (:class:`DeltaModel`). Version 1 (every target whole) is still read."""

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
    drive_root: str | None = Field(None, min_length=1, description="The node the behavior "
                                   "is driven from (default: the joint controller's choice).")


Index = Annotated[int, Strict(), Field(ge=0)] | None


class ModuleDeltaModel(ModuleModel):
    """A module added or changed (whole); ``at``: its index in the new module order
    when inserted before the end."""

    at: Index = Field(None, description="Index in the new module order (default: the end).")


class ConnectionDeltaModel(ConnectionModel):
    """A connection added or changed (whole, its id required); ``at``: its index in the
    new connection order when inserted before the end."""

    id: str = Field(min_length=1, description="Edge id (module id for edge modules).")
    at: Index = Field(None, description="Index in the new connection order (default: the end).")


class DeltaModel(StrictModel):
    """A configuration as its changes to the one before (:class:`ConfigurationDelta`):
    applied in the order removed connections, removed modules, modules, connections."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, coerce_numbers_to_str=True)

    name: str | None = Field(None, description="The new name, when it changes.")
    description: str | None = Field(None, description="The new description, when it changes.")
    removed_connections: list[str] = Field(default_factory=list,
                                           description="Ids of connections removed.")
    removed_modules: list[str] = Field(default_factory=list, description="Ids of modules "
                                       "removed (with no connection left).")
    modules: list[ModuleDeltaModel] = Field(default_factory=list,
                                            description="Modules added or changed.")
    connections: list[ConnectionDeltaModel] = Field(default_factory=list,
                                                    description="Connections added or changed.")


class TreeModel(StrictModel):
    """An action's kinematic tree: its topology as changes to the action's target without
    its vectors (usually none), and its nodes in BFS order
    (:mod:`msrr.core.kinematics.tree_file`)."""

    topology: DeltaModel = Field(default_factory=DeltaModel)
    nodes: list[NodeModel] = Field(min_length=1)


class ActionModel(StrictModel):
    type: ActionType
    target: DeltaModel = Field(default_factory=DeltaModel, description="The action's target "
                               "as its changes to the previous target (the start for the "
                               "first action).")
    modules: list[str] = Field(default_factory=list)
    changes: list[ChangeModel] = Field(default_factory=list)
    goals: dict[str, list[Coordinate]] = Field(default_factory=dict)
    cost: Cost = 0.0
    kinematic_tree: TreeModel | None = None
    note: str = ""
    behavior: BehaviorModel | None = None
    reaches: str = ""
    retrieved: str = ""


class PlanFile(StrictModel):
    """A plan file (``platform plan --json``; read back with :func:`load_plan`): the start
    whole, every action's target as changes to the one before, and the goal as changes to
    the start (so a lost or repeated action shows as a chain that misses the goal)."""

    schema_version: Annotated[Literal[2], BeforeValidator(not_boolean)] = Field(
        description="File format version.")
    robot: str = Field(min_length=1)
    planner: str
    start: ConfigurationFile
    actions: list[ActionModel] = Field(max_length=MAX_ACTIONS)
    goal: DeltaModel = Field(default_factory=DeltaModel, description="The goal as its "
                             "changes to the start.")
    mapping: dict[str, str] = {}
    notes: list[str] = []
    stats: dict[str, Number] = {}


class ActionModelV1(ActionModel):
    """An action of a version 1 plan file: its target and tree whole."""

    target: ConfigurationFile  # type: ignore[assignment]
    kinematic_tree: KinematicTreeFile | None = None  # type: ignore[assignment]


class PlanFileV1(StrictModel):
    """A version 1 plan file: every configuration whole (read, no longer written)."""

    schema_version: Annotated[int, Strict()] = Field(1, ge=1, le=1)
    robot: str = Field(min_length=1)
    planner: str
    start: ConfigurationFile
    goal: ConfigurationFile
    actions: list[ActionModelV1] = Field(max_length=MAX_ACTIONS)
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
        direction=None if call.direction is None else list(call.direction),
        drive_root=call.drive_root)


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
            (model.direction[0], model.direction[1], model.direction[2]),
            drive_root=model.drive_root)
    except ConfigurationError as exc:
        raise ConfigurationError(exc.message, source=source,
                                 field=f"{field}.{exc.field}" if exc.field else field) from None


def _vector(v: np.ndarray | None) -> list[float] | None:
    return None if v is None else v.tolist()


def delta_to_model(delta: ConfigurationDelta) -> DeltaModel:
    """The file model of ``delta`` (exact floats: a round trip is lossless)."""
    return DeltaModel(
        name=delta.name, description=delta.description,
        removed_connections=list(delta.removed_edges),
        removed_modules=list(delta.removed_vertices),
        modules=[ModuleDeltaModel(id=v.id, kind=v.kind, position=_vector(v.position), at=at)
                 for v, at in delta.vertices],
        connections=[ConnectionDeltaModel(id=e.id, source=e.source, target=e.target,
                                          kind=e.kind, z=_vector(e.z), x=_vector(e.x),
                                          ports=e.ports, at=at) for e, at in delta.edges])


def _read_only(values: list[float] | None, check: bool) -> np.ndarray | None:
    if values is None:
        return None
    if check:
        return unit(values)
    array = np.array(values, dtype=np.float64)
    array.flags.writeable = False
    return array


def delta_from_model(model: DeltaModel) -> ConfigurationDelta:
    """The :class:`ConfigurationDelta` of a file model (vectors checked unit by the model)."""
    return ConfigurationDelta(
        removed_vertices=tuple(model.removed_modules),
        vertices=tuple((Vertex(m.id, m.kind, _read_only(m.position, False)), m.at)
                       for m in model.modules),
        removed_edges=tuple(model.removed_connections),
        edges=tuple((Edge(c.id, c.source, c.target, c.kind, _read_only(c.z, True),
                          _read_only(c.x, True), None if c.ports is None else tuple(c.ports)),
                     c.at) for c in model.connections),
        name=model.name, description=model.description)


def _skeleton(config: Configuration) -> Configuration:
    """``config`` without vectors: the base a kinematic tree's topology is stored against."""
    return config.derive(z={}, x={})


def _tree_model(tree: KinematicTree | None, target: Configuration) -> TreeModel | None:
    if tree is None:
        return None
    delta = replace(difference(_skeleton(target), tree.configuration), description=None)
    return TreeModel(topology=delta_to_model(delta),
                     nodes=[NodeModel.model_validate(node.to_dict()) for node in tree.nodes])


def plan_to_model(plan: Plan) -> PlanFile:
    """The file model of ``plan``: the start whole, every action's target as its
    :func:`~msrr.core.delta.difference` from the one before, the goal as its difference
    from the start (independent of the actions, so the chain is checked against it)."""
    actions, before = [], plan.start
    for a in plan.actions:
        actions.append(ActionModel(
            type=a.type, target=delta_to_model(difference(before, a.target)),
            modules=list(a.modules), changes=[ChangeModel(**c.__dict__) for c in a.changes],
            goals=a.goals, cost=a.cost, kinematic_tree=_tree_model(a.kinematic_tree, a.target),
            note=a.note, behavior=_behavior_model(a.behavior), reaches=a.reaches,
            retrieved=a.retrieved))
        before = a.target
    return PlanFile(schema_version=SCHEMA_VERSION, robot=plan.robot, planner=plan.planner,
                    start=configuration_to_model(plan.start), actions=actions,
                    goal=delta_to_model(difference(plan.start, plan.goal)), mapping=plan.mapping,
                    notes=plan.notes, stats=plan.stats)


def _at(exc: ConfigurationError, source: str | None, field: str) -> ConfigurationError:
    """``exc`` naming ``source`` and its field under ``field``."""
    return ConfigurationError(exc.message, source=source,
                              field=f"{field}.{exc.field}" if exc.field else field)


def _configuration(model: ConfigurationFile, robot: str, source: str | None, field: str
                   ) -> Configuration:
    try:
        config = configuration_from_model(model)
    except ConfigurationError as exc:
        raise _at(exc, source, field) from None
    if config.robot != robot:
        raise ConfigurationError(f"a configuration of robot {config.robot!r} in a plan for "
                                 f"{robot!r}", source=source, field=f"{field}.robot")
    return config


def _check_action(action: Action, i: int, source: str | None, has: Callable[[str], bool]
                  ) -> None:
    """The ids an action names exist in its target (``has``: vertices, or edges that are
    modules)."""
    for j, module in enumerate(action.modules):
        if not has(module):
            raise ConfigurationError(f"module {module!r} is not in the action's target",
                                     source=source, field=f"actions[{i}].modules[{j}]")
    for module in action.goals:
        if not has(module):
            raise ConfigurationError(f"module {module!r} is not in the action's target",
                                     source=source, field=f"actions[{i}].goals")
    for j, change in enumerate(action.changes):
        for end in (change.source, change.target):
            if not has(end):
                raise ConfigurationError(f"module {end!r} is not in the action's target",
                                         source=source, field=f"actions[{i}].changes[{j}]")
    for j, command in enumerate(action.behavior.commands if action.behavior else ()):
        if not has(command.module):
            raise ConfigurationError(f"module {command.module!r} is not in the action's "
                                     "target", source=source,
                                     field=f"actions[{i}].behavior.commands[{j}]")
    root = action.behavior.drive_root if action.behavior else None
    if root is not None and root not in action.target.vertices(virtual=False):
        raise ConfigurationError(f"no node {root!r} in the action's target", source=source,
                                 field=f"actions[{i}].behavior.drive_root")


def _tree(document: dict[str, Any] | None, robot: str, modes: Mapping[str, type],
          source: str | None, field: str) -> KinematicTree | None:
    if document is None:
        return None
    try:
        tree = KinematicTree.from_dict(document, modes=modes, source=source)
    except ConfigurationError as exc:
        raise _at(exc, source, field) from None
    if tree.configuration.robot != robot:
        raise ConfigurationError(f"a tree of robot {tree.configuration.robot!r} in a plan for "
                                 f"{robot!r}", source=source, field=f"{field}.robot")
    return tree


def _tree_document(model: TreeModel | None, target: Configuration, source: str | None,
                   field: str) -> dict[str, Any] | None:
    """The kinematic tree document (:mod:`~msrr.core.kinematics.tree_file`) of a
    version 2 tree: its topology applied to the target's skeleton."""
    if model is None:
        return None
    draft = Draft(_skeleton(target))
    try:
        draft.apply(delta_from_model(model.topology))
    except ConfigurationError as exc:
        raise _at(exc, source, f"{field}.topology") from None
    topology = configuration_to_model(draft.build()).model_dump(mode="json", exclude_none=True)
    return {"schema_version": TREE_SCHEMA_VERSION, "robot": target.robot,
            "configuration": draft.name, "modules": topology["modules"],
            "connections": topology["connections"],
            "nodes": [n.model_dump(mode="json") for n in model.nodes]}


def _action(a: ActionModel, target: Configuration, tree: KinematicTree | None,
            source: str | None, where: str) -> Action:
    action = Action(type=a.type, target=target, modules=tuple(a.modules),
                    changes=tuple(ConnectionChange(c.source, c.target, c.source_port,
                                                   c.target_port, c.edge_id) for c in a.changes),
                    goals=a.goals, cost=a.cost, kinematic_tree=tree, note=a.note,
                    behavior=_behavior_call(a.behavior, source, f"{where}.behavior"),
                    reaches=a.reaches, retrieved=a.retrieved)
    if action.type is ActionType.BEHAVIOR and action.behavior is None:
        raise ConfigurationError("a behavior action names no behavior", source=source,
                                 field=f"{where}.behavior")
    return action


def _check_mapping(plan: Plan, source: str | None) -> Plan:
    for module in plan.mapping:
        if module not in plan.start:
            raise ConfigurationError(f"module {module!r} is not in the start",
                                     source=source, field="mapping")
    return plan


def plan_from_model(model: PlanFile | PlanFileV1, source: str | None = None,
                    modes: Mapping[str, type] | None = None) -> Plan:
    """A :class:`Plan` from its file model (either version); every configuration names
    the plan's robot, every change applies to the configuration before it, every id an
    action names is in its target; errors name ``source`` and the field.

    A version 2 file's targets are :class:`~msrr.core.delta.DerivedConfiguration` s, each
    built the first time it is read.

    Args:
        model: the parsed file.
        source: file name for error messages.
        modes: the robot's joint modes (``Robot.joint_modes``), to read the actions'
            kinematic trees back as :class:`~msrr.core.kinematics.KinematicTree` s.
    """
    if isinstance(model, PlanFileV1):
        return _plan_from_v1(model, source, modes or {})
    start = _configuration(model.start, model.robot, source, "start")
    draft, before, actions = Draft(start), start, []
    for i, a in enumerate(model.actions):
        where = f"actions[{i}]"
        target = _derived(before, a.target, draft, source, f"{where}.target")
        tree = _tree(_tree_document(a.kinematic_tree, target, source, f"{where}.kinematic_tree"),
                     model.robot, modes or {}, source, f"{where}.kinematic_tree")
        action = _action(a, target, tree, source, where)
        _check_action(action, i, source, lambda m: m in draft.vertices or m in draft.edges)
        actions.append(action)
        before = target
    goal = _derived(start, model.goal, Draft(start), source, "goal")
    return _check_mapping(Plan(robot=model.robot, planner=model.planner, start=start, goal=goal,
                               actions=actions, mapping=model.mapping, notes=model.notes,
                               stats=model.stats), source)


def _derived(before: Configuration, model: DeltaModel, draft: Draft, source: str | None,
             field: str) -> Configuration:
    """``before`` changed by ``model``, checked on ``draft`` (which it changes too)."""
    delta = delta_from_model(model)
    try:
        draft.apply(delta)
    except ConfigurationError as exc:
        raise _at(exc, source, field) from None
    return DerivedConfiguration(before, delta) if delta else before


def _plan_from_v1(model: PlanFileV1, source: str | None, modes: Mapping[str, type]) -> Plan:
    actions = []
    for i, a in enumerate(model.actions):
        where = f"actions[{i}]"
        target = _configuration(a.target, model.robot, source, f"{where}.target")
        document = None if a.kinematic_tree is None else \
            a.kinematic_tree.model_dump(mode="json", exclude_none=True)
        tree = _tree(document, model.robot, modes, source, f"{where}.kinematic_tree")
        action = _action(a, target, tree, source, where)
        names = set(target.vertices()) | set(target.edge_ids())
        _check_action(action, i, source, names.__contains__)
        actions.append(action)
    start = _configuration(model.start, model.robot, source, "start")
    goal = _configuration(model.goal, model.robot, source, "goal")
    return _check_mapping(Plan(robot=model.robot, planner=model.planner, start=start, goal=goal,
                               actions=actions, mapping=model.mapping, notes=model.notes,
                               stats=model.stats), source)


# -- validation ---------------------------------------------------------------------------


class _Window:
    """The part of a :class:`~msrr.core.delta.Draft` one step touched, read the way
    :func:`~msrr.core.robot.check_structure`, :func:`links` and :func:`_port_pairs` read a
    configuration (kinds and degrees from the whole draft), so a step is checked in
    O(its changes): the rest was checked before and did not change."""

    def __init__(self, draft: Draft, vertices: Iterable[str], edges: Iterable[str]):
        self.robot = draft.robot
        self._draft = draft
        self._vertices = [v for v in dict.fromkeys(vertices) if v in draft.vertices]
        self._edges = [draft.edges[e] for e in dict.fromkeys(edges) if e in draft.edges]

    def vertices(self) -> list[str]:
        return self._vertices

    def edges(self) -> list[Edge]:
        return self._edges

    def kind_of(self, vertex: str) -> str:
        return self._draft.vertices[vertex].kind

    def is_virtual(self, vertex: str) -> bool:
        return self._draft.vertices[vertex].kind == VIRTUAL

    def degree(self, vertex: str) -> int:
        return len(self._draft.incident[vertex])

    def modules(self) -> dict[str, str]:
        found = {v: self.kind_of(v) for v in self._vertices if not self.is_virtual(v)}
        found.update({e.id: e.kind for e in self._edges if e.kind is not None})
        return found


@dataclass
class _Step:
    """One step of a plan walked by :func:`_walk`: what it touched before and after."""

    where: str
    said: str
    delta: ConfigurationDelta
    before: dict[str, str]
    after: _Window
    made: set[ConnectionKey]
    broken: set[ConnectionKey]


def _touched(draft: Draft, delta: ConfigurationDelta) -> tuple[set[str], set[str]]:
    """The vertices and edges whose checks ``delta`` can change on ``draft``: those it
    writes or removes, the ends of the edges it writes or removes (degrees), and the
    edges of a vertex whose kind changes (ports, links)."""
    vertices = set(delta.removed_vertices) | {v.id for v, _ in delta.vertices}
    edges = set(delta.removed_edges) | {e.id for e, _ in delta.edges}
    for edge_id in edges:
        old = draft.edges.get(edge_id)
        if old is not None:
            vertices.update((old.source, old.target))
    vertices.update(end for e, _ in delta.edges for end in (e.source, e.target))
    for v, _ in delta.vertices:
        old = draft.vertices.get(v.id)
        if old is not None and old.kind != v.kind:
            edges.update(draft.incident[v.id])
    return vertices, edges


def _walk(plan: Plan) -> Iterator[_Step]:
    """Every step of ``plan`` (each action, then the goal) with the links it makes and
    breaks and the modules it touches, from one draft changed by each step's
    :func:`~msrr.core.delta.difference` (O(changes) for derived targets)."""
    draft, before, said = Draft(plan.start), plan.start, "the start"
    steps = [(f"actions[{i}]", a.target, f"actions[{i}].target")
             for i, a in enumerate(plan.actions)]
    for where, config, name in [*steps, ("goal", plan.goal, "goal")]:
        delta = difference(before, config)
        if not delta.size:  # nothing to apply: no link, module or rule can change
            draft.apply(delta)
            yield _Step(where, said, delta, {}, _Window(draft, (), ()), set(), set())
            before, said = config, name
            continue
        vertices, edges = _touched(draft, delta)
        old = _Window(draft, vertices, edges)
        have, modules = Counter(key for key, _ in links(old)), old.modules()
        draft.apply(delta)
        after = _Window(draft, vertices, edges)
        want = Counter(key for key, _ in links(after))
        yield _Step(where, said, delta, modules, after, set(want - have), set(have - want))
        before, said = config, name


def check_plan(plan: Plan, robot: Robot) -> None:
    """Validate ``plan`` whole against ``robot``: its start and goal follow every rule of
    the robot; every action target has only the robot's module kinds, ports and legal
    port pairs (an intermediate configuration may break a topology rule on purpose,
    e.g. while split); and the actions follow one another from the start to the goal
    (:func:`check_chain`).

    A target is checked where it differs from the one before (the start is checked
    whole), so a plan of k actions over n modules costs O(n + its changes).

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
    check_chain(plan, robot)


def check_chain(plan: Plan, robot: Robot | None = None) -> None:
    """Validate that ``plan``'s actions follow one another: each action's target has the
    modules of the step before (the start for the first), its type and ``changes`` are
    the links that step makes and breaks, its ``modules`` name every module its changes
    and goals name, no action repeats the one before it, and the last target is the
    plan's goal (its modules and links). With ``robot``, every action target has only
    its module kinds, ports and legal port pairs too.

    Raises:
        ConfigurationError: naming the field (``actions[3].changes``, ``goal``...).
    """
    unchecked = _port_pairs(plan.start, robot) if robot is not None else []
    for i, step in enumerate(_walk(plan)):
        if step.where == "goal":
            _same_modules(step.before, step.after.modules(), step.said, "goal")
            if step.made or step.broken:
                raise ConfigurationError(
                    f"is not where the actions end: {step.said} lacks {_names(step.made)} "
                    f"and has {_names(step.broken)} besides", field="goal")
            break
        if robot is not None and (unchecked or step.delta.size):
            found = (unchecked + check_structure(step.after, robot.spec)  # type: ignore[arg-type]
                     + _port_pairs(step.after, robot))  # type: ignore[arg-type]
            if found:
                raise ConfigurationError(f"{found[0].where}: {found[0].message}",
                                         field=f"{step.where}.target")
            unchecked = []
        _check_step(plan, i, step)


def _check_step(plan: Plan, i: int, step: _Step) -> None:
    """The checks of :func:`check_chain` on one action."""
    action, where, said = plan.actions[i], step.where, step.said
    _same_modules(step.before, step.after.modules(), said, f"{where}.target")
    made, broken = step.made, step.broken
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
    if i and _repeats(action, plan.actions[i - 1], step.delta):
        raise ConfigurationError("repeats the action before it", field=where)


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


def _same_modules(have: Mapping[str, str], want: Mapping[str, str], said: str, field: str
                  ) -> None:
    """Refuse a step whose modules (id -> kind, of the ids it touched) differ from those
    of the step before."""
    if have != want:
        extra = sorted(set(want) - set(have), key=natural_key)
        gone = sorted(set(have) - set(want), key=natural_key)
        kinds = sorted((m for m in set(have) & set(want) if have[m] != want[m]), key=natural_key)
        parts = [f"{what} {', '.join(ids)}" for what, ids in (
            ("modules not in " + said + ":", extra), ("lacks", gone),
            ("other module kinds of", kinds)) if ids]
        raise ConfigurationError(f"has other modules than {said} ({'; '.join(parts)})",
                                 field=field)


def _repeats(action: Action, before: Action, delta: ConfigurationDelta) -> bool:
    """Whether ``action`` is ``before`` again (a copied step: nothing left to do);
    ``delta`` takes ``before``'s target to ``action``'s."""
    if (action.type, action.modules, action.changes, action.goals, action.behavior,
            action.reaches) != (before.type, before.modules, before.changes, before.goals,
                                before.behavior, before.reaches):
        return False
    return not delta or \
        configuration_to_model(action.target) == configuration_to_model(before.target)


def _dumps(data: dict[str, Any]) -> str:
    """A plan file's text: compact JSON, one line per top-level field and per action."""
    def compact(value: Any) -> str:
        return json.dumps(value, separators=(",", ":"))

    fields = []
    for key, value in data.items():
        text = compact(value)
        if key == "actions" and value:
            text = "[\n" + ",\n".join(compact(a) for a in value) + "\n]"
        fields.append(f"{compact(key)}:{text}")
    return "{\n" + ",\n".join(fields) + "\n}\n"


def save_plan(plan: Plan, path: str | os.PathLike[str]) -> None:
    """Write ``plan`` as JSON (:class:`PlanFile`, version :data:`SCHEMA_VERSION`),
    atomically."""
    data = plan_to_model(plan).model_dump(mode="json", exclude_none=True, exclude_defaults=True)
    data = {"schema_version": SCHEMA_VERSION, **data}
    atomic_write_text(path, _dumps(data))


def parse_plan_file(data: Any, source: str | None = None) -> PlanFile | PlanFileV1:
    """The file model of a parsed plan file, by its ``schema_version`` (1 when absent).

    Raises:
        ConfigurationError: an unknown version or a bad field, naming ``source`` and it.
    """
    version = data.get("schema_version", 1) if isinstance(data, dict) else SCHEMA_VERSION
    if version == 1 and not isinstance(version, bool):
        return parse_model(PlanFileV1, data, source)
    if version != SCHEMA_VERSION or isinstance(version, bool):
        raise ConfigurationError(f"unknown plan file version {version!r}: this platform "
                                 f"reads versions 1 and {SCHEMA_VERSION}", source=source,
                                 field="schema_version")
    return parse_model(PlanFile, data, source)


def load_plan(path: str | os.PathLike[str],
              robot: Robot | Callable[[str], Robot] | None = None) -> Plan:
    """Read a plan file (version 1 or 2) and, when ``robot`` is given, validate it
    (:func:`check_plan`).

    ``robot`` may be a function giving the robot of the name the file holds, as
    :func:`msrr.core.plugins.load_plan` passes.

    Raises:
        ConfigurationError: a bad file, field or id, or a broken rule of ``robot``;
            naming the file and the field.
    """
    model = parse_plan_file(read_json(path), str(path))
    if robot is not None and not isinstance(robot, Robot):
        robot = robot(model.robot)
    plan = plan_from_model(model, str(path), None if robot is None else robot.joint_modes)
    if robot is not None:
        try:
            check_plan(plan, robot)
        except ConfigurationError as exc:
            raise exc.at(str(path)) from None
    return plan
