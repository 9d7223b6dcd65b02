"""Brute-force reference: every isomorphism, its distance, sorted.

Independent of the tree search: vertex bijections come from networkx's
``MultiGraphMatcher`` (kinds must agree, parallel-edge counts are matched), and every
assignment of parallel edges that it leaves open is enumerated as a product of
permutations; direction (``inv``) and port constraints are checked per edge. Used by
tests and by ``benchmarks/iso_search.py`` as the "brute-force sorting" of the FreeSN
paper, section 7.1.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import networkx as nx
from networkx.algorithms import isomorphism

from ..configuration import Configuration
from .iso_search import mapping_from_indices
from .mapping import Mapping
from .topology import Topology, edge_inversion, signatures_match

__all__ = ["brute_force_isomorphisms", "enumerate_isomorphisms"]

IndexIsomorphism = tuple[list[int], list[tuple[int, int, bool]]]


def _graph(topology: Topology) -> nx.MultiGraph:
    graph = nx.MultiGraph()
    for i, kind in enumerate(topology.kinds):
        graph.add_node(i, kind=kind)
    for s, t in topology.ends:
        graph.add_edge(s, t)
    return graph


def _edge_assignments(system: Topology, reference: Topology, ref_of: list[int]
                      ) -> Iterator[list[tuple[int, int, bool]]]:
    """Every legal edge mapping under the vertex bijection ``ref_of``."""
    groups = []
    for (s, t) in sorted({tuple(sorted(ends)) for ends in system.ends}):
        sys_edges = system.neighbors[s][t]
        groups.append((sys_edges, reference.neighbors[ref_of[s]][ref_of[t]]))
    per_group = []
    for sys_edges, ref_edges in groups:
        options = []
        for perm in itertools.permutations(ref_edges):
            pairs = []
            for e, f in zip(sys_edges, perm, strict=True):
                inv = edge_inversion(system, e, reference, f, ref_of)
                if inv is None:
                    break
                pairs.append((e, f, inv))
            else:
                options.append(pairs)
        per_group.append(options)
    for choice in itertools.product(*per_group):
        yield [pair for pairs in choice for pair in pairs]


def _enumerate(system: Topology, reference: Topology) -> Iterator[IndexIsomorphism]:
    matcher = isomorphism.MultiGraphMatcher(
        _graph(system), _graph(reference),
        node_match=isomorphism.categorical_node_match("kind", None))
    for bijection in matcher.isomorphisms_iter():
        ref_of = [bijection[i] for i in range(len(system.vertices))]
        for edges in _edge_assignments(system, reference, ref_of):
            yield ref_of, edges


def enumerate_isomorphisms(system: Configuration, reference: Configuration
                           ) -> Iterator[tuple[dict[str, str], dict[str, tuple[str, bool]]]]:
    """Every isomorphism as ``(node map, edge map with inv)``, without distances."""
    if not signatures_match(system, reference):
        return
    sys, ref = Topology.of(system), Topology.of(reference)
    for ref_of, edges in _enumerate(sys, ref):
        yield ({sys.vertices[s]: ref.vertices[r] for s, r in enumerate(ref_of)},
               {sys.edge_ids[e]: (ref.edge_ids[f], inv) for e, f, inv in edges})


def brute_force_isomorphisms(system: Configuration, reference: Configuration, *,
                             gamma: float = 0.0) -> list[Mapping]:
    """Every isomorphism from ``system`` onto ``reference``, sorted by distance.

    Distances are ``vectorMatch`` of each complete mapping, the same function the tree
    search uses for complete mappings. Cost grows linearly with the number of
    isomorphisms; keep it to small cases and benchmarks.
    """
    if not signatures_match(system, reference):
        return []
    sys, ref = Topology.of(system), Topology.of(reference)
    found = [mapping_from_indices(sys, ref, ref_of, edges, gamma=gamma)
             for ref_of, edges in _enumerate(sys, ref)]
    return sorted(found, key=lambda m: m.distance)
