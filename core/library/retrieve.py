"""Behavior retrieval (FreeSN paper, section 6.3, Fig. 15).

Given the system configuration and a target (a library configuration or a behavior),
the system is matched into its sub-library with the configuration matcher (Alg. 4,
Fig. 15(a)), the cheapest action path by motion cost is found in the action graph
(Dijkstra), and every configuration and kinematic tree of the path is mapped into the
system's own ids by composing the match mapping with the edges' module mappings
(Fig. 15(b), (c)). The result is ready for the executor (section 4, Fig. 15(d)).

**One frame.** Every library configuration is stored in its own root horizontal frame,
so two consecutive configurations of a path may differ by an arbitrary yaw (S6N3's
rigid triangle turns by 120 degrees between steps when the root node changes). The
retrieved targets are therefore expressed one after the other in the frame of the
previous one: each is turned by the yaw that best aligns it with its predecessor on the
connections both have (eq. 8, :func:`msrr.core.alignment.align_yaw`), starting from the
match yaw that aligns the first with the system. A docking strut then aims where it
will dock, and the executor's goals never jump by a frame change.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise

import networkx as nx
import numpy as np

from ..actions import detect_action
from ..alignment import align_yaw, angles_between, rot_z
from ..configuration import Configuration
from ..kinematics import KinematicTree
from ..mapping import ModuleMap
from ..matching import COST_IK
from ..plan import Action, ActionType
from ..robot import Robot
from . import engine
from .model import (
    ActionEdge,
    Behavior,
    CommandGain,
    Library,
    LibraryError,
    RetrievalError,
    SubLibrary,
    TreeRef,
)

__all__ = ["INLIER", "Retrieval", "RetrievedStep", "align_to", "frame_turn", "locate",
           "retrieve", "shortest_path"]


@dataclass(frozen=True)
class RetrievedStep:
    """One step of a retrieved sequence, in the system's ids.

    Attributes:
        library_id: the library configuration this step reaches.
        target: that configuration in the system's ids and frame (turned by :attr:`yaw`).
        tree: the kinematic tree that executes the step, in the system's ids.
        tree_ref: which library tree it is.
        action: the action type (section 4.1).
        cost: motion cost of the step (the match cost for the first, approach step).
        yaw: the turn [rad] from the library configuration's own frame to the frame of
            ``target`` (the system's, shared by every step of a retrieval).
    """

    library_id: str
    target: Configuration
    tree: KinematicTree
    tree_ref: TreeRef
    action: ActionType
    cost: float
    yaw: float = 0.0


@dataclass
class Retrieval:
    """A retrieved sequence (Fig. 15(b)-(c)).

    Attributes:
        sublibrary: the sub-library searched.
        start: the library configuration the system matched.
        match_cost: inverse-kinematics cost from the system to ``start``.
        mapping: system ids -> ids of ``start``'s group.
        steps: the approach step to ``start``, then one step per action edge.
        behavior: the behavior asked for, if any.
        behavior_steps: a sequence behavior's steps after the target, in system ids
            (for a looping behavior, ending back at its start).
        commands: a mapping behavior's commands, in system ids.
        target_mapping: ids of the target configuration's group -> system ids.
        drive_root: the behavior's drive root (:attr:`Behavior.drive_root`) in system ids.
    """

    sublibrary: str
    start: str
    match_cost: float
    mapping: ModuleMap
    steps: list[RetrievedStep]
    behavior: Behavior | None = None
    behavior_steps: list[RetrievedStep] = field(default_factory=list)
    commands: tuple[CommandGain, ...] = ()
    target_mapping: ModuleMap | None = None
    drive_root: str | None = None

    @property
    def cost(self) -> float:
        """Total motion cost of :attr:`steps`."""
        return float(sum(s.cost for s in self.steps))

    def actions(self, system: Configuration) -> list[Action]:
        """The steps (then the behavior's steps) as executor actions starting at ``system``;
        each says where it comes from in :attr:`~msrr.core.plan.Action.retrieved`."""
        out, before = [], system
        for step in [*self.steps, *self.behavior_steps]:
            out.append(_action(before, step, self.sublibrary))
            before = step.target
        return out

    def mapping_text(self, system: Configuration) -> str:
        """``"N1->n3, N2->n1, ..."``: the system's modules -> the matched configuration's."""
        return ", ".join(f"{k}->{v}" for k, v in sorted(self.mapping.nodes.items())
                         if not system.is_virtual(k))


def _action(before: Configuration, step: RetrievedStep, sublibrary: str) -> Action:
    action = detect_action(before, step.target, note=f"library {step.library_id}")
    action.cost, action.kinematic_tree = step.cost, step.tree
    action.retrieved = f"{sublibrary} {step.library_id} (tree {step.tree_ref})"
    return action


INLIER = np.radians(10.0)
"""A connection counts as unmoved between two steps when, after the frame turn, its ``z``
is within this angle of the previous one [rad]."""


def frame_turn(config: Configuration, previous: Configuration) -> float:
    """The yaw [rad] that takes ``config``'s frame onto ``previous``'s: the turn that
    brings the most connections (both have) within :data:`INLIER` of their previous
    direction, refined by eq. 8 on those (:func:`~msrr.core.alignment.align_yaw`).

    A step moves some connections and keeps the rest (a strut swings 150 degrees to dock,
    the triangle holds), so a least-squares yaw over all of them would turn the
    unmoved part by a compromise; the consensus over candidate turns (one per
    connection with a horizontal component) ignores the moved ones. 0 when they share
    no vector.
    """
    both = {e.id for e in previous.edges() if e.z is not None}
    ids = [e.id for e in config.edges() if e.id in both and e.z is not None]
    if not ids:
        return 0.0
    old, new = previous.vectors(ids), config.vectors(ids)
    candidates = [0.0]
    for j in range(len(ids)):
        if np.hypot(*old[:2, j]) > 0.2 and np.hypot(*new[:2, j]) > 0.2:
            candidates.append(float(np.arctan2(old[1, j], old[0, j])
                                    - np.arctan2(new[1, j], new[0, j])))
    best, best_key = 0.0, None
    for yaw in candidates:
        angles = angles_between(old, rot_z(yaw) @ new)
        inliers = angles < INLIER
        key = (-int(inliers.sum()), float(np.sum(angles[inliers] ** 2)))
        if best_key is None or key < best_key:
            best, best_key = yaw, key
    inliers = angles_between(old, rot_z(best) @ new) < INLIER
    if inliers.any():
        best = align_yaw(old[:, inliers], new[:, inliers]).theta
    return float(np.arctan2(np.sin(best), np.cos(best)))


def align_to(config: Configuration, previous: Configuration) -> tuple[Configuration, float]:
    """``config`` in ``previous``'s frame (turned by :func:`frame_turn`), and the turn."""
    yaw = frame_turn(config, previous)
    if yaw == 0.0:
        return config, 0.0
    turn = rot_z(yaw)
    z = {e.id: turn @ e.z for e in config.edges() if e.z is not None}
    x = {e.id: turn @ e.x for e in config.edges() if e.x is not None}
    return config.with_vectors(z=z, x=x or None), float(yaw)


def shortest_path(sub: SubLibrary, start: str, target: str) -> list[str]:
    """Configuration ids of the cheapest action path from ``start`` to ``target``.

    Raises:
        RetrievalError: ``target`` is unreachable; names the groups that are reachable
            and the edges leaving them that a simulation found infeasible.
    """
    graph = sub.graph()
    try:
        return nx.dijkstra_path(graph, start, target, weight="cost")
    except nx.NetworkXNoPath:
        reachable = nx.descendants(graph, start) | {start}
        groups = sorted({graph.nodes[n]["group"] for n in reachable})
        names = ", ".join(f"{g} ({sub.groups[g].name})" for g in groups)
        blocked = [f"{e.source}->{e.target} ({e.action.value})" for e in sub.edges
                   if e.feasible is False and e.source in reachable
                   and e.target not in reachable]
        raise RetrievalError(
            f"{target} (group {sub.configurations[target].group}) cannot be reached from "
            f"{start} in sub-library {sub.name}; reachable groups: {names}"
            + (f"; left out as infeasible by the library's check: {', '.join(blocked)}"
               if blocked else "")) from None


class _Mapper:
    """Expresses library configurations and trees in the system's ids, step by step."""

    def __init__(self, sub: SubLibrary, yaw: float, modes: engine.Modes):
        self.sub, self.modes = sub, modes
        self.yaw = yaw
        self.rotation = rot_z(yaw)

    def express(self, config_id: str, to_system: ModuleMap) -> tuple[Configuration, ModuleMap]:
        config = self.sub.configurations[config_id].configuration
        return to_system.apply(config.skeletal(), rotation=self.rotation,
                               name=self.sub.configurations[config_id].name or config_id)

    def tree(self, ref: TreeRef, config: Configuration, to_system: ModuleMap) -> KinematicTree:
        return engine.tree_in_ids(self.sub.groups[ref.group].trees[ref.name], to_system, config,
                                  self.modes)

    def follow(self, path: list[str], to_system: ModuleMap, config: Configuration
               ) -> tuple[list[RetrievedStep], ModuleMap]:
        """Steps along ``path`` (ids) from its first configuration (``config`` in system
        ids, ``to_system`` its ids -> system ids), and the last one's map to system ids."""
        graph = self.sub.graph()
        steps = []
        for u, v in pairwise(path):
            if not graph.has_edge(u, v):
                raise LibraryError(f"no action edge {u} -> {v} in sub-library {self.sub.name}")
            edge: ActionEdge = graph[u][v]["edge"]
            before = self.sub.configurations[u].configuration
            forward = edge.module_map(before)
            next_map = forward.inverse().then(to_system)
            target, used = self.express(v, next_map)
            target, turn = align_to(target, config)   # into the previous step's frame
            yaw = self.yaw + turn
            if edge.tree.group == self.sub.configurations[u].group:
                tree = self.tree(edge.tree, config, to_system)
            else:
                tree = self.tree(edge.tree, target, used)
            steps.append(RetrievedStep(v, target, tree, edge.tree, edge.action, edge.cost,
                                       float(np.arctan2(np.sin(yaw), np.cos(yaw)))))
            to_system, config = used, target
        return steps, to_system


def _commands(behavior: Behavior, to_system: ModuleMap) -> tuple[CommandGain, ...]:
    out = []
    for command in behavior.commands:
        module, connector = to_system.image(command.module, command.connector)
        out.append(CommandGain(module, command.command, command.gains, connector))
    return tuple(out)


def library_cost(library: Library) -> str:
    """The motion cost a library was built with (``build.cost``; IK when not recorded)."""
    return engine.cost_kind(str(library.build.get("cost", COST_IK)))


def locate(library: Library, configuration: Configuration, robot: Robot
           ) -> engine.MatchOutcome:
    """The library configuration ``configuration`` matches best (Alg. 4, Fig. 15(a)),
    with the mapping of its ids and the yaw that aligns the two.

    Raises:
        LibraryError: no sub-library of its module counts.
        RetrievalError: it is isomorphic to no group of its sub-library.
    """
    label = configuration.signature().label(robot.spec)
    sub = library.sublibrary(label)
    signature = configuration.signature()
    candidates = [(c.id, c.configuration, next(iter(sub.groups[c.group].trees.values())))
                  for c in sub.configurations.values()
                  if sub.groups[c.group].reference.signature() == signature]
    outcome = (engine.best_match(configuration, candidates, library_cost(library),
                                 robot.joint_modes) if candidates else None)
    if outcome is None:
        groups = ", ".join(f"{g.id} ({g.name})" for g in sub.groups.values())
        raise RetrievalError(f"{configuration.name or 'the configuration'} is not isomorphic "
                             f"to any group of sub-library {label} (groups: {groups})")
    return outcome


def retrieve(library: Library, system: Configuration, robot: Robot, *, to: str | None = None,
             behavior: str | None = None) -> Retrieval:
    """The cheapest action sequence from ``system`` to a target, in the system's ids.

    Args:
        library: the behavior library.
        system: the current system configuration, in its own ids.
        robot: the library's robot (module kinds name the sub-library; joint modes load
            the kinematic trees).
        to: a library configuration id or name.
        behavior: a behavior name; the path leads to its start configuration.

    Raises:
        LibraryError: neither or both targets, an unknown target or sub-library.
        RetrievalError: the system matches no configuration of its sub-library, or the
            target cannot be reached (the message names the reachable groups).
    """
    if (to is None) == (behavior is None):
        raise LibraryError("give exactly one target: a configuration or a behavior")
    if system.robot != library.robot:
        raise LibraryError(f"the system is a {system.robot} configuration, library "
                           f"{library.name} is for {library.robot}")
    if robot.name != library.robot:
        raise LibraryError(f"library {library.name} is for {library.robot}, not {robot.name}")
    label = system.signature().label(robot.spec)
    sub = library.sublibrary(label)
    chosen: Behavior | None = None
    if behavior is not None:
        if behavior not in sub.behaviors:
            raise LibraryError(f"no behavior {behavior!r} in sub-library {label} (known: "
                               f"{', '.join(sub.behaviors) or 'none'})")
        chosen = sub.behaviors[behavior]
        target = chosen.start
    else:
        assert to is not None
        target = sub.configuration(to).id
    outcome = locate(library, system, robot)
    path = shortest_path(sub, outcome.key, target)
    mapper = _Mapper(sub, outcome.yaw, robot.joint_modes)
    start_config, to_system = mapper.express(outcome.key, outcome.mapping.inverse())
    group = sub.groups[sub.configurations[outcome.key].group]
    first_tree = TreeRef(group.id, next(iter(group.trees)))
    steps = [RetrievedStep(outcome.key, start_config, mapper.tree(first_tree, start_config,
                                                                   to_system),
                           first_tree, ActionType.MOVING, outcome.cost, outcome.yaw)]
    path_steps, final_map = mapper.follow(path, to_system, start_config)
    steps += path_steps
    retrieval = Retrieval(sub.name, outcome.key, outcome.cost, outcome.mapping, steps, chosen,
                          target_mapping=final_map)
    if chosen is not None:
        if chosen.kind == "sequence":
            loop = [chosen.start, *chosen.steps] + ([chosen.start] if chosen.loop else [])
            retrieval.behavior_steps, _ = mapper.follow(loop, final_map, steps[-1].target)
        else:
            retrieval.commands = _commands(chosen, final_map)
        if chosen.drive_root is not None:
            retrieval.drive_root = final_map.nodes[chosen.drive_root]
    return retrieval

