"""Collision-free order and grid routes for the moves of rigid groups (issue 17).

After the undocks, every rigid group (a matched subconfiguration, a kept chain, or a
free module) translates on the grid of docked positions from its start cells to its
goal cells; all MMRP modules keep heading 0 between moves, so a move ends translated.
Groups are routed one at a time (:mod:`.schedule` drives legs that keep apart at
once). A group may move when its goal cells are free; its route is an A* search over
unit drives along its heading and quarter turns in place (:mod:`.motion`: a y-leg is
driven turned) in which every cell a motion sweeps is free, so the swept area of the
route never touches another module. When no group can reach its goal (two groups
holding each other's goal cells, or a goal only reachable through a cell someone
still holds), a group that blocks a goal is *parked*: moved to the nearest
placement, by route length, that covers and touches no goal cell still awaited --
the intent of the potential field of section 4.3 (nearest free place, no crossing)
applied to a rigid group. Groups whose goal cells
sit in pockets of the goal (cells with many goal neighbours) go first, so pockets
are filled before they close.
"""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

from msrr.core.errors import PlanningError

from .motion import blocked, drive_paths, turn_paths

__all__ = ["Cell", "Route", "Routing", "route_groups"]

Cell = tuple[int, int]
STEPS: tuple[Cell, ...] = ((1, 0), (-1, 0), (0, 1), (0, -1))
DIRECT_LIMIT = 24
"""Most groups for which the greedy order is tried first (its failed searches grow
quadratically; evacuate-and-assemble scales)."""


@dataclass(frozen=True)
class Route:
    """One move of one rigid group.

    Attributes:
        modules: the group.
        corners: the cell of the group's first module at the start, at every turn
            and at the end (straight axis-aligned segments between consecutive
            corners; the other modules keep their offsets).
        parking: whether the move parks the group out of the way (it moves again later).
    """

    modules: tuple[str, ...]
    corners: tuple[Cell, ...]
    parking: bool = False


TURN = 1
"""Cost of a quarter turn of a group in the route search [cells]."""


@lru_cache(maxsize=4096)
def _sweeps(shape: tuple[Cell, ...]) -> dict[tuple[int, int, int] | str, tuple[Cell, ...]]:
    """The cells (offsets from the placement) that each motion of a group of ``shape``
    sweeps (:mod:`.motion`): a unit drive ``(dx, dy, rotated)`` and a quarter turn."""
    cells = [(float(x), float(y)) for x, y in shape]
    out: dict[tuple[int, int, int] | str, tuple[Cell, ...]] = {
        "turn": tuple(sorted(blocked(turn_paths(cells))))}
    for dx, dy in STEPS:
        rotated = int(dy != 0)
        out[(dx, dy, rotated)] = tuple(sorted(blocked(drive_paths(cells, (dx, dy),
                                                                  rotated=bool(rotated)))))
    return out


@lru_cache(maxsize=4096)
def _sweep_masks(shape: tuple[Cell, ...]) -> dict[tuple[int, int, int] | str,
                                                tuple[tuple[int, int, int], ...]]:
    """:func:`_sweeps` as row masks (:func:`_masks`)."""
    return {key: _masks(cells) for key, cells in _sweeps(shape).items()}


class _Occupied(dict[Cell, int]):
    """Which group holds each cell, kept also as one bit mask per row (bit ``k`` of row
    ``y``: cell ``(base + k, y)`` is held), so that a sweep is tested a row at a time
    (:func:`_hits`) instead of a cell at a time."""

    def __init__(self, cells: Mapping[Cell, int] | None = None):
        super().__init__()
        self.rows: dict[int, int] = {}
        self.base: int | None = None
        for cell, group in (cells or {}).items():
            self[cell] = group

    def __setitem__(self, cell: Cell, group: int) -> None:
        super().__setitem__(cell, group)
        x, y = cell
        if self.base is None or x < self.base:
            shift = 64 if self.base is None else self.base - x + 64
            self.rows = {k: v << shift for k, v in self.rows.items()}
            self.base = x - 64 if self.base is None else self.base - shift
        self.rows[y] = self.rows.get(y, 0) | 1 << (x - self.base)

    def __delitem__(self, cell: Cell) -> None:
        super().__delitem__(cell)
        self.rows[cell[1]] &= ~(1 << (cell[0] - (self.base or 0)))

    def others(self, me: int, cells: Sequence[Cell]) -> tuple[dict[int, int], int]:
        """The row masks with ``cells`` that ``me`` holds left out, and the base."""
        rows = dict(self.rows)
        base = self.base or 0
        for x, y in cells:
            if self.get((x, y)) == me:
                rows[y] &= ~(1 << (x - base))
        return rows, base


@lru_cache(maxsize=8192)
def _masks(offsets: tuple[Cell, ...]) -> tuple[tuple[int, int, int], ...]:
    """``offsets`` as ``(dy, dx of bit 0, bit mask)`` per row."""
    by_row: dict[int, list[int]] = {}
    for dx, dy in offsets:
        by_row.setdefault(dy, []).append(dx)
    return tuple((dy, min(xs), sum(1 << (x - min(xs)) for x in set(xs)))
                 for dy, xs in sorted(by_row.items()))


def _hits(masks: tuple[tuple[int, int, int], ...], t: Cell, rows: Mapping[int, int],
          base: int, count: bool) -> int:
    """How many cells of a sweep (:func:`_masks`) placed at ``t`` are held in ``rows``
    (``count`` False: 0 or 1)."""
    n = 0
    for dy, dx, mask in masks:
        row = rows.get(t[1] + dy)
        if row:
            shift = t[0] + dx - base
            bits = (row >> shift if shift >= 0 else row << -shift) & mask
            if bits:
                if not count:
                    return 1
                n += bits.bit_count()
    return n


def _search(shape: Sequence[Cell], start: Cell, occupied: Mapping[Cell, int], me: int,
            done: Callable[[Cell], bool], goal: Cell | None, bounds: tuple[int, int, int, int],
            limit: int, penalty: int = 0,
            heuristic: Callable[[Cell], int] | None = None) -> list[Cell] | None:
    """A* (``goal`` given) or best-first to ``done`` over the motions of a group of ``shape``.

    A state is a placement ``t`` and a heading, 0 or turned a quarter (:mod:`.motion`):
    at heading 0 the group drives along x, turned along y, and turns in place between
    them; every motion is allowed when the cells it sweeps are free (held by nobody or
    by ``me``), and the search ends at heading 0. A single module turns within its
    cell, so it just steps. With ``penalty`` > 0 occupied cells are allowed at that
    extra cost per cell (to find which groups block the cheapest route).

    Returns:
        The placements in order (a turn repeats none), or None.
    """
    lo_x, lo_y, hi_x, hi_y = bounds
    single = len(shape) == 1 and shape[0] == (0, 0)
    sweeps = None if single else _sweep_masks(tuple(shape))
    if not isinstance(occupied, _Occupied):
        occupied = _Occupied(occupied)
    rows, base = occupied.others(me, [(start[0] + s[0], start[1] + s[1]) for s in shape])
    counted = bool(penalty)
    first = (start[0], start[1], 0)
    parent: dict[tuple[int, int, int], tuple[int, int, int] | None] = {first: None}
    cost = {first: 0}

    def h(t: Cell) -> int:
        if heuristic is not None:
            return heuristic(t)
        return 0 if goal is None else abs(t[0] - goal[0]) + abs(t[1] - goal[1])

    frontier = [(h(start), 0, first)]
    expanded = 0
    get = occupied.get
    while frontier:
        _, g, state = heapq.heappop(frontier)
        g = -g
        if g > cost[state]:
            continue
        x, y, turned_ = state
        if not turned_ and done((x, y)):
            path = [state]
            while parent[path[-1]] is not None:
                path.append(parent[path[-1]])
            cells = [(q[0], q[1]) for q in reversed(path)]
            return [c for k, c in enumerate(cells) if k == 0 or cells[k - 1] != c]
        expanded += 1
        if expanded > limit:
            return None
        # the motions: unit drives along the heading's axis, and a turn in place
        motions: list[tuple[tuple[int, int, int], int, tuple | None]] = []
        for dx, dy in STEPS:
            if single or (dy != 0) == bool(turned_):
                n = (x + dx, y + dy, turned_)
                if lo_x <= n[0] <= hi_x and lo_y <= n[1] <= hi_y:
                    motions.append((n, 1, None if single else sweeps[(dx, dy, turned_)]))
        if not single:
            motions.append(((x, y, 1 - turned_), TURN, sweeps["turn"]))
        for n, step, masks in motions:
            c = g + step
            if c >= cost.get(n, 1 << 30):  # no better even if free: skip the sweep test
                continue
            blocked_ = int(get((n[0], n[1]), me) != me) if masks is None else \
                _hits(masks, (x, y), rows, base, counted)
            if blocked_:
                if not penalty:
                    continue
                c += penalty * blocked_
                if c >= cost.get(n, 1 << 30):
                    continue
            cost[n] = c
            parent[n] = state
            heapq.heappush(frontier, (c + h((n[0], n[1])), -c, n))
    return None


def _swept(shape: Sequence[Cell], path: Sequence[Cell]) -> set[Cell]:
    """Every cell the group of ``shape`` sweeps along a :func:`_search` path (unit steps
    between placements): the turns before and after each y-run and the drives, as
    :func:`_search` tests them, not only the cells of its placements."""
    if len(shape) == 1 and shape[0] == (0, 0):
        return set(path)
    sweeps = _sweeps(tuple(shape))
    out: set[Cell] = {(path[0][0] + s[0], path[0][1] + s[1]) for s in shape}
    heading = 0
    for a, b in zip(path, path[1:], strict=False):
        dx, dy = b[0] - a[0], b[1] - a[1]
        if int(dy != 0) != heading:  # a y-step is driven turned, an x-step not
            heading = 1 - heading
            out.update((a[0] + s[0], a[1] + s[1]) for s in sweeps["turn"])
        out.update((a[0] + s[0], a[1] + s[1]) for s in sweeps[(dx, dy, heading)])
    if heading:
        end = path[-1]
        out.update((end[0] + s[0], end[1] + s[1]) for s in sweeps["turn"])
    return out


@lru_cache(maxsize=4096)
def _envelope(shape: tuple[Cell, ...]) -> tuple[Cell, ...]:
    """Every cell (offset from the placement) a group of ``shape`` may sweep while it
    turns or drives turned, besides its own cells."""
    if len(shape) == 1 and shape[0] == (0, 0):
        return shape
    sweeps = _sweeps(shape)
    return tuple(sorted({*shape, *sweeps["turn"], *sweeps[(0, 1, 1)], *sweeps[(0, -1, 1)]}))


def _leg_clear(shape: Sequence[Cell], a: Cell, b: Cell, rows: Mapping[int, int],
               base: int) -> bool:
    """Whether a group of ``shape`` can drive the straight leg ``a`` -> ``b``, turns
    included (:mod:`.motion`), over cells free in ``rows`` (:meth:`_Occupied.others`)."""
    step = ((b[0] > a[0]) - (b[0] < a[0]), (b[1] > a[1]) - (b[1] < a[1]))
    single = len(shape) == 1 and shape[0] == (0, 0)
    if single:
        sweep = _masks(((0, 0), step))
    else:
        sweeps = _sweep_masks(tuple(shape))
        sweep = sweeps[(*step, int(step[1] != 0))]
        if step[1] and (_hits(sweeps["turn"], a, rows, base, False)
                        or _hits(sweeps["turn"], b, rows, base, False)):
            return False
    t = a
    while t != b:
        if _hits(sweep, t, rows, base, False):
            return False
        t = (t[0] + step[0], t[1] + step[1])
    return True


def _straighten(path: list[Cell], shape: Sequence[Cell], occupied: Mapping[Cell, int],
                me: int) -> list[Cell]:
    """Fewer turns: replace runs of legs of ``path`` by one straight leg or one L where
    the group's sweep is free (the same test as the search), farthest first."""
    if not isinstance(occupied, _Occupied):
        occupied = _Occupied(occupied)
    rows, base = occupied.others(me, [(path[0][0] + s[0], path[0][1] + s[1]) for s in shape])
    corners = list(_corners(path))
    out = [corners[0]]
    i = 0
    while i < len(corners) - 1:
        a = corners[i]
        for j in range(len(corners) - 1, i + 1, -1):
            b = corners[j]
            if a[0] == b[0] or a[1] == b[1]:
                if _leg_clear(shape, a, b, rows, base):
                    out.append(b)
                    break
                continue
            corner = next((c for c in ((b[0], a[1]), (a[0], b[1]))
                           if _leg_clear(shape, a, c, rows, base)
                           and _leg_clear(shape, c, b, rows, base)), None)
            if corner is not None:
                out += [corner, b]
                break
        else:  # the search's own leg, valid as found
            j = i + 1
            out.append(corners[j])
        i = j
    return out


def _region(seed: Cell, walls: Collection[Cell], box: tuple[int, int, int, int],
            seen: set[Cell], limit: int = 400) -> set[Cell] | None:
    """The cells 4-connected to ``seed`` around ``walls``, or None if it reaches outside
    ``box`` or grows past ``limit`` cells (open, for all the routing cares)."""
    region = {seed}
    stack = [seed]
    while stack:
        c = stack.pop()
        if not (box[0] <= c[0] <= box[2] and box[1] <= c[1] <= box[3]):
            seen |= region
            return None
        for dx, dy in STEPS:
            n = (c[0] + dx, c[1] + dy)
            if n not in walls and n not in region:
                region.add(n)
                stack.append(n)
        if len(region) > limit:
            seen |= region
            return None
    seen |= region
    return region


def _shapes(groups: Sequence[Sequence[str]], goal: Mapping[str, Cell]) -> list[tuple[Cell, ...]]:
    """Cell offsets of every group's modules from its first module."""
    return [tuple((goal[m][0] - goal[g[0]][0], goal[m][1] - goal[g[0]][1]) for m in g)
            for g in groups]


def _bounds(cells: Collection[Cell], margin: int) -> tuple[int, int, int, int]:
    return (min(c[0] for c in cells) - margin, min(c[1] for c in cells) - margin,
            max(c[0] for c in cells) + margin, max(c[1] for c in cells) + margin)


def _pocket_order(groups: Sequence[Sequence[str]], start: Mapping[str, Cell],
                  goal: Mapping[str, Cell], priority: Sequence[str]) -> list[int]:
    """The groups not at their goal, those whose goal cells sit deepest in a pocket of the
    goal (most goal neighbours of other groups) first, then by ``priority``."""
    goal_cells = {goal[m] for group in groups for m in group}
    rank = {m: i for i, m in enumerate(priority)}
    pocket = []
    for group in groups:
        own = {goal[m] for m in group}
        pocket.append(max(sum((goal[m][0] + dx, goal[m][1] + dy) in goal_cells
                              and (goal[m][0] + dx, goal[m][1] + dy) not in own
                              for dx, dy in STEPS) for m in group))
    return sorted((i for i, g in enumerate(groups) if start[g[0]] != goal[g[0]]),
                  key=lambda i: (-pocket[i], min(rank.get(m, len(rank)) for m in groups[i])))


class _Greedy:
    """The greedy order of :func:`_direct`: where every group is, which goal cells are
    final and which still awaited, and the routes so far."""

    def __init__(self, groups: Sequence[Sequence[str]], start: Mapping[str, Cell],
                 goal: Mapping[str, Cell], priority: Sequence[str], max_parks: int):
        self.groups, self.goal, self.max_parks = groups, goal, max_parks
        self.where = dict(start)
        self.occupied = _Occupied({start[m]: i for i, group in enumerate(groups)
                                   for m in group})
        self.goal_cells = {goal[m]: i for i, group in enumerate(groups) for m in group}
        self.shapes = _shapes(groups, goal)
        self.pending = _pocket_order(groups, start, goal, priority)
        margin = max(len(g) for g in groups) + 3
        bounds = self.bounds = _bounds([*start.values(), *goal.values()], margin)
        self.limit = min(4 * (bounds[2] - bounds[0] + 1) * (bounds[3] - bounds[1] + 1), 4000)
        self.box = (bounds[0] + margin, bounds[1] + margin, bounds[2] - margin,
                    bounds[3] - margin)
        self.parks = [0] * len(groups)
        self.routes: list[Route] = []
        self.final: set[Cell] = {start[m] for i, g in enumerate(groups)
                                 if i not in self.pending for m in g}
        self.awaited_cells = {goal[m]: i for i in self.pending for m in groups[i]}

    def move(self, index: int, path: list[Cell], parking: bool) -> None:
        group = self.groups[index]
        path = _straighten(path, self.shapes[index], self.occupied, index)
        end = path[-1]
        for m in group:
            del self.occupied[self.where[m]]
        for m, s in zip(group, self.shapes[index], strict=True):
            self.where[m] = (end[0] + s[0], end[1] + s[1])
            self.occupied[self.where[m]] = index
        self.routes.append(Route(tuple(group), _corners(path), parking))

    def encloses(self, index: int) -> bool:
        """Whether placing ``index`` at its goal walls in a cell some pending group needs."""
        own = {self.goal[m] for m in self.groups[index]}
        walls = self.final | own
        seen: set[Cell] = set()
        for c0 in own:
            for dx, dy in STEPS:
                c = (c0[0] + dx, c0[1] + dy)
                if c in walls or c in seen:
                    continue
                region = _region(c, walls, self.box, seen)
                if region is not None and any(
                        self.awaited_cells.get(r, index) != index
                        or self.occupied.get(r, index) not in (index, None) for r in region):
                    return True
        return False

    def search(self, index: int, penalty: int = 0) -> list[Cell] | None:
        """The route of ``index`` to its goal (``penalty``: see :func:`_search`)."""
        target = self.goal[self.groups[index][0]]
        return _search(self.shapes[index], self.where[self.groups[index][0]], self.occupied,
                       index, lambda t: t == target, target, self.bounds, self.limit,
                       penalty=penalty)

    def to_goal(self, index: int, safe: bool = True) -> bool:
        group = self.groups[index]
        if any(self.occupied.get(self.goal[m], index) != index for m in group):
            return False
        if safe and self.encloses(index):
            return False
        path = self.search(index)
        if path is None:
            return False
        self.move(index, path, parking=False)
        for m in group:
            self.final.add(self.goal[m])
            del self.awaited_cells[self.goal[m]]
        return True

    def park(self, index: int, awaited: Collection[int], protect: Collection[Cell] = ()
             ) -> bool:
        """Move ``index`` to the nearest place that touches no goal of ``awaited``."""
        if self.parks[index] >= self.max_parks:
            return False
        reserved: set[Cell] = set(protect)
        for j in awaited:
            if j != index:
                for m in self.groups[j]:
                    c = self.goal[m]
                    reserved.add(c)
                    reserved.update((c[0] + dx, c[1] + dy) for dx, dy in STEPS)
        shape = self.shapes[index]
        here = self.where[self.groups[index][0]]

        def clear(t: Cell) -> bool:
            return t != here and not any((s[0] + t[0], s[1] + t[1]) in reserved for s in shape)

        path = _search(shape, here, self.occupied, index, clear, None, self.bounds, self.limit)
        if path is None:
            return False
        self.parks[index] += 1
        for m in self.groups[index]:
            self.final.discard(self.where[m])
            self.awaited_cells[self.goal[m]] = index
        self.move(index, path, parking=True)
        return True

    def clear_way(self, index: int) -> bool:
        """Park the groups on the cheapest route of ``index`` to its goal, then move it."""
        path = self.search(index, penalty=4 * len(self.groups))
        if path is None:
            return False
        protect = _swept(self.shapes[index], path)
        blockers = list(dict.fromkeys(self.occupied[c] for c in protect
                                      if self.occupied.get(c, index) != index))
        awaited = {*self.pending, index}
        for b in blockers:
            if not self.park(b, awaited, protect):
                return False
            if b not in self.pending:
                self.pending.append(b)
        return self.to_goal(index)

    def run(self) -> list[Route] | None:
        """Move, clear the way or park until every group is home; None when stuck."""
        pending = self.pending
        while pending:
            moved = next((i for i in pending if self.to_goal(i)), None)
            if moved is None:
                moved = next((i for i in list(pending) if self.clear_way(i)), None)
            if moved is not None:
                pending.remove(moved)
                continue
            awaited = set(pending)
            blockers = [i for i in pending
                        if any(self.goal_cells.get(self.where[m], i) != i
                               for m in self.groups[i])]
            for i in [*blockers, *(i for i in pending if i not in blockers)]:
                if self.park(i, awaited):
                    break
            else:
                return None
        return self.routes


def _direct(groups: Sequence[Sequence[str]], start: Mapping[str, Cell],
            goal: Mapping[str, Cell], priority: Sequence[str], max_parks: int
            ) -> list[Route] | None:
    """Greedy order: any group whose goal is free and reachable, parking blockers.

    Returns None when it gets stuck (then :func:`_staged` plans from the start).
    """
    return _Greedy(groups, start, goal, priority, max_parks).run()


def _split(group: list[str], links: set[frozenset[str]]) -> tuple[list[str], list[str],
                                                                 frozenset[str]]:
    """Cut the kept connection of ``group`` that leaves the most even two pieces (ties: the
    first in the order of ``group``, so the choice never depends on string hashing)."""
    rank = {m: k for k, m in enumerate(group)}
    inner = sorted((e for e in links if e <= rank.keys()),
                   key=lambda e: sorted(rank[m] for m in e))
    best: tuple[int, list[str], list[str], frozenset[str]] | None = None
    for cut in inner:
        a = min(cut, key=rank.__getitem__)
        piece, stack = {a}, [a]
        while stack:
            u = stack.pop()
            for e in inner:
                if e != cut and u in e:
                    (w,) = e - {u}
                    if w not in piece:
                        piece.add(w)
                        stack.append(w)
        worst = max(len(piece), len(group) - len(piece))
        if best is None or worst < best[0]:
            best = (worst, [m for m in group if m in piece],
                    [m for m in group if m not in piece], cut)
    assert best is not None  # a group of two or more modules has a kept connection
    return best[1], best[2], best[3]


def _staged(groups: Sequence[Sequence[str]], start: Mapping[str, Cell],
            goal: Mapping[str, Cell], links: Collection[frozenset[str]],
            max_cuts: int | None = None
            ) -> tuple[list[Route], list[frozenset[str]]] | None:
    """Evacuate, then assemble: a slower order that does not get stuck.

    Every moving group leaves for its own slot in a row of parking slots below the
    configurations (outermost groups first, each by a free route), then the groups
    come back in the reverse of an order that peels the goal from the outside, so
    every goal cell is reached before anything closes the way in. A group that stays
    put but walls in a moving one (at its start or its goal) moves out and back too.
    Rigid groups hooked into each other so that no translation separates them are
    split: the kept connection that halves the largest such group is undocked (and
    docked again at the goal), one more dock/undock pair.

    Both peels are incremental (:class:`_Peel`): when a peel gets stuck, what it found
    before stays valid after a standing group is set moving (it stood in the way all
    along) or a stuck group is split (its pieces cover the same cells), so each peel
    resumes where it stopped, from the split group's turn on.

    Returns:
        The routes and the kept connections cut, as module pairs; None once more than
        ``max_cuts`` connections would be cut.
    """
    parts = [list(g) for g in groups]
    kept = set(links)
    cut: list[frozenset[str]] = []
    moving = {i for i, g in enumerate(parts) if start[g[0]] != goal[g[0]]}
    box = _bounds([*start.values(), *goal.values()], 0)
    peels = (_Peel(lambda i: [start[m] for m in parts[i]]),
             _Peel(lambda i: [goal[m] for m in parts[i]]))
    reach = 0
    while True:
        shapes = _shapes(parts, goal)
        frame = _Frame.around(box, shapes, reach)
        reach = frame.reach
        try:
            return _staged_once(parts, shapes, moving, frame, peels), cut
        except _Walled as walled:
            if walled.neighbours - moving:
                moving |= walled.neighbours
                continue
            largest = max(sorted(walled.neighbours | walled.stuck), key=lambda i: len(parts[i]))
            if len(parts[largest]) < 2:
                raise PlanningError("no collision-free order of the moves found: single "
                                    f"module {parts[largest][0]} is walled in") from None
            if max_cuts is not None and len(cut) >= max_cuts:
                return None
            piece_a, piece_b, edge = _split(parts[largest], kept)
            kept.discard(edge)
            cut.append(edge)
            parts[largest] = piece_a
            parts.append(piece_b)
            moving.add(len(parts) - 1)
            for peel in peels:
                peel.forget(largest)


class _Walled(Exception):
    def __init__(self, neighbours: set[int], stuck: set[int]):
        super().__init__()
        self.neighbours = neighbours
        self.stuck = stuck


@dataclass(frozen=True)
class _Frame:
    """The box of every start and goal cell and the rectangular lane around it.

    Attributes:
        box: ``(lo_x, lo_y, hi_x, hi_y)`` of the start and goal cells.
        reach: more than every group's extent [cells].
        lane: the lane's corners, ``2 * reach`` cells outside the box, same layout.
    """

    box: tuple[int, int, int, int]
    reach: int
    lane: tuple[int, int, int, int]

    @classmethod
    def around(cls, box: tuple[int, int, int, int], shapes: Sequence[tuple[Cell, ...]],
               at_least: int = 0) -> _Frame:
        """The frame of ``box`` for groups of ``shapes``, its reach at least ``at_least``
        (a wider lane keeps every route found in a narrower one valid)."""
        lo_x, lo_y, hi_x, hi_y = box
        reach = max(at_least,
                    max(max(abs(c) for s in _envelope(sh) for c in s) for sh in shapes) + 2)
        return cls(box, reach, (lo_x - 2 * reach, lo_y - 2 * reach, hi_x + 2 * reach,
                                hi_y + 2 * reach))

    def outside(self, shape: Sequence[Cell]) -> Callable[[Cell], bool]:
        """Whether a placement of ``shape`` has every cell of its envelope outside the box
        (there it can turn and drive out without touching the box)."""
        lo_x, lo_y, hi_x, hi_y = self.box
        cover = _envelope(tuple(shape))
        return lambda t: all(not (lo_x <= s[0] + t[0] <= hi_x and lo_y <= s[1] + t[1] <= hi_y)
                             for s in cover)

    def to_border(self) -> Callable[[Cell], int]:
        """Cells from a placement to just outside the box (the peel's A* heuristic)."""
        lo_x, lo_y, hi_x, hi_y = self.box
        return lambda t: max(0, min(t[0] - lo_x, hi_x - t[0], t[1] - lo_y, hi_y - t[1]) + 1)

    def to_lane(self, i: int, shape: Sequence[Cell], t: Cell) -> list[Cell]:
        """From a placement of group ``i`` outside the box, straight out to the lane in a
        direction in which no cell crosses the box, then along the lane to its bottom side."""
        lo_x, lo_y, hi_x, hi_y = self.box
        lane = self.lane
        cells = [(c[0] + t[0], c[1] + t[1]) for c in _envelope(tuple(shape))]
        beside_x = [not lo_x <= x <= hi_x for x, _ in cells]
        beside_y = [not lo_y <= y <= hi_y for _, y in cells]
        if all(y < lo_y or b for (_, y), b in zip(cells, beside_x, strict=True)):
            return [(t[0], lane[1])]
        if all(x < lo_x or b for (x, _), b in zip(cells, beside_y, strict=True)):
            return [(lane[0], t[1]), (lane[0], lane[1])]
        if all(x > hi_x or b for (x, _), b in zip(cells, beside_y, strict=True)):
            return [(lane[2], t[1]), (lane[2], lane[1])]
        if all(y > hi_y or b for (_, y), b in zip(cells, beside_x, strict=True)):
            corner = lane[0] if t[0] - lane[0] <= lane[2] - t[0] else lane[2]
            return [(t[0], lane[3]), (corner, lane[3]), (corner, lane[1])]
        raise _Walled(set(), {i})  # wrapped round the box: no straight way out


class _Peel:
    """An order in which the moving groups can leave the box one by one, and how, found
    incrementally.

    Every group not peeled yet stands where ``cells_of`` says; a peeled group has left.
    What a peel found stays valid when a standing group is set moving (it stood in the
    way of every earlier escape, and still does until its turn) and when a group not
    peeled yet is split (its pieces cover the cells it covered); :meth:`forget` drops
    the escapes from a split group's turn on.

    Args:
        cells_of: the cells of group ``i`` in this peel (start or goal).
    """

    def __init__(self, cells_of: Callable[[int], list[Cell]]):
        self.cells_of = cells_of
        self.order: list[int] = []
        self.escape: dict[int, list[Cell]] = {}

    def forget(self, i: int) -> None:
        """Group ``i`` changed shape: peel it, and every group after it, again."""
        if i in self.escape:
            for j in self.order[self.order.index(i):]:
                del self.escape[j]
            del self.order[len(self.escape):]

    def run(self, shapes: Sequence[tuple[Cell, ...]], moving: set[int], frame: _Frame
            ) -> tuple[list[int], dict[int, list[Cell]]]:
        """Peel every moving group not peeled yet, outermost first.

        Raises:
            _Walled: no moving group left has a way out; with the groups on their
                cheapest ways.
        """
        lo_x, lo_y, hi_x, hi_y = frame.box
        to_border = frame.to_border()
        cells_of, order, escape = self.cells_of, self.order, self.escape
        occupied = _Occupied({c: i for i in range(len(shapes)) if i not in escape
                              for c in cells_of(i)})
        inside = _bounds([(lo_x, lo_y), (hi_x, hi_y)], frame.reach)
        limit = 4 * (inside[2] - inside[0] + 1) * (inside[3] - inside[1] + 1)
        left = deque(sorted(moving - escape.keys(), key=lambda i: to_border(cells_of(i)[0])))
        failures = 0
        while left:
            i = left[0]
            path = _search(shapes[i], cells_of(i)[0], occupied, i, frame.outside(shapes[i]),
                           None, inside, limit, heuristic=to_border)
            if path is None:
                left.rotate(-1)
                failures += 1
                if failures <= len(left):
                    continue
                near: set[int] = set()
                for j in left:
                    path = _search(shapes[j], cells_of(j)[0], occupied, j,
                                   frame.outside(shapes[j]), None, inside, limit,
                                   penalty=4 * len(shapes), heuristic=to_border)
                    near |= {occupied[c] for c in (_swept(shapes[j], path) if path else ())
                             if occupied.get(c, j) != j}
                raise _Walled(near, set(left))
            failures = 0
            left.popleft()
            order.append(i)
            escape[i] = _straighten(path, shapes[i], occupied, i)
            for c in cells_of(i):
                del occupied[c]
        return order, escape


def _staged_once(groups: Sequence[Sequence[str]], shapes: Sequence[tuple[Cell, ...]],
                 moving: set[int], frame: _Frame, peels: tuple[_Peel, _Peel]) -> list[Route]:
    """One evacuate-and-assemble plan from the peels of the start and of the goal
    (resumed); raises :class:`_Walled` if a peel gets stuck.

    Outside the box, routes follow a rectangular lane ``2 * reach`` cells around it
    (``reach`` exceeds every group's extent, so a group on the lane is clear of the
    box) to a row of slots below the lane, each slot entered straight from above.
    Inside the box, a route is the escape path found by the peel, which stays valid:
    when a group leaves (or, reversed, arrives) exactly the groups that the peel saw
    are in the box.
    """
    lane, reach, box = frame.lane, frame.reach, frame.box
    out_order, out_paths = peels[0].run(shapes, moving, frame)
    in_peel, in_paths = peels[1].run(shapes, moving, frame)
    slot: dict[int, Cell] = {}
    x = box[0]
    for i in out_order:  # side by side, each clear of its neighbours' turns
        xs = [c[0] for c in _envelope(shapes[i])]
        slot[i] = (x - min(xs), lane[1] - 2 * reach)
        x += max(xs) - min(xs) + 2
    routes: list[Route] = []
    for i in out_order:
        escape = out_paths[i]
        path = [*escape, *frame.to_lane(i, shapes[i], escape[-1]), (slot[i][0], lane[1]),
                slot[i]]
        routes.append(Route(tuple(groups[i]), _corners(path), parking=True))
    for i in reversed(in_peel):
        escape = in_paths[i]
        path = [*escape, *frame.to_lane(i, shapes[i], escape[-1]), (slot[i][0], lane[1]),
                slot[i]][::-1]
        routes.append(Route(tuple(groups[i]), _corners(path), parking=False))
    return routes


def _corners(points: Sequence[Cell]) -> tuple[Cell, ...]:
    """The corners of a polyline of axis-aligned segments (unit steps or longer)."""
    steps: list[Cell] = [points[0]]
    for p in points[1:]:
        q = steps[-1]
        if p == q:
            continue
        if p[0] != q[0] and p[1] != q[1]:
            raise AssertionError(f"route leg {q} -> {p} is not axis-aligned")  # internal bug
        steps.append(p)
    if len(steps) <= 2:
        return tuple(steps)
    out = [steps[0]]
    for a, b, c in zip(steps, steps[1:], steps[2:], strict=False):
        d1 = ((b[0] > a[0]) - (b[0] < a[0]), (b[1] > a[1]) - (b[1] < a[1]))
        d2 = ((c[0] > b[0]) - (c[0] < b[0]), (c[1] > b[1]) - (c[1] < b[1]))
        if d1 != d2:
            out.append(b)
    out.append(steps[-1])
    return tuple(out)


@dataclass(frozen=True)
class Routing:
    """The moves in executable order and the kept connections cut to make them possible.

    Attributes:
        routes: the moves.
        cut: kept connections undocked so hooked groups can separate (module pairs).
    """

    routes: list[Route]
    cut: list[frozenset[str]]


def route_groups(groups: Sequence[Sequence[str]], start: Mapping[str, Cell],
                 goal: Mapping[str, Cell], *, links: Collection[frozenset[str]] = (),
                 priority: Sequence[str] = (), max_parks: int = 3,
                 direct: bool = True, max_cuts: int | None = None) -> Routing | None:
    """Order the groups' moves and route each through free cells, parking where needed.

    First greedily (:func:`_direct`): a group moves when its goal is free, it has a
    free route and its arrival walls in no cell a pending group needs; when none
    can, blockers are parked at the nearest place that touches no awaited goal.
    Should that get stuck, the order is planned again from the start by
    evacuating and assembling (:func:`_staged`).

    Args:
        groups: the rigid groups (every module in exactly one).
        start: start cell of every module (after the undocks).
        goal: goal cell of every module, same frame; groups translate rigidly.
        links: the kept connections that hold the groups together (module pairs).
        priority: tie-break order of the moves (modules earlier move earlier).
        max_parks: how often the greedy order may park one group.
        direct: try the greedy order first (False: evacuate and assemble only).
        max_cuts: give up (return None) rather than cut more kept connections.

    Returns:
        The moves in executable order (groups already at their goal do not appear
        unless they had to move out of the way) and the connections cut; None when
        that would take more than ``max_cuts`` cuts.

    Raises:
        PlanningError: two modules on one cell, a group that is no translation of
            its goal, or a group walled in for good.
    """
    seen: dict[Cell, str] = {}
    for group in groups:
        for m in group:
            if start[m] in seen:
                raise PlanningError(f"modules {seen[start[m]]} and {m} start on one cell "
                                    f"{start[m]}")
            seen[start[m]] = m
    for group, shape in zip(groups, _shapes(groups, goal), strict=True):
        if any((start[m][0] - start[group[0]][0], start[m][1] - start[group[0]][1]) != s
               for m, s in zip(group, shape, strict=True)):
            raise PlanningError(f"group {','.join(group)} is not a translation of its goal")
    if not groups:
        return Routing([], [])
    routes = _direct(groups, start, goal, priority, max_parks) \
        if direct and len(groups) <= DIRECT_LIMIT else None
    if routes is not None:
        return Routing(routes, [])
    staged = _staged(groups, start, goal, links, max_cuts)
    return None if staged is None else Routing(*staged)
