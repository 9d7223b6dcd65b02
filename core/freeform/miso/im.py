"""A reimplementation of Luo and Lam's IM heuristic, the yardstick of the benchmark.

Not msrr's planner and not the authors' code: IM as their paper and repository
describe it (``FreeformRobotics/MISO_connection``, ``IM/POINTER_Pairing.py``), rewritten
from that description so the benchmark compares against it in the same run, and one
of the candidates of :func:`~.pairing.heuristic_pairing` (which so never keeps fewer
connections than IM):

1. Each configuration becomes a rooted forest: free modules are roots; in what is
   left, the walk along connectors from the lowest unvisited module reaches a module
   twice -- its connection is cut and it becomes a root.
2. A module's *CNL* lists its children's subtree sizes; its *pointer* reads as one
   integer the digits of its CNL (lists ``[0]`` and ``[1]`` left out) followed by its
   children's pointers, children by increasing subtree size, equal sizes by increasing
   pointer.
3. Rounds: a virtual ground carries the roots of what is still unpaired on each side;
   the two grounds pair, and top-down every paired couple's children are paired by a
   minimum-weight full matching whose weights are the ranks of ``|pointer(a) -
   pointer(b)|``. What is left unpaired goes to the next round.

The cost is Luo and Lam's: connections broken plus made, ``|E_I| + |E_F| - 2 kept``
(:func:`~.model.changes`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from .model import FREE, MisoProblem, children_of

__all__ = ["im_pairing"]


def _forest(parent: Sequence[int]) -> list[int]:
    """Free modules are roots; each cycle is cut where the walk from the lowest
    unvisited module first repeats."""
    n = len(parent)
    cut = list(parent)
    children = children_of(parent)
    seen = [False] * n

    def visit(root: int) -> None:
        stack = [root]
        while stack:
            u = stack.pop()
            seen[u] = True
            stack.extend(c for c in children[u] if c != root)

    for s in range(n):
        if parent[s] == FREE:
            visit(s)
    for s in range(n):
        if not seen[s]:
            walk, j = set(), s
            while j not in walk:
                walk.add(j)
                j = parent[j]
            cut[j] = FREE
            visit(j)
    return cut


def _pointers(forest: Sequence[int]) -> list[int]:
    children = children_of(forest)
    order, stack = [], [i for i, p in enumerate(forest) if p == FREE]
    while stack:
        u = stack.pop()
        order.append(u)
        stack.extend(children[u])
    size = [1] * len(forest)
    digits: list[str] = [""] * len(forest)
    for u in reversed(order):
        cnl = [size[c] for c in children[u]]
        size[u] += sum(cnl)
        own = "".join(str(k) for k in sorted(cnl)) if len(cnl) > 1 else (
            str(cnl[0]) if cnl and cnl[0] > 1 else "")
        kids = sorted(children[u], key=lambda c: (size[c], int(digits[c] or "0")))
        digits[u] = own + "".join(digits[c] for c in kids)
    return [int(d or "0") for d in digits]


def im_pairing(problem: MisoProblem) -> list[int]:
    """IM's pairing (start index -> goal index), reimplemented (module docstring)."""
    n = problem.n
    fa, fb = _forest(problem.start), _forest(problem.goal)
    ka, kb = children_of(fa), children_of(fb)
    sa, sb = _pointers(fa), _pointers(fb)
    pair, inv = [FREE] * n, [FREE] * n
    while FREE in pair:
        ua = [u for u in range(n) if pair[u] == FREE and (fa[u] == FREE or pair[fa[u]] != FREE)]
        ub = [v for v in range(n) if inv[v] == FREE and (fb[v] == FREE or inv[fb[v]] != FREE)]
        stack = _match(ua, ub, sa, sb)
        while stack:
            a, b = stack.pop()
            pair[a], inv[b] = b, a
            ca = [c for c in ka[a] if pair[c] == FREE]
            cb = [c for c in kb[b] if inv[c] == FREE]
            if ca and cb:
                stack.extend(_match(ca, cb, sa, sb))
    return pair


def _match(us: list[int], vs: list[int], sa: list[int], sb: list[int]
           ) -> list[tuple[int, int]]:
    if not us or not vs:
        return []
    gaps = sorted({abs(sa[u] - sb[v]) for u in us for v in vs})
    rank = {g: k for k, g in enumerate(gaps)}
    weight = np.array([[rank[abs(sa[u] - sb[v])] for v in vs] for u in us], dtype=np.float64)
    rows, cols = linear_sum_assignment(weight)
    return [(us[r], vs[c]) for r, c in zip(rows, cols, strict=True)]
