"""The behavior library (FreeSN paper, section 6.1, Figs. 13(e) and 14(f)).

The library is hierarchical:

* a :class:`Library` holds :class:`SubLibrary` objects keyed by module counts
  (``S6N3``: six struts and three nodes, named by :meth:`Signature.label`);
* a sub-library holds :class:`Group` objects, one per topology isomorphism class,
  each with a reference topology, one or more kinematic trees and skeletal
  configurations (:class:`LibraryConfiguration`) that all share the reference ids;
* :class:`Behavior` objects: a configuration sequence (possibly looping: squirm,
  crawl) or a linear map from low-dimensional parameters to module commands
  ("wheeled move": system speed to connector speeds);
* a directed graph of feasible actions (:class:`ActionEdge`): each edge carries the
  kinematic tree that executes it, its motion cost, its action type, the mapping
  of ids when the ids change (always across groups) and a feasibility flag that a
  simulation fills in (section 6.2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import networkx as nx

from ..configuration import Configuration
from ..errors import ConfigurationError, PlanningError
from ..mapping import ModuleMap
from ..plan import ActionType, CommandGain, natural_key

__all__ = [
    "ActionEdge",
    "Behavior",
    "CommandGain",
    "Group",
    "Library",
    "LibraryConfiguration",
    "LibraryError",
    "RetrievalError",
    "SubLibrary",
    "TreeRef",
    "default_drive_root",
]


class LibraryError(ConfigurationError):
    """A library (file or in-memory) or a library source is malformed."""


class RetrievalError(PlanningError):
    """No library sequence reaches the requested target from the system."""


@dataclass(frozen=True, order=True)
class TreeRef:
    """A kinematic tree of a group: ``(group id, tree name)``."""

    group: str
    name: str

    def __str__(self) -> str:
        return f"{self.group}/{self.name}"


@dataclass
class Group:
    """One topology isomorphism class of a sub-library (Fig. 14(f), green circles).

    Attributes:
        id: ``"<sub-library>-<n>"`` such as ``"S6N3-1"``.
        name: designer's name (``"triangle-three-legs"``).
        reference: the reference topology graph with a reference skeletal configuration.
        trees: kinematic trees of the reference topology, name -> serialised tree
            (``KinematicTree.to_dict()``), in the reference ids.
        description: one line.
    """

    id: str
    name: str
    reference: Configuration
    trees: dict[str, dict] = field(default_factory=dict)
    description: str = ""


@dataclass
class LibraryConfiguration:
    """A skeletal configuration of a group, in the group's reference ids.

    Attributes:
        id: ``"<group id>.<n>"`` such as ``"S6N3-4.2"``.
        group: id of its group.
        configuration: the skeletal configuration (reference topology, own ``z``).
        name: names of the source configurations merged into it (first one shown).
        origins: where it came from: ``"<source>:<sequence>[<step>]"`` entries.
    """

    id: str
    group: str
    configuration: Configuration
    names: tuple[str, ...] = ()
    origins: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.names[0] if self.names else ""


@dataclass(frozen=True)
class Behavior:
    """A labelled behavior (section 6.2): a configuration sequence or a parameter mapping.

    Attributes:
        name: the label (``"squirm"``, ``"wheeled-move"``).
        kind: ``"sequence"`` or ``"mapping"``.
        start: the library configuration the behavior starts from.
        steps: for sequences, the configuration ids after ``start``, in order; each
            consecutive pair is an edge of the action graph.
        loop: for sequences, whether the last step returns to ``start`` and repeats.
        parameters: for mappings, the low-dimensional parameter names.
        commands: for mappings, the linear map from parameters to module commands.
        description: one line.
        drive_root: the node the behavior is driven from, in the start's ids: a joint
            controller that drives from one node grows its drive from it (FreeSN's
            driving tree); ``None`` (a library built before it was recorded): the
            controller's own choice.
    """

    name: str
    kind: Literal["sequence", "mapping"]
    start: str
    steps: tuple[str, ...] = ()
    loop: bool = False
    parameters: tuple[str, ...] = ()
    commands: tuple[CommandGain, ...] = ()
    description: str = ""
    drive_root: str | None = None


def default_drive_root(configuration: Configuration) -> str:
    """A behavior's drive root when its sources name none (:attr:`Behavior.drive_root`):
    of the nodes with the most connections, the first by id (natural order). Chosen in
    the library's ids, so a build labelled any way is driven from the same node."""
    nodes = configuration.vertices(virtual=False)
    most = max(configuration.degree(n) for n in nodes)
    return min((n for n in nodes if configuration.degree(n) == most), key=natural_key)


@dataclass
class ActionEdge:
    """A feasible action between two library configurations (Fig. 14(f), black arrows).

    Attributes:
        source: id of the configuration the action starts from.
        target: id of the configuration it reaches.
        action: the action type (section 4.1).
        tree: the kinematic tree that executes the motion: the source group's for
            connections (the system moves to ``S_conn`` before connecting, Fig. 9), the
            target group's otherwise (Fig. 10).
        cost: motion cost: the inverse-kinematics cost from source to target vectors.
        mapping: source ids -> target ids, ``None`` for the identity (same group).
        feasible: set by a simulation check; ``None`` until one has run.
    """

    source: str
    target: str
    action: ActionType
    tree: TreeRef
    cost: float
    mapping: ModuleMap | None = None
    feasible: bool | None = None

    def module_map(self, source: Configuration) -> ModuleMap:
        """The mapping of this edge, the identity on ``source`` when none is stored."""
        return self.mapping if self.mapping is not None else ModuleMap.identity(source)


@dataclass
class SubLibrary:
    """The configurations of one module count (``S6N3``) and the actions between them."""

    name: str
    groups: dict[str, Group] = field(default_factory=dict)
    configurations: dict[str, LibraryConfiguration] = field(default_factory=dict)
    behaviors: dict[str, Behavior] = field(default_factory=dict)
    edges: list[ActionEdge] = field(default_factory=list)

    def configuration(self, key: str) -> LibraryConfiguration:
        """The configuration with id (or name) ``key``; the error lists the ids."""
        if key in self.configurations:
            return self.configurations[key]
        for config in self.configurations.values():
            if key in config.names:
                return config
        raise LibraryError(f"no configuration {key!r} in sub-library {self.name} (known: "
                           f"{', '.join(self.configurations) or 'none'})")

    def group_of(self, config_id: str) -> Group:
        return self.groups[self.configurations[config_id].group]

    def graph(self) -> nx.DiGraph:
        """The action digraph: one arc per (source, target), the cheapest edge kept.

        Node attribute ``group``; arc attributes ``cost`` and ``edge`` (the :class:`ActionEdge`).
        Edges a simulation marked infeasible are left out.
        """
        graph = nx.DiGraph()
        for config in self.configurations.values():
            graph.add_node(config.id, group=config.group)
        for edge in self.edges:
            if edge.feasible is False:
                continue
            old = graph.get_edge_data(edge.source, edge.target)
            if old is None or edge.cost < old["cost"]:
                graph.add_edge(edge.source, edge.target, cost=edge.cost, edge=edge)
        return graph


@dataclass
class Library:
    """A behavior library of one robot: its sub-libraries and how it was built.

    Attributes:
        robot: robot name.
        name: library name (``"S6N3"`` for a library of one sub-library).
        sublibraries: name -> :class:`SubLibrary`.
        build: parameters and sources of the build (merge threshold, file digests).
        description: one line.
    """

    robot: str
    name: str
    sublibraries: dict[str, SubLibrary] = field(default_factory=dict)
    build: dict = field(default_factory=dict)
    description: str = ""

    def sublibrary(self, name: str) -> SubLibrary:
        try:
            return self.sublibraries[name]
        except KeyError:
            raise LibraryError(f"no sub-library {name!r} in library {self.name} (known: "
                               f"{', '.join(self.sublibraries) or 'none'})") from None

    def find_configuration(self, key: str) -> tuple[SubLibrary, LibraryConfiguration]:
        """The sub-library and configuration with id or name ``key``."""
        for sub in self.sublibraries.values():
            try:
                return sub, sub.configuration(key)
            except LibraryError:
                continue
        known = [c for s in self.sublibraries.values() for c in s.configurations]
        raise LibraryError(f"no configuration {key!r} in library {self.name} (known: "
                           f"{', '.join(known) or 'none'})")

    def find_behavior(self, name: str) -> tuple[SubLibrary, Behavior]:
        """The sub-library and behavior called ``name``."""
        for sub in self.sublibraries.values():
            if name in sub.behaviors:
                return sub, sub.behaviors[name]
        known = [b for s in self.sublibraries.values() for b in s.behaviors]
        raise LibraryError(f"no behavior {name!r} in library {self.name} (known: "
                           f"{', '.join(known) or 'none'})")
