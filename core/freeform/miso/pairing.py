"""The heuristic pairing: which goal module each start module becomes.

Modules are identical, so a plan is a pairing ``pi`` (start module -> goal module) and
steps. A connection ``i -> p`` of the start is *kept* when the goal relabelled by
``pi^-1`` holds it too; Luo and Lam's metric, connections broken plus made, is
``|E_start| + |E_goal| - 2 kept``, so the pairing maximises ``kept`` (and, second,
pairs free modules with free ones: each such pair saves a step). Cycles are cut
(:func:`~.model.rooted`), so both configurations are rooted forests.

:func:`heuristic_pairing` (polynomial):

1. *Up to* ``EXHAUSTIVE_LIMIT`` *modules: exhaustive greedy.* Rounds pair the fragment
   root and unpaired module (either side) whose top-down alignment scores best --
   ``sim(u, v)``, the most connections kept below ``u`` and ``v`` with their children
   matched by a maximum-weight assignment (``scipy.optimize.linear_sum_assignment``),
   +1 when the pair keeps the connection to already paired parents -- and align them.
   Restarts from other forced first pairs (``RESTART_BUDGET // n``) and from other cuts
   of the cycles (``CUT_TRIES`` per side); the pairing keeping the most wins.
2. *Larger: alignment rounds* (up to ``GREEDY_LIMIT`` modules, one pass of the
   exhaustive greedy too, the better kept). Each round pairs the roots of the still
   unpaired fragments -- first, for every paired ``(p, q)``, unpaired children of ``p``
   with those of ``q`` (a kept connection each), then free roots with free roots, then
   the rest -- by one assignment, and aligns every couple top down. The weight of a
   couple is an estimate of the connections its alignment keeps, from level profiles
   (``sum_k min(L_u(k), L_v(k))`` over the first ``PROFILE_DEPTH`` levels, then the
   smaller remainder: an upper bound, exact for chains), with equal heights preferred
   (``EXACT_FIT``: a chain that ends where the other ends leaves no cut). Alignment
   goes top down, so an unpaired module's subtree stays unpaired and the profiles of
   the whole forests, computed once, stay exact.
3. *Swaps.* Local search on the pairing: a start module whose connection is not kept
   trades partners with the module paired to a goal child of its parent's partner (or
   its parent with the module paired to its target's goal parent) when that keeps more
   connections (counted on every connection either swap can change); up to
   ``ALL_SWAPS_LIMIT`` modules every pair is tried too, up to ``ROTATIONS_LIMIT`` every
   rotation of three.
4. *Never worse than IM.* IM's pairing (:func:`~.im.im_pairing`) improved by swaps is a
   candidate too; swaps never lose a kept connection, so the pairing returned keeps at
   least as many connections as IM's and makes no more connection changes.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from .chains import chain_pairing
from .im import im_pairing
from .model import FREE, MisoProblem, children_of, cycles, pairing_score, rooted

__all__ = ["PROFILE_DEPTH", "heuristic_pairing", "improve_by_swaps"]

SMALL_MATCH = 9
"""Largest assignment (rows x columns) solved by trying every assignment in Python."""

EXACT_FIT = 4
"""Weight of a couple of equal heights, in kept connections."""

PROFILE_DEPTH = 8
"""Levels of a subtree's profile the alignment estimate compares one by one."""


class _Fragments:
    """One rooted forest with level profiles (one row per module: how many modules lie
    1, 2, ... ``PROFILE_DEPTH`` levels below it, then deeper) and heights, for the
    alignment estimate."""

    def __init__(self, forest: Sequence[int], kids: list[list[int]]):
        self.kids = kids
        self.roots = [u for u in range(len(forest)) if forest[u] == FREE]
        order = list(self.roots)   # breadth-first: children after their parent
        for u in order:
            order.extend(self.kids[u])
        depth = PROFILE_DEPTH
        zero = [0] * (depth + 1)
        self.row: dict[int, list[int]] = {}
        self.height: dict[int, int] = {}
        for u in reversed(order):
            ks = self.kids[u]
            if not ks:
                self.row[u], self.height[u] = zero, 0
                continue
            row = [len(ks)] + [0] * depth
            tall = 0
            for c in ks:
                below = self.row[c]
                row[1:depth] = map(int.__add__, row[1:depth], below[:depth - 1])
                row[depth] += below[depth - 1] + below[depth]
                tall = max(tall, self.height[c])
            self.row[u], self.height[u] = row, tall + 1
        self.size = {u: 1 + sum(r) for u, r in self.row.items()}

    def arrays(self, modules: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Profile rows (len, PROFILE_DEPTH + 1) and heights (len,) of ``modules``."""
        return (np.array([self.row[m] for m in modules], dtype=np.int64),
                np.array([self.height[m] for m in modules], dtype=np.int64))


class _Rounds:
    """Pairing by rounds of top-down alignment (module docstring, part 2)."""

    def __init__(self, problem: MisoProblem):
        self.n = problem.n
        self.fa, self.fb = rooted(problem.start), rooted(problem.goal)
        self.ka, self.kb = children_of(self.fa), children_of(self.fb)
        self.free_a = [p == FREE for p in problem.start]
        self.free_b = [p == FREE for p in problem.goal]
        self.pair = [FREE] * self.n
        self.inv = [FREE] * self.n

    def run(self) -> list[int]:
        # Alignment pairs top down, so an unpaired module's whole subtree stays unpaired:
        # the profiles of the whole forests stay exact for every fragment.
        A = _Fragments(self.fa, self.ka)
        B = _Fragments(self.fb, self.kb)
        ra, rb = list(A.roots), list(B.roots)
        while ra:
            couples = self._kept_couples(ra, rb, A, B) + self._root_couples(ra, rb, A, B)
            left_a: list[int] = []
            left_b: list[int] = []
            for a, b in couples:
                if self.pair[a] == FREE and self.inv[b] == FREE:
                    self._align(a, b, A, B, left_a, left_b)
            ra = sorted([u for u in ra if self.pair[u] == FREE] + left_a)
            rb = sorted([v for v in rb if self.inv[v] == FREE] + left_b)
        return self.pair

    def _kept_couples(self, ra: list[int], rb: list[int], A: _Fragments, B: _Fragments
                      ) -> list[tuple[int, int]]:
        """Unpaired children of paired ``p``, ``q``, matched: each a kept connection."""
        groups: dict[int, list[int]] = {}
        for a in ra:
            p = self.fa[a]
            if p != FREE:
                groups.setdefault(p, []).append(a)
        by_q: dict[int, list[int]] = {}
        for b in rb:
            q = self.fb[b]
            if q != FREE:
                by_q.setdefault(q, []).append(b)
        couples = []
        for p in sorted(groups):
            bs = by_q.get(self.pair[p])
            if bs:
                couples += self._match(groups[p], bs, A, B)
        return couples

    def _root_couples(self, ra: list[int], rb: list[int], A: _Fragments, B: _Fragments
                      ) -> list[tuple[int, int]]:
        """The other roots, matched by the alignment estimate (free with free first)."""
        fa = [u for u in ra if self.free_a[u] and self.pair[u] == FREE]
        fb = [v for v in rb if self.free_b[v] and self.inv[v] == FREE]
        couples = self._match(fa, fb, A, B) if fa and fb else []
        taken_a, taken_b = {u for u, _ in couples}, {v for _, v in couples}
        return couples + self._match(
            [u for u in ra if u not in taken_a and self.pair[u] == FREE],
            [v for v in rb if v not in taken_b and self.inv[v] == FREE], A, B)

    @staticmethod
    def _match(us: list[int], vs: list[int], A: _Fragments, B: _Fragments
               ) -> list[tuple[int, int]]:
        """A maximum-weight assignment of ``us`` to ``vs``, weights ``1 + s(u, v)``."""
        if not us or not vs:
            return []
        if len(us) == 1 and len(vs) == 1:
            return [(us[0], vs[0])]
        big = 2 * len(A.kids) + 1
        if len(us) * len(vs) <= SMALL_MATCH:   # tiny: every assignment, in Python
            ra_, rb_, ha_, hb_ = A.row, B.row, A.height, B.height
            w = [[(1 + sum(map(min, ra_[u], rb_[v]))) * big - abs(ha_[u] - hb_[v])
                  + (ha_[u] == hb_[v]) * big * EXACT_FIT for v in vs] for u in us]
            if len(us) <= len(vs):
                best = max(itertools.permutations(range(len(vs)), len(us)),
                           key=lambda cols: sum(w[r][c] for r, c in enumerate(cols)))
                return [(us[r], vs[c]) for r, c in enumerate(best)]
            best = max(itertools.permutations(range(len(us)), len(vs)),
                       key=lambda rows: sum(w[r][c] for c, r in enumerate(rows)))
            return [(us[r], vs[c]) for c, r in enumerate(best)]
        (pa, ha), (pb, hb) = A.arrays(us), B.arrays(vs)
        kept = np.minimum(pa[:, None, :], pb[None, :, :]).sum(axis=2)
        # ties go to equal heights: a chain that ends where the other ends leaves no cut
        gap = np.abs(ha[:, None] - hb[None, :])
        weight = (1 + kept) * big - gap + (gap == 0) * big * EXACT_FIT
        if len(us) == 1 or len(vs) == 1:   # one side single: its best partner
            k = int(np.argmax(weight))
            return [(us[k // len(vs)], vs[k % len(vs)])]
        rows, cols = linear_sum_assignment(weight, maximize=True)
        return [(us[r], vs[c]) for r, c in zip(rows, cols, strict=True)]

    def _align(self, u: int, v: int, A: _Fragments, B: _Fragments, left_a: list[int],
               left_b: list[int]) -> None:
        """Pair ``u`` with ``v`` and their subtrees top down; children left unmatched go
        to ``left_a`` and ``left_b`` (roots of the next round)."""
        stack = [(u, v)]
        while stack:
            a, b = stack.pop()
            self.pair[a], self.inv[b] = b, a
            ca, cb = A.kids[a], B.kids[b]
            if len(ca) == 1 and len(cb) == 1:
                stack.append((ca[0], cb[0]))
                continue
            matched = self._match(ca, cb, A, B)
            stack.extend(matched)
            if len(ca) != len(cb):
                used_a, used_b = {x for x, _ in matched}, {y for _, y in matched}
                left_a.extend(c for c in ca if c not in used_a)
                left_b.extend(c for c in cb if c not in used_b)


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


def _greedy_pairing(problem: MisoProblem, first: tuple[int, int] | None,
                    cuts: tuple[int, int] = (0, 0)) -> list[int]:
    """Rounds that pair the fragment root and unpaired module (either side) whose
    top-down alignment scores best (exact ``sim``, every candidate): twice the kept
    connections, +2 when the pair keeps the connection to already paired parents, +1
    for two free modules."""
    n = problem.n
    pa, pb = rooted(problem.start, cuts[0]), rooted(problem.goal, cuts[1])
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


CUT_TRIES = 8
"""Cuts of the cycles tried per side by the exhaustive greedy (the first included)."""

RESTART_BUDGET = 400
"""Greedy pairings tried on small instances: ``RESTART_BUDGET // n`` forced first pairs."""

EXHAUSTIVE_LIMIT = 40
"""Largest module count paired by the exhaustive greedy (larger: the rounds)."""

GREEDY_LIMIT = 120
"""Largest module count for which the rounds' pairing competes with one pass of the
exhaustive greedy (no restarts): 3-7 % fewer changes at 50-120 modules, at most a few
hundred milliseconds (a count, not a clock, so the plan stays deterministic)."""


def improve_by_swaps(problem: MisoProblem, pair: list[int], *, passes: int = 20,
                     thorough: bool = True) -> list[int]:
    """Swap partners while a swap keeps more connections (module docstring, part 3).

    The gain of swapping ``i`` and ``j`` counts the kept connections out of and into
    both modules before and after, and free-with-free pairs as a tie-break
    (``KEPT_WEIGHT`` each kept connection: a swap never trades one for free pairs), so
    the pairing's :func:`~.model.pairing_score` only grows.
    """
    pa, pb, n = problem.start, problem.goal, problem.n
    pair = list(pair)
    inv = [0] * n
    for a, b in enumerate(pair):
        inv[b] = a
    ka, kb = children_of(pa), children_of(pb)

    def local(i: int, j: int) -> int:
        """Kept connections out of ``i``, ``j`` and their children (x ``KEPT_WEIGHT``),
        plus 1 per free-free pair among ``i``, ``j``: every connection a swap of the two
        can change."""
        total = 0
        for s in (i, j):
            p = pa[s]
            total += (pb[pair[s]] == FREE if p == FREE
                      else KEPT_WEIGHT * (pb[pair[s]] == pair[p]))
        for s in ka[i]:
            if s != j:
                total += KEPT_WEIGHT * (pb[pair[s]] == pair[i])
        for s in ka[j]:
            if s != i:
                total += KEPT_WEIGHT * (pb[pair[s]] == pair[j])
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
        if not gained and thorough and n <= ALL_SWAPS_LIMIT:   # small: every pair
            for u, w in itertools.combinations(range(n), 2):
                before = local(u, w)
                pair[u], pair[w] = pair[w], pair[u]
                if local(u, w) > before:
                    inv[pair[u]], inv[pair[w]] = u, w
                    gained = True
                else:
                    pair[u], pair[w] = pair[w], pair[u]
        if not gained and thorough and n <= ROTATIONS_LIMIT:   # tiny: rotations of three
            gained = _rotate_threes(pa, pb, pair, inv, ka)
        if not gained:
            break
    return pair


def _rotate_threes(pa: Sequence[int], pb: Sequence[int], pair: list[int], inv: list[int],
                   ka: list[list[int]]) -> bool:
    """Rotate the partners of three modules wherever that keeps more connections."""
    def around(mods: tuple[int, ...]) -> int:
        sources = set(mods).union(*(ka[m] for m in mods))
        total = 0
        for s in sorted(sources):
            p = pa[s]
            if p == FREE:
                total += s in mods and pb[pair[s]] == FREE
            else:
                total += KEPT_WEIGHT * (pb[pair[s]] == pair[p])
        return total

    gained = False
    for u, w, x in itertools.combinations(range(len(pa)), 3):
        for order in ((u, w, x), (u, x, w)):
            before = around(order)
            a, b, c = order
            pair[a], pair[b], pair[c] = pair[b], pair[c], pair[a]
            if around(order) > before:
                for m in order:
                    inv[pair[m]] = m
                gained = True
                break
            pair[a], pair[b], pair[c] = pair[c], pair[a], pair[b]
    return gained


KEPT_WEIGHT = 4
"""Weight of a kept connection in the swaps' and rotations' local counts: more than the
free-free pairs one move can change (two for a swap, three for a rotation), so a move
that loses a kept connection never pays."""

ROTATIONS_LIMIT = 12
"""Largest module count for which :func:`improve_by_swaps` also rotates every three."""

ALL_SWAPS_LIMIT = 40
"""Largest module count for which :func:`improve_by_swaps` also tries every pair."""


def heuristic_pairing(problem: MisoProblem) -> list[int]:
    """A pairing ``pi`` (start index -> goal index) that keeps many connections, and never
    fewer than Luo and Lam's IM: the best, by :func:`~.model.pairing_score`, of the
    greedy's (steps 1-3 of the module docstring), IM's pairing (:func:`~.im.im_pairing`)
    improved by swaps, and, when one side is made of chains, the best path cover packed
    into the chains (:func:`~.chains.chain_pairing`) improved by swaps. Swaps never lose a
    kept connection, so the result keeps at least as many as IM's pairing: its connection
    changes are never more than IM's."""
    others = (im_pairing(problem), chain_pairing(problem))
    return _best_of(problem, [_greedy_best(problem)] + [
        improve_by_swaps(problem, other) for other in others if other is not None])


def _best_of(problem: MisoProblem, pairings: list[list[int]]) -> list[int]:
    """The pairing of highest :func:`~.model.pairing_score`, the first on a tie."""
    return max(pairings, key=lambda pair: pairing_score(problem, pair))


def _greedy_best(problem: MisoProblem) -> list[int]:
    """Steps 1-3 of the module docstring."""
    n = problem.n
    if n > EXHAUSTIVE_LIMIT:
        firsts = [_Rounds(problem).run()]
        if n <= GREEDY_LIMIT:   # one greedy pass too, while it costs little
            firsts.append(_greedy_pairing(problem, None))
        return _best_of(problem, [improve_by_swaps(problem, pair) for pair in firsts])
    best = improve_by_swaps(problem, _greedy_pairing(problem, None), thorough=False)
    best_v = pairing_score(problem, best)
    restarts = RESTART_BUDGET // n - 1
    aligner = _Aligner(children_of(rooted(problem.start)), children_of(rooted(problem.goal)))
    firsts = sorted(((aligner.sim(u, v), u, v) for u in range(n) for v in range(n)),
                    key=lambda t: (-t[0], t[1], t[2]))
    longest = [max(map(len, cycles(p)), default=1) for p in (problem.start, problem.goal)]
    cuts = [(0, k) for k in range(1, min(longest[1], CUT_TRIES))] + [
        (k, 0) for k in range(1, min(longest[0], CUT_TRIES))]
    tries = [((u, v), (0, 0)) for _, u, v in firsts[:max(restarts, 0)]] + [
        (None, c) for c in cuts]
    for first, cut in tries:   # other first pairs; cycles cut elsewhere
        pair = improve_by_swaps(problem, _greedy_pairing(problem, first, cut), thorough=False)
        value = pairing_score(problem, pair)
        if value > best_v:
            best, best_v = pair, value
    return improve_by_swaps(problem, best)
