"""Certified optimum for larger systems: an integer program over the face-product graph.

Not part of the paper: the reference the benchmark measures the hybrid planner
against beyond the 9 modules of the exhaustive :func:`~msrr.plugins.mmrp.optimum.optimum`.

Minimising dock/undock pairs means maximising the start connections
``connect(uF_u, vF_v)`` whose image ``connect(f(u)F_u, f(v)F_v)`` is a goal
connection. A kept connection pairs a start connection with a goal connection of
the same faces, which fixes the images of both ends: the edge ``(u, f(u))``-``(v,
f(v))`` of the face-product graph. So, with a binary ``x[a, b]`` for every product
pair that lies on a product edge (a maps to b) and ``y[e]`` for every product edge:

    maximise   sum_e y[e]
    subject to sum_b x[a, b] <= 1 for every start module a,
               sum_a x[a, b] <= 1 for every goal module b,
               y[e] <= x[p], y[e] <= x[q] for the two ends p, q of e,
               sum of y over the product edges of one start connection <= 1,
               sum of y over the product edges of one goal connection <= 1,
               x binary, 0 <= y <= 1.

Any partial matching x extends to a bijection (unmatched modules paired in order)
without losing a kept connection, so the optimum of the program is the optimum over
bijections. Solved by HiGHS through :func:`scipy.optimize.milp`; the result is
certified when HiGHS proves optimality within the time limit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

from msrr.core import Configuration
from msrr.core.errors import PlanningError

from .representation import FaceLinks, face_links

__all__ = ["CertifiedOptimum", "certified_optimum"]


@dataclass(frozen=True)
class CertifiedOptimum:
    """The best bijection found and what HiGHS proved about it.

    Attributes:
        mapping: start id -> goal id.
        kept: connections the mapping keeps.
        pairs: dock/undock pairs, ``|E_g| - kept``.
        bound: proven lower bound on the pairs of any bijection.
        certified: ``pairs == bound`` (optimality proven within the time limit).
        seconds: solver wall time [s].
        nodes: branch-and-bound nodes HiGHS explored.
    """

    mapping: dict[str, str]
    kept: int
    pairs: int
    bound: int
    certified: bool
    seconds: float
    nodes: int


_Edge = tuple[str, str, str, str]
"""A connection ``(u, F_u, v, F_v)``, named from its T or L end."""


def _oriented(links: FaceLinks) -> list[_Edge]:
    """Every connection once, from its T or L end."""
    return [(u, f, v, f2) for u in links for f, (v, f2) in links[u].items() if f in "TL"]


@dataclass(frozen=True)
class _ProductGraph:
    """The face-product graph's pairs that lie on a product edge, and its edges.

    Attributes:
        pairs: ``(a, b)`` (start module a maps to goal module b) -> column of ``x``.
        edges: ``(start edge, goal edge, pair p, pair q)``, one per column of ``y``.
    """

    pairs: dict[tuple[str, str], int]
    edges: list[tuple[int, int, int, int]]


def _product(edges_c: list[_Edge], edges_g: list[_Edge]) -> _ProductGraph:
    """Pair every start connection with every goal connection of the same faces."""
    by_faces: dict[tuple[str, str], list[int]] = {}
    for k, (_, f, _, f2) in enumerate(edges_g):
        by_faces.setdefault((f, f2), []).append(k)
    pair_index: dict[tuple[str, str], int] = {}
    product: list[tuple[int, int, int, int]] = []
    for i, (u, f, v, f2) in enumerate(edges_c):
        for k in by_faces.get((f, f2), ()):
            p_, _, q_, _ = edges_g[k]
            p = pair_index.setdefault((u, p_), len(pair_index))
            q = pair_index.setdefault((v, q_), len(pair_index))
            product.append((i, k, p, q))
    return _ProductGraph(pair_index, product)


def _constraints(graph: _ProductGraph) -> LinearConstraint:
    """The program's rows (module doc): each module mapped once, ``y`` under both ends'
    ``x``, each start and each goal connection kept once."""
    n_x, n_y = len(graph.pairs), len(graph.edges)
    rows, cols, vals, lower, upper = [], [], [], [], []

    def row(entries: list[tuple[int, float]], lo: float, hi: float) -> None:
        r = len(lower)
        for col, val in entries:
            rows.append(r)
            cols.append(col)
            vals.append(val)
        lower.append(lo)
        upper.append(hi)

    by_c: dict[str, list[int]] = {}
    by_g: dict[str, list[int]] = {}
    for (a, b), p in graph.pairs.items():
        by_c.setdefault(a, []).append(p)
        by_g.setdefault(b, []).append(p)
    for group in (*by_c.values(), *by_g.values()):
        if len(group) > 1:
            row([(p, 1.0) for p in group], -np.inf, 1.0)
    per_c: dict[int, list[int]] = {}
    per_g: dict[int, list[int]] = {}
    for e, (i, k, p, q) in enumerate(graph.edges):
        row([(n_x + e, 1.0), (p, -1.0)], -np.inf, 0.0)
        row([(n_x + e, 1.0), (q, -1.0)], -np.inf, 0.0)
        per_c.setdefault(i, []).append(n_x + e)
        per_g.setdefault(k, []).append(n_x + e)
    for group in (*per_c.values(), *per_g.values()):
        if len(group) > 1:
            row([(col, 1.0) for col in group], -np.inf, 1.0)
    matrix = coo_matrix((vals, (rows, cols)), shape=(len(lower), n_x + n_y)).tocsr()
    return LinearConstraint(matrix, lower, upper)


@dataclass(frozen=True)
class _Solution:
    """What HiGHS returned: the pairs it maps, a proven bound on the kept connections,
    the branch-and-bound nodes and whether it proved optimality."""

    kept_pairs: list[tuple[str, str]]
    bound_kept: int
    nodes: int
    certified: bool


def _solve(graph: _ProductGraph, goal_edges: int, time_limit: float) -> _Solution:
    """Maximise the kept connections ``sum y`` with HiGHS (binary ``x``, ``0 <= y <= 1``)."""
    n_x, n_y = len(graph.pairs), len(graph.edges)
    cost = np.concatenate([np.zeros(n_x), -np.ones(n_y)])
    result = milp(cost, constraints=_constraints(graph),
                  integrality=np.concatenate([np.ones(n_x), np.zeros(n_y)]),
                  bounds=Bounds(0.0, 1.0),
                  options={"time_limit": float(time_limit), "disp": False})
    if result.x is None:
        raise PlanningError(f"the integer program found no solution ({result.message})")
    dual = getattr(result, "mip_dual_bound", None)
    bound_kept = int(np.floor(-dual + 1e-6)) if dual is not None and np.isfinite(dual) \
        else goal_edges
    pairs_by_index = {p: ab for ab, p in graph.pairs.items()}
    return _Solution([pairs_by_index[p] for p in range(n_x) if result.x[p] > 0.5], bound_kept,
                     int(getattr(result, "mip_node_count", 0) or 0), result.status == 0)


def _bijection(kept_pairs: list[tuple[str, str]], modules_c: list[str], modules_g: list[str]
               ) -> dict[str, str]:
    """The matched pairs, the unmatched modules paired in order (no kept connection lost)."""
    mapping: dict[str, str] = {}
    used: set[str] = set()
    for a, b in kept_pairs:
        if a not in mapping and b not in used:
            mapping[a] = b
            used.add(b)
    rest = iter(b for b in modules_g if b not in used)
    for a in modules_c:
        if a not in mapping:
            mapping[a] = next(rest)
    return mapping


def certified_optimum(start: Configuration, goal: Configuration, *,
                      time_limit: float = 60.0) -> CertifiedOptimum:
    """The bijection start -> goal that keeps the most connections, by integer programming.

    Args:
        start: the start configuration.
        goal: the goal configuration, same number of modules.
        time_limit: HiGHS time limit [s]; past it the best mapping found is returned
            with ``certified=False``.

    Raises:
        PlanningError: module counts differ.
    """
    modules_c, modules_g = start.vertices(), goal.vertices()
    if len(modules_c) != len(modules_g):
        raise PlanningError(f"start has {len(modules_c)} modules and goal {len(modules_g)}")
    links_c, links_g = face_links(start), face_links(goal)
    edges_c, edges_g = _oriented(links_c), _oriented(links_g)
    graph = _product(edges_c, edges_g)
    began = time.perf_counter()
    solution = _solve(graph, len(edges_g), time_limit) if graph.edges else \
        _Solution([], 0, 0, True)
    mapping = _bijection(solution.kept_pairs, modules_c, modules_g)
    kept = sum(links_g[mapping[u]].get(f) == (mapping[v], f2) for u, f, v, f2 in edges_c)
    certified = solution.certified
    bound_kept = kept if certified else solution.bound_kept
    pairs = len(edges_g) - kept
    bound = len(edges_g) - max(bound_kept, kept) if not certified else pairs
    return CertifiedOptimum(mapping, kept, pairs, bound, pairs == bound,
                            time.perf_counter() - began, solution.nodes)
