"""Step order: legal steps from a start to the goal a pairing gives, under the robot's
rules, one step per mismatched module whenever the rules allow (:func:`order_steps`)."""

from __future__ import annotations

from collections.abc import Sequence

from ...errors import PlanningError
from .model import FREE, UNLIMITED, MisoLimits, Step, count_flows, depths

__all__ = ["greedy_order", "order_steps"]


class _State:
    """A pointer array with in-degrees kept up to date, for long step sequences."""

    def __init__(self, parent: Sequence[int], limits: MisoLimits):
        self.parent = list(parent)
        self.limits = limits
        self.indeg = [0] * len(self.parent)
        for p in self.parent:
            if p != FREE:
                self.indeg[p] += 1

    def flows(self, module: int, new: int) -> bool:
        """Whether re-targeting ``module`` to ``new`` is a flow (:func:`~.model.is_flow`)."""
        old = self.parent[module]
        return (old != FREE and new != FREE and new != module and self.indeg[module] == 0
                and (self.parent[new] == old or self.parent[old] == new))

    def blocker(self, module: int, new: int) -> int | None:
        """``None`` when the step is legal (:func:`~.model.step_is_legal`), else a
        module whose temporary release would unblock it (``FREE`` when none would)."""
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

    def apply(self, module: int, new: int) -> Step:
        step = Step(module, self.parent[module], new)
        if step.old != FREE:
            self.indeg[step.old] -= 1
        if new != FREE:
            self.indeg[new] += 1
        self.parent[module] = new
        return step


def order_steps(start: Sequence[int], goal: Sequence[int],
                goal_depth: Sequence[int] | None = None, *,
                limits: MisoLimits = UNLIMITED) -> list[Step]:
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

    Raises:
        PlanningError: no progress (a bug: every release frees a module that was held).
    """
    if goal_depth is None:
        goal_depth = depths(goal)
    plain = greedy_order(start, goal, goal_depth, limits, flows_first=False)
    flowing = greedy_order(start, goal, goal_depth, limits, flows_first=True)
    if len(flowing) > len(plain) or (len(flowing) == len(plain) and count_flows(
            start, flowing) < count_flows(start, plain)):
        return plain
    return flowing


def greedy_order(start: Sequence[int], goal: Sequence[int], goal_depth: Sequence[int],
                 limits: MisoLimits, *, flows_first: bool) -> list[Step]:
    """One greedy pass of :func:`order_steps`; ``flows_first``: a legal pending flow
    before any other legal move."""
    n = len(start)
    state = _State(start, limits)
    steps: list[Step] = []
    pending = sorted((i for i in range(n) if start[i] != goal[i]),
                     key=lambda i: (goal_depth[i], i))
    while pending:
        if len(steps) > 2 * n:
            raise PlanningError("MISO step ordering made no progress")
        chosen = None
        if flows_first:
            chosen = next((k for k, i in enumerate(pending) if state.flows(i, goal[i])
                           and state.blocker(i, goal[i]) is None), None)
        if chosen is None:
            chosen = next((k for k, i in enumerate(pending)
                           if state.blocker(i, goal[i]) is None), None)
        if chosen is not None:
            i = pending.pop(chosen)
            steps.append(state.apply(i, goal[i]))
            continue
        steps.append(_release(state, pending, goal))
    return steps


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
