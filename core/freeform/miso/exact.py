"""Exact pairing by integer programming, and brute-force references for tests.

:func:`exact_pairing` solves, with ``scipy.optimize.milp`` (HiGHS branch and cut), the
pairing that keeps the most connections -- so the fewest connection changes -- and,
among those, pairs the most free modules with free ones (the fewest mismatches ``d``).
Variables: ``x[a, b] = 1`` when start module ``a`` becomes goal module ``b``
(an assignment), and ``y[i, b] <= x[i, b]`` for every held start connector ``i`` and
held goal connector ``b``: ``i``'s connection is kept as ``b``'s. A kept connection needs
the parents paired too; summing over the goal children of a goal module ``q`` (one of
them at most is ``i``'s partner) and over the start children of ``p``::

    sum_{b : parent_goal(b) = q} y[i, b] <= x[parent(i), q]     for every i, q
    sum_{i : parent(i) = p}      y[i, b] <= x[p, parent_goal(b)] for every b, p

Objective: ``max (n + 1) sum y + sum_{a free, b free} x[a, b]`` -- every kept
connection outweighs all free pairs, so the optimum is lexicographic.
"""

from __future__ import annotations

import itertools
import time

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

from ...errors import PlanningError
from .model import (
    FREE,
    MisoProblem,
    canonical_form,
    changes,
    children_of,
    pairing_score,
    step_is_legal,
    targets,
)

__all__ = ["ExactPairing", "brute_force_changes", "brute_force_steps", "exact_pairing"]


class ExactPairing:
    """The result of :func:`exact_pairing`.

    Attributes:
        pair: goal index of every start module.
        proved: HiGHS proved the optimum (within ``time_limit``).
        ms: solver wall time [ms].
    """

    def __init__(self, pair: list[int], proved: bool, ms: float):
        self.pair, self.proved, self.ms = pair, proved, ms


def exact_pairing(problem: MisoProblem, *, time_limit: float = 60.0,
                  start: list[int] | None = None) -> ExactPairing:
    """The pairing with the fewest connection changes, then the most free-free pairs.

    Args:
        problem: the instance.
        time_limit: seconds HiGHS may take; past it the best pairing found (or
            ``start``, if better) is returned with ``proved=False``.
        start: a known pairing (the heuristic's), kept when HiGHS finds none better.
    """
    t0 = time.perf_counter()
    n, pa, pb = problem.n, problem.start, problem.goal
    ca, cb = children_of(pa), children_of(pb)
    held_a = [i for i in range(n) if pa[i] != FREE]
    held_b = [b for b in range(n) if pb[b] != FREE]
    nx_ = n * n
    yi = {(i, b): nx_ + k for k, (i, b) in enumerate(itertools.product(held_a, held_b))}
    nv = nx_ + len(yi)
    rows, cols, vals, lo, hi = [], [], [], [], []
    r = 0

    def row(entries: list[tuple[int, float]], low: float, high: float) -> None:
        nonlocal r
        for c, v in entries:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        lo.append(low)
        hi.append(high)
        r += 1

    for a in range(n):
        row([(a * n + b, 1.0) for b in range(n)], 1, 1)
    for b in range(n):
        row([(a * n + b, 1.0) for a in range(n)], 1, 1)
    for (i, b), k in yi.items():
        row([(k, 1.0), (i * n + b, -1.0)], -np.inf, 0)
    for i in held_a:
        for q in range(n):
            if cb[q]:
                row([(yi[(i, b)], 1.0) for b in cb[q]] + [(pa[i] * n + q, -1.0)], -np.inf, 0)
    for b in held_b:
        for p in range(n):
            if ca[p]:
                row([(yi[(i, b)], 1.0) for i in ca[p]] + [(p * n + pb[b], -1.0)], -np.inf, 0)
    c = np.zeros(nv)
    c[nx_:] = -(n + 1.0)
    for a in range(n):
        if pa[a] == FREE:
            for b in range(n):
                if pb[b] == FREE:
                    c[a * n + b] = -1.0
    matrix = coo_matrix((vals, (rows, cols)), shape=(r, nv)).tocsr()
    result = milp(c, constraints=LinearConstraint(matrix, lo, hi), integrality=np.ones(nv),
                  bounds=Bounds(0, 1), options={"time_limit": time_limit, "mip_rel_gap": 0.0,
                                                "disp": False})
    ms = 1e3 * (time.perf_counter() - t0)
    if result.x is None:
        if start is None:
            raise PlanningError(f"exact MISO pairing: HiGHS found no pairing ({result.message})")
        return ExactPairing(list(start), False, ms)
    x = np.asarray(result.x[:nx_]).reshape(n, n)
    pair = [int(b) for b in np.argmax(x, axis=1)]
    proved = result.status == 0
    if start is not None and pairing_score(problem, start) > pairing_score(problem, pair):
        pair = list(start)
    return ExactPairing(pair, proved, ms)


def brute_force_changes(problem: MisoProblem) -> int:
    """The fewest connection changes over every pairing (small ``n``): the reference for
    :func:`exact_pairing`."""
    if problem.n > 8:
        raise PlanningError("brute force over pairings is for at most 8 modules")
    return min(changes(problem.start, targets(problem, list(perm)))
               for perm in itertools.permutations(range(problem.n)))


def brute_force_steps(problem: MisoProblem, max_steps: int = 10) -> int:
    """The fewest legal steps to any configuration isomorphic to the goal, by
    breadth-first search over labelled configurations (small ``n``)."""
    target = canonical_form(problem.goal)
    n, limits = problem.n, problem.limits
    origin = tuple(problem.start)
    if canonical_form(origin) == target:
        return 0
    seen, frontier = {origin}, [origin]
    for depth in range(1, max_steps + 1):
        nxt = []
        for state in frontier:
            for i in range(n):
                for k in range(FREE, n):
                    if not step_is_legal(state, i, k, limits):
                        continue
                    new = list(state)
                    new[i] = k
                    key = tuple(new)
                    if key in seen:
                        continue
                    if canonical_form(key) == target:
                        return depth
                    seen.add(key)
                    nxt.append(key)
        frontier = nxt
    raise PlanningError(f"no MISO plan within {max_steps} steps")
