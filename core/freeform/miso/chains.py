"""Pairing when one side is made of chains: vertical paths of the other side packed into
the chains.

When every piece of the start is a chain (no module carries two; Luo and Lam's human
example starts from six), a pairing keeps a start connection exactly where a stretch of
a chain lies along a *vertical path* of the goal (each module's goal parent is the next
one up). Cutting every chain into such stretches, ``kept = n - stretches``: the fewest
changes need the fewest stretches. A rooted forest with ``L`` leaves needs at least
``L`` vertical paths (one ends at every leaf), and exactly ``L`` when every module with
children continues the path of one of them; the stretches then are those paths, cut
further only where their lengths do not add up to the chains' lengths.

:func:`chain_pairing` tries a few such covers (at every branching module the path of the
tallest child continues, or of the shortest, or of the one in the middle), packs their
paths into the chains -- for each chain, longest first, a subset of whole paths that
fills it exactly (subset-sum), and what is left laid end to end into the rest, a cut at
every chain boundary it crosses -- and returns the pairing with the fewest stretches.
Polynomial: a subset-sum of ``O(n L)`` per chain and cover. A goal made of chains is the same problem with start
and goal exchanged (a pairing and its inverse keep the same connections).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .model import FREE, MisoProblem, children_of, rooted

__all__ = ["chain_pairing", "is_chains"]


def is_chains(parent: Sequence[int]) -> bool:
    """Whether every piece is a chain: no cycle, no module carrying two."""
    carried = np.bincount([p for p in parent if p != FREE], minlength=len(parent))
    return bool(np.all(carried <= 1)) and list(rooted(parent)) == list(parent)


def chain_pairing(problem: MisoProblem) -> list[int] | None:
    """A pairing (start index -> goal index) from the best path cover, or ``None`` when
    neither side is made of chains."""
    if is_chains(problem.start):
        return _pair(problem.start, problem.goal)
    if is_chains(problem.goal):
        inverse = _pair(problem.goal, problem.start)
        pair = [0] * problem.n
        for b, a in enumerate(inverse):
            pair[a] = b
        return pair
    return None


def _chains(parent: Sequence[int]) -> list[list[int]]:
    """Each chain from its free module down, longest first (ties: smallest top)."""
    kids = children_of(parent)
    out = []
    for top in (i for i, p in enumerate(parent) if p == FREE):
        chain = [top]
        while kids[chain[-1]]:
            chain.append(kids[chain[-1]][0])
        out.append(chain)
    return sorted(out, key=lambda c: (-len(c), c[0]))


def _paths(forest: Sequence[int], choose: int) -> list[list[int]]:
    """A cover of ``forest`` by as many vertical paths as it has leaves, each top down:
    at a branching module the path of its child of ``choose`` rank by height (0 the
    tallest, -1 the shortest, 1 the middle one) continues."""
    kids = children_of(forest)
    order = [i for i, p in enumerate(forest) if p == FREE]
    for u in order:
        order.extend(kids[u])
    height = [0] * len(forest)
    for u in reversed(order):
        height[u] = 1 + max((height[k] for k in kids[u]), default=0)
    paths = []
    starts = [i for i, p in enumerate(forest) if p == FREE]
    while starts:
        path = [starts.pop()]
        while kids[path[-1]]:
            ranked = sorted(kids[path[-1]], key=lambda k: (-height[k], k))
            pick = ranked[min(choose, len(ranked) - 1) if choose >= 0 else choose]
            starts.extend(k for k in ranked if k != pick)
            path.append(pick)
        paths.append(path)
    return sorted(paths, key=lambda p: (-len(p), p[0]))


def _exact_subset(lengths: list[int], want: int) -> list[int] | None:
    """Indices of ``lengths`` adding up to ``want`` exactly (subset-sum), or ``None``."""
    reach: list[int | None] = [None] * (want + 1)   # sum -> last item index reaching it
    reach[0] = -1
    came: list[int] = [0] * (want + 1)
    for i, size in enumerate(lengths):
        for s in range(want, size - 1, -1):
            if reach[s] is None and reach[s - size] is not None:   # items before i
                reach[s], came[s] = i, s - size
    if reach[want] is None:
        return None
    picked, s = [], want
    while s:
        picked.append(reach[s])
        s = came[s]
    return picked


def _pack(chains: list[list[int]], paths: list[list[int]]) -> list[int]:
    """The goal module each chain module becomes: whole paths that fill a chain exactly
    go there; the rest are laid end to end over the chains left."""
    left = list(paths)
    fills: dict[int, list[list[int]]] = {}
    for c, chain in enumerate(chains):
        picked = _exact_subset([len(p) for p in left], len(chain))
        if picked is not None:
            fills[c] = [left[i] for i in sorted(picked)]
            left = [p for i, p in enumerate(left) if i not in picked]
    rest = [m for p in left for m in p]
    out: list[int] = []
    for c, chain in enumerate(chains):
        if c in fills:
            out.extend(m for p in fills[c] for m in p)
        else:
            out.extend(rest[:len(chain)])
            rest = rest[len(chain):]
    return out


def _pair(chained: Sequence[int], other: Sequence[int]) -> list[int]:
    """The pairing (``chained`` index -> ``other`` index) of the cover packing best."""
    chains = _chains(chained)
    order = [m for c in chains for m in c]
    forest = rooted(other)
    best, best_kept = None, -1
    for choose in (0, -1, 1):
        laid = _pack(chains, _paths(forest, choose))
        pair = [0] * len(chained)
        for a, b in zip(order, laid, strict=True):
            pair[a] = b
        kept = sum(1 for a, p in enumerate(chained) if p != FREE and other[pair[a]] == pair[p])
        if kept > best_kept:
            best, best_kept = pair, kept
    assert best is not None
    return best
