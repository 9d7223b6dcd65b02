"""Module mappings between configurations: composition, inversion, relabelling.

A library stores every configuration in its group's reference ids (FreeSN paper,
section 6.1) and every action edge that changes ids carries the mapping from the
source configuration's ids to the target's (Fig. 14(f)). Retrieval composes these
mappings with the matcher's system-to-library mapping so that every step comes out
in the system's own ids (Fig. 15(c)).

A :class:`ModuleMap` maps vertices to vertices and edges to ``(edge, inv)``, where
``inv`` says the two edges point in opposite directions (Alg. 3, ``inv = XOR(...)``);
relabelling through an inverted edge swaps its ends and negates its vectors.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..configuration import Configuration

__all__ = ["ModuleMap", "end_vertex", "free_vertex_name"]


def end_vertex(config: Configuration, edge_id: str, at_source: bool) -> str:
    """The vertex at the source (``at_source``) or target end of ``edge_id``."""
    edge = config.edge(edge_id)
    return edge.source if at_source else edge.target


def free_vertex_name(edge_id: str, at_source: bool, taken: set[str]) -> str:
    """A fresh, deterministic name for the free connector at one end of ``edge_id``."""
    base = f"{edge_id}:{'a' if at_source else 'b'}"
    name, n = base, 1
    while name in taken:
        n += 1
        name = f"{base}#{n}"
    return name


@dataclass(frozen=True)
class ModuleMap:
    """A (partial) mapping of vertex and edge ids from one configuration to another.

    Attributes:
        nodes: vertex id -> vertex id (modules and, where known, virtual vertices).
        edges: edge id -> (edge id, inv); ``inv`` is True when the edges point in
            opposite directions.
    """

    nodes: Mapping[str, str] = field(default_factory=dict)
    edges: Mapping[str, tuple[str, bool]] = field(default_factory=dict)

    @classmethod
    def identity(cls, config: Configuration) -> ModuleMap:
        """The identity on ``config``'s vertices and edges."""
        return cls({v: v for v in config.vertices()}, {e: (e, False) for e in config.edge_ids()})

    def is_identity(self) -> bool:
        return (all(k == v for k, v in self.nodes.items())
                and all(k == e and not inv for k, (e, inv) in self.edges.items()))

    def inverse(self) -> ModuleMap:
        """The inverse mapping (the maps are injective)."""
        return ModuleMap({v: k for k, v in self.nodes.items()},
                         {e: (k, inv) for k, (e, inv) in self.edges.items()})

    def then(self, other: ModuleMap) -> ModuleMap:
        """``other`` after ``self``: ids ``self`` maps and ``other`` maps further."""
        nodes = {k: other.nodes[v] for k, v in self.nodes.items() if v in other.nodes}
        edges = {}
        for k, (e, inv) in self.edges.items():
            if e in other.edges:
                e2, inv2 = other.edges[e]
                edges[k] = (e2, inv != inv2)
        return ModuleMap(nodes, edges)

    def completed(self, source: Configuration, target: Configuration) -> ModuleMap:
        """This map extended to the virtual vertices that stay free between two configurations.

        A virtual vertex of ``source`` at one end of a mapped edge corresponds to the
        vertex at the matching end of the image edge in ``target`` when that one is
        virtual too (the connector stays free across the action).
        """
        nodes = dict(self.nodes)
        for edge_id, (image, inv) in self.edges.items():
            if edge_id not in source.edge_ids() or image not in target.edge_ids():
                continue
            for at_source in (True, False):
                here = end_vertex(source, edge_id, at_source)
                there = end_vertex(target, image, at_source != inv)
                if source.is_virtual(here) and target.is_virtual(there):
                    nodes.setdefault(here, there)
        return ModuleMap(nodes, dict(self.edges))

    def apply(self, config: Configuration, *, name: str | None = None) -> tuple[
            Configuration, ModuleMap]:
        """``config`` relabelled through this map, and the full map actually used.

        Edges mapped with ``inv`` have their ends swapped and ``z``/``x`` negated.
        Unmapped virtual vertices get fresh names from their edge
        (:func:`free_vertex_name`); an unmapped connection that is not a module keeps its
        id (fresh if taken); an unmapped module is an error.

        Raises:
            KeyError: a module (vertex or edge) of ``config`` is not mapped.
        """
        nodes = dict(self.nodes)
        taken = {v for v in nodes.values()}
        for vertex in config.vertices():
            if vertex in nodes:
                continue
            if not config.is_virtual(vertex):
                raise KeyError(f"module {vertex!r} is not mapped")
            (edge,) = config.incident(vertex)
            image, inv = self.edges.get(edge.id, (edge.id, False))
            nodes[vertex] = free_vertex_name(image, (edge.source == vertex) != inv, taken)
            taken.add(nodes[vertex])
        out = Configuration(config.robot, name=config.name if name is None else name,
                            description=config.description)
        for vertex in config.vertices():
            out.add_module(nodes[vertex], config.kind_of(vertex), position=config.position(vertex))
        edges = dict(self.edges)
        taken_edges = {e for e, _ in edges.values()}
        for edge in config.edges():
            if edge.id not in edges:
                if edge.kind is not None:
                    raise KeyError(f"module {edge.id!r} is not mapped")
                edges[edge.id] = (free_vertex_name(edge.id, True, taken_edges)
                                  if edge.id in taken_edges else edge.id, False)
                taken_edges.add(edges[edge.id][0])
            image, inv = edges[edge.id]
            source, target = nodes[edge.source], nodes[edge.target]
            z, x = edge.z, edge.x
            if inv:
                source, target = target, source
                z = None if z is None else -np.asarray(z)
                x = None if x is None else -np.asarray(x)
            ports = edge.ports[::-1] if (inv and edge.ports) else edge.ports
            out.connect(source, target, id=image, kind=edge.kind, z=z, x=x, ports=ports)
        used = {k: nodes[k] for k in config.vertices()}
        used_edges = {e: edges[e] for e in config.edge_ids()}
        return out, ModuleMap(used, used_edges)

    def to_dict(self) -> dict[str, dict]:
        """A JSON-ready form, keys sorted: ``{"nodes": {...}, "edges": {id: [id, inv]}}``."""
        return {"nodes": dict(sorted(self.nodes.items())),
                "edges": {k: [e, inv] for k, (e, inv) in sorted(self.edges.items())}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Mapping]) -> ModuleMap:
        return cls(dict(data.get("nodes", {})),
                   {k: (str(v[0]), bool(v[1])) for k, v in data.get("edges", {}).items()})
