"""Kinematic trees: kinematic nodes connected by ports (paper section 3.2).

A :class:`KinematicTree` partitions a configuration's edges and vertices among
kinematic nodes. Each non-root node hangs from its parent through the ends of its
edges that it does not own (its *attachments*; the first is its *input port*). The
root is a fixed node. Breadth-first order of the nodes fixes the layout of ``Z``,
``X`` (one column per edge, node by node) and ``sigma`` (node by node).

Every cycle of the topology must lie inside one fixed or parallel node (closing, at
most, through ports of that node's parent); anything else is refused with a
:class:`KinematicTreeError` that names the cycle (:func:`~.cycles.find_cycle_through`).

Trees serialise to JSON (:mod:`.tree_file`) with :meth:`KinematicTree.to_dict`,
:meth:`KinematicTree.from_dict`, :func:`save_tree` and :func:`load_tree`; the default
tree of a configuration is built by :func:`~.build.default_tree`.
"""

from __future__ import annotations

import json
import os
from collections import deque
from collections.abc import Iterable, Sequence
from functools import cached_property
from typing import Any

import networkx as nx
import numpy as np

from ..configuration import Configuration
from ..errors import ConfigurationError, UnknownNameError
from ..files import atomic_write_text, read_json
from .cycles import find_cycle_through
from .node import KinematicNode, KinematicTreeError
from .tree_file import NodeTypes, read_tree_document, tree_document

__all__ = [
    "KinematicTree",
    "check_same_topology",
    "load_tree",
    "save_tree",
]


def _label(node: KinematicNode) -> str:
    inside = ",".join(node.edges) if node.edges else ",".join(node.vertices)
    return f"{node.name}[{inside}]"


class KinematicTree:
    """Kinematic nodes over one configuration's topology, in breadth-first order.

    Args:
        config: the configuration whose topology the nodes cover (its vectors are not
            used; a copy of the topology is kept).
        nodes: the nodes, in any order; exactly one of them, the root, has no
            attachment, and it must be a fixed node.

    Attributes:
        configuration: the topology (a copy of ``config``).
        nodes: nodes in BFS order; ``nodes[0]`` is the root.
        parents: index of each node's parent in ``nodes`` (-1 for the root).
        input_ports: the parent vertex each node hangs from (``None`` for the root).
        edges: edge ids in layout order: the columns of ``Z`` and ``X``.
        slices: each node's slice of ``sigma``.
        dim: total joint-space dimension, the length of ``sigma``.

    Raises:
        KinematicTreeError: the nodes do not partition the topology, or a cycle
            crosses nodes or runs through a module joint.
    """

    def __init__(self, config: Configuration, nodes: Iterable[KinematicNode]):
        self.configuration = config.with_vectors(z={}, x={})
        self.configuration.name, self.configuration.description = config.name, config.description
        nodes = list(nodes)
        owner_edge, owner_vertex = self._partition(nodes)
        attachments = [self._attachments(node, owner_vertex) for node in nodes]
        roots = [i for i, a in enumerate(attachments) if not a]
        if len(roots) != 1:
            listed = ", ".join(_label(nodes[i]) for i in roots) or "none"
            raise KinematicTreeError(f"a kinematic tree needs exactly one root node (a node "
                                     f"none of whose edges reach another node); found {listed}")
        root = roots[0]
        if nodes[root].family != "fixed":
            raise KinematicTreeError(f"the root node {_label(nodes[root])} must be a fixed node")
        parent_of: list[int] = []
        for i, node in enumerate(nodes):
            owners = sorted({owner_vertex[v] for v in attachments[i]})
            if i == root:
                parent_of.append(-1)
                continue
            if len(owners) > 1 or (len(attachments[i]) > 1 and node.family == "module_joint"):
                self._cycle_error(node.edges, nodes, owner_edge)
            parent = owners[0]
            distinct_ports = len(set(attachments[i])) > 1
            if distinct_ports and nodes[parent].family != "fixed":
                raise KinematicTreeError(
                    f"{_label(node)} closes a cycle through ports "
                    f"{', '.join(attachments[i])} of {_label(nodes[parent])}; only a fixed "
                    "parent keeps its ports rigid")
            if node.family == "module_joint" and self._has_cycle(node, attachments[i]):
                self._cycle_error(node.edges, nodes, owner_edge)
            self._check_connected(node, attachments[i])
            parent_of.append(parent)
        order = self._bfs(nodes, root, parent_of, attachments, owner_edge)
        index = {old: new for new, old in enumerate(order)}
        self.nodes: tuple[KinematicNode, ...] = tuple(nodes[i] for i in order)
        self.parents: tuple[int, ...] = tuple(
            -1 if parent_of[i] < 0 else index[parent_of[i]] for i in order)
        self.input_ports: tuple[str | None, ...] = tuple(
            attachments[i][0] if attachments[i] else None for i in order)
        self.attachments: tuple[tuple[str, ...], ...] = tuple(attachments[i] for i in order)
        self.edges: tuple[str, ...] = tuple(e for node in self.nodes for e in node.edges)
        slices, start = [], 0
        for node in self.nodes:
            slices.append(slice(start, start + node.dim))
            start += node.dim
        self.slices: tuple[slice, ...] = tuple(slices)
        self.dim = start
        self._column = {e: j for j, e in enumerate(self.edges)}
        self._node_of_vertex = {v: index[owner_vertex[v]] for v in owner_vertex}
        self._engine: Any = None
        self._ground: Any = None   # (GroundModel, GroundOp), see ground.ground_op

    # -- validation -----------------------------------------------------------------------

    def _partition(self, nodes: list[KinematicNode]) -> tuple[dict[str, int], dict[str, int]]:
        config = self.configuration
        owner_edge: dict[str, int] = {}
        owner_vertex: dict[str, int] = {}
        known_edges, known_vertices = set(config.edge_ids()), set(config.vertices())
        for i, node in enumerate(nodes):
            if not isinstance(node, KinematicNode):
                raise KinematicTreeError(f"nodes[{i}] is {node!r}, not a KinematicNode")
            for e in node.edges:
                if e not in known_edges:
                    raise KinematicTreeError(f"{_label(node)}: no edge {e!r} in configuration "
                                             f"{config.name or '(unnamed)'}")
                if e in owner_edge:
                    raise KinematicTreeError(f"edge {e} is in two nodes: "
                                             f"{_label(nodes[owner_edge[e]])} and {_label(node)}")
                owner_edge[e] = i
            for v in node.vertices:
                if v not in known_vertices:
                    raise KinematicTreeError(f"{_label(node)}: no vertex {v!r} in the "
                                             "configuration")
                if v in owner_vertex:
                    raise KinematicTreeError(
                        f"vertex {v} is owned by two nodes: {_label(nodes[owner_vertex[v]])} "
                        f"and {_label(node)}")
                owner_vertex[v] = i
        missing_e = [e for e in config.edge_ids() if e not in owner_edge]
        missing_v = [v for v in config.vertices() if v not in owner_vertex]
        if missing_e:
            raise KinematicTreeError(f"edge(s) {', '.join(missing_e)} belong to no kinematic node")
        if missing_v:
            raise KinematicTreeError(f"vertex(es) {', '.join(missing_v)} belong to no kinematic "
                                     "node")
        return owner_edge, owner_vertex

    def _attachments(self, node: KinematicNode, owner_vertex: dict[str, int]) -> tuple[str, ...]:
        own = set(node.vertices)
        found: list[str] = []
        for e in node.edges:
            edge = self.configuration.edge(e)
            for end in (edge.source, edge.target):
                if end not in own:
                    found.append(end)
        return tuple(found)

    def _has_cycle(self, node: KinematicNode, attachments: tuple[str, ...]) -> bool:
        graph = nx.MultiGraph()
        for e in node.edges:
            edge = self.configuration.edge(e)
            graph.add_edge(*("^" if v in attachments else v for v in (edge.source, edge.target)))
        return len(node.edges) >= graph.number_of_nodes()

    def _check_connected(self, node: KinematicNode, attachments: tuple[str, ...]) -> None:
        graph = nx.Graph()
        graph.add_node("^")
        graph.add_nodes_from(node.vertices)
        for e in node.edges:
            edge = self.configuration.edge(e)
            graph.add_edge(*("^" if v in attachments else v for v in (edge.source, edge.target)))
        loose = [v for v in node.vertices if not nx.has_path(graph, "^", v)]
        if loose:
            raise KinematicTreeError(f"{_label(node)}: vertex(es) {', '.join(loose)} are not "
                                     "connected to the parent through the node's own edges")

    def _cycle_error(self, edges: Sequence[str], nodes: list[KinematicNode],
                     owner_edge: dict[str, int]) -> None:
        cycle = find_cycle_through(self.configuration, edges)
        if cycle is None:  # pragma: no cover - a cross-node attachment always closes a cycle
            raise KinematicTreeError(f"edges {', '.join(edges)} attach to several nodes")
        vertices, cycle_edges = cycle
        through = []
        for e in cycle_edges:
            label = _label(nodes[owner_edge[e]])
            if label not in through:
                through.append(label)
        loop = " - ".join([*vertices, vertices[0]])
        raise KinematicTreeError(
            f"cycle {loop} (edges {', '.join(cycle_edges)}) is not inside one fixed or "
            f"parallel node: it runs through {', '.join(through)}")

    def _bfs(self, nodes: list[KinematicNode], root: int, parent_of: list[int],
             attachments: list[tuple[str, ...]], owner_edge: dict[str, int]) -> list[int]:
        edge_rank = {e: i for i, e in enumerate(self.configuration.edge_ids())}
        children: dict[int, list[int]] = {}
        for i, p in enumerate(parent_of):
            if p >= 0:
                children.setdefault(p, []).append(i)

        def key(i: int) -> tuple[int, int]:
            parent = nodes[parent_of[i]]
            return (parent.vertices.index(attachments[i][0]),
                    min((edge_rank[e] for e in nodes[i].edges), default=0))

        order, queue = [], deque([root])
        while queue:
            i = queue.popleft()
            order.append(i)
            queue.extend(sorted(children.get(i, []), key=key))
        if len(order) != len(nodes):
            stray = [i for i in range(len(nodes)) if i not in set(order)]
            self._cycle_error([e for i in stray for e in nodes[i].edges], nodes, owner_edge)
        return order

    # -- reading -----------------------------------------------------------------------------

    @property
    def root(self) -> KinematicNode:
        return self.nodes[0]

    @property
    def robot(self) -> str:
        return self.configuration.robot

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint bounds in ``sigma`` layout, each shape (dim,) (read-only arrays)."""
        lo = np.concatenate([n.bounds[0] for n in self.nodes]) if self.dim else np.zeros(0)
        hi = np.concatenate([n.bounds[1] for n in self.nodes]) if self.dim else np.zeros(0)
        lo.flags.writeable = hi.flags.writeable = False
        return lo, hi

    def column(self, edge_id: str) -> int:
        """Column of edge ``edge_id`` in ``Z`` and ``X``."""
        try:
            return self._column[edge_id]
        except KeyError:
            raise UnknownNameError("edge of this kinematic tree", edge_id, self.edges) from None

    def node_of_edge(self, edge_id: str) -> KinematicNode:
        return next(n for n in self.nodes if edge_id in n.edges)

    def node_of_vertex(self, vertex: str) -> KinematicNode:
        return self.nodes[self._node_of_vertex[vertex]]

    def split(self, sigma: np.ndarray) -> list[np.ndarray]:
        """``sigma`` cut into one array per node, in :attr:`nodes` order."""
        sigma = np.asarray(sigma, dtype=np.float64)
        return [sigma[s] for s in self.slices]

    def check_configuration(self, config: Configuration) -> None:
        """Raise unless ``config`` has this tree's topology (same ids, same ends)."""
        check_same_topology(self.configuration, config)

    def __len__(self) -> int:
        return len(self.nodes)

    def __repr__(self) -> str:
        return (f"<KinematicTree robot={self.robot} nodes={len(self.nodes)} "
                f"edges={len(self.edges)} dim={self.dim}>")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, KinematicTree):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    # -- files -------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary: topology and nodes in BFS order (:mod:`.tree_file`)."""
        return tree_document(self.configuration, self.nodes)

    @classmethod
    def from_dict(cls, data: Any, config: Configuration | None = None, *,
                  modes: NodeTypes, source: str | None = None) -> KinematicTree:
        """A tree from :meth:`to_dict` output.

        Args:
            data: the parsed JSON.
            config: the configuration the tree belongs to; its topology must match the
                stored one. Without it the stored topology is used.
            modes: node classes by name (``Robot.joint_modes``); ``"fixed"`` is
                :class:`~.node.FixedNode` unless given.
            source: file name for error messages.

        Raises:
            KinematicTreeError: a malformed document, an unknown node type (listing the
                known ones), or a topology mismatch.
        """
        topology, nodes = read_tree_document(data, modes, source)
        if config is not None and topology.robot != config.robot:
            raise KinematicTreeError(f"a tree of robot {topology.robot!r} for a configuration "
                                     f"of {config.robot!r}", source=source, field="robot")
        try:
            if config is not None:
                check_same_topology(topology, config)
            return cls(config if config is not None else topology, nodes)
        except ConfigurationError as exc:  # named after the document it came from
            raise KinematicTreeError(exc.message, source=exc.source or source,
                                     field=exc.field) from None


def check_same_topology(mine: Configuration, theirs: Configuration) -> None:
    """Raise :class:`KinematicTreeError` unless both have the same vertices and edges
    (ids, ends and module kinds)."""
    a = {e.id: (e.source, e.target) for e in mine.edges()}
    b = {e.id: (e.source, e.target) for e in theirs.edges()}
    if a == b and set(mine.vertices()) == set(theirs.vertices()):
        kinds = [f"vertex {v} is {mine.kind_of(v)!r} in the tree, {theirs.kind_of(v)!r} in the "
                 "configuration" for v in mine.vertices() if mine.kind_of(v) != theirs.kind_of(v)]
        kinds += [f"edge {e.id} is {e.kind!r} in the tree, {theirs.edge(e.id).kind!r} in the "
                  "configuration" for e in mine.edges() if e.kind != theirs.edge(e.id).kind]
        if kinds:
            raise KinematicTreeError(f"configuration does not have the tree's module kinds "
                                     f"({kinds[0]})")
        return
    parts = [f"{what} {', '.join(ids)}" for what, ids in (
        ("unknown edges", sorted(set(b) - set(a))), ("missing edges", sorted(set(a) - set(b))),
        ("edges with other ends", sorted(e for e in set(a) & set(b) if a[e] != b[e])),
        ("unknown vertices", sorted(set(theirs.vertices()) - set(mine.vertices()))),
        ("missing vertices", sorted(set(mine.vertices()) - set(theirs.vertices())))) if ids]
    raise KinematicTreeError(f"configuration does not have the tree's topology ({'; '.join(parts)})")


def save_tree(tree: KinematicTree, path: str | os.PathLike[str]) -> None:
    """Write ``tree`` as JSON to ``path`` atomically."""
    atomic_write_text(path, json.dumps(tree.to_dict(), indent=2) + "\n")


def load_tree(path: str | os.PathLike[str], config: Configuration | None = None, *,
              modes: NodeTypes) -> KinematicTree:
    """Read a tree file written by :func:`save_tree`; ``modes`` as in
    :meth:`KinematicTree.from_dict`."""
    return KinematicTree.from_dict(read_json(path), config, modes=modes, source=str(path))
