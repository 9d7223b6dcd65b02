"""MISO connection planning: the fewest connection changes between two MISO trees.

Multiple-In-degree Single-Out-degree (MISO) modules -- FreeBOT, SnailBot -- have one
connector each: a module makes at most one out-connection but may carry any number
of others (``msrr.core.robot.MisoRules``). Luo and Lam (2023, "Auto-optimizing
connection planning method for chain-type modular self-reconfiguration robots",
the planning the FreeSN paper cites in section 2.1) plan the connection changes between
two such configurations with a polynomial-time pairing heuristic and an exact search.
This module implements that problem from its statement; the code is our own.

**Model.** A connected configuration of ``n`` identical MISO modules is a pointer
array ``parent[i]``: the module that module ``i``'s connector sits on, ``-1`` if free. It
is a *tree* (``n - 1`` connections, exactly one free module, the *sink*) or, with every
connector used, *unicyclic* (one cycle). Start and goal are trees; intermediate
configurations may close the one cycle.

A *step* re-targets one module's connector, ``parent[i]: j -> k`` (``j`` or ``k`` may
be ``-1``: a pure connection or disconnection); the module's own in-tree moves with it.
A step is legal when the configuration after it is connected: in a tree, the sink
may connect anywhere, another module only onto a module outside its own in-tree
``T_i``; in a unicyclic configuration a module on the cycle may go anywhere (or free
itself), another only outside ``T_i``. A step whose module is a leaf (no module on it)
and whose new target is a neighbour of the old one (one sits on the other) is the
FreeSN paper's *flow* (section 4.1; :func:`is_flow`, the pointer-array form of
:func:`msrr.core.actions.flow_move`).

**Metric.** The number of steps: every re-targeting counts one, flow or not. A flow is
one step because section 4.1 makes it one action ("the disconnection and connection
happen simultaneously") and Luo and Lam count reconfiguration steps by the connection
changes of one module; both planners use this metric, so the exact planner's optimum
is the heuristic's yardstick. Flows break ties: among step orders of equal length the
heuristic keeps the one with more flows, the exact planner's A* the one with fewer
non-flow steps (:func:`order_steps`, :func:`_shortest`). Maximising flows across
pairings is not attempted.

**Problem.** Modules are identical, so the goal's ids are labels to assign: find a
pairing ``pi`` (start module -> goal module) and a legal step sequence from the
start to the goal relabelled by ``pi^-1`` with the fewest steps. Every module whose
target differs needs at least one step, so for a pairing

    d(pi) = |{i : G_pi(i) != parent(i)}|,   G_pi(i) = pi^-1(parent_goal(pi(i)))

is a lower bound on its steps; ``d`` is ``(n - 1 - kept) + [pi(sink) != goal sink]``
with ``kept`` the connections both configurations share under ``pi``.

**Algorithms.**

* :func:`solve_heuristic` (polynomial): the pairing greedily aligns the largest
  common rooted sub-trees, top down: ``sim(u, v)`` is the most connections kept when
  ``u`` pairs ``v`` and their subtrees align, a maximum-weight bipartite matching of
  the children (``1 + sim`` per child pair; scipy's ``linear_sum_assignment``), chains
  walked without recursion. Each round pairs the fragment root and goal node (or goal
  fragment root and start node) with the best score and removes them; leftovers pair
  arbitrarily. Steps are then ordered by the goal depth of their target (the start's
  sink first when it moves), which needs exactly ``d(pi)`` steps when the sinks
  agree; a module whose target lies in its own in-tree is unblocked by one temporary
  move.
* :func:`solve_exact` (exponential): branch and bound over pairings in the goal's
  breadth-first order with the admissible bound ``max(partial d, ceil(sum |in-degree
  change| / 2))`` (a step changes two in-degrees by one), goal siblings with equal
  subtree shapes taking increasing start indices (one side only: breaking start and
  goal symmetries together could cut every optimum),
  and for each complete pairing an A* over legal steps with the consistent heuristic
  "modules not at their target". Starts from the heuristic's plan as upper bound.
* :func:`brute_force_steps`: breadth-first search over every labelled configuration
  until one is isomorphic to the goal -- the reference the exact search is tested
  against.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..actions import flow_move, topology_diff
from ..configuration import Configuration
from ..errors import PlanningError
from ..plan import Action, ActionType, ConnectionChange, Plan

__all__ = [
    "MisoPlanner",
    "MisoProblem",
    "MisoSolution",
    "Step",
    "brute_force_steps",
    "canonical_form",
    "count_flows",
    "is_flow",
    "order_steps",
    "plan_miso",
    "random_miso_tree",
    "solve_exact",
    "solve_heuristic",
    "step_is_legal",
]

FREE = -1
"""``parent[i]`` of a module whose connector is free."""


# -- the problem ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Step:
    """Module ``module`` moves its connector from ``old`` to ``new`` (indices; -1 free)."""

    module: int
    old: int
    new: int


@dataclass(frozen=True)
class MisoProblem:
    """Start and goal MISO trees as pointer arrays.

    Attributes:
        start_ids: module ids of the start, index order.
        start: ``parent`` of each start module (index, or -1 for the sink).
        goal_ids: module ids of the goal (labels to assign).
        goal: ``parent`` of each goal module.
    """

    start_ids: tuple[str, ...]
    start: tuple[int, ...]
    goal_ids: tuple[str, ...]
    goal: tuple[int, ...]

    @classmethod
    def from_parents(cls, start: Sequence[int], goal: Sequence[int]) -> MisoProblem:
        """A problem over anonymous modules ``0..n-1`` (ids ``"0"``, ``"1"``...)."""
        if len(start) != len(goal):
            raise PlanningError(f"start has {len(start)} modules, goal {len(goal)}")
        for name, parent in (("start", start), ("goal", goal)):
            _check_tree(parent, name)
        ids = tuple(str(i) for i in range(len(start)))
        return cls(ids, tuple(start), ids, tuple(goal))

    @classmethod
    def from_configurations(cls, start: Configuration, goal: Configuration) -> MisoProblem:
        """Read two configurations of MISO modules (trees, no virtual vertices).

        Raises:
            PlanningError: module counts differ, or either is not a connected MISO tree.
        """
        s_ids, s_parent = pointer_form(start, "start")
        g_ids, g_parent = pointer_form(goal, "goal")
        if len(s_ids) != len(g_ids):
            raise PlanningError(f"start {start.name or ''} has {len(s_ids)} modules, goal "
                                f"{goal.name or ''} has {len(g_ids)}")
        kinds = sorted(start.kind_of(v) for v in s_ids), sorted(goal.kind_of(v) for v in g_ids)
        if kinds[0] != kinds[1]:
            raise PlanningError("start and goal are made of different module kinds")
        return cls(s_ids, s_parent, g_ids, g_parent)

    @property
    def n(self) -> int:
        return len(self.start)


def pointer_form(config: Configuration, what: str = "configuration"
                 ) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """Module ids and ``parent`` pointers of a MISO tree configuration.

    Raises:
        PlanningError: a virtual vertex, a module with two out-connections, or not a
            connected tree.
    """
    ids = tuple(config.vertices())
    index = {v: i for i, v in enumerate(ids)}
    parent = [FREE] * len(ids)
    for v in ids:
        if config.is_virtual(v):
            raise PlanningError(f"{what} {config.name or ''}: MISO planning takes modules "
                                f"only, {v} is a virtual vertex")
    for edge in config.edges():
        i = index[edge.source]
        if parent[i] != FREE:
            raise PlanningError(f"{what} {config.name or ''}: module {edge.source} has two "
                                "out-connections; MISO modules have one connector")
        parent[i] = index[edge.target]
    _check_tree(parent, f"{what} {config.name or ''}".strip())
    return ids, tuple(parent)


def _check_tree(parent: Sequence[int], what: str) -> None:
    n = len(parent)
    if n == 0:
        raise PlanningError(f"{what}: no modules")
    if sum(1 for p in parent if p == FREE) != 1 or not _reaches_sink(parent):
        raise PlanningError(f"{what}: not one connected tree (every module's connections "
                            "must lead to the one module with a free connector)")


def _reaches_sink(parent: Sequence[int]) -> bool:
    n = len(parent)
    state = [0] * n  # 0 unknown, 1 on the current walk, 2 reaches the sink
    for start in range(n):
        walk, j = [], start
        while j != FREE and state[j] == 0:
            state[j] = 1
            walk.append(j)
            j = parent[j]
        if j != FREE and state[j] == 1:
            return False
        for w in walk:
            state[w] = 2
    return True


def children_of(parent: Sequence[int]) -> list[list[int]]:
    """In-neighbours of every module: ``children[j] = [i : parent[i] == j]``."""
    children: list[list[int]] = [[] for _ in parent]
    for i, p in enumerate(parent):
        if p != FREE:
            children[p].append(i)
    return children


def _bfs(parent: Sequence[int]) -> tuple[list[int], list[int]]:
    """Breadth-first order from the sink and the depth of every module."""
    children = children_of(parent)
    root = parent.index(FREE)
    order, depth = [root], [0] * len(parent)
    for u in order:
        for c in children[u]:
            depth[c] = depth[u] + 1
            order.append(c)
    return order, depth


def shape_labels(parent: Sequence[int]) -> list[int]:
    """AHU labels: equal labels <=> isomorphic rooted subtrees (ints, per module)."""
    order, _ = _bfs(parent)
    children = children_of(parent)
    table: dict[tuple[int, ...], int] = {}
    label = [0] * len(parent)
    for u in reversed(order):
        key = tuple(sorted(label[c] for c in children[u]))
        label[u] = table.setdefault(key, len(table))
    return label


def canonical_form(parent: Sequence[int]) -> tuple | None:
    """A hashable form equal for isomorphic rooted trees; ``None`` unless a tree."""
    if sum(1 for p in parent if p == FREE) != 1 or not _reaches_sink(parent):
        return None
    order, _ = _bfs(parent)
    children = children_of(parent)
    form: list[tuple] = [()] * len(parent)
    for u in reversed(order):
        form[u] = tuple(sorted(form[c] for c in children[u]))
    return form[order[0]]


def random_miso_tree(n: int, rng: np.random.Generator, *, max_branching: int | None = None,
                     max_in_degree: int = 6) -> tuple[int, ...]:
    """A random MISO tree as a pointer array, like the instance generator of Luo and Lam.

    Modules join in random order, each onto a random module already placed whose
    in-degree is below ``max_in_degree``; a module may take a second connection only
    while fewer than ``max_branching`` modules branch (``None``: no bound).
    """
    order = rng.permutation(n)
    parent = [FREE] * n
    indeg = [0] * n
    placed = [int(order[0])]
    branching = 0
    for t in range(1, n):
        i = int(order[t])
        while True:
            p = placed[int(rng.integers(len(placed)))]
            if indeg[p] >= max_in_degree:
                continue
            if indeg[p] == 1 and max_branching is not None and branching >= max_branching:
                continue
            break
        branching += indeg[p] == 1
        parent[i], indeg[p] = p, indeg[p] + 1
        placed.append(i)
    return tuple(parent)


# -- legality -----------------------------------------------------------------------------


def _cycle(parent: Sequence[int]) -> set[int]:
    """The modules on the cycle of a unicyclic pointer array."""
    j = 0
    for _ in range(len(parent)):
        j = parent[j]
    cycle, k = {j}, parent[j]
    while k != j:
        cycle.add(k)
        k = parent[k]
    return cycle


def step_is_legal(parent: Sequence[int], module: int, new: int) -> bool:
    """Whether re-targeting ``module``'s connector to ``new`` (-1: free) leaves the
    configuration connected (``parent`` a tree or unicyclic, connected)."""
    if new == module or parent[module] == new:
        return False
    sinks = [j for j, p in enumerate(parent) if p == FREE]
    if sinks:
        if module == sinks[0]:
            return new != FREE
        stop: set[int] = set()
    else:
        stop = _cycle(parent)
        if module in stop:
            return True
    if new == FREE:
        return False
    j = new
    while j != FREE and j not in stop:
        if j == module:
            return False
        j = parent[j]
    return True


class _State:
    """A pointer array with its sink or cycle kept up to date, for long step sequences."""

    def __init__(self, parent: Sequence[int]):
        self.parent = list(parent)
        self.sink = self.parent.index(FREE) if FREE in self.parent else FREE
        self.cycle: set[int] = set() if self.sink != FREE else _cycle(self.parent)
        self.indeg = [0] * len(self.parent)
        for p in self.parent:
            if p != FREE:
                self.indeg[p] += 1

    def flows(self, module: int, new: int) -> bool:
        """Whether re-targeting ``module`` to ``new`` is a flow (:func:`is_flow`)."""
        old = self.parent[module]
        return (old != FREE and new != FREE and new != module and self.indeg[module] == 0
                and (self.parent[new] == old or self.parent[old] == new))

    def legal(self, module: int, new: int) -> bool:
        parent = self.parent
        if new == module or parent[module] == new:
            return False
        if self.sink != FREE:
            if module == self.sink:
                return new != FREE
        elif module in self.cycle:
            return True
        if new == FREE:
            return False
        j, stop = new, self.cycle
        while j != FREE and j not in stop:
            if j == module:
                return False
            j = parent[j]
        return True

    def apply(self, module: int, new: int) -> Step:
        step = Step(module, self.parent[module], new)
        if step.old != FREE:
            self.indeg[step.old] -= 1
        if new != FREE:
            self.indeg[new] += 1
        self.parent[module] = new
        if new == FREE:
            self.sink, self.cycle = module, set()
        elif self.sink == module or module in self.cycle:
            self.sink = FREE
            self.cycle = _cycle(self.parent)
        return step


# -- pairing ------------------------------------------------------------------------------------


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


def _sizes(children: list[list[int]], roots: Iterable[int]) -> dict[int, int]:
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


RESTART_BUDGET = 400
"""Greedy pairings tried per instance: ``max(1, RESTART_BUDGET // n)`` forced first pairs."""

ROUND_WIDTH = 64
"""Largest fragment roots scored per side in each greedy round."""


def heuristic_pairing(problem: MisoProblem) -> list[int]:
    """A pairing ``pi`` (start index -> goal index) that keeps many connections.

    Greedy rounds of top-down alignment (module docstring). The plain greedy runs
    once; for small instances it is restarted from other forced first pairs, the best
    scoring pairs of whole subtrees first, ``max(1, RESTART_BUDGET // n)`` runs in all,
    and the pairing with the fewest mismatches wins. Polynomial: each round scores
    at most ``ROUND_WIDTH`` fragment roots per side against unpaired modules, pruned
    by subtree sizes.
    """
    n = problem.n
    best = _greedy_pairing(problem, None)
    best_d = mismatches(problem.start, targets(problem, best))
    restarts = RESTART_BUDGET // n - 1
    if restarts <= 0 or best_d == 0:
        return best
    aligner = _Aligner(children_of(problem.start), children_of(problem.goal))
    firsts = sorted(((aligner.sim(u, v), u, v) for u in range(n) for v in range(n)),
                    key=lambda t: -t[0])
    for _, u, v in firsts[:restarts]:
        pair = _greedy_pairing(problem, (u, v))
        d = mismatches(problem.start, targets(problem, pair))
        if d < best_d:
            best, best_d = pair, d
            if d == 0:
                break
    return best


def _greedy_pairing(problem: MisoProblem, first: tuple[int, int] | None) -> list[int]:
    n, pa, pb = problem.n, problem.start, problem.goal
    sink_a, sink_b = pa.index(FREE), pb.index(FREE)
    kids_a, kids_b = children_of(pa), children_of(pb)
    pair: list[int] = [FREE] * n
    free_a, free_b = set(range(n)), set(range(n))

    def bonus(u: int, v: int) -> int:
        if u == sink_a and v == sink_b:
            return 1
        return int(pa[u] != FREE and pb[v] != FREE and pair[pa[u]] == pb[v])

    while free_a:
        ca = [[c for c in kids if c in free_a] if u in free_a else []
              for u, kids in enumerate(kids_a)]
        cb = [[c for c in kids if c in free_b] if v in free_b else []
              for v, kids in enumerate(kids_b)]
        roots_a = [u for u in free_a if pa[u] == FREE or pa[u] not in free_a]
        roots_b = [v for v in free_b if pb[v] == FREE or pb[v] not in free_b]
        size_a, size_b = _sizes(ca, roots_a), _sizes(cb, roots_b)
        aligner = _Aligner(ca, cb)
        if first is not None:
            best_pair, first = first, None
        else:
            best, best_pair = 0, None
            by_a = sorted(free_a, key=lambda u: (-size_a[u], u))
            by_b = sorted(free_b, key=lambda v: (-size_b[v], v))
            for roots, others, size_r, size_o, flip in (
                    (roots_a, by_b, size_a, size_b, False), (roots_b, by_a, size_b, size_a, True)):
                for r in sorted(roots, key=lambda x: (-size_r[x], x))[:ROUND_WIDTH]:
                    if size_r[r] <= best:
                        break
                    for o in others:
                        # sim <= min(size) - 1 and the bonus is at most 1
                        if min(size_r[r], size_o[o]) <= best:
                            break
                        u, v = (o, r) if flip else (r, o)
                        score = aligner.sim(u, v) + bonus(u, v)
                        if score > best:
                            best, best_pair = score, (u, v)
            if best_pair is None:
                break
        for a, b in aligner.align(*best_pair):
            pair[a] = b
            free_a.discard(a)
            free_b.discard(b)
    # leftovers: a child of a paired module onto a free child of its partner, then any
    for a in sorted(free_a):
        p = pa[a]
        if p != FREE and pair[p] != FREE:
            for b in kids_b[pair[p]]:
                if b in free_b:
                    pair[a] = b
                    free_a.discard(a)
                    free_b.discard(b)
                    break
    for a, b in zip(sorted(free_a), sorted(free_b), strict=True):
        pair[a] = b
    return pair


def targets(problem: MisoProblem, pair: Sequence[int]) -> list[int]:
    """``G_pi``: the goal's parent of every start module, in start indices."""
    inverse = [0] * problem.n
    for a, b in enumerate(pair):
        inverse[b] = a
    return [FREE if problem.goal[b] == FREE else inverse[problem.goal[b]] for b in pair]


def mismatches(parent: Sequence[int], goal: Sequence[int]) -> int:
    """``d``: modules whose connector is not yet on its target."""
    return sum(1 for p, g in zip(parent, goal, strict=True) if p != g)


# -- step order ---------------------------------------------------------------------------


def order_steps(start: Sequence[int], goal: Sequence[int],
                goal_depth: Sequence[int] | None = None) -> list[Step]:
    """Legal steps from ``start`` to ``goal`` (both pointer arrays in start indices).

    The start's sink moves first when it has to; then modules move in increasing goal
    depth, each straight onto its target once that is legal. When none is legal, one
    temporary move unblocks the shallowest blocked module (module docstring).

    Flows first: the same greedy is also run preferring, at every step, a pending
    module whose move is a flow (:func:`is_flow`; each flow can make its parent's other
    leaves flow next, as a chain collapsing into a star), and that order is kept unless
    it needs more steps. Both orders move every pending module straight to its target,
    so the flows cost nothing in steps.

    Raises:
        PlanningError: no progress (a bug: the order always terminates).
    """
    if goal_depth is None:
        goal_depth = _bfs(goal)[1]
    plain = _greedy_order(start, goal, goal_depth, flows_first=False)
    flowing = _greedy_order(start, goal, goal_depth, flows_first=True)
    if len(flowing) > len(plain):
        return plain
    if len(flowing) == len(plain) and count_flows(start, flowing) < count_flows(start, plain):
        return plain
    return flowing


def _greedy_order(start: Sequence[int], goal: Sequence[int], goal_depth: Sequence[int],
                  *, flows_first: bool) -> list[Step]:
    n = len(start)
    state = _State(start)
    steps: list[Step] = []
    pending = sorted((i for i in range(n) if start[i] != goal[i]), key=lambda i: goal_depth[i])
    limit = 3 * n + 10
    while pending:
        if len(steps) > limit:
            raise PlanningError("MISO step ordering made no progress")
        moved = False
        for allowed in ((state.flows, state.legal) if flows_first else (state.legal,)):
            idx = next((k for k, i in enumerate(pending) if allowed(i, goal[i])), None)
            if idx is not None:
                i = pending.pop(idx)
                steps.append(state.apply(i, goal[i]))
                moved = True
                break
        if moved:
            continue
        steps.append(_unblock(state, pending, goal))
        pending = sorted((i for i in range(n) if state.parent[i] != goal[i]),
                         key=lambda i: goal_depth[i])
    return steps


def is_flow(parent: Sequence[int], module: int, new: int) -> bool:
    """Whether re-targeting ``module``'s connector to ``new`` is a flow (section 4.1) in
    the pointer array ``parent``: ``module`` is a leaf (connected to its parent only, no
    module on it) and ``new`` is a neighbour of its parent (the parent sits on ``new``,
    or ``new`` sits on the parent). The pointer-array form of
    :func:`msrr.core.actions.flow_move` (tests check they agree on every step)."""
    old = parent[module]
    return (old != FREE and new != FREE and new != module and module not in parent
            and (parent[new] == old or parent[old] == new))


def count_flows(start: Sequence[int], steps: Iterable[Step]) -> int:
    """How many of ``steps``, applied from ``start``, are flows."""
    parent, flows = list(start), 0
    for step in steps:
        flows += is_flow(parent, step.module, step.new)
        parent[step.module] = step.new
    return flows


def _unblock(state: _State, pending: list[int], goal: Sequence[int]) -> Step:
    """One temporary move that makes a blocked pending move legal."""
    parent = state.parent
    for i in pending:
        k = goal[i]
        if k == FREE:
            continue
        # k lies in T_i: move the module just below i on the path k -> i out of T_i
        j = k
        while parent[j] != i:
            j = parent[j]
        anchor = state.sink if state.sink != FREE else min(state.cycle)
        if state.legal(j, anchor):
            return state.apply(j, anchor)
    # only the goal's sink is blocked: it is off the cycle; re-close the cycle through it
    g = next(i for i in pending if goal[i] == FREE)
    for c in sorted(state.cycle):
        if state.legal(c, g):
            return state.apply(c, g)
    raise PlanningError("MISO step ordering found no temporary move")  # pragma: no cover


# -- solutions ----------------------------------------------------------------------------


@dataclass
class MisoSolution:
    """A pairing and the steps that realise it.

    Attributes:
        pairing: goal index of every start module.
        steps: legal steps from the start to the relabelled goal.
        lower_bound: a proven lower bound on the optimum (``d`` of the pairing for the
            heuristic, the optimum itself when ``optimal``).
        optimal: the exact search proved the step count minimal.
        stats: counters (``nodes``, ``pairings``, ``time_ms``).
    """

    pairing: list[int]
    steps: list[Step]
    lower_bound: int
    optimal: bool = False
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def cost(self) -> int:
        return len(self.steps)


def solve_heuristic(problem: MisoProblem) -> MisoSolution:
    """Polynomial-time pairing and step order (module docstring)."""
    t0 = time.perf_counter()
    pair = heuristic_pairing(problem)
    goal = targets(problem, pair)
    depth_b = _bfs(problem.goal)[1]
    steps = order_steps(problem.start, goal, [depth_b[b] for b in pair])
    d = mismatches(problem.start, goal)
    return MisoSolution(pair, steps, d, optimal=False,
                        stats={"time_ms": 1e3 * (time.perf_counter() - t0)})


def _shortest(start: Sequence[int], goal: Sequence[int], bound: int,
              depth: Sequence[int]) -> list[Step] | None:
    """Fewest legal steps from ``start`` to ``goal`` if fewer than ``bound``, else None.

    The goal-depth order first (optimal when it needs only ``d`` steps), then A* with
    the consistent heuristic ``d`` over every legal step; among paths of equal length
    A* keeps the one with fewer steps that are not flows (lexicographic cost
    ``(steps, non-flows)``, still admissible and consistent with ``(d, 0)``).
    """
    d = mismatches(start, goal)
    if d >= bound:
        return None
    greedy = order_steps(start, goal, depth)
    if len(greedy) == d:
        return greedy
    n = len(start)
    best_known = min(bound, len(greedy))
    origin = tuple(start)
    came: dict[tuple[int, ...], tuple[tuple[int, ...], Step] | None] = {origin: None}
    cost = {origin: (0, 0)}
    heap = [(d, 0, 0, origin)]
    target = tuple(goal)
    while heap:
        f, rough, g, state = heapq.heappop(heap)
        if (g, rough) > cost[state]:
            continue
        if state == target:
            steps = []
            while came[state] is not None:
                state, step = came[state]
                steps.append(step)
            return steps[::-1] if len(steps) < bound else None
        if f >= best_known:
            break
        for i in range(n):
            for k in range(FREE, n):
                if not step_is_legal(state, i, k):
                    continue
                nxt = list(state)
                nxt[i] = k
                key = tuple(nxt)
                ng, nrough = g + 1, rough + (not is_flow(state, i, k))
                if (ng, nrough) < cost.get(key, (1 << 30, 0)):
                    cost[key] = (ng, nrough)
                    came[key] = (state, Step(i, state[i], k))
                    h = mismatches(key, target)
                    if ng + h < best_known:
                        heapq.heappush(heap, (ng + h, nrough, ng, key))
    return greedy if len(greedy) < bound else None


def solve_exact(problem: MisoProblem, *, node_limit: int = 2_000_000) -> MisoSolution:
    """Branch and bound over pairings with A* step ordering (module docstring).

    Args:
        problem: the instance.
        node_limit: pairing-tree nodes to expand before giving up proof of optimality
            (the best plan found so far is returned with ``optimal=False``).
    """
    t0 = time.perf_counter()
    heuristic = solve_heuristic(problem)
    n, pa, pb = problem.n, problem.start, problem.goal
    best_pair, best_steps = heuristic.pairing, heuristic.steps
    order_b, depth_b = _bfs(pb)
    label_b = shape_labels(pb)
    children_a = children_of(pa)
    indeg_a = [len(c) for c in children_a]
    indeg_b = [len(c) for c in children_of(pb)]
    # goal symmetry: a later sibling with the same subtree shape takes a larger index
    twin_before = [FREE] * n
    seen: dict[tuple[int, int], int] = {}
    for v in order_b:
        key = (pb[v], label_b[v])
        twin_before[v] = seen.get(key, FREE)
        seen[key] = v
    assign = [FREE] * n   # goal -> start
    used = [False] * n
    stats = {"nodes": 0.0, "pairings": 0.0}
    exhausted = True

    def search(pos: int, partial: int, degree_gap: int) -> None:
        nonlocal best_pair, best_steps, exhausted
        stats["nodes"] += 1
        if stats["nodes"] > node_limit:
            exhausted = False
            return
        if max(partial, -(-degree_gap // 2)) >= len(best_steps):
            return
        if pos == n:
            stats["pairings"] += 1
            pair = [0] * n
            for b, a in enumerate(assign):
                pair[a] = b
            goal = targets(problem, pair)
            found = _shortest(pa, goal, len(best_steps), [depth_b[b] for b in pair])
            if found is not None and len(found) < len(best_steps):
                best_pair, best_steps = pair, found
            return
        v = order_b[pos]
        p = FREE if pb[v] == FREE else assign[pb[v]]
        low = assign[twin_before[v]] if twin_before[v] != FREE else FREE
        candidates = [i for i in range(n) if not used[i] and i > low]
        candidates.sort(key=lambda i: pa[i] != p)
        for i in candidates:
            used[i], assign[v] = True, i
            search(pos + 1, partial + (pa[i] != p), degree_gap + abs(indeg_a[i] - indeg_b[v]))
            used[i], assign[v] = False, FREE

    search(0, 0, 0)
    goal = targets(problem, best_pair)
    return MisoSolution(best_pair, best_steps, len(best_steps) if exhausted else 0,
                        optimal=exhausted,
                        stats={**stats, "time_ms": 1e3 * (time.perf_counter() - t0),
                               "heuristic_steps": float(heuristic.cost),
                               "mismatches": float(mismatches(pa, goal))})


def brute_force_steps(problem: MisoProblem, max_steps: int = 12) -> int:
    """The optimum by breadth-first search over labelled configurations (small ``n``).

    Every legal step from every configuration reached, until one is a tree isomorphic
    to the goal. Independent of the pairing: the reference for :func:`solve_exact`.

    Raises:
        PlanningError: nothing within ``max_steps``.
    """
    target = canonical_form(problem.goal)
    n = problem.n
    origin = tuple(problem.start)
    if canonical_form(origin) == target:
        return 0
    seen = {origin}
    frontier = [origin]
    for depth in range(1, max_steps + 1):
        nxt = []
        for state in frontier:
            for i in range(n):
                for k in range(FREE, n):
                    if not step_is_legal(state, i, k):
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


# -- plans ---------------------------------------------------------------------------------------


def _configuration(template: Configuration, ids: Sequence[str], parent: Sequence[int],
                   vectors: dict[tuple[int, int], np.ndarray], edge_ids: dict[tuple[int, int], str],
                   name: str) -> Configuration:
    config = Configuration(template.robot, name=name)
    for v in ids:
        config.add_module(v, template.kind_of(v))
    for i, p in enumerate(parent):
        if p != FREE:
            key = (i, p)
            config.connect(ids[i], ids[p], id=edge_ids.get(key),
                           z=vectors.get(key, np.array([0.0, 0.0, 1.0])))
    return config


KEEP_LABELS_LIMIT = 64
"""Largest module count for which :func:`_keep_labels` searches a plan."""


def _keep_labels(solution: MisoSolution, problem: MisoProblem) -> MisoSolution:
    """``solution``, or the plan in which every module keeps its own id when the goal
    uses the start's ids and that plan has no more steps and no fewer flows.

    Modules are identical, so the pairing is the planner's choice; but a goal written in
    the system's ids says where each module should end, and an equally short plan that
    relabels two arms of a star would make them swap places physically.
    """
    n = len(problem.start)
    if sorted(problem.start_ids) != sorted(problem.goal_ids) or n > KEEP_LABELS_LIMIT:
        return solution
    index = {m: b for b, m in enumerate(problem.goal_ids)}
    identity = [index[m] for m in problem.start_ids]
    if identity == list(solution.pairing):
        return solution
    goal = targets(problem, identity)
    depth = _bfs(problem.goal)[1]
    steps = _shortest(problem.start, goal, solution.cost + 1, [depth[b] for b in identity])
    if steps is None or len(steps) > solution.cost or \
            count_flows(problem.start, steps) < count_flows(problem.start, solution.steps):
        return solution
    return MisoSolution(identity, steps, solution.lower_bound,
                        optimal=solution.optimal and len(steps) == solution.cost,
                        stats=solution.stats)


def _same_shape(a: Configuration, b: Configuration) -> bool:
    """Same connections (by ends) with the same vectors."""
    def links(c: Configuration) -> dict[tuple[str, str], tuple]:
        return {(e.source, e.target): tuple(e.z) for e in c.edges()}
    return links(a) == links(b)


def plan_miso(start: Configuration, goal: Configuration, *, exact: bool = False,
              planner: str = "miso", node_limit: int = 2_000_000) -> Plan:
    """A :class:`~msrr.core.plan.Plan` of MISO connection changes from ``start`` to ``goal``.

    Each step becomes one action, typed by the one rule of
    :mod:`msrr.core.actions`: a *connection* (the free module connects), a
    *disconnection* (a module on the cycle frees itself), a *flow*
    (:func:`~msrr.core.actions.flow_move`: a leaf moves to a neighbour of its parent) or,
    for any other re-targeting, a break-and-make *parallel connection* (disconnection
    first, then connection; the module carries its in-tree). A last *moving* action
    sets the goal's vectors. Kept connections keep their ids and vectors; new ones take
    the goal's vectors.
    """
    problem = MisoProblem.from_configurations(start, goal)
    solution = _keep_labels((solve_exact(problem, node_limit=node_limit) if exact
                             else solve_heuristic(problem)), problem)
    ids = problem.start_ids
    final = targets(problem, solution.pairing)
    goal_vectors = {}
    goal_edges = {(goal.vertices().index(e.source), goal.vertices().index(e.target)): e
                  for e in goal.edges()}
    for i, b in enumerate(solution.pairing):
        if problem.goal[b] != FREE:
            goal_vectors[(i, final[i])] = goal_edges[(b, problem.goal[b])].z
    index = {v: i for i, v in enumerate(ids)}
    vectors: dict[tuple[int, int], np.ndarray] = dict(goal_vectors)
    edge_ids: dict[tuple[int, int], str] = {}
    for e in start.edges():
        key = (index[e.source], index[e.target])
        vectors[key], edge_ids[key] = e.z, e.id   # kept connections keep their vectors
    parent = list(problem.start)
    current = start.copy()
    actions: list[Action] = []
    flows = reconnections = 0
    for t, step in enumerate(solution.steps, 1):
        i = step.module
        broken = (ConnectionChange(ids[i], ids[step.old]),) if step.old != FREE else ()
        made = (ConnectionChange(ids[i], ids[step.new]),) if step.new != FREE else ()
        parent[i] = step.new
        after = _configuration(start, ids, parent, vectors, edge_ids, f"step {t}")
        if broken and made and flow_move(current, topology_diff(current, after)) is not None:
            flows += 1
            kind, verb = ActionType.FLOW, "flow"
        elif not made:
            kind, verb = ActionType.DISCONNECTION, "free"
        elif not broken:
            kind, verb = ActionType.CONNECTION, "connect"
        else:
            reconnections += 1
            kind, verb = ActionType.PARALLEL_CONNECTION, "reconnect"
        old = ids[step.old] if step.old != FREE else "(free)"
        new = ids[step.new] if step.new != FREE else "(free)"
        actions.append(Action(kind, after, tuple(dict.fromkeys(
            m for c in broken + made for m in (c.source, c.target))), broken + made,
            note=f"{verb} {ids[i]}: {old} -> {new} (step {t})"))
        current = after
    reached = _configuration(start, ids, final, goal_vectors, edge_ids,
                             goal.name or "goal")
    if actions or not _same_shape(current, reached):   # a step's own motion (a flow
        # ends where the leaf touches its new parent) does not set the goal's vectors
        actions.append(Action(ActionType.MOVING, reached, ids, note="take the goal's shape"))
    mapping = {ids[a]: problem.goal_ids[b] for a, b in enumerate(solution.pairing)}
    notes = []
    if exact and not solution.optimal:
        notes.append(f"exact search stopped after {node_limit} nodes: best plan found, "
                     "optimality not proved")
    return Plan(robot=start.robot, planner=planner, start=start.copy(), goal=reached,
                actions=actions, mapping=mapping, notes=notes,
                stats={"steps": float(solution.cost), "lower_bound": float(solution.lower_bound),
                       "kept": float(sum(1 for i, p in enumerate(problem.start)
                                         if p != FREE and final[i] == p)),
                       "flows": float(flows), "reconnections": float(reconnections),
                       "optimal": float(solution.optimal), **solution.stats})


@dataclass(frozen=True)
class MisoPlanner:
    """The MISO connection planner as a registered ``Planner`` (heuristic or exact)."""

    name: str = "miso"
    description: str = ("MISO connection planning: tree-alignment pairing, connectivity-"
                        "preserving step order (Luo and Lam 2023)")
    exact: bool = False
    node_limit: int = 2_000_000

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """Plan ``start`` -> ``goal``; deterministic (``seed`` unused)."""
        return plan_miso(start, goal, exact=self.exact, planner=self.name,
                         node_limit=self.node_limit)


MISO_EXACT = MisoPlanner(name="miso-exact", exact=True,
                         description="MISO connection planning, exact: branch and bound over "
                                     "pairings, A* over steps (proved fewest steps)")
