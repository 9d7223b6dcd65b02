"""Automatic library creation (FreeSN paper, section 6.2, Fig. 14).

Inputs are designed groups (reference topology, kinematic trees, Fig. 14(a)) and
recorded configuration sequences with intermediate configurations at topology
changes (Fig. 14(b), (c)). Every sequence configuration is matched against the
library configurations of its sub-library with the configuration matcher (Alg. 4),
remapped into the ids of the matched group's reference topology (Fig. 14(d)) and
merged into the matched configuration when the inverse-kinematics cost between them
is at most the merge threshold (Fig. 14(e)); otherwise it becomes a new
configuration of that group. Consecutive configurations become feasible-action
edges with their kinematic tree, motion cost, action type and module mapping
(Fig. 14(f)); labelled sequences and parameter mappings become behaviors.

Everything is processed in source order with deterministic matching and inverse
kinematics, so building twice from the same sources gives the same library.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass

import networkx as nx

from ..actions import classify, topology_diff
from ..configuration import Configuration
from ..errors import ConfigurationError
from ..mapping import ModuleMap
from ..matching import COST_DISTANCE, tied
from ..plan import ActionType
from ..robot import Robot
from . import engine
from .model import (
    ActionEdge,
    Behavior,
    CommandGain,
    Group,
    Library,
    LibraryConfiguration,
    LibraryError,
    SubLibrary,
    TreeRef,
    default_drive_root,
)
from .sources import DesignedGroup, LibrarySources, MappingBehaviorSource, RecordedSequence

__all__ = ["DEFAULT_MERGE_THRESHOLD", "Progress", "build_library", "build_steps",
           "vectors_on"]

DEFAULT_MERGE_THRESHOLD = 1e-5
"""Largest inverse-kinematics cost at which two configurations are merged (Fig. 14(e))."""

COST_DIGITS = 9

Progress = Callable[[str], None]
"""Called once per configuration placed, with a short description."""

CONNECTING = (ActionType.CONNECTION, ActionType.PARALLEL_CONNECTION)


@dataclass(frozen=True)
class _Placement:
    """Where a source configuration landed: library id and source ids -> group ids."""

    config_id: str
    mapping: ModuleMap


def build_steps(sources: LibrarySources) -> int:
    """Number of configurations a build places (the length of its progress bar)."""
    return (sum(1 + len(g.configurations) for g in sources.groups)
            + sum(len(s.steps) for s in sources.sequences))


def vectors_on(topology: Configuration, other: Configuration, mapping: ModuleMap
               ) -> Configuration:
    """``topology`` with the ``z`` of ``other`` on every edge ``mapping`` sends into it.

    Args:
        topology: the configuration whose topology and ids are kept.
        other: the configuration whose vectors are taken.
        mapping: ``topology`` ids -> ``other`` ids; unmapped edges keep their own ``z``.
    """
    z = {}
    for edge in topology.edges():
        image = mapping.edges.get(edge.id)
        if image is None or image[0] not in other.edge_ids():
            z[edge.id] = edge.z
            continue
        vector = other.edge(image[0]).z
        z[edge.id] = -vector if image[1] else vector
    return topology.with_vectors(z=z, x={})


def _isomorphic(a: Configuration, b: Configuration) -> bool:
    same_kind = nx.algorithms.isomorphism.categorical_node_match("kind", None)
    return nx.is_isomorphic(a.undirected(), b.undirected(), node_match=same_kind)


def _modules_only(mapping: ModuleMap, source: Configuration) -> ModuleMap:
    """``mapping`` without virtual vertices of ``source`` (they are re-derived per edge)."""
    return ModuleMap({v: w for v, w in mapping.nodes.items()
                      if v in source and not source.is_virtual(v)}, dict(mapping.edges))


class _Builder:
    """State of one build: the library so far and where each named configuration landed."""

    def __init__(self, sources: LibrarySources, robot: Robot, threshold: float, cost: str,
                 progress: Progress | None):
        if robot.name != sources.robot:
            raise LibraryError(f"the sources are for robot {sources.robot!r}, not {robot.name!r}")
        self.robot, self.spec, self.modes = robot, robot.spec, robot.joint_modes
        self.cost = engine.cost_kind(cost)
        self.threshold = threshold
        self.progress = progress or (lambda _: None)
        self.library = Library(sources.robot, sources.name, description=sources.description,
                               build={"merge_threshold": threshold, "cost": cost,
                                      "sources": [{"file": f, "sha256": h}
                                                  for f, h in sources.files]})
        self.named: dict[str, _Placement] = {}
        self.edge_keys: set[str] = set()

    # -- groups and configurations (Fig. 14(a), (d), (e)) ------------------------------

    def sublibrary(self, config: Configuration) -> SubLibrary:
        label = config.signature().label(self.spec)
        return self.library.sublibraries.setdefault(label, SubLibrary(label))

    def add_group(self, designed: DesignedGroup) -> None:
        where = f"{designed.origin}: group {designed.name!r}"
        sub = self.sublibrary(designed.reference)
        for group in sub.groups.values():
            if _isomorphic(group.reference, designed.reference):
                raise LibraryError(f"{where}: its topology is isomorphic to group {group.id} "
                                   f"({group.name}); one group per isomorphism class")
        gid = f"{sub.name}-{len(sub.groups) + 1}"
        reference = designed.reference.skeletal()
        trees = {}
        for tree in designed.trees:
            if tree.name in trees:
                raise LibraryError(f"{where}: duplicate tree name {tree.name!r}")
            trees[tree.name] = engine.design_tree(reference, tree, self.robot)
        sub.groups[gid] = Group(gid, designed.name, reference, trees, designed.description)
        cid = f"{gid}.1"
        sub.configurations[cid] = LibraryConfiguration(
            cid, gid, reference, (designed.reference.name,) if designed.reference.name else (),
            (f"{designed.origin}:{designed.name}",))
        self._name(designed.reference.name, _Placement(cid, ModuleMap.identity(reference)))
        self.progress(f"group {gid}")
        for j, config in enumerate(designed.configurations):
            placed = self.place(config, f"{designed.origin}:{designed.name}[{j}]")
            if sub.configurations[placed.config_id].group != gid:
                raise LibraryError(f"{where}: configurations[{j}] does not have the group's "
                                   "topology")

    def _name(self, name: str, placement: _Placement) -> None:
        if name:
            self.named.setdefault(name, placement)

    def place(self, config: Configuration, origin: str) -> _Placement:
        """Match, remap and merge-or-add one configuration (Fig. 14(d), (e))."""
        sub = self.sublibrary(config)
        signature = config.signature()
        candidates = [(c.id, c.configuration, next(iter(sub.groups[c.group].trees.values())))
                      for c in sub.configurations.values()
                      if sub.groups[c.group].reference.signature() == signature]
        outcome = engine.best_match(config, candidates, self.cost, self.modes) if candidates else None
        if outcome is None:
            raise LibraryError(f"{origin}: configuration {config.name!r} is not isomorphic to "
                               f"any designed group of {sub.name} (groups: "
                               f"{', '.join(sub.groups) or 'none'}); design its group first")
        matched = sub.configurations[outcome.key]
        remapped, mapping = outcome.mapping.apply(config)
        if outcome.cost <= self.threshold or tied(outcome.cost, self.threshold):
            matched.names = tuple(dict.fromkeys([*matched.names, config.name] if config.name
                                                else matched.names))
            matched.origins = (*matched.origins, origin)
            placement = _Placement(matched.id, mapping)
        else:
            number = 1 + sum(1 for c in sub.configurations.values() if c.group == matched.group)
            cid = f"{matched.group}.{number}"
            reference = sub.groups[matched.group].reference
            skeletal = reference.with_vectors(z={e.id: e.z for e in remapped.edges()}, x={})
            skeletal.name = config.name or cid
            sub.configurations[cid] = LibraryConfiguration(
                cid, matched.group, skeletal, (config.name,) if config.name else (), (origin,))
            placement = _Placement(cid, mapping)
        self._name(config.name, placement)
        self.progress(f"{origin} -> {placement.config_id}")
        return placement

    # -- edges and behaviors (Fig. 14(f)) ----------------------------------------------

    def add_edge(self, sub: SubLibrary, a: _Placement, b: _Placement, tree_name: str | None,
                 origin: str) -> None:
        """The feasible action from placement ``a`` to ``b`` of one recorded sequence."""
        ca = sub.configurations[a.config_id].configuration
        cb = sub.configurations[b.config_id].configuration
        mapping = _modules_only(a.mapping.inverse().then(b.mapping), ca).completed(ca, cb)
        try:
            diff = topology_diff(ca, cb, mapping)
            action = classify(ca, cb, mapping)
        except ConfigurationError as exc:
            raise LibraryError(f"{origin}: {exc.message}") from None
        if diff.made and diff.broken and action is not ActionType.FLOW:
            raise LibraryError(f"{origin}: one step both breaks ({len(diff.broken)}) and makes "
                               f"({len(diff.made)}) connections; a library edge executes in one "
                               "topology, so record the intermediate configuration between them")
        same = sub.configurations[a.config_id].group == sub.configurations[b.config_id].group
        identity = same and mapping.is_identity()
        if action is ActionType.MOVING and a.config_id == b.config_id and identity:
            return
        in_source = action in CONNECTING
        group = sub.groups[sub.configurations[a.config_id if in_source else b.config_id].group]
        name = tree_name if tree_name in group.trees else next(iter(group.trees))
        tree = group.trees[name]
        if in_source:
            cost = engine.edge_cost(self.cost, tree, ca, vectors_on(ca, cb, mapping), self.modes)
        else:
            cost = engine.edge_cost(self.cost, tree, vectors_on(cb, ca, mapping.inverse()), cb,
                                    self.modes)
        edge = ActionEdge(a.config_id, b.config_id, action, TreeRef(group.id, name),
                          round(max(cost, 0.0), COST_DIGITS), None if identity else mapping)
        key = json.dumps([edge.source, edge.target, edge.action.value, str(edge.tree),
                          None if edge.mapping is None else edge.mapping.to_dict()])
        if key not in self.edge_keys:
            self.edge_keys.add(key)
            sub.edges.append(edge)

    def add_sequence(self, sequence: RecordedSequence) -> None:
        origin = f"{sequence.origin}:{sequence.name}"
        placements = [self.place(s.configuration, f"{origin}[{j}]")
                      for j, s in enumerate(sequence.steps)]
        sub = self.sublibrary(sequence.steps[0].configuration)
        pairs = list(zip(range(len(placements) - 1), range(1, len(placements)), strict=True))
        if sequence.loop and len(placements) > 1:
            pairs.append((len(placements) - 1, 0))
        for i, j in pairs:
            self.add_edge(sub, placements[i], placements[j], sequence.steps[j].tree,
                          f"{origin}[{i}->{j}]")
        if sequence.behavior:
            if sequence.behavior in sub.behaviors:
                raise LibraryError(f"{origin}: behavior {sequence.behavior!r} is defined twice")
            ids = [p.config_id for p in placements]
            sub.behaviors[sequence.behavior] = Behavior(
                sequence.behavior, "sequence", ids[0], tuple(ids[1:]), sequence.loop,
                description=sequence.description,
                drive_root=self.drive_root(sub, placements[0], sequence.drive_root, origin))

    def add_mapping_behavior(self, behavior: MappingBehaviorSource) -> None:
        origin = f"{behavior.origin}: behavior {behavior.name!r}"
        placement = self.named.get(behavior.start)
        if placement is None:
            raise LibraryError(f"{origin}: no configuration named {behavior.start!r} in the "
                               f"sources (known: {', '.join(sorted(self.named)) or 'none'})")
        sub, _ = self.library.find_configuration(placement.config_id)
        if behavior.name in sub.behaviors:
            raise LibraryError(f"{origin}: behavior {behavior.name!r} is defined twice")
        commands = []
        for command in behavior.commands:
            try:
                module, connector = placement.mapping.image(command.module, command.connector)
            except ConfigurationError:
                raise LibraryError(f"{origin}: module {command.module!r} is not in "
                                   f"configuration {behavior.start!r}") from None
            commands.append(CommandGain(module, command.command, command.gains, connector))
        sub.behaviors[behavior.name] = Behavior(
            behavior.name, "mapping", placement.config_id, parameters=behavior.parameters,
            commands=tuple(commands), description=behavior.description,
            drive_root=self.drive_root(sub, placement, behavior.drive_root, origin))

    @staticmethod
    def drive_root(sub: SubLibrary, placement: _Placement, declared: str | None,
                   origin: str) -> str:
        """A behavior's drive root in its group's ids: the sources' node, else
        :func:`~.model.default_drive_root` of the group's reference."""
        reference = sub.group_of(placement.config_id).reference
        if declared is None:
            return default_drive_root(reference)
        root = placement.mapping.nodes.get(declared)
        if root is None or root not in reference.vertices(virtual=False):
            raise LibraryError(f"{origin}: drive_root {declared!r} is no node of the "
                               "behavior's start configuration")
        return root


def build_library(sources: LibrarySources, robot: Robot, *,
                  merge_threshold: float = DEFAULT_MERGE_THRESHOLD, cost: str = COST_DISTANCE,
                  progress: Progress | None = None) -> Library:
    """Build a library from designed groups and recorded sequences (section 6.2, Fig. 14).

    Args:
        sources: the inputs, see :func:`~msrr.core.library.sources.load_sources`.
        robot: the robot the sources describe (joint modes for the trees, module kinds
            for sub-library names).
        merge_threshold: configurations whose motion cost to an existing library
            configuration is at most this (or tied with it) are merged into it.
        cost: motion cost, ``"distance"`` (eq. 8; byte-identical builds on every
            machine) or ``"ik"`` (eq. 6; its solver's round-off depends on the BLAS
            kernel), see :mod:`msrr.core.matching.cost`.
        progress: called once per configuration placed.

    Raises:
        LibraryError: a sequence configuration without a designed group, isomorphic
            designed groups, an action that both connects and disconnects, unknown names.
    """
    builder = _Builder(sources, robot, merge_threshold, cost, progress)
    for group in sources.groups:
        builder.add_group(group)
    for sequence in sources.sequences:
        builder.add_sequence(sequence)
    for behavior in sources.behaviors:
        builder.add_mapping_behavior(behavior)
    return builder.library
