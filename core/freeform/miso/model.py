"""The MISO connection problem: configurations as pointer arrays, the robot's rules,
legal steps, both metrics, and random instances of Luo and Lam's kinds.

A configuration of ``n`` MISO modules is a pointer array ``parent[i]``: the module that
module ``i``'s one connector sits on, :data:`FREE` (-1) when it holds nothing. Any
pointer array is a *functional graph*: pieces, each a tree (one free module, its
*root*) or unicyclic (every connector used, one cycle). A *step* re-targets one
connector, ``parent[i]: j -> k`` (``j`` or ``k`` may be :data:`FREE`); the module's
in-tree moves with it. Pieces split and merge as steps require.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ...configuration import Configuration
from ...errors import PlanningError

__all__ = [
    "FREE",
    "MisoLimits",
    "MisoProblem",
    "Step",
    "UNLIMITED",
    "canonical_form",
    "changes",
    "children_of",
    "count_flows",
    "cycles",
    "depths",
    "is_flow",
    "kept",
    "mismatches",
    "pairing_score",
    "pieces",
    "pointer_form",
    "random_cyclic",
    "random_forest",
    "random_miso_tree",
    "rooted",
    "step_changes",
    "step_is_legal",
    "targets",
]

FREE = -1
"""``parent[i]`` of a module whose connector is free."""

Docking = Literal["child", "descendant"]
Carrying = Literal["in-tree", "nothing"]


@dataclass(frozen=True)
class MisoLimits:
    """A MISO robot's connection rules, declared in its ``robot.json`` (``miso``).

    Attributes:
        max_in: most connections one module carries (others' connectors on it);
            ``None``: no limit. FreeBOT: 6, as Luo and Lam's model.
        no_docking_onto: ``"child"`` -- a module never docks onto a module whose
            connector sits on it (two modules on each other: the core's connections
            are direction-free, so that would be one connection twice; Luo and Lam's
            generator forbids it too); ``"descendant"`` -- never onto any module of
            its own in-tree, so no cycle is ever made (a robot whose modules cannot
            close a ring).
        carries: what a module takes along when it docks somewhere new: ``"in-tree"``
            -- every module docked on it, directly or not (a piece travels as one
            body; FreeBOT); ``"nothing"`` -- only a module nothing is docked on may
            dock (SnailBot: its connector is rigid with its shell, so a docked
            module's tracks hold its parent, not the floor, and a piece cannot
            travel). Letting go (a step to free) moves nothing and is always allowed.
            Under ``"nothing"`` no ring can be closed (its last module would carry
            its predecessor), so such a robot cannot build a goal with a cycle.
    """

    max_in: int | None = None
    no_docking_onto: Docking = "child"
    carries: Carrying = "in-tree"

    def __post_init__(self) -> None:
        if self.max_in is not None and (isinstance(self.max_in, bool)
                                        or not isinstance(self.max_in, int) or self.max_in < 1):
            raise PlanningError(f"MISO rules: max_in must be an integer >= 1 or None, got "
                                f"{self.max_in!r}")
        if self.no_docking_onto not in ("child", "descendant"):
            raise PlanningError("MISO rules: no_docking_onto must be 'child' or 'descendant', "
                                f"got {self.no_docking_onto!r}")
        if self.carries not in ("in-tree", "nothing"):
            raise PlanningError("MISO rules: carries must be 'in-tree' or 'nothing', got "
                                f"{self.carries!r}")

    def violations(self, parent: Sequence[int]) -> list[str]:
        """Why ``parent`` is no configuration of a robot with these rules (empty: it is)."""
        found = []
        if self.max_in is not None:
            indeg = np.bincount([p for p in parent if p != FREE], minlength=len(parent))
            over = [i for i in range(len(parent)) if indeg[i] > self.max_in]
            if over:
                found.append(f"module {over[0]} carries {int(indeg[over[0]])} connections "
                             f"(at most {self.max_in})")
        for i, p in enumerate(parent):
            if p != FREE and parent[p] == i:
                found.append(f"modules {min(i, p)} and {max(i, p)} sit on each other")
                break
        if self.no_docking_onto == "descendant" and cycles(parent):
            found.append("it holds a cycle (this robot never docks onto its own in-tree)")
        return found

    def unbuildable(self, parent: Sequence[int]) -> list[str]:
        """Why no plan under these rules can end in ``parent`` (empty: one can)."""
        if self.carries == "nothing" and cycles(parent):
            return ["it holds a cycle, and the last module to close a ring would carry its "
                    "predecessor (a docking module of this robot carries nothing)"]
        return []


UNLIMITED = MisoLimits()
"""No cap on carried connections; no docking onto one's child (the core's connections
are direction-free, so no robot may)."""


@dataclass(frozen=True)
class Step:
    """Module ``module`` moves its connector from ``old`` to ``new`` (indices; -1 free)."""

    module: int
    old: int
    new: int

    @property
    def changes(self) -> int:
        """Connections broken plus made: 2 for a move, 1 to connect or free."""
        return (self.old != FREE) + (self.new != FREE)


@dataclass(frozen=True)
class MisoProblem:
    """Start and goal MISO configurations as pointer arrays, and the robot's rules.

    Attributes:
        start_ids: module ids of the start, index order.
        start: ``parent`` of each start module (index, or -1 when free).
        goal_ids: module ids of the goal (labels to assign).
        goal: ``parent`` of each goal module.
        limits: the robot's rules.
    """

    start_ids: tuple[str, ...]
    start: tuple[int, ...]
    goal_ids: tuple[str, ...]
    goal: tuple[int, ...]
    limits: MisoLimits = UNLIMITED

    @classmethod
    def from_parents(cls, start: Sequence[int], goal: Sequence[int],
                     limits: MisoLimits = UNLIMITED) -> MisoProblem:
        """A problem over anonymous modules ``0..n-1`` (ids ``"0"``, ``"1"``...).

        Raises:
            PlanningError: sizes differ, a pointer is out of range, or a configuration
                breaks the rules.
        """
        if len(start) != len(goal):
            raise PlanningError(f"start has {len(start)} modules, goal {len(goal)}")
        for name, parent in (("start", start), ("goal", goal)):
            _check(parent, limits, name)
        unbuildable = limits.unbuildable(goal)
        if unbuildable:
            raise PlanningError(f"goal: {unbuildable[0]}")
        ids = tuple(str(i) for i in range(len(start)))
        return cls(ids, tuple(int(p) for p in start), ids, tuple(int(p) for p in goal), limits)

    @classmethod
    def from_configurations(cls, start: Configuration, goal: Configuration,
                            limits: MisoLimits = UNLIMITED) -> MisoProblem:
        """Read two configurations of MISO modules (any pieces, cycles allowed).

        Raises:
            PlanningError: module counts or kinds differ, a virtual vertex, a module
                with two out-connections, or a configuration that breaks the rules.
        """
        s_ids, s_parent = pointer_form(start, "start")
        g_ids, g_parent = pointer_form(goal, "goal")
        if len(s_ids) != len(g_ids):
            raise PlanningError(f"start {start.name or ''} has {len(s_ids)} modules, goal "
                                f"{goal.name or ''} has {len(g_ids)}")
        kinds = sorted(start.kind_of(v) for v in s_ids), sorted(goal.kind_of(v) for v in g_ids)
        if kinds[0] != kinds[1]:
            raise PlanningError("start and goal are made of different module kinds")
        for name, config, ids, parent in (("start", start, s_ids, s_parent),
                                          ("goal", goal, g_ids, g_parent)):
            problems = limits.violations(parent)
            if problems:
                raise PlanningError(f"{name} {config.name or ''}: not a configuration of "
                                    f"robot {config.robot!r}: "
                                    + _named(problems[0], ids))
        unbuildable = limits.unbuildable(g_parent)
        if unbuildable:
            raise PlanningError(f"goal {goal.name or ''}: robot {goal.robot!r} cannot build "
                                f"it: {unbuildable[0]}")
        return cls(s_ids, s_parent, g_ids, g_parent, limits)

    @property
    def n(self) -> int:
        return len(self.start)


def _named(problem: str, ids: Sequence[str]) -> str:
    """``problem`` with module indices replaced by ids ("module 3" -> "module F4")."""
    words = problem.split()
    out = []
    for k, w in enumerate(words):
        prev = words[k - 1] if k else ""
        if w.isdigit() and prev in ("module", "modules", "and"):
            w = ids[int(w)]
        out.append(w)
    return " ".join(out)


def _check(parent: Sequence[int], limits: MisoLimits, what: str) -> None:
    n = len(parent)
    if n == 0:
        raise PlanningError(f"{what}: no modules")
    bad = [i for i, p in enumerate(parent) if not (p == FREE or 0 <= p < n) or p == i]
    if bad:
        raise PlanningError(f"{what}: module {bad[0]} points at {parent[bad[0]]}")
    problems = limits.violations(parent)
    if problems:
        raise PlanningError(f"{what}: {problems[0]}")


def pointer_form(config: Configuration, what: str = "configuration"
                 ) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """Module ids and ``parent`` pointers of a MISO configuration (any pieces).

    Raises:
        PlanningError: a virtual vertex, or a module with two out-connections.
    """
    ids = tuple(config.vertices())
    index = {v: i for i, v in enumerate(ids)}
    parent = [FREE] * len(ids)
    for v in ids:
        if config.is_virtual(v):
            raise PlanningError(f"{what} {config.name or ''}: MISO planning takes modules "
                                f"only, {v} is a virtual vertex")
    if not ids:
        raise PlanningError(f"{what} {config.name or ''}: no modules")
    for edge in config.edges():
        i = index[edge.source]
        if parent[i] != FREE:
            raise PlanningError(f"{what} {config.name or ''}: module {edge.source} has two "
                                "out-connections; MISO modules have one connector")
        parent[i] = index[edge.target]
    return ids, tuple(parent)


# -- structure -----------------------------------------------------------------------------


def children_of(parent: Sequence[int]) -> list[list[int]]:
    """In-neighbours of every module: ``children[j] = [i : parent[i] == j]`` (increasing)."""
    children: list[list[int]] = [[] for _ in parent]
    for i, p in enumerate(parent):
        if p != FREE:
            children[p].append(i)
    return children


def cycles(parent: Sequence[int]) -> list[list[int]]:
    """The cycles of a pointer array, each from its smallest module, in that order."""
    n = len(parent)
    state = [0] * n  # 0 unseen, 1 on the current walk, 2 done
    found = []
    for s in range(n):
        walk, j = [], s
        while j != FREE and state[j] == 0:
            state[j] = 1
            walk.append(j)
            j = parent[j]
        if j != FREE and state[j] == 1:
            cyc = walk[walk.index(j):]
            k = cyc.index(min(cyc))
            found.append(cyc[k:] + cyc[:k])
        for w in walk:
            state[w] = 2
    return sorted(found)


def pieces(parent: Sequence[int]) -> int:
    """The number of pieces (connected groups): one per root and per cycle."""
    return sum(1 for p in parent if p == FREE) + len(cycles(parent))


def rooted(parent: Sequence[int], shift: int = 0) -> list[int]:
    """The pointer array with each cycle cut (its ``shift``-th module from the smallest,
    along the connectors, becomes a root): a forest of rooted trees, deterministic."""
    cut = list(parent)
    for cyc in cycles(parent):
        cut[cyc[shift % len(cyc)]] = FREE
    return cut


def depths(parent: Sequence[int]) -> list[int]:
    """Depth of every module below its piece's root (cycles cut as :func:`rooted`)."""
    forest = rooted(parent)
    children = children_of(forest)
    depth = [0] * len(parent)
    stack = [i for i, p in enumerate(forest) if p == FREE]
    while stack:
        u = stack.pop()
        for c in children[u]:
            depth[c] = depth[u] + 1
            stack.append(c)
    return depth


def canonical_form(parent: Sequence[int]) -> tuple:
    """A hashable form equal exactly for isomorphic pointer arrays: the sorted forms of
    the pieces (rooted trees by AHU nesting; a cycle as its least rotation)."""
    forest = rooted(parent)
    children = children_of(forest)
    form: dict[int, tuple] = {}
    order, stack = [], [i for i, p in enumerate(forest) if p == FREE]
    while stack:
        u = stack.pop()
        order.append(u)
        stack.extend(children[u])
    for u in reversed(order):
        form[u] = tuple(sorted(form[c] for c in children[u]))
    parts = []
    for i, p in enumerate(parent):
        if p == FREE:
            parts.append(("tree", form[i]))
    for cyc in cycles(parent):
        # each cycle module's own form: its children off the cycle
        on = set(cyc)
        own = [tuple(sorted(form[c] for c in _children_in(parent, m) if c not in on))
               for m in cyc]
        parts.append(("cycle", min(tuple(own[k:] + own[:k]) for k in range(len(own)))))
    return tuple(sorted(parts))


def _children_in(parent: Sequence[int], module: int) -> list[int]:
    """The modules whose connector sits on ``module``."""
    return [i for i, p in enumerate(parent) if p == module]


# -- pairing and metrics --------------------------------------------------------------------


def targets(problem: MisoProblem, pair: Sequence[int]) -> list[int]:
    """The goal's parent of every start module under ``pair`` (start index -> goal
    index), in start indices."""
    inverse = [0] * problem.n
    for a, b in enumerate(pair):
        inverse[b] = a
    return [FREE if problem.goal[b] == FREE else inverse[problem.goal[b]] for b in pair]


def mismatches(parent: Sequence[int], goal: Sequence[int]) -> int:
    """``d``: modules whose connector is not yet on its target (a lower bound on steps)."""
    return sum(1 for p, g in zip(parent, goal, strict=True) if p != g)


def kept(parent: Sequence[int], goal: Sequence[int]) -> int:
    """Connections both pointer arrays hold (same module on the same module)."""
    return sum(1 for p, g in zip(parent, goal, strict=True) if p == g != FREE)


def changes(parent: Sequence[int], goal: Sequence[int]) -> int:
    """Connections broken plus made going straight from ``parent`` to ``goal``: the
    size of the symmetric difference of their connection sets (Luo and Lam's metric,
    ``||X_F - X_I||_F^2`` of the adjacency matrices)."""
    a = sum(1 for p in parent if p != FREE)
    b = sum(1 for g in goal if g != FREE)
    return a + b - 2 * kept(parent, goal)


def pairing_score(problem: MisoProblem, pair: Sequence[int]) -> tuple[int, int]:
    """How good a pairing is, higher better, compared lexicographically: the connections
    it keeps (so the fewest connection changes first), then its free-free pairs (each
    saves a step)."""
    goal = targets(problem, pair)
    held = sum(1 for p, g in zip(problem.start, goal, strict=True) if p == g != FREE)
    free = sum(1 for p, g in zip(problem.start, goal, strict=True) if p == g == FREE)
    return held, free


def step_changes(steps: Iterable[Step]) -> int:
    """Connections broken plus made by ``steps``."""
    return sum(s.changes for s in steps)


# -- steps ---------------------------------------------------------------------------------


def step_is_legal(parent: Sequence[int], module: int, new: int,
                  limits: MisoLimits = UNLIMITED) -> bool:
    """Whether ``module`` may re-target its connector to ``new`` (-1: free itself) under
    the robot's rules: not onto itself or where it already is, not onto a module that
    carries ``limits.max_in`` connections, not onto its child (or, for
    ``"descendant"``, any module of its in-tree); under ``limits.carries == "nothing"``
    only a module nothing is docked on docks. Pieces may split and merge."""
    if new == module or parent[module] == new:
        return False
    if new == FREE:
        return True
    if limits.carries == "nothing" and module in parent:
        return False
    if limits.max_in is not None and sum(1 for p in parent if p == new) >= limits.max_in:
        return False
    if limits.no_docking_onto == "child":
        return parent[new] != module
    j, seen = new, 0
    while j != FREE and seen <= len(parent):
        if j == module:
            return False
        j, seen = parent[j], seen + 1
    return True


def is_flow(parent: Sequence[int], module: int, new: int) -> bool:
    """Whether re-targeting ``module``'s connector to ``new`` is a flow (FreeSN section
    4.1) in the pointer array ``parent``: ``module`` is a leaf (connected to its parent
    only, no module on it) and ``new`` is a neighbour of its parent (the parent sits on
    ``new``, or ``new`` sits on the parent). The pointer-array form of
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


# -- random instances (Luo and Lam's kinds, generated from their description) ---------------


def random_miso_tree(n: int, rng: np.random.Generator, *, max_branching: int | None = None,
                     max_in_degree: int = 6) -> tuple[int, ...]:
    """A random single tree: modules join in random order, each onto a random placed
    module that carries fewer than ``max_in_degree``; a module may take a second
    connection only while fewer than ``max_branching`` modules branch (``None``: no
    bound)."""
    order = rng.permutation(n)
    parent = [FREE] * n
    indeg = [0] * n
    placed = [int(order[0])]
    open_ = [int(order[0])]          # placed modules that may take one more
    branching = 0
    for t in range(1, n):
        i = int(order[t])
        while True:
            k = int(rng.integers(len(open_)))
            p = open_[k]
            if indeg[p] == 1 and max_branching is not None and branching >= max_branching:
                open_[k] = open_[-1]
                open_.pop()
                continue
            break
        branching += indeg[p] == 1
        parent[i], indeg[p] = p, indeg[p] + 1
        if indeg[p] >= max_in_degree:
            open_.remove(p)
        placed.append(i)
        open_.append(i)
    return tuple(parent)


def random_forest(n: int, pieces_: int, rng: np.random.Generator, *,
                  max_in_degree: int = 6) -> tuple[int, ...]:
    """``pieces_`` random trees (sizes from a random composition of ``n``) in one pointer
    array, module indices shuffled."""
    cuts = np.sort(rng.choice(np.arange(1, n), size=pieces_ - 1, replace=False)) \
        if pieces_ > 1 else np.array([], dtype=int)
    sizes = np.diff(np.concatenate([[0], cuts, [n]])).astype(int)
    labels = rng.permutation(n)
    parent = [FREE] * n
    base = 0
    for size in sizes:
        tree = random_miso_tree(int(size), rng, max_in_degree=max_in_degree)
        for i, p in enumerate(tree):
            parent[int(labels[base + i])] = FREE if p == FREE else int(labels[base + p])
        base += int(size)
    return tuple(parent)


def random_cyclic(n: int, rng: np.random.Generator, *, max_in_degree: int = 6,
                  max_free: int = 6) -> tuple[int, ...]:
    """A random MISO graph as Luo and Lam draw theirs: every module in turn picks, at
    random, a module that carries fewer than ``max_in_degree`` (not itself, not one
    sitting on it) or to stay free while fewer than ``max_free`` are; pieces and
    cycles arise as they fall."""
    parent = [FREE] * n
    indeg = [0] * n
    free_left = max_free
    for i in range(n):
        while True:
            j = int(rng.integers(n + 1))   # n: stay free
            if j == n:
                if free_left > 0:
                    free_left -= 1
                    break
                continue
            if j == i or parent[j] == i or indeg[j] >= max_in_degree:
                continue
            parent[i] = j
            indeg[j] += 1
            break
    return tuple(parent)
