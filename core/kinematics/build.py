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
from typing import Literal

import networkx as nx

from ..configuration import Configuration
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
        inside = [e.id for e in config.edges()
                  if e.source in group_of and group_of[e.source] == group_of.get(e.target)]
        found = find_cycle_through(config, inside)
        assert found is not None  # every edge inside a group lies on a cycle
        loop = " - ".join([*found[0], found[0][0]])
        raise KinematicTreeError(f"cycle {loop} (edges {', '.join(found[1])}): the topology is "
                                 "not a tree; use cycles='fixed' or build the tree with a fixed "
                                 "or parallel node around it")

    def super_vertex(v: str) -> str:
        return f"#group{group_of[v]}" if v in group_of else v

    # the topology with every group contracted to one super vertex
    contracted = nx.Graph()
    order = {v: i for i, v in enumerate(config.vertices())}
    rank: dict[str, tuple] = {}
    members: dict[str, list[str]] = {}
    inner: dict[str, list[str]] = {}
    for v in config.vertices():
        s = super_vertex(v)
        contracted.add_node(s)
        members.setdefault(s, []).append(v)
        candidate = (0 if not config.is_virtual(v) else 1, -config.degree(v), order[v])
        rank[s] = min(rank.get(s, candidate), candidate)
    bridges = []
    for e in config.edges():
        s, t = super_vertex(e.source), super_vertex(e.target)
        if s == t:
            inner.setdefault(s, []).append(e.id)
        else:
            bridges.append(e)
            contracted.add_edge(s, t)
    centre = tree_centre(contracted, rank)

    nodes: list[KinematicNode] = [FixedNode(inner.get(centre, []), members[centre])]
    by_super: dict[str, list] = {}
    for e in bridges:
        by_super.setdefault(super_vertex(e.source), []).append(e)
        by_super.setdefault(super_vertex(e.target), []).append(e)
    queue, seen = deque([centre]), {centre}
    while queue:
        s = queue.popleft()
        for e in by_super.get(s, []):
            far = e.target if super_vertex(e.source) == s else e.source
            sf = super_vertex(far)
            if sf in seen:
                continue
            seen.add(sf)
            nodes.append(joint_mode.for_edge(e, far))
            rest = [v for v in members[sf] if v != far]
            if rest or inner.get(sf):
                nodes.append(FixedNode(inner.get(sf, []), rest))
            queue.append(sf)
    return KinematicTree(config, nodes)
