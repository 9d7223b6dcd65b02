"""The heuristic pairing: which goal module each start module becomes.

Modules are identical, so a plan is a pairing ``pi`` (start module -> goal module) and
steps. A connection ``i -> p`` of the start is *kept* when the goal relabelled by
``pi^-1`` holds it too; Luo and Lam's metric, connections broken plus made, is
``|E_start| + |E_goal| - 2 kept``, so the pairing maximises ``kept`` (and, second,
pairs free modules with free ones: each such pair saves a step).

:func:`heuristic_pairing` (polynomial, module docstring of :mod:`msrr.core.freeform.miso`):

1. *Rounds of top-down alignment.* Cycles are cut before their smallest module, so
   both configurations are rooted forests. Each round takes the *fragments* -- the
   maximal groups of still unpaired modules, rooted where the parent is paired or
   free -- and pairs fragment roots: first, for every paired ``(p, q)``, the unpaired
   children of ``p`` with those of ``q`` (a kept connection each), then the remaining
   roots largest first. Each paired couple is aligned top-down: the children of both
   matched by a maximum-weight assignment (``scipy.optimize.linear_sum_assignment``)
   of ``1 + s(a, b)``, where ``s`` estimates the connections an alignment of the two
   subtrees keeps from their level profiles (``sum_k min(L_a(k), L_b(k))`` over the
   first ``PROFILE_DEPTH`` levels, then the smaller remainder: an upper bound that is
   exact for chains), and down the matched pairs; chains are walked without
   assignments.
2. *Swaps.* Local search on the pairing: a start module whose connection is not kept
   trades partners with the module paired to a goal child of its parent's partner when
   that keeps more connections (counted on both modules' connections in and out), until
   no swap gains.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from .model import FREE, MisoProblem, children_of, rooted, targets

__all__ = ["PROFILE_DEPTH", "heuristic_pairing", "improve_by_swaps"]

PROFILE_DEPTH = 8
"""Levels of a subtree's profile the alignment estimate compares one by one."""


class _Fragments:
    """The still unpaired part of one rooted forest, with level profiles (one row per
    module: how many unpaired modules lie 1, 2, ... ``PROFILE_DEPTH`` levels below it,
    then deeper) for the alignment estimate."""

    def __init__(self, forest: Sequence[int], kids: list[list[int]], unpaired: list[bool]):
        self.kids = [[c for c in ks if unpaired[c]] if unpaired[u] else []
                     for u, ks in enumerate(kids)]
        self.roots = [u for u in range(len(forest))
                      if unpaired[u] and (forest[u] == FREE or not unpaired[forest[u]])]
        levels: list[list[int]] = [list(self.roots)]   # breadth-first, level by level
        while levels[-1]:
            levels.append([c for u in levels[-1] for c in self.kids[u]])
        up = np.asarray(forest, dtype=np.int64)
        profile = np.zeros((len(forest), PROFILE_DEPTH + 1), dtype=np.int64)
        for level in reversed(levels[1:-1]):   # deepest first: each level into its parents
            nodes = np.asarray(level, dtype=np.int64)
            rows = profile[nodes]
            shifted = np.zeros_like(rows)
            shifted[:, 0] = 1
            shifted[:, 1:PROFILE_DEPTH] = rows[:, :PROFILE_DEPTH - 1]
            shifted[:, PROFILE_DEPTH] = rows[:, PROFILE_DEPTH - 1] + rows[:, PROFILE_DEPTH]
            np.add.at(profile, up[nodes], shifted)
        self.profile = profile
        self.size = profile.sum(axis=1) + 1


class _Rounds:
    """Pairing by rounds of top-down alignment (module docstring, part 1)."""

    def __init__(self, problem: MisoProblem):
        self.n = problem.n
        self.fa, self.fb = rooted(problem.start), rooted(problem.goal)
        self.ka, self.kb = children_of(self.fa), children_of(self.fb)
        self.free_a = [p == FREE for p in problem.start]
        self.free_b = [p == FREE for p in problem.goal]
        self.pair = [FREE] * self.n
        self.inv = [FREE] * self.n

    def run(self) -> list[int]:
        while True:
            ua = [p == FREE for p in self.pair]
            ub = [p == FREE for p in self.inv]
            if not any(ua):
                return self.pair
            A = _Fragments(self.fa, self.ka, ua)
            B = _Fragments(self.fb, self.kb, ub)
            couples = self._kept_couples(A, B) + self._root_couples(A, B)
            for a, b in couples:
                if self.pair[a] == FREE and self.inv[b] == FREE:
                    self._align(a, b, A, B)

    def _kept_couples(self, A: _Fragments, B: _Fragments) -> list[tuple[int, int]]:
        """Unpaired children of paired ``p``, ``q``, matched: each a kept connection."""
        groups: dict[int, list[int]] = {}
        for a in A.roots:
            p = self.fa[a]
            if p != FREE:
                groups.setdefault(p, []).append(a)
        by_q: dict[int, list[int]] = {}
        for b in B.roots:
            q = self.fb[b]
            if q != FREE:
                by_q.setdefault(q, []).append(b)
        couples = []
        for p in sorted(groups):
            bs = by_q.get(self.pair[p])
            if bs:
                couples += self._match(groups[p], bs, A, B)
        return couples

    def _root_couples(self, A: _Fragments, B: _Fragments) -> list[tuple[int, int]]:
        """The other roots, matched by the alignment estimate (free with free first)."""
        fa = [u for u in A.roots if self.free_a[u]]
        fb = [v for v in B.roots if self.free_b[v]]
        couples = self._match(fa, fb, A, B) if fa and fb else []
        paired = {u for u, _ in couples} | {v + self.n for _, v in couples}
        return couples + self._match([u for u in A.roots if u not in paired],
                                     [v for v in B.roots if v + self.n not in paired], A, B)

    @staticmethod
    def _match(us: list[int], vs: list[int], A: _Fragments, B: _Fragments
               ) -> list[tuple[int, int]]:
        """A maximum-weight assignment of ``us`` to ``vs``, weights ``1 + s(u, v)``."""
        if not us or not vs:
            return []
        if len(us) == 1 and len(vs) == 1:
            return [(us[0], vs[0])]
        weight = 1 + np.minimum(A.profile[us][:, None, :], B.profile[vs][None, :, :]).sum(axis=2)
        if len(us) == 1 or len(vs) == 1:   # one side single: its best partner
            k = int(np.argmax(weight))
            return [(us[k // len(vs)], vs[k % len(vs)])]
        rows, cols = linear_sum_assignment(weight, maximize=True)
        return [(us[r], vs[c]) for r, c in zip(rows, cols, strict=True)]

    def _align(self, u: int, v: int, A: _Fragments, B: _Fragments) -> None:
        stack = [(u, v)]
        while stack:
            a, b = stack.pop()
            self.pair[a], self.inv[b] = b, a
            ca, cb = A.kids[a], B.kids[b]
            if not ca or not cb:
                continue
            if len(ca) == 1 and len(cb) == 1:
                stack.append((ca[0], cb[0]))
            else:
                stack.extend(self._match(ca, cb, A, B))

class _Aligner:
    """Top-down alignment scores ``sim(u, v)`` on the still unpaired parts of two trees."""

    def __init__(self, ca: list[list[int]], cb: list[list[int]]):
        self.ca, self.cb = ca, cb
        self.memo: dict[tuple[int, int], int] = {}

    def sim(self, u: int, v: int) -> int:
        """Most connections kept below ``u`` and ``v`` when they pair (top down)."""
        ca, cb, memo = self.ca, self.cb, self.memo
        walked, run = [], 0
        while True:
            hit = memo.get((u, v))
            if hit is not None:
                base = hit
                break
            cu, cv = ca[u], cb[v]
            if not cu or not cv:
                base = 0
                memo[(u, v)] = 0
                break
            if len(cu) == 1 and len(cv) == 1:
                walked.append((u, v))
                u, v = cu[0], cv[0]
                run += 1
                continue
            base = self._branch(u, v)[0]
            memo[(u, v)] = base
            break
        for k, key in enumerate(walked):
            memo[key] = base + run - k
        return base + run

    def _branch(self, u: int, v: int) -> tuple[int, list[tuple[int, int]]]:
        cu, cv = self.ca[u], self.cb[v]
        if len(cu) == 1:
            scores = [self.sim(cu[0], b) for b in cv]
            j = int(np.argmax(scores))
            return 1 + scores[j], [(cu[0], cv[j])]
        if len(cv) == 1:
            scores = [self.sim(a, cv[0]) for a in cu]
            j = int(np.argmax(scores))
            return 1 + scores[j], [(cu[j], cv[0])]
        weight = np.array([[1 + self.sim(a, b) for b in cv] for a in cu], dtype=np.float64)
        rows, cols = linear_sum_assignment(weight, maximize=True)
        return int(weight[rows, cols].sum()), [(cu[r], cv[c]) for r, c in zip(rows, cols,
                                                                               strict=True)]

    def align(self, u: int, v: int) -> list[tuple[int, int]]:
        """The pairs of the alignment whose score :meth:`sim` gives, ``(u, v)`` first."""
        pairs, stack = [], [(u, v)]
        while stack:
            a, b = stack.pop()
            pairs.append((a, b))
            cu, cv = self.ca[a], self.cb[b]
            if not cu or not cv:
                continue
            if len(cu) == 1 and len(cv) == 1:
                stack.append((cu[0], cv[0]))
                continue
            stack.extend(self._branch(a, b)[1])
        return pairs



def _sizes(children: list[list[int]], roots: list[int]) -> dict[int, int]:
    size: dict[int, int] = {}
    order: list[int] = []
    stack = list(roots)
    while stack:
        u = stack.pop()
        order.append(u)
        stack.extend(children[u])
    for u in reversed(order):
        size[u] = 1 + sum(size[c] for c in children[u])
    return size


ROUND_WIDTH = 64
"""Largest fragment roots scored per side in each round of the exhaustive greedy."""


def _greedy_pairing(problem: MisoProblem, first: tuple[int, int] | None) -> list[int]:
    """Rounds that pair the fragment root and unpaired module (either side) whose
    top-down alignment scores best (exact ``sim``, every candidate): twice the kept
    connections, +2 when the pair keeps the connection to already paired parents, +1
    for two free modules."""
    n = problem.n
    pa, pb = rooted(problem.start), rooted(problem.goal)
    free_a = [p == FREE for p in problem.start]
    free_b = [p == FREE for p in problem.goal]
    kids_a, kids_b = children_of(pa), children_of(pb)
    pair: list[int] = [FREE] * n
    open_a, open_b = [True] * n, [True] * n

    def bonus(u: int, v: int) -> int:
        if free_a[u] and free_b[v]:
            return 1
        return 2 * int(pa[u] != FREE and pb[v] != FREE and pair[pa[u]] == pb[v])

    while any(open_a):
        ca = [[c for c in kids if open_a[c]] if open_a[u] else []
              for u, kids in enumerate(kids_a)]
        cb = [[c for c in kids if open_b[c]] if open_b[v] else []
              for v, kids in enumerate(kids_b)]
        roots_a = [u for u in range(n) if open_a[u] and (pa[u] == FREE or not open_a[pa[u]])]
        roots_b = [v for v in range(n) if open_b[v] and (pb[v] == FREE or not open_b[pb[v]])]
        size_a, size_b = _sizes(ca, roots_a), _sizes(cb, roots_b)
        aligner = _Aligner(ca, cb)
        if first is not None:
            best_pair, first = first, None
        else:
            best, best_pair = -1, None
            by_a = sorted(size_a, key=lambda u: (-size_a[u], u))
            by_b = sorted(size_b, key=lambda v: (-size_b[v], v))
            for roots, others, size_r, size_o, flip in (
                    (roots_a, by_b, size_a, size_b, False), (roots_b, by_a, size_b, size_a, True)):
                for r in sorted(roots, key=lambda x: (-size_r[x], x))[:ROUND_WIDTH]:
                    if 2 * size_r[r] <= best:
                        break
                    for o in others:
                        if 2 * min(size_r[r], size_o[o]) <= best:
                            break   # 2 sim + bonus <= 2 (min size - 1) + 2
                        u, v = (o, r) if flip else (r, o)
                        score = 2 * aligner.sim(u, v) + bonus(u, v)
                        if score > best:
                            best, best_pair = score, (u, v)
        assert best_pair is not None
        for a, b in aligner.align(*best_pair):
            pair[a] = b
            open_a[a] = open_b[b] = False
    return pair


RESTART_BUDGET = 400
"""Greedy pairings tried on small instances: ``RESTART_BUDGET // n`` forced first pairs."""

EXHAUSTIVE_LIMIT = 150
"""Largest module count paired by the exhaustive greedy (larger: the rounds)."""


def improve_by_swaps(problem: MisoProblem, pair: list[int], *, passes: int = 20) -> list[int]:
    """Swap partners while a swap keeps more connections (module docstring, part 2).

    The gain of swapping ``i`` and ``j`` counts the kept connections out of and into
    both modules before and after, and free-with-free pairs as a tie-break.
    """
    pa, pb, n = problem.start, problem.goal, problem.n
    pair = list(pair)
    inv = [0] * n
    for a, b in enumerate(pair):
        inv[b] = a
    ka, kb = children_of(pa), children_of(pb)

    def local(i: int, j: int) -> int:
        """Kept connections out of ``i``, ``j`` and their children (x2), plus 1 per
        free-free pair among ``i``, ``j``: every connection a swap of the two can change."""
        total = 0
        for s in (i, j):
            p = pa[s]
            total += pb[pair[s]] == FREE if p == FREE else 2 * (pb[pair[s]] == pair[p])
        for s in ka[i]:
            if s != j:
                total += 2 * (pb[pair[s]] == pair[i])
        for s in ka[j]:
            if s != i:
                total += 2 * (pb[pair[s]] == pair[j])
        return total

    for _ in range(passes):
        gained = False
        for i in range(n):
            p = pa[i]
            if p == FREE or (pb[pair[i]] != FREE and pair[p] == pb[pair[i]]):
                continue
            swaps = [(i, inv[b]) for b in kb[pair[p]]]
            if pb[pair[i]] != FREE:   # or give i's parent the partner i's target needs
                swaps.append((p, inv[pb[pair[i]]]))
            for u, w in swaps:
                if u == w:
                    continue
                before = local(u, w)
                pair[u], pair[w] = pair[w], pair[u]
                if local(u, w) > before:
                    inv[pair[u]], inv[pair[w]] = u, w
                    gained = True
                    break
                pair[u], pair[w] = pair[w], pair[u]
        if not gained and n <= ALL_SWAPS_LIMIT:   # small: every pair of modules
            for u, w in itertools.combinations(range(n), 2):
                before = local(u, w)
                pair[u], pair[w] = pair[w], pair[u]
                if local(u, w) > before:
                    inv[pair[u]], inv[pair[w]] = u, w
                    gained = True
                else:
                    pair[u], pair[w] = pair[w], pair[u]
        if not gained:
            break
    return pair


ALL_SWAPS_LIMIT = 40
"""Largest module count for which :func:`improve_by_swaps` also tries every pair."""


def heuristic_pairing(problem: MisoProblem) -> list[int]:
    """A pairing ``pi`` (start index -> goal index) that keeps many connections."""
    n = problem.n
    if n > EXHAUSTIVE_LIMIT:
        return improve_by_swaps(problem, _Rounds(problem).run())
    best = improve_by_swaps(problem, _greedy_pairing(problem, None))
    best_v = _value(problem, best)
    restarts = RESTART_BUDGET // n - 1
    if restarts <= 0:
        return best
    aligner = _Aligner(children_of(rooted(problem.start)), children_of(rooted(problem.goal)))
    firsts = sorted(((aligner.sim(u, v), u, v) for u in range(n) for v in range(n)),
                    key=lambda t: (-t[0], t[1], t[2]))
    for _, u, v in firsts[:restarts]:
        pair = improve_by_swaps(problem, _greedy_pairing(problem, (u, v)))
        value = _value(problem, pair)
        if value > best_v:
            best, best_v = pair, value
    return best


def _value(problem: MisoProblem, pair: list[int]) -> int:
    """Twice the kept connections plus the free-free pairs (higher is better)."""
    goal = targets(problem, pair)
    return sum(2 * (p == g != FREE) + (p == g == FREE)
               for p, g in zip(problem.start, goal, strict=True))
