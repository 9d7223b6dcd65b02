"""Indexed undirected views of configurations, shared by the search and the brute force.

Everything the isomorphism search needs about one configuration, computed once:
vertex kinds and degrees, neighbour multiplicities (parallel edges), the VF2++ node
order and the edge compatibility rule (kinds, directions with ``inv``, ports as hard
constraints). FreeSN paper, Alg. 2 lines 1-7 (signature rejection) and the
``undirected``, ``nextNode`` and ``feasibleCandidates`` functions.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from ..configuration import Configuration

__all__ = ["Topology", "edge_inversion", "signatures_match", "vf2pp_order"]


def signatures_match(system: Configuration | Topology, reference: Configuration | Topology
                     ) -> bool:
    """Whether module counts and ordered degrees agree (Alg. 2 lines 2-7).

    Given two :class:`Topology` views it compares the stronger invariant they carry (the
    multisets of vertex labels and of edge kinds), which implies equal signatures.
    """
    if isinstance(system, Topology) and isinstance(reference, Topology):
        return (system.label_counts() == reference.label_counts()
                and Counter(system.edge_kinds) == Counter(reference.edge_kinds))
    if isinstance(system, Topology) or isinstance(reference, Topology):
        raise TypeError("compare two configurations or two topologies")
    return system.signature() == reference.signature()


@dataclass(frozen=True)
class Topology:
    """An indexed undirected multigraph view of a configuration.

    Attributes:
        config: the configuration.
        vertices: vertex ids; a vertex's index is its position here.
        kinds: vertex kinds, by index.
        degrees: vertex degrees (parallel edges counted), by index.
        neighbors: per vertex, ``{neighbour index: edge indices between them}``.
        edge_ids: edge ids; an edge's index is its position here.
        ends: ``(source index, target index)`` per edge.
        edge_kinds: edge kinds per edge.
        ports: ``(source port, target port)`` or None per edge.
        z: connection vectors, shape (n_edges, 3), NaN where an edge has none.
        x: forward vectors, shape (n_edges, 3), NaN where an edge has none.
        labels: per vertex, a label invariant under isomorphism (kind, degree and the
            sorted kinds, degrees and multiplicities of its neighbours).
    """

    config: Configuration
    vertices: tuple[str, ...]
    kinds: tuple[str, ...]
    degrees: tuple[int, ...]
    neighbors: tuple[dict[int, tuple[int, ...]], ...]
    edge_ids: tuple[str, ...]
    ends: tuple[tuple[int, int], ...]
    edge_kinds: tuple[str | None, ...]
    ports: tuple[tuple[str, str] | None, ...]
    z: np.ndarray
    x: np.ndarray
    labels: tuple[tuple, ...]

    @classmethod
    def of(cls, config: Configuration) -> Topology:
        """Build the view of ``config``."""
        vertices = tuple(config.vertices())
        index = {v: i for i, v in enumerate(vertices)}
        edges = config.edges()
        neighbors: list[dict[int, list[int]]] = [{} for _ in vertices]
        for k, e in enumerate(edges):
            s, t = index[e.source], index[e.target]
            neighbors[s].setdefault(t, []).append(k)
            neighbors[t].setdefault(s, []).append(k)
        kinds = tuple(config.kind_of(v) for v in vertices)
        degrees = tuple(config.degree(v) for v in vertices)
        labels = tuple(
            (kinds[i], degrees[i],
             tuple(sorted((kinds[j], degrees[j], len(ks)) for j, ks in neighbors[i].items())))
            for i in range(len(vertices)))

        def stack(attribute: str) -> np.ndarray:
            rows = [getattr(e, attribute) for e in edges]
            return np.array([r if r is not None else (np.nan,) * 3 for r in rows],
                            dtype=np.float64).reshape(len(edges), 3)

        return cls(config, vertices, kinds, degrees,
                   tuple({j: tuple(ks) for j, ks in nb.items()} for nb in neighbors),
                   tuple(e.id for e in edges), tuple((index[e.source], index[e.target])
                                                     for e in edges),
                   tuple(e.kind for e in edges), tuple(e.ports for e in edges),
                   stack("z"), stack("x"), labels)

    def label_counts(self) -> Counter:
        """How many vertices carry each label."""
        return Counter(self.labels)


def edge_inversion(system: Topology, e: int, reference: Topology, f: int,
                   ref_of: dict[int, int] | list[int]) -> bool | None:
    """``inv`` of mapping system edge ``e`` onto reference edge ``f``, or None if illegal.

    The ends of ``e`` must already be mapped (``ref_of``: system vertex index -> reference
    vertex index). ``inv`` is true when the mapped edge points the other way (Alg. 3 line
    8); kinds must agree and ports are hard constraints: equal, or swapped when inverted.

    Args:
        system: the system view.
        e: system edge index.
        reference: the reference view.
        f: reference edge index.
        ref_of: the node mapping.
    """
    if system.edge_kinds[e] != reference.edge_kinds[f]:
        return None
    s, t = system.ends[e]
    ends = (ref_of[s], ref_of[t])
    if ends == reference.ends[f]:
        inv = False
    elif ends[::-1] == reference.ends[f]:
        inv = True
    else:
        return None
    p, q = system.ports[e], reference.ports[f]
    if (p is None) != (q is None):
        return None
    if p is not None and q is not None and p != (q[::-1] if inv else q):
        return None
    return inv


def vf2pp_order(system: Topology, reference: Topology) -> list[int]:
    """The VF2++ matching order of the system's vertices (``nextNode``, Alg. 2 line 17).

    Each connected component is ordered breadth first from its vertex with the rarest
    label in the reference and the highest degree; inside a BFS level the vertex with the
    most already-ordered neighbours goes first, then the higher degree, then the rarer
    label (Juettner and Madarasi 2018).
    """
    rarity = reference.label_counts()
    remaining = set(range(len(system.vertices)))
    order: list[int] = []
    placed: set[int] = set()
    while remaining:
        root = min(remaining, key=lambda v: (rarity[system.labels[v]], -system.degrees[v], v))
        level, seen = [root], {root}
        while level:
            pending = list(level)
            while pending:
                best = max(pending, key=lambda v: (
                    sum(1 for w in system.neighbors[v] if w in placed), system.degrees[v],
                    -rarity[system.labels[v]], -v))
                pending.remove(best)
                order.append(best)
                placed.add(best)
                remaining.discard(best)
            nxt = []
            for v in level:
                for w in sorted(system.neighbors[v]):
                    if w not in seen:
                        seen.add(w)
                        nxt.append(w)
            level = nxt
    return order
