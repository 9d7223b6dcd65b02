"""Among pairings of the fewest changes, the one whose pieces travel least: a geometric
tie-break when the configurations carry places.

A pairing ``pi`` cuts the start into *fragments*: the modules joined by kept connections
(``goal[pi(i)] == pi(start[i])``), each a rooted tree that lands, unchanged, on an
isomorphic subtree of the goal, its *image*. Two fragments of the same rooted shape can
trade images: inside each, every connection stays kept; at their borders nothing was
kept (a fragment is maximal), so the trade keeps at least as many connections. Which
fragment takes which image is the planner's free choice -- the topology alone does not
tell it -- and the pieces the plan moves are these fragments (with riders: fragments
below that leave later). :func:`class_moves` proposes that choice by place: per class of
equal shapes, one minimum-cost assignment (``scipy.optimize.linear_sum_assignment``) of
fragments to images, the cost of a fragment on an image the sum over its modules of the
straight distance from its start place to its goal place, less a weight above any such
sum when both roots are free (a free module paired with a free one saves a step: those
pairs are kept first). A trade also changes which riders travel with which piece, so the
planner judges each class's trade on the steps themselves (:func:`step_travel`: each
step's piece, its travel and its modules); :func:`nearer_pairing` makes every class's
trade at once.

The goal's places come from its own vectors, in a frame of their own; they are put in
the start's frame by the piece that stays: the largest fragment whose root is free in
both configurations (nothing docks it anywhere, so the goal is built around it where it
lies), fitted by a turn about ``z`` and a shift (least squares over its modules, Kabsch
in the floor plane). With no such fragment the goal's places are taken as they are.

Deterministic: fragments in the order of their roots' indices, classes by an integer
encoding of rooted shapes (AHU) assigned in that order, ties left to the assignment
solver, which is deterministic; a class's trade is proposed only when it moves the
modules strictly less.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from ...alignment import best_turn, rot_z
from ..layout import SLIDE_OVERLAP, WAY_IN
from .model import FREE, MisoProblem, Step, children_of, pairing_score, rooted, targets
from .order import Ride

__all__ = ["class_moves", "closed_ways", "fragments", "goal_in_start_frame",
           "heading_turn", "hold", "nearer_pairing", "riding_ways", "step_travel", "travel"]


def fragments(problem: MisoProblem, pair: Sequence[int]) -> list[list[int]]:
    """The start's fragments under ``pair``, each in a canonical top-down order (its root
    first; children by shape, then index), in the order of their roots' indices; cycles
    are cut as :func:`~.model.rooted` cuts them."""
    forest = rooted(problem.start)
    final = targets(problem, pair)
    kids = [[c for c in cs if final[c] == forest[c]] for cs in children_of(forest)]
    roots = [i for i in range(problem.n) if forest[i] == FREE or final[i] != forest[i]]
    shape = _shapes(kids, roots)
    out = []
    for r in roots:
        order, stack = [], [r]
        while stack:
            u = stack.pop()
            order.append(u)
            stack.extend(sorted(kids[u], key=lambda c: (shape[c], c), reverse=True))
        out.append(order)
    return out


def _shapes(kids: list[list[int]], roots: list[int]) -> dict[int, int]:
    """An integer per module, equal for two modules exactly when their subtrees (along
    ``kids``) have the same rooted shape (AHU encoding, ids by first appearance)."""
    order = list(roots)
    for u in order:
        order.extend(kids[u])
    table: dict[tuple[int, ...], int] = {}
    shape: dict[int, int] = {}
    for u in reversed(order):
        key = tuple(sorted(shape[c] for c in kids[u]))
        shape[u] = table.setdefault(key, len(table))
    return shape


def goal_in_start_frame(problem: MisoProblem, pair: Sequence[int], start_places: np.ndarray,
                        goal_places: np.ndarray) -> np.ndarray:
    """``goal_places`` (n, 3) moved into the start's frame by the piece that stays (module
    docstring): the largest fragment whose root is free in both, fitted by a turn about
    ``z`` and a shift; unchanged when there is none."""
    stays = [f for f in fragments(problem, pair)
             if problem.start[f[0]] == FREE and problem.goal[pair[f[0]]] == FREE]
    if not stays:
        return np.array(goal_places, dtype=np.float64)
    anchor = max(stays, key=len)   # the first of the largest (roots in index order)
    p = np.asarray(goal_places, dtype=np.float64)[[pair[a] for a in anchor]]
    q = np.asarray(start_places, dtype=np.float64)[anchor]
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    yaw = best_turn(p[:, :2], q[:, :2])
    c, s = np.cos(yaw), np.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return (np.asarray(goal_places, dtype=np.float64) - pc) @ turn.T + qc


def travel(pair: Sequence[int], start_places: np.ndarray, goal_places: np.ndarray) -> float:
    """Module-metres of ``pair``: the sum of the straight distances from each module's
    start place to its goal place [m]."""
    goal = np.asarray(goal_places, dtype=np.float64)[list(pair)]
    return float(np.linalg.norm(np.asarray(start_places, dtype=np.float64) - goal,
                                axis=1).sum())


def class_moves(problem: MisoProblem, pair: Sequence[int], start_places: np.ndarray,
                goal_places: np.ndarray) -> list[dict[int, int]]:
    """Per class of equal shapes whose fragments travel less on other images (module
    docstring), the new image of each member module: ``{start index: goal index}``;
    classes in the order of their first fragment. ``goal_places`` (n, 3) in the goal's
    index order, in any frame (moved by :func:`goal_in_start_frame`) [m]."""
    goal = goal_in_start_frame(problem, pair, start_places, goal_places)
    here = np.asarray(start_places, dtype=np.float64)
    forest = rooted(problem.start)
    classes: dict[tuple[int, ...], list[list[int]]] = {}
    for f in fragments(problem, pair):   # a class: one shape, read in canonical order
        classes.setdefault(_signature(forest, f), []).append(f)
    moves = []
    for members in classes.values():
        if len(members) < 2:
            continue
        froms = here[np.array(members)]                                    # (k, s, 3)
        images = goal[np.array([[pair[a] for a in f] for f in members])]   # (k, s, 3)
        cost = np.stack([np.linalg.norm(f[None] - images, axis=2).sum(axis=1)
                         for f in froms])
        free_a = np.array([problem.start[f[0]] == FREE for f in members])
        free_b = np.array([problem.goal[pair[f[0]]] == FREE for f in members])
        kept_free = free_a[:, None] & free_b[None, :]
        now = float(np.trace(cost)) - (cost.sum() + 1.0) * int(np.trace(kept_free))
        cost -= (cost.sum() + 1.0) * kept_free
        rows, cols = linear_sum_assignment(cost)
        if float(cost[rows, cols].sum()) < now - 1e-9:
            moves.append({a: pair[b] for r, c in zip(rows, cols, strict=True)
                          for a, b in zip(members[r], members[c], strict=True)})
    return moves


def nearer_pairing(problem: MisoProblem, pair: Sequence[int], start_places: np.ndarray,
                   goal_places: np.ndarray) -> list[int]:
    """``pair`` with every class's move (:func:`class_moves`) made: the modules travel
    least from ``start_places`` to ``goal_places`` among the fragments' reassignments;
    ``pair`` itself unless that keeps as many connections."""
    new = list(pair)
    for move in class_moves(problem, pair, start_places, goal_places):
        for a, b in move.items():
            new[a] = b
    return new if pairing_score(problem, new) >= pairing_score(problem, pair) else list(pair)


def step_travel(problem: MisoProblem, pair: Sequence[int], steps: Sequence[Step],
                start_places: np.ndarray, goal_places: np.ndarray
                ) -> list[tuple[int, float]]:
    """The modules of the piece each step moves, and its straight travel [m]: its
    centroid's shift plus the arc its turn sweeps at its reach, the piece laid where the
    plan holds it once docked (:func:`hold`: at the goal places ``goal_places`` (n, 3),
    goal index order, in the start's frame, its riders turned with the module they hang
    from); ``(1, 0.0)`` for a step to free. Short of a way over the floor: one turn, no
    detours, no obstacles."""
    final = targets(problem, pair)
    there = np.asarray(goal_places, dtype=np.float64)[list(pair)]
    pos = np.array(start_places, dtype=np.float64)
    parent = list(problem.start)
    kids = children_of(parent)
    out = []
    for step in steps:
        if step.old != FREE:
            kids[step.old].remove(step.module)
        parent[step.module] = step.new
        if step.new == FREE:
            out.append((1, 0.0))
            continue
        kids[step.new].append(step.module)
        piece, now = hold(pos, parent, kids, final, there, step.module, step.old)
        was = pos[piece].copy()
        pos[piece] = now
        out.append((len(piece), _move(was, now)))
    return out


def heading_turn(before: np.ndarray, after: np.ndarray) -> float:
    """The turn about the vertical from connection vector ``before`` to ``after`` [rad]
    (their first two components); 0 when either is (nearly) vertical, where no heading is
    defined."""
    if min(float(np.hypot(before[0], before[1])), float(np.hypot(after[0], after[1]))) < 1e-6:
        return 0.0
    return float(np.arctan2(after[1], after[0]) - np.arctan2(before[1], before[0]))


def hold(pos: np.ndarray, parent: Sequence[int], kids: Sequence[Sequence[int]],
         final: Sequence[int], there: np.ndarray, module: int, old: int
         ) -> tuple[list[int], np.ndarray]:
    """Where the piece ``module`` docks with lies once docked, as the plan holds it
    (``planner._carry``, on connection vectors): ``module``, and each module hanging
    from a module so placed by its goal connection, at its goal place; a *rider* (a
    module hanging by a connection it leaves later) with its in-tree turned rigidly about
    the module it hangs from by that module's turn (:func:`heading_turn` of its own
    connection, before to after; for ``module`` that was free, of its first child's
    connection) and carried with it.

    ``pos`` (n, 3): the places before the step; ``parent``, ``kids``: the pointer array
    after the step and its children; ``final``: every module's goal parent; ``there``
    (n, 3): the goal places (start index order); ``old``: ``module``'s parent before.
    Returns the piece (top down, a ring closed by the step walked once) and its places
    (k, 3) [m]."""
    if old != FREE:
        before = pos[module] - pos[old]
    else:
        before = pos[min(kids[module])] - pos[module] if kids[module] else np.zeros(3)
    turn = {module: heading_turn(before, there[module] - there[parent[module]])}
    new = {module: there[module]}
    placed, piece = {module}, [module]
    for m in piece:
        for c in sorted(kids[m]):
            if c in turn:
                continue
            if m in placed and final[c] == m:
                placed.add(c)
                new[c] = there[c]
                turn[c] = heading_turn(pos[c] - pos[m], there[c] - there[m])
            else:
                turn[c] = turn[m]
                new[c] = new[m] + rot_z(turn[m]) @ (pos[c] - pos[m])
            piece.append(c)
    return piece, np.array([new[m] for m in piece], dtype=np.float64).reshape(-1, 3)


def _move(before: np.ndarray, after: np.ndarray) -> float:
    """A piece's straight travel from ``before`` to ``after`` (n, 3) [m]: its centroid's
    shift plus its turn about ``z`` (least squares, Kabsch in the floor plane) times its
    reach (its farthest module from the centroid), the arc its end sweeps turning."""
    turn = abs(best_turn(before[:, :2], after[:, :2]))
    reach = float(np.max(np.linalg.norm(before[:, :2] - before[:, :2].mean(axis=0), axis=1)))
    return float(np.linalg.norm(after.mean(axis=0) - before.mean(axis=0))) + reach * turn


def _signature(forest: Sequence[int], fragment: list[int]) -> tuple[int, ...]:
    """The fragment's shape as its canonical order's parent positions (``-1`` at the
    root): equal exactly when two fragments' canonical orders correspond module by
    module."""
    at = {m: k for k, m in enumerate(fragment)}
    return tuple(at.get(forest[m], -1) if k else -1 for k, m in enumerate(fragment))


def closed_ways(problem: MisoProblem, pair: Sequence[int], goal_places: np.ndarray
                ) -> dict[int, set[int]]:
    """Which docking pieces close another's way in, laid at their goal places: for each
    fragment root ``j`` that moves (:func:`fragments`), the fragment roots ``i`` whose
    way in its docked body crosses (start indices).

    A piece of two or more modules docks by sliding in along the line from its target
    through its centroid (a straight piece drives only along its own line): its way in
    is its docked body slid back along that line by its own length and the last
    stretch, ``WAY_IN`` (:mod:`~msrr.core.freeform.layout`'s, as ``piece_way``'s): where
    it stands clear of neighbours as long as itself docked either side of it. A module
    of another piece's docked body closer than the spacing less ``SLIDE_OVERLAP`` to that
    swept body closes it: docked first, that piece leaves no way in (``piece_way``
    refuses such a way); the piece that holds its target does not count (it docks first
    anyway). The spacing is the goal's own, the median length of
    its connections. ``goal_places`` (n, 3): the goal's places in goal index order, in
    the start's frame (:func:`goal_in_start_frame`) [m]. Lone modules roll in from any
    side and close no way here.
    """
    there = np.asarray(goal_places, dtype=np.float64)[list(pair)][:, :2]
    ways, gap = _ways_in(problem, pair, there)
    bodies = _moving_bodies(problem, pair, there)
    out: dict[int, set[int]] = {}
    for i, (body, line, back, carrier) in ways.items():
        for j, other in bodies.items():
            if j not in (i, carrier) and _swept_distance(body, line, back, other) < gap:
                out.setdefault(j, set()).add(i)
    return out


def riding_ways(problem: MisoProblem, pair: Sequence[int], start_places: np.ndarray,
                goal_places: np.ndarray) -> dict[int, dict[int, Ride]]:
    """Where the riders of each docking piece ride: for each fragment root ``j`` that
    moves, per *rider* ``r`` (a module that hangs, in the start, from a module of ``j``'s
    fragment by a connection it leaves later), the moving pieces (fragment roots) that
    ``r``'s in-tree comes nearer than the gap to, where it rides: laid from the start as
    the plan holds it once ``j`` has docked (:func:`hold`). A :class:`~.order.Ride`:
    ``ways``, the pieces whose way in (as :func:`closed_ways`') or docked body it
    crosses (a lone module's body is its way), and ``bodies``, those whose docked body it
    lies on. The carrier itself, a piece whose target is in the rider, and the rider's
    own pieces do not count. ``start_places`` (n, 3); ``goal_places`` (n, 3) in goal
    index order, in the start's frame (:func:`goal_in_start_frame`) [m]."""
    here = np.asarray(start_places, dtype=np.float64)
    there = np.asarray(goal_places, dtype=np.float64)[list(pair)]
    ways, gap = _ways_in(problem, pair, there[:, :2])
    final, start = targets(problem, pair), rooted(problem.start)
    kids = children_of(start)
    moving = _moving_bodies(problem, pair, there[:, :2], pieces=True)
    out: dict[int, dict[int, Ride]] = {}
    for j, f in moving.items():
        body = set(f)
        if all(r in body for p in f for r in kids[p]):
            continue
        parent = list(start)
        parent[j] = final[j]
        piece, places = hold(here, parent, kids, final, there, j, start[j])
        at = dict(zip(piece, places[:, :2], strict=True))
        for p in f:
            for r in (r for r in kids[p] if r not in body):
                tree = [r]
                for m in tree:
                    tree.extend(kids[m])
                ride = np.array([at[m] for m in tree])
                others = [i for i in moving if i != j and i not in tree
                          and final[i] not in tree]
                lies = {i for i in others if float(np.min(np.linalg.norm(
                    ride[:, None] - there[moving[i]][None, :, :2], axis=2))) < gap}
                crosses = {i for i in others if i in ways and _swept_distance(
                    ways[i][0], ways[i][1], ways[i][2], ride) < gap}
                if lies or crosses:
                    out.setdefault(j, {})[r] = Ride(frozenset(lies | crosses),
                                                    frozenset(lies))
    return out


def _moving_bodies(problem: MisoProblem, pair: Sequence[int], there: np.ndarray,
                   pieces: bool = False) -> dict[int, np.ndarray | list[int]]:
    """The fragments that dock somewhere new, by root: their goal places ``there``
    (start index order, (n, 2)) [m], or (``pieces``) their modules."""
    final = targets(problem, pair)
    return {f[0]: (f if pieces else there[f]) for f in fragments(problem, pair)
            if final[f[0]] != FREE and final[f[0]] != problem.start[f[0]]}


def _ways_in(problem: MisoProblem, pair: Sequence[int], there: np.ndarray
             ) -> tuple[dict[int, tuple[np.ndarray, np.ndarray, float, int | None]], float]:
    """Each moving piece of two or more modules' way in (:func:`closed_ways`), by its
    root: its docked body (k, 2), its unit line, how far back it is swept [m], the root of
    the piece that holds its target (or ``None``); and the gap that closes a way [m]."""
    final = targets(problem, pair)
    links = [float(np.linalg.norm(there[i] - there[p])) for i, p in enumerate(final)
             if p != FREE]
    if not links:
        return {}, 0.0
    moving = _moving_bodies(problem, pair, there, pieces=True)
    holder = {m: j for j, f in moving.items() for m in f}
    out = {}
    for j, f in moving.items():
        if len(f) < 2:
            continue
        body = there[f]
        line = body.mean(axis=0) - there[final[j]]
        if float(np.linalg.norm(line)) < 1e-9:
            continue
        back = float(np.max(np.linalg.norm(body - body[0], axis=1))) + WAY_IN
        out[j] = (body, line / np.linalg.norm(line), back, holder.get(final[j]))
    return out, float(np.median(links)) - SLIDE_OVERLAP


def _swept_distance(body: np.ndarray, line: np.ndarray, back: float, points: np.ndarray
                    ) -> float:
    """The least distance [m] from ``points`` (k, 2) to ``body`` (m, 2) slid from where
    it is up to ``back`` [m] along the unit ``line`` (2,): each module's segment."""
    rel = points[:, None, :] - body[None, :, :]                        # (k, m, 2)
    along = np.clip(rel @ line, 0.0, back)
    return float(np.min(np.linalg.norm(rel - along[..., None] * line, axis=2)))
