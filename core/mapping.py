"""Module maps: the one id mapping between two configurations.

A :class:`ModuleMap` sends vertex ids to vertex ids and edge ids to ``(edge id, inv)``,
where ``inv`` says the two edges point in opposite directions: the FreeSN paper's
``f_node``, ``f_edge`` and ``inv`` (Alg. 2 output, Alg. 3 line 8). The matcher returns
one (system ids -> reference ids, :class:`msrr.core.matching.Mapping` adds its
distance and yaw); the library stores one on every action edge that changes ids
(section 6.1, Fig. 14(f)) and composes them at retrieval (Fig. 15(c)).

Reversed edges. ``z`` is the connection direction from an edge's source to its target;
``x`` is the forward direction of the module body (section 3.1). Seeing an edge from its
other end swaps its ends and ports and negates ``z``; the body, and so ``x``, does not
turn. This is Alg. 3 lines 12-13, which negate ``z_ref`` when ``inv`` and leave
``x_ref`` as it is. :meth:`ModuleMap.apply` follows it, so applying a map and then its
inverse gives back the configuration exactly.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .configuration import Configuration, unique_id
from .errors import ConfigurationError

__all__ = ["CONNECTOR_ENDS", "EdgeImage", "ModuleMap", "end_vertex", "free_vertex_name"]

EdgeImage = tuple[str, bool]
"""Image of an edge: ``(edge id, inv)``."""

CONNECTOR_ENDS = ("source", "target")
"""Names of the two connector ends of an edge module (behavior commands use them)."""


def end_vertex(config: Configuration, edge_id: str, at_source: bool) -> str:
    """The vertex at the source (``at_source``) or target end of ``edge_id``."""
    edge = config.edge(edge_id)
    return edge.source if at_source else edge.target


def free_vertex_name(edge_id: str, at_source: bool, taken: set[str]) -> str:
    """A fresh, deterministic name for the free connector at one end of ``edge_id``."""
    return unique_id(f"{edge_id}:{'a' if at_source else 'b'}", taken)


@dataclass(frozen=True)
class ModuleMap:
    """A (partial) injective mapping of vertex and edge ids from one configuration to another.

    Attributes:
        nodes: vertex id -> vertex id (modules and, where known, virtual vertices).
        edges: edge id -> ``(edge id, inv)``; ``inv`` is true when the two edges point in
            opposite directions.
    """

    nodes: Mapping[str, str] = field(default_factory=dict)
    edges: Mapping[str, EdgeImage] = field(default_factory=dict)

    @classmethod
    def identity(cls, config: Configuration) -> ModuleMap:
        """The identity on ``config``'s vertices and edges."""
        return ModuleMap({v: v for v in config.vertices()},
                         {e: (e, False) for e in config.edge_ids()})

    def is_identity(self) -> bool:
        return (all(k == v for k, v in self.nodes.items())
                and all(k == e and not inv for k, (e, inv) in self.edges.items()))

    def inverted(self) -> list[str]:
        """Edges whose image points the other way."""
        return [e for e, (_, inv) in self.edges.items() if inv]

    def image(self, module: str, connector: str | None = None) -> tuple[str, str | None]:
        """Where a module, and one connector end of it, go under this map.

        Args:
            module: a vertex id or the id of an edge that is a module (a strut).
            connector: ``"source"`` or ``"target"`` end of an edge module, or ``None``;
                the two are swapped when the edge is reversed.

        Raises:
            ConfigurationError: ``module`` is not mapped.
        """
        if module in self.edges:
            image, inv = self.edges[module]
            if inv and connector in CONNECTOR_ENDS:
                connector = CONNECTOR_ENDS[1 - CONNECTOR_ENDS.index(connector)]
            return image, connector
        if module in self.nodes:
            return self.nodes[module], connector
        raise ConfigurationError(f"module {module!r} is not mapped")

    def inverse(self) -> ModuleMap:
        """The inverse mapping (maps are injective); ``inv`` flags are symmetric."""
        return ModuleMap({v: k for k, v in self.nodes.items()},
                         {e: (k, inv) for k, (e, inv) in self.edges.items()})

    def then(self, other: ModuleMap) -> ModuleMap:
        """``other`` after ``self``: the ids ``self`` maps and ``other`` maps further.

        ``a.then(b).apply(c)`` equals ``b.apply(a.apply(c))`` on what both map.
        """
        nodes = {k: other.nodes[v] for k, v in self.nodes.items() if v in other.nodes}
        edges = {}
        for k, (e, inv) in self.edges.items():
            if e in other.edges:
                e2, inv2 = other.edges[e]
                edges[k] = (e2, inv != inv2)
        return ModuleMap(nodes, edges)

    def completed(self, source: Configuration, target: Configuration) -> ModuleMap:
        """This map extended to the virtual vertices that stay free from ``source`` to ``target``.

        A virtual vertex of ``source`` at one end of a mapped edge corresponds to the
        vertex at the matching end of the image edge in ``target`` when that one is
        virtual too (the connector stays free across the action).
        """
        nodes = dict(self.nodes)
        source_edges, target_edges = set(source.edge_ids()), set(target.edge_ids())
        for edge_id, (image, inv) in self.edges.items():
            if edge_id not in source_edges or image not in target_edges:
                continue
            for at_source in (True, False):
                here = end_vertex(source, edge_id, at_source)
                there = end_vertex(target, image, at_source != inv)
                if source.is_virtual(here) and target.is_virtual(there):
                    nodes.setdefault(here, there)
        return ModuleMap(nodes, dict(self.edges))

    def apply(self, config: Configuration, *, name: str | None = None,
              rotation: np.ndarray | None = None) -> tuple[Configuration, ModuleMap]:
        """``config`` in this map's target ids, and the complete map actually used.

        Edges mapped with ``inv`` are turned around (ends and ports swapped, ``z``
        negated, ``x`` kept; see the module docstring). Unmapped virtual vertices get
        fresh names from their edge (:func:`free_vertex_name`); an unmapped connection
        that is not a module keeps its id (a fresh one if taken).

        Args:
            config: a configuration in this map's source ids.
            name: the result's name; ``config``'s when omitted.
            rotation: rotation applied to every vector, shape (3, 3) (a match's yaw).

        Raises:
            ConfigurationError: a module (vertex or edge module) of ``config`` is not
                mapped, or two ids map to one.
        """
        vertices = config.vertices()
        nodes = {v: self.nodes[v] for v in vertices if v in self.nodes}
        taken = set(self.nodes.values())
        for vertex in vertices if len(nodes) < len(vertices) else ():
            if vertex in nodes:
                continue
            if not config.is_virtual(vertex):
                raise ConfigurationError(f"module {vertex!r} of configuration "
                                         f"{config.name or config.robot!r} is not mapped")
            (edge,) = config.incident(vertex)
            image, inv = self.edges.get(edge.id, (edge.id, False))
            nodes[vertex] = free_vertex_name(image, (edge.source == vertex) != inv, taken)
            taken.add(nodes[vertex])
        edges: dict[str, EdgeImage] = {}
        taken_edges = {e for e, _ in self.edges.values()}
        for edge_id in config.edge_ids():
            if edge_id in self.edges:
                edges[edge_id] = self.edges[edge_id]
                continue
            edge = config.edge(edge_id)
            if edge.kind is not None:
                raise ConfigurationError(f"module {edge.id!r} of configuration "
                                         f"{config.name or config.robot!r} is not mapped")
            fresh = (free_vertex_name(edge.id, True, taken_edges) if edge.id in taken_edges
                     else edge.id)
            edges[edge.id] = (fresh, False)
            taken_edges.add(fresh)
        out = config.derive(vertices=nodes, edges={e: image for e, (image, _) in edges.items()},
                            reverse=[e for e, (_, inv) in edges.items() if inv],
                            rotation=rotation, name=name)
        return out, ModuleMap(nodes, edges)

    def to_dict(self) -> dict[str, dict]:
        """A JSON-ready form, keys sorted: ``{"nodes": {...}, "edges": {id: [id, inv]}}``."""
        return {"nodes": dict(sorted(self.nodes.items())),
                "edges": {k: [e, inv] for k, (e, inv) in sorted(self.edges.items())}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Mapping]) -> ModuleMap:
        """The inverse of :meth:`to_dict`."""
        return ModuleMap(dict(data.get("nodes", {})),
                         {k: (str(v[0]), bool(v[1])) for k, v in data.get("edges", {}).items()})
