"""Cycles of a configuration's topology, as the kinematic trees need them (paper section 3.2).

A kinematic tree may hold a cycle only inside one fixed or parallel node, so the
tree needs to name a cycle when it refuses one (:func:`find_cycle_through`) and the
default tree needs the vertex groups that must stay rigid (:func:`cyclic_groups`).
"""

from __future__ import annotations

from collections.abc import Iterable

import networkx as nx

from ..configuration import Configuration

__all__ = ["cyclic_groups", "find_cycle_through"]


def find_cycle_through(config: Configuration, edges: Iterable[str]
                       ) -> tuple[list[str], list[str]] | None:
    """The shortest cycle of the topology through one of ``edges``: (vertices, edge ids).

    The vertices run from the chosen edge's target back to its source; the edge ids
    follow them and end with the chosen edge. ``None`` when no edge lies on a cycle.
    """
    graph = nx.MultiGraph()
    graph.add_nodes_from(config.vertices())
    for e in config.edges():
        graph.add_edge(e.source, e.target, key=e.id)
    best: tuple[list[str], list[str]] | None = None
    for edge_id in edges:
        edge = config.edge(edge_id)
        graph.remove_edge(edge.source, edge.target, key=edge_id)
        try:
            path = nx.shortest_path(graph, edge.target, edge.source)
        except nx.NetworkXNoPath:
            path = None
        if path is not None and (best is None or len(path) < len(best[0])):
            ids = [next(iter(graph.get_edge_data(a, b)))
                   for a, b in zip(path, path[1:], strict=False)]
            best = (path, [*ids, edge_id])
        graph.add_edge(edge.source, edge.target, key=edge_id)
    return best


def cyclic_groups(config: Configuration) -> list[set[str]]:
    """Disjoint vertex sets that lie on cycles, one per group of touching cycles.

    A vertex is in a group when it belongs to a biconnected block with a cycle or to a
    doubled edge; blocks that share a vertex form one group. Groups come in the order
    of their first vertex in ``config.vertices()``.
    """
    simple = nx.Graph()
    simple.add_nodes_from(config.vertices())
    ends: dict[frozenset[str], int] = {}
    for e in config.edges():
        simple.add_edge(e.source, e.target)
        pair = frozenset((e.source, e.target))
        ends[pair] = ends.get(pair, 0) + 1
    cyclic = nx.Graph()
    for block in nx.biconnected_component_edges(simple):
        block = list(block)
        if len(block) > 1:
            cyclic.add_edges_from(block)
    cyclic.add_edges_from(tuple(pair) for pair, count in ends.items() if count > 1)
    order = {v: i for i, v in enumerate(config.vertices())}
    return sorted((set(c) for c in nx.connected_components(cyclic)),
                  key=lambda group: min(order[v] for v in group))
