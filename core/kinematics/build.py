"""The default kinematic tree of a configuration and the graph centre it is rooted at
(FreeSN paper, section 3.2).

The paper's default tree puts a fixed node at the centre of the topology and one
module joint on every edge. Cycles cannot run through module joints, so every group
of cycles (:func:`~.cycles.cyclic_groups`) is held rigid in one fixed node, and the
centre is taken on the topology with each group contracted to one vertex.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import Literal

import networkx as nx

from ..configuration import Configuration, Edge
from .cycles import cyclic_groups, find_cycle_through
from .node import FixedNode, KinematicNode, KinematicTreeError, ModuleJointNode
from .tree import KinematicTree

__all__ = ["default_tree", "tree_centre"]


def tree_centre(graph: nx.Graph, rank: Mapping[Hashable, tuple]) -> Hashable:
    """The centre of a connected ``graph``: a vertex of smallest eccentricity, ties
    broken by ``rank`` (smaller first)."""
    if graph.number_of_nodes() == 1:
        return next(iter(graph.nodes))
    return min(nx.center(graph), key=lambda v: rank[v])


def _refuse_cycles(config: Configuration, group_of: Mapping[str, int]) -> None:
    """Raise naming one cycle of ``config`` (every edge inside a group lies on one)."""
    inside = [e.id for e in config.edges()
              if e.source in group_of and group_of[e.source] == group_of.get(e.target)]
    found = find_cycle_through(config, inside)
    assert found is not None  # every edge inside a group lies on a cycle
    loop = " - ".join([*found[0], found[0][0]])
    raise KinematicTreeError(f"cycle {loop} (edges {', '.join(found[1])}): the topology is "
                             "not a tree; use cycles='fixed' or build the tree with a fixed "
                             "or parallel node around it")


@dataclass(frozen=True)
class _Contraction:
    """The topology with every group of cycles contracted to one super vertex.

    Attributes:
        graph: the contracted topology (a tree).
        of: module -> its super vertex (``#group<n>``, or the module itself).
        rank: super vertex -> the best rank of its modules (real before virtual, then
            larger degree, then first listed).
        members: super vertex -> its modules, in configuration order.
        inner: super vertex -> the edges inside it.
        bridges: the edges between two super vertices.
    """

    graph: nx.Graph
    of: dict[str, str]
    rank: dict[str, tuple]
    members: dict[str, list[str]]
    inner: dict[str, list[str]]
    bridges: list[Edge]


def _contract(config: Configuration, group_of: Mapping[str, int]) -> _Contraction:
    """Contract every group of cycles (``group_of``: module -> its group) to one vertex."""
    of = {v: f"#group{group_of[v]}" if v in group_of else v for v in config.vertices()}
    graph = nx.Graph()
    order = {v: i for i, v in enumerate(config.vertices())}
    rank: dict[str, tuple] = {}
    members: dict[str, list[str]] = {}
    inner: dict[str, list[str]] = {}
    for v in config.vertices():
        s = of[v]
        graph.add_node(s)
        members.setdefault(s, []).append(v)
        candidate = (0 if not config.is_virtual(v) else 1, -config.degree(v), order[v])
        rank[s] = min(rank.get(s, candidate), candidate)
    bridges = []
    for e in config.edges():
        s, t = of[e.source], of[e.target]
        if s == t:
            inner.setdefault(s, []).append(e.id)
        else:
            bridges.append(e)
            graph.add_edge(s, t)
    return _Contraction(graph, of, rank, members, inner, bridges)


def _grow(tree: _Contraction, centre: str, joint_mode: type[KinematicNode]
          ) -> list[KinematicNode]:
    """The nodes breadth-first from a fixed node at ``centre``: a module joint per bridge,
    owning its end away from the root, and a fixed node for the rest of a super vertex."""
    of, inner, members = tree.of, tree.inner, tree.members
    nodes: list[KinematicNode] = [FixedNode(inner.get(centre, []), members[centre])]
    by_super: dict[str, list] = {}
    for e in tree.bridges:
        by_super.setdefault(of[e.source], []).append(e)
        by_super.setdefault(of[e.target], []).append(e)
    queue, seen = deque([centre]), {centre}
    while queue:
        s = queue.popleft()
        for e in by_super.get(s, []):
            far = e.target if of[e.source] == s else e.source
            sf = of[far]
            if sf in seen:
                continue
            seen.add(sf)
            nodes.append(joint_mode.for_edge(e, far))
            rest = [v for v in members[sf] if v != far]
            if rest or inner.get(sf):
                nodes.append(FixedNode(inner.get(sf, []), rest))
            queue.append(sf)
    return nodes


def default_tree(config: Configuration, joint_mode: type[KinematicNode], *,
                 cycles: Literal["fixed", "error"] = "fixed") -> KinematicTree:
    """The default kinematic tree of ``config`` (paper section 3.2).

    A fixed root at the topology's centre (vertex of smallest eccentricity; ties go to
    a real module before a virtual one, then to the larger degree, then to the first
    listed) and one module joint of ``joint_mode`` per edge, owning the edge's end
    away from the root.

    Args:
        config: a connected configuration.
        joint_mode: the module-joint node class, resolved by the caller
            (``robot.default_joint_mode()`` or ``robot.joint_modes[name]``).
        cycles: ``"fixed"`` holds every group of cycles of the topology rigid in a
            fixed node (the root, if the group holds the centre); ``"error"`` refuses a
            topology with cycles and names one.

    Raises:
        KinematicTreeError: ``joint_mode`` is not a module joint, the topology is not
            connected, or it has a cycle and ``cycles="error"``.
    """
    if not (isinstance(joint_mode, type) and issubclass(joint_mode, ModuleJointNode)):
        name = getattr(joint_mode, "name", joint_mode)
        raise KinematicTreeError(f"joint mode {name!r} is not a module joint node class")
    if len(config) == 0 or not config.is_connected():
        raise KinematicTreeError("a kinematic tree needs one connected configuration")
    groups = cyclic_groups(config)
    group_of = {v: g for g, members in enumerate(groups) for v in members}
    if groups and cycles == "error":
        _refuse_cycles(config, group_of)
    contracted = _contract(config, group_of)
    centre = tree_centre(contracted.graph, contracted.rank)
    return KinematicTree(config, _grow(contracted, centre, joint_mode))
