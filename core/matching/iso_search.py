"""Isomorphism tree search: module mappings in ascending distance (FreeSN paper, Alg. 2-3).

A best-first search over partial mappings. A tree node holds the node mapping so far,
the edge mapping with ``inv`` flags, and running sums of its distance bound. Children
either map the next system vertex in VF2++ order onto a feasible reference vertex
(same label, same multiplicities towards the mapped neighbours), or, when mapped
vertices are joined by parallel edges (FreeSN struts between the same nodes), assign
the next of those edges; single edges and free struts (edges to virtual vertices) are
mapped with their vertex. Ports (MMRP faces) are hard constraints.

The queue key of a partial mapping is an admissible lower bound of the eq. 8 distance of
the mapped sub-configuration (:class:`~msrr.core.matching.distance.PartialBound`); a
complete mapping is keyed by its exact distance from ``vectorMatch``
(:func:`~msrr.core.matching.distance.vector_match`, computed lazily when the mapping
is first popped). Because a completion's distance is never below the bound of any of
its prefixes, mappings come out in ascending distance: the first is a minimum.
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..configuration import Configuration
from .cost import MatchingError
from .distance import PartialBound, bound_terms, elevation, vector_match
from .mapping import Mapping
from .topology import Topology, edge_inversion, signatures_match, vf2pp_order

__all__ = ["iso_search", "mapping_from_indices"]

DEADLINE_CHECK_EVERY = 64


@dataclass(frozen=True, slots=True)
class _Node:
    """One node of the isomorphism tree (the ``Lambda`` of Alg. 3)."""

    depth: int                                   # system vertices mapped, in VF2++ order
    ref_of: tuple[int, ...]                      # system vertex -> reference vertex or -1
    used: int                                    # bitmask of used reference vertices
    edges: tuple[tuple[int, int, bool], ...]     # (system edge, reference edge, inv)
    pending: tuple[tuple[tuple[int, ...], tuple[int, ...]], ...]  # parallel groups left
    bound: PartialBound


def mapping_from_indices(system: Topology, reference: Topology, ref_of: list[int] | tuple,
                         edges: list[tuple[int, int, bool]] | tuple, *,
                         gamma: float = 0.0) -> Mapping:
    """The :class:`Mapping` of an index-level isomorphism, with its eq. 8 distance.

    The distance is ``vectorMatch`` over the edges, in system edge order, that have ``z``
    on both sides; the brute force uses the same function, so the two agree exactly.
    """
    image = sorted(edges)
    e_idx = np.array([e for e, _, _ in image], dtype=int)
    f_idx = np.array([f for _, f, _ in image], dtype=int)
    sign = np.array([-1.0 if inv else 1.0 for _, _, inv in image])
    z_sys, z_ref = system.z[e_idx], reference.z[f_idx] * sign[:, None]
    keep = ~(np.isnan(z_sys).any(axis=1) | np.isnan(z_ref).any(axis=1))
    x_sys, x_ref = system.x[e_idx][keep], reference.x[f_idx][keep]
    use_x = gamma > 0 and keep.any() and not (np.isnan(x_sys).any() or np.isnan(x_ref).any())
    fit = vector_match(z_sys[keep].T, z_ref[keep].T,
                       x_sys=x_sys.T if use_x else None, x_ref=x_ref.T if use_x else None,
                       gamma=gamma if use_x else 0.0)
    return Mapping(
        nodes={system.vertices[s]: reference.vertices[r] for s, r in enumerate(ref_of)},
        edges={system.edge_ids[e]: (reference.edge_ids[f], inv) for e, f, inv in image},
        distance=fit.cost, yaw=fit.theta, rms_angle=fit.rms_angle)


def _vectors(z: np.ndarray) -> list[tuple[float, float, float] | None]:
    """Rows of ``z`` as float tuples, None where an edge has no vector."""
    return [None if np.isnan(row).any() else (float(row[0]), float(row[1]), float(row[2]))
            for row in z]


class _Search:
    """The state shared by the expansions of one search (Alg. 2 lines 1-9)."""

    def __init__(self, system: Topology, reference: Topology, gamma: float):
        self.sys, self.ref = system, reference
        self.gamma = gamma
        self.order = vf2pp_order(self.sys, self.ref)
        self.by_label: dict[tuple, list[int]] = {}
        for r, label in enumerate(self.ref.labels):
            self.by_label.setdefault(label, []).append(r)
        self.z_sys = _vectors(self.sys.z)
        self.z_ref = _vectors(self.ref.z)
        self.z_ref_neg = [None if z is None else (-z[0], -z[1], -z[2]) for z in self.z_ref]
        self.elev_sys = [None if z is None else elevation(z) for z in self.z_sys]
        self.elev_ref = [None if z is None else elevation(z) for z in self.z_ref]

    def root(self) -> _Node:
        return _Node(0, (-1,) * len(self.sys.vertices), 0, (), (), PartialBound())

    def _with_edge(self, bound: PartialBound, e: int, f: int, inv: bool) -> PartialBound:
        z_sys, z_ref = self.z_sys[e], (self.z_ref_neg if inv else self.z_ref)[f]
        if z_sys is None or z_ref is None:
            return bound
        elev_ref = -self.elev_ref[f] if inv else self.elev_ref[f]
        return bound.add(bound_terms(z_sys, z_ref, self.elev_sys[e], elev_ref))

    def feasible_candidates(self, node: _Node, u: int) -> list[int]:
        """Reference vertices ``u`` may map to (``feasibleCandidates``, Alg. 2 line 18)."""
        sys_nb, ref_of = self.sys.neighbors[u], node.ref_of
        wanted = {ref_of[w]: len(ks) for w, ks in sys_nb.items() if ref_of[w] >= 0}
        out = []
        for c in self.by_label.get(self.sys.labels[u], ()):
            if node.used >> c & 1:
                continue
            got = {x: len(ks) for x, ks in self.ref.neighbors[c].items() if node.used >> x & 1}
            if got == wanted:
                out.append(c)
        return out

    def map_vertex(self, node: _Node, u: int, c: int) -> _Node | None:
        """Extend ``node`` with ``u -> c`` and the edges it closes (``subConfigMatch``, Alg. 3)."""
        ref_of = list(node.ref_of)
        ref_of[u] = c
        edges, pending, bound = list(node.edges), list(node.pending), node.bound
        for w, sys_edges in self.sys.neighbors[u].items():
            if ref_of[w] < 0 or w == u:
                continue
            ref_edges = self.ref.neighbors[c][ref_of[w]]
            if len(sys_edges) > 1:
                pending.append((sys_edges, ref_edges))
                continue
            e, f = sys_edges[0], ref_edges[0]
            inv = edge_inversion(self.sys, e, self.ref, f, ref_of)
            if inv is None:
                return None
            edges.append((e, f, inv))
            bound = self._with_edge(bound, e, f, inv)
        return _Node(node.depth + 1, tuple(ref_of), node.used | (1 << c), tuple(edges),
                     tuple(pending), bound)

    def children(self, node: _Node) -> Iterator[_Node]:
        """Every child of ``node`` in the isomorphism tree."""
        if node.pending:
            (sys_edges, ref_edges), rest = node.pending[0], node.pending[1:]
            e = sys_edges[0]
            for f in ref_edges:
                inv = edge_inversion(self.sys, e, self.ref, f, node.ref_of)
                if inv is None:
                    continue
                left = tuple(g for g in ref_edges if g != f)
                group = ((sys_edges[1:], left),) if len(sys_edges) > 1 else ()
                yield _Node(node.depth, node.ref_of, node.used, (*node.edges, (e, f, inv)),
                            group + rest, self._with_edge(node.bound, e, f, inv))
            return
        u = self.order[node.depth]
        for c in self.feasible_candidates(node, u):
            child = self.map_vertex(node, u, c)
            if child is not None:
                yield child

    def complete(self, node: _Node) -> bool:
        return node.depth == len(self.order) and not node.pending


def iso_search(system: Configuration, reference: Configuration, *, gamma: float = 0.0,
               deadline: float | None = None,
               clock: Callable[[], float] = time.monotonic) -> Iterator[Mapping]:
    """Isomorphisms from ``system`` onto ``reference`` in ascending distance (Alg. 2).

    Non-isomorphic pairs are rejected by signature first (Alg. 2 lines 2-7). The
    generator is lazy: stop after the first mapping (a minimum-distance one) or keep
    iterating; run to exhaustion it yields every isomorphism once.

    Args:
        system: the current configuration.
        reference: the configuration to map onto.
        gamma: weight of forward vectors in the distance (0: skeletal, as for FreeSN).
        deadline: an instant of ``clock`` after which the search stops.
        clock: the time source of ``deadline`` (:func:`time.monotonic`).

    Yields:
        :class:`Mapping` objects with non-decreasing :attr:`Mapping.distance`.

    Raises:
        MatchingError: a connection that is a module (a strut) has no ``z``: eq. 8
            cannot be evaluated, and counting it as distance 0 would be a lie.
    """
    for which, config in (("system", system), ("reference", reference)):
        for edge in config.edges():
            if edge.kind is not None and edge.z is None:
                raise MatchingError(f"{which} {config.name or config.robot}: connection "
                                    f"{edge.id} ({edge.kind}) has no z; the distance (eq. 8) "
                                    "needs one")
    sys_view, ref_view = Topology.of(system), Topology.of(reference)
    if not signatures_match(sys_view, ref_view):
        return
    search = _Search(sys_view, ref_view, gamma)
    tie = itertools.count()
    queue: list[tuple[float, int, _Node, Mapping | None]] = [
        (0.0, next(tie), search.root(), None)]
    pops = 0
    while queue:
        pops += 1
        if deadline is not None and (pops - 1) % DEADLINE_CHECK_EVERY == 0 \
                and clock() > deadline:
            return
        key, _, node, mapping = heapq.heappop(queue)
        if mapping is not None:
            yield mapping
        elif search.complete(node):
            mapping = mapping_from_indices(search.sys, search.ref, node.ref_of, node.edges,
                                           gamma=gamma)
            heapq.heappush(queue, (mapping.distance, next(tie), node, mapping))
        else:
            for child in search.children(node):
                heapq.heappush(queue, (max(key, child.bound.value()), next(tie), child, None))
