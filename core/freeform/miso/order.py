"""Step order: legal steps from a start to the goal a pairing gives, under the robot's
rules, one step per mismatched module whenever the rules allow (:func:`order_steps`)."""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from typing import NamedTuple

import numpy as np

from ...errors import PlanningError
from .model import FREE, UNLIMITED, MisoLimits, Step, count_flows, cycles, depths

__all__ = ["Ride", "RiderClash", "Riding", "greedy_order", "leaf_order", "order_steps"]


class Ride(NamedTuple):
    """Where one rider rides once its carrier has docked (:func:`~.places.riding_ways`)."""

    ways: frozenset[int]
    """The moving modules (piece roots) whose way in, or docked body, the rider crosses."""
    bodies: frozenset[int]
    """Those whose docked body it lies on (a subset of ``ways``)."""


Riding = Mapping[int, Mapping[int, Ride]]
"""Per moving module, per rider it carries, where that rider rides (:class:`Ride`)."""


class RiderClash(PlanningError):
    """No legal move keeps every rider clear: each would dock a piece across a rider or
    carry a rider onto a docked piece (:func:`order_steps` with ``riding``)."""

    def __init__(self, step: int, module: int, rider: int, piece: int, carried: bool):
        self.step, self.module, self.rider, self.piece = step, module, rider, piece
        self.carried = carried
        super().__init__(self.describe(str))

    def describe(self, name: Callable[[int], str]) -> str:
        """The one-line refusal, modules named by ``name`` (index -> id)."""
        m, r, w = name(self.module), name(self.rider), name(self.piece)
        clash = (f"{m} would carry its rider {r} onto {w}'s docked body" if self.carried
                 else f"{m} would dock across {r}, which rides {w} until its own step")
        return (f"no step order keeps the riders clear: at step {self.step} every legal "
                f"move clashes, first {clash}")


class _State:
    """A pointer array with in-degrees kept up to date, for long step sequences."""

    def __init__(self, parent: Sequence[int], limits: MisoLimits):
        self.parent = list(parent)
        self.limits = limits
        self.indeg = [0] * len(self.parent)
        self.on: list[set[int]] = [set() for _ in self.parent]   # who sits on each
        for i, p in enumerate(self.parent):
            if p != FREE:
                self.indeg[p] += 1
                self.on[p].add(i)

    def flows(self, module: int, new: int) -> bool:
        """Whether re-targeting ``module`` to ``new`` is a flow (:func:`~.model.is_flow`)."""
        old = self.parent[module]
        return (old != FREE and new != FREE and new != module and self.indeg[module] == 0
                and (self.parent[new] == old or self.parent[old] == new))

    def blocker(self, module: int, new: int) -> int | None:
        """``None`` when the step is legal (:func:`~.model.step_is_legal`); ``FREE`` when
        ``new`` carries ``max_in`` already (one of its modules must leave); else the
        module next below ``module`` on the way from ``new`` (``new`` itself for the
        child rule): releasing a pending module on that way unblocks the step."""
        parent, limits = self.parent, self.limits
        if new == FREE:
            return None
        if limits.max_in is not None and self.indeg[new] >= limits.max_in:
            return FREE   # the caller picks a leaving child of ``new``
        if limits.no_docking_onto == "child":
            return new if parent[new] == module else None
        j, path = new, []
        while j != FREE:
            if j == module:
                return path[0] if path else FREE
            path.append(j)
            j = parent[j]
        return None

    def settled(self, module: int, pending: set[int], known: dict[int, bool]) -> bool:
        """Whether no pending module lies on ``module``'s way to its root (or round its
        ring): nothing there moves any more, so what docks on it stays put. ``known``:
        answers so far for this state, extended with every module of the way walked."""
        way: dict[int, None] = {}     # ordered, with fast membership
        answer = True
        while module != FREE:
            if module in known:
                answer = known[module]
                break
            if module in pending:
                answer = False
                break
            if module in way:      # round a ring that holds no pending module
                break
            way[module] = None
            module = self.parent[module]
        known.update(dict.fromkeys(way, answer))
        return answer

    def split_first(self, module: int, goal: Sequence[int], pending: set[int]) -> int:
        """The module to move before ``module``: the pending module of ``module``'s
        in-tree farthest from it whose step is legal onto a settled target, else
        ``module``. Moving it first splits its piece off where it lies, so ``module``
        carries less and no piece ever leaves from inside a piece that has travelled
        and docked (the human example's chains are cut from their far ends)."""
        best, seen, layer = module, {module}, list(self.on[module])
        known: dict[int, bool] = {}
        while layer:
            seen.update(layer)
            best = min((j for j in layer if j in pending and self.blocker(j, goal[j]) is None
                        and self.settled(goal[j], pending, known)), default=best)
            layer = [c for j in layer for c in self.on[j] if c not in seen]
        return best

    def carries(self, module: int, other: int) -> bool:
        """Whether ``other`` lies in ``module``'s in-tree (its connector path leads there)."""
        for _ in range(len(self.parent)):
            other = self.parent[other]
            if other in (FREE, module):
                return other == module
        return False

    def apply(self, module: int, new: int) -> Step:
        step = Step(module, self.parent[module], new)
        if step.old != FREE:
            self.indeg[step.old] -= 1
            self.on[step.old].discard(module)
        if new != FREE:
            self.indeg[new] += 1
            self.on[new].add(module)
        self.parent[module] = new
        return step


def order_steps(start: Sequence[int], goal: Sequence[int],
                goal_depth: Sequence[int] | None = None, *,
                limits: MisoLimits = UNLIMITED,
                closes: Mapping[int, Collection[int]] | None = None,
                riding: Riding | None = None) -> list[Step]:
    """Legal steps from ``start`` to ``goal`` (pointer arrays over the same indices).

    Modules move in increasing goal depth (:func:`~.model.depths` of ``goal``), each
    straight onto its target as soon as the rules allow: then the plan has exactly one
    step per mismatched module, ``d``, and its connection changes are those of the two
    connection sets. When every pending move is blocked -- its target carries
    ``limits.max_in`` connections, or is its child (its in-tree, for
    ``"descendant"``) -- one blocking module that must move anyway is released first
    (a *temporary* step to free); it connects to its target later. A release breaks the
    connection the module's direct move would break, so the plan's connection changes
    stay exactly those of the two sets; it costs one step.

    The greedy runs twice, once taking a pending flow (:func:`~.model.is_flow`) first
    whenever one is legal; that order is kept unless it needs more steps or holds
    fewer flows.

    ``closes[j]``: the modules whose way onto their target ``j``'s move would close once
    ``j`` has docked (:func:`~.places.closed_ways`, from the floor's places). A move
    that would close a pending module's way waits while another legal move does not
    (the next pending module in goal depth, split as it would be); when every legal
    move would close one, the first is made. ``riding[j][r]``: where rider ``r`` rides
    once ``j`` has docked carrying it (:class:`Ride`, :func:`~.places.riding_ways`).
    A rider never meets a piece (:func:`_clash`): no move docks a piece across a rider
    that rides there, and no carrier brings a rider onto a piece docked there; so the
    piece waits until the rider has left, or the carrier until its rider has left
    first, by its own step. A carrier whose riders would cross a pending piece's way
    also waits, as a move that would close it (the riders leave first, or that piece
    docks first).

    Under ``limits.carries == "nothing"`` the order is :func:`leaf_order`.

    Raises:
        RiderClash: every legal move clashes with a rider (in both greedy passes).
        PlanningError: no progress (a bug: every release frees a module that was held).
    """
    if goal_depth is None:
        goal_depth = depths(goal)
    if limits.carries == "nothing":
        return leaf_order(start, goal, goal_depth, limits)
    orders: list[list[Step]] = []
    for flows_first in (False, True):
        try:
            orders.append(greedy_order(start, goal, goal_depth, limits,
                                       flows_first=flows_first, closes=closes, riding=riding))
        except RiderClash as clash:
            refused = clash
    if not orders:
        raise refused
    plain, flowing = orders[0], orders[-1]
    if len(flowing) > len(plain) or (len(flowing) == len(plain) and count_flows(
            start, flowing) < count_flows(start, plain)):
        return plain
    return flowing


def greedy_order(start: Sequence[int], goal: Sequence[int], goal_depth: Sequence[int],
                 limits: MisoLimits, *, flows_first: bool,
                 closes: Mapping[int, Collection[int]] | None = None,
                 riding: Riding | None = None) -> list[Step]:
    """One greedy pass of :func:`order_steps`; ``flows_first``: a legal pending flow
    before any other legal move; ``closes``, ``riding``: as :func:`order_steps`'s."""
    n = len(start)
    state = _State(start, limits)
    steps: list[Step] = []
    pending = sorted((i for i in range(n) if start[i] != goal[i]),
                     key=lambda i: (goal_depth[i], i))
    waiting = set(pending)
    # the flow test of every pending module at once (index n stands for free)
    par = np.array([n if p == FREE else p for p in start] + [n], dtype=np.int64)
    deg = np.array(state.indeg + [0], dtype=np.int64)
    aim = np.array([n if g == FREE else g for g in goal] + [n], dtype=np.int64)
    while pending:
        if len(steps) > 2 * n:
            raise PlanningError("MISO step ordering made no progress")
        chosen = None
        if flows_first:
            at = np.asarray(pending, dtype=np.int64)
            old, new = par[at], aim[at]
            flows = (deg[at] == 0) & (old != n) & (new != n) & ((par[new] == old)
                                                                 | (par[old] == new))
            chosen = next((int(k) for k in np.flatnonzero(flows)
                           if state.blocker(pending[k], goal[pending[k]]) is None), None)
        i = None if chosen is None else state.split_first(pending[chosen], goal, waiting)
        if i is None or _clash(state, i, waiting, riding or {}) is not None:
            i = _next_move(state, pending, goal, waiting, closes or {}, riding or {},
                           len(steps) + 1)
        if i is not None:
            pending.remove(i)
            waiting.discard(i)
            step = state.apply(i, goal[i])
        else:
            step = _release(state, pending, goal)
        steps.append(step)
        par[step.module] = n if step.new == FREE else step.new
        deg[step.old] -= step.old != FREE
        deg[step.new] += step.new != FREE
    return steps


def _next_move(state: _State, pending: list[int], goal: Sequence[int], waiting: set[int],
               closes: Mapping[int, Collection[int]], riding: Riding, step: int
               ) -> int | None:
    """The module to move next: the first legal pending module in ``pending``'s order,
    split as :meth:`_State.split_first` splits it, that clashes with no rider
    (:func:`_clash`) and closes no pending module's way (``closes``, its riders'
    included), else the first legal one that clashes with no rider; ``None`` when no
    move is legal.

    Raises:
        RiderClash: every legal move clashes (``step``: the step it would be)."""
    first, clash = None, None
    for k in pending:
        if state.blocker(k, goal[k]) is not None:
            continue
        i = state.split_first(k, goal, waiting)
        hit = _clash(state, i, waiting, riding)
        if hit is not None:
            clash = clash or RiderClash(step, i, *hit)
            continue
        riders = riding.get(i, {})
        if waiting.isdisjoint(closes.get(i, ())) and not any(
                r in waiting and not waiting.isdisjoint(ride.ways) and state.carries(i, r)
                for r, ride in riders.items()):
            return i
        first = i if first is None else first
    if first is None and clash is not None:
        raise clash
    return first


def _clash(state: _State, i: int, waiting: set[int], riding: Riding
           ) -> tuple[int, int, bool] | None:
    """Whether moving ``i`` now makes a rider meet a piece, and which: ``(rider, piece,
    carried)``. A rider rides from its carrier's step (while it still hangs from it) to
    its own; ``i`` docks across one that rides there (``carried`` false, ``piece`` its
    carrier), or ``i`` carries one onto a piece docked where it would ride (``carried``
    true); else ``None``."""
    for r, ride in riding.get(i, {}).items():
        if r in waiting and state.carries(i, r):
            docked = sorted(ride.bodies - waiting)
            if docked:
                return r, docked[0], True
    for j, riders in riding.items():
        if j in waiting:
            continue
        for r, ride in riders.items():
            if i in ride.ways and r in waiting and state.carries(j, r):
                return r, j, False
    return None


def _release(state: _State, pending: list[int], goal: Sequence[int]) -> Step:
    """Free one held pending module that blocks the first pending move."""
    parent = state.parent
    for i in pending:
        k = goal[i]
        j = state.blocker(i, k)
        if j == FREE:   # full target: one of its modules must leave it anyway
            j = next((c for c in pending if parent[c] == k and goal[c] != k), FREE)
        elif j is not None and goal[j] == parent[j]:
            # a descendant rule block: release the first pending module on the path
            j = k
            while j != FREE and goal[j] == parent[j]:
                j = parent[j]
            j = FREE if j == i else j
        if j is not None and j != FREE and parent[j] != FREE:
            return state.apply(j, FREE)
    raise PlanningError("MISO step ordering found no module to release")  # pragma: no cover


def leaf_order(start: Sequence[int], goal: Sequence[int], goal_depth: Sequence[int],
               limits: MisoLimits) -> list[Step]:
    """Legal steps from ``start`` to an acyclic ``goal`` (pointer arrays) for a robot whose
    docking module carries nothing (``limits.carries == "nothing"``): a piece that must
    move is taken apart into modules that each move alone, and built again.

    Letting go moves nothing, so a pending module whose goal is free lets go at once.
    Each ring of the start is opened by letting go one of its pending modules (the goal
    has no ring, so every ring holds one), one that is free in the goal if there is.
    Then pending modules are taken in increasing goal depth, so the goal is built from
    its roots out: one docks straight onto its target once nothing is docked on it, the
    target carries fewer than ``limits.max_in`` and is *settled* (no pending module on
    the target's way to its root: that one would have to shed all it carries, this
    module too). When none can,
    the first pending module held up by a module that carries others (itself, one on its
    target's way, or a leaving module of its full target) sheds: the first pending
    module of that module's in-tree lets go (the break its own move needs anyway), else
    a kept leaf does (a temporary step; it docks back later, two steps and two changes
    more).

    Raises:
        PlanningError: no progress (a bug).
    """
    n = len(start)
    state = _State(start, limits)
    parent, indeg = state.parent, state.indeg
    on: list[set[int]] = [set() for _ in range(n)]
    for i, p in enumerate(parent):
        if p != FREE:
            on[p].add(i)
    pending = {i for i in range(n) if start[i] != goal[i]}
    steps: list[Step] = []

    def settled(k: int) -> bool:
        while k != FREE:
            if k in pending:
                return False
            k = parent[k]
        return True

    def movable(i: int) -> bool:
        k = goal[i]
        return k == FREE or (indeg[i] == 0 and settled(k) and (
            limits.max_in is None or indeg[k] < limits.max_in))

    def move(i: int, new: int) -> None:
        if parent[i] != FREE:
            on[parent[i]].discard(i)
        if new != FREE:
            on[new].add(i)
        steps.append(state.apply(i, new))
        (pending.discard if new == goal[i] else pending.add)(i)

    for ring in cycles(start):
        move(min((m for m in ring if m in pending), key=lambda m: goal[m] != FREE), FREE)
    while pending:
        if len(steps) > 4 * n:
            raise PlanningError("MISO step ordering (docking modules carry nothing) made no "
                                "progress")
        order = sorted(pending, key=lambda i: (goal_depth[i], i))
        i = next((i for i in order if movable(i)), None)
        if i is None:
            i = _shed(order, goal, parent, on, indeg, pending, limits)
        move(i, goal[i] if movable(i) else FREE)
    return steps


def _shed(order: list[int], goal: Sequence[int], parent: list[int], on: list[set[int]],
          indeg: list[int], pending: set[int], limits: MisoLimits) -> int:
    """The module to let go when no pending module can dock (:func:`leaf_order`)."""
    for i in order:
        k = goal[i]
        if indeg[i] > 0:
            holder = i
        elif limits.max_in is not None and indeg[k] >= limits.max_in:
            holder = min(c for c in on[k] if goal[c] != k)   # one must leave it anyway
        else:
            holder = k
            while holder not in pending:   # the first pending module on the way
                holder = parent[holder]
            if holder == k and indeg[k] == 0:
                continue   # a pending target that carries nothing: it docks in its turn
        if indeg[holder] == 0:
            return holder   # a leaving module of a full target
        layer, kept_leaf = sorted(on[holder]), None
        while layer:
            found = next((m for m in layer if m in pending), None)
            if found is not None:
                return found
            kept_leaf = next((m for m in layer if not on[m]), kept_leaf)
            layer = sorted(c for m in layer for c in on[m])
        if kept_leaf is not None:
            return kept_leaf
    raise PlanningError("MISO step ordering (docking modules carry nothing) found no "
                        "module to move")  # pragma: no cover
