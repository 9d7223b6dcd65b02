"""The way of a piece over the floor: turns in place and straight drives, the whole
piece's swept area kept clear of every other module.

A FreeBOT piece travels as one rigid body
(:meth:`~msrr.core.freeform.world.FreeformWorld.command_travel`), but a *straight* piece
(every centre on one line) moves like a car without steering lock: along its line, and
turning about its centroid; it cannot roll across its line (nothing outside it gives a
torque about that line). Following a grid way that runs across the line therefore
crawls (measured in ``chains-to-tree``: a chain of four asked to go 0.02 m/s along a way
across its line made about 1 mm/s, and the steering that turned it onto the way swung
its end into a module of the row it had left, where it pushed for 10 s without moving).

So the way is planned as the piece moves: a sequence of :class:`Leg` -- a turn in place
about the centroid, or a straight drive (along the line for a straight piece, any
direction for a bent one) -- found by a hybrid A* over poses ``(centroid, heading)``
(Dolgov et al., 2010: continuous poses, visited cells of ``_CELL`` and headings of
``pi / 8`` from the goal's), each move collision-checked over the area it sweeps:
every module of the piece, sampled at most ``_SAMPLE`` apart along its own arc or line,
keeps ``spacing + _CLEARANCE`` from every other module at floor level (or, from a module
it already touches, no closer than it starts). Each expanded pose also tries the direct
way, turn to face the goal, drive, turn to the goal heading (the analytic expansion of
hybrid A*). The cost is the farthest any module travels (a drive's length, a turn's angle
times the piece's radius about its centroid): the time at the speed bound. The search is
led by the length of the centroid's shortest way round the other modules (Dolgov et al.'s
holonomic-with-obstacles heuristic, :func:`_way_lengths`), not the straight distance
alone: behind a wall across the straight line the straight distance leads the search
into the pocket before the wall, which it fills until its bound on poses. A search
that reaches its bound (``_EXPANSIONS`` poses) without a way is run again with its
estimate weighted by ``_INFLATE`` (weighted A*, Pohl 1970): the cheapest way round a
wall through a door costs every pose whose cost so far plus estimate is below the way's,
which in a scene of hundreds of modules are tens of thousands (the human example's action
33: 69,064); led by twice the estimate, the search goes for the door (273 poses) and the
way costs at most about twice the cheapest (there 17.68 m against 17.71 m, in more legs);
its lattice's zigzags are then shortcut by direct ways between two of its poses
(:func:`_shortcut`).
"""

from __future__ import annotations

import functools
import heapq
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..alignment import rot_z, wrap_angle
from ..errors import ExecutionError
from .layout import SLIDE_OVERLAP, WAY_IN
from .travel import Locator, best_turn, piece_goal, straight_line

__all__ = ["Leg", "PieceWay", "normalized", "piece_way", "plan_piece_way", "plan_legs",
           "poses_along"]

_CELL = 0.02          # visited cells of the search [m], for a piece of reach _REACH
_STEP = 0.03          # a drive of the search [m], for a piece of reach _REACH
_REACH = 0.16         # a longer piece's cells and drives grow with its reach [m]
_TURN = np.pi / 8     # a turn of the search [rad]
_SAMPLE = 0.005       # collision samples along a move, at the farthest module [m]
_CLEARANCE = 0.008    # kept between shells [m]
_STAND = 0.005        # a stand keeps this much more than the way's clearance [m]: the
#                       search's poses lie on a lattice and its direct way ends in a turn
#                       at the stand, so a stand free by a hair (the human example's
#                       action 46: 0.2 mm between two docked chains) is reached only
#                       exactly down its line, never by the search
_GRAZE = 0.010        # a module touched at the start is kept this much closer [m]: the
#                       map's own bend (2 deg of angle noise over a row puts its modules
#                       millimetres off its line, and the piece's too)
_GOAL_STRAIGHT = 0.02  # a goal's shape is straight within this many spacings of a line
_SHORT = 0.02         # the way stops this far short of the docking spot [m]
_LAST = WAY_IN        # its last stretch, straight in [m]
_EXPANSIONS = 20000   # the search gives up after this many poses
_INFLATE = 2.0        # a search cut off at its bound is run again led by its estimate this
#                       many times over (weighted A*, Pohl 1970: a way at most this many
#                       times the cheapest, for an estimate that never overshoots)
_DIRECT = 8           # the direct way is tried from every this many poses
_CHUNK = 256          # collision points checked at once (a move stops at the first hit)
_FIELD = 0.025        # cells of the centroid's shortest way round the others [m]
_OCTILE = float(np.sqrt(4.0 - 2.0 * np.sqrt(2.0)))   # an 8-connected way's length over
#                                                     the straight one's, at most


@dataclass(frozen=True)
class Leg:
    """One move of a piece: ``turn`` in place about its centroid to ``heading``, or
    ``drive`` straight to centroid ``to`` (2,) [m] keeping ``heading`` (the root's map
    heading [rad] at the leg's end)."""

    kind: str
    to: np.ndarray
    heading: float


@dataclass(frozen=True)
class PieceWay:
    """How a piece travels to dock its free module ``root`` on ``target`` (map frame:
    :class:`~msrr.core.freeform.travel.Locator`): the ``legs`` from where it is (its
    centroid ``origin`` (2,) [m], its modules at ``shape`` (m, 2) [m] from it, in the
    order of ``piece``, at heading ``heading``) to a stop short of its docking spot, then
    the guarded push along ``push`` (unit (2,), the piece's line for a straight piece)
    toward ``centre`` (the target's) until the connector latches. ``line``: a straight
    piece's line (unit (2,), at heading 0; it drives along it only), else ``None``.
    ``at_goal``: it docks at its goal place (else at a free place touching the target).

    A heading is the piece's: the root's map heading when the way was planned, plus the
    turn of the piece's shape since (:meth:`heading_of`), not the root's heading now (a
    free module's magnet unit turns in its rolling shell, not with its piece's arms).
    """

    root: str
    target: str
    piece: tuple[str, ...]
    origin: np.ndarray
    shape: np.ndarray
    heading: float
    legs: tuple[Leg, ...]
    centre: np.ndarray
    push: np.ndarray
    line: np.ndarray | None
    at_goal: bool = False

    def heading_of(self, centres: Mapping[str, np.ndarray]) -> float:
        """The piece's heading [rad] with its modules at ``centres`` (map, (2,) or (3,)):
        ``heading`` plus the least-squares turn from ``shape`` to them."""
        now = np.array([np.asarray(centres[m], dtype=float)[:2] for m in self.piece])
        return wrap_angle(self.heading + best_turn(self.shape, now))

    def travel(self) -> float:
        """The farthest any module goes along the legs [m]: each drive's length, each
        turn's angle times the piece's reach from its centroid (the way's cost)."""
        reach = float(np.max(np.linalg.norm(self.shape, axis=1)))
        return _cost(list(self.legs), (self.origin, self.heading), reach)

    def direction(self, stage: int) -> np.ndarray:
        """The unit direction (2,) of drive ``stage`` (from the end of the leg before it,
        or from ``origin``)."""
        start = self.legs[stage - 1].to if stage else self.origin
        step = self.legs[stage].to - start
        norm = float(np.linalg.norm(step))
        return step / norm if norm > 1e-12 else np.zeros(2)


class _Space:
    """The other modules as obstacles of a piece whose modules sit at ``offsets`` (m, 2)
    from its centroid at heading 0 [m]; each obstacle keeps ``spacing + _CLEARANCE`` from
    every module, less where the ``start`` pose (centroid (2,), heading) already comes
    closer (the piece just let go of it, or lies beside it)."""

    def __init__(self, others: np.ndarray, offsets: np.ndarray, spacing: float,
                 start: tuple[np.ndarray, float]):
        self.offsets = offsets
        self.reach = float(np.max(np.linalg.norm(offsets, axis=1))) if len(offsets) else 0.0
        self.others = others
        self.tree = cKDTree(others) if len(others) else None
        keep = np.full(len(others), spacing + _CLEARANCE)
        if len(others):
            now = _modules(offsets, *start)
            near = np.min(np.linalg.norm(others[:, None, :] - now[None, :, :], axis=2), axis=1)
            keep = np.minimum(keep, near - _GRAZE)
        self.keep = keep
        self.limit = spacing + _CLEARANCE

    def free(self, centres: np.ndarray, headings: np.ndarray, escaping: bool = False) -> bool:
        """Whether the piece at every pose (centroids (k, 2), headings (k,)) is clear;
        ``escaping``: it drives straight out of its start, where it may stay as close to
        what it touches as it starts (else it keeps the full clearance). The poses are
        checked ``_CHUNK`` points at a time, in order, and the first one that is not clear
        ends the check (a move is refused as soon as its first pose hits)."""
        if self.tree is None:
            return True
        per = max(1, _CHUNK // len(self.offsets))
        for lo in range(0, len(centres), per):
            points = _poses(self.offsets, centres[lo:lo + per], headings[lo:lo + per])
            if not self._clear(points, escaping):
                return False
        return True

    def _clear(self, points: np.ndarray, escaping: bool) -> bool:
        """Whether every point (n, 2) keeps its clearance: the full one from its nearest
        obstacle, or (``escaping``) each of its 8 nearest obstacles' own ``keep``."""
        if not escaping:
            dist, _ = self.tree.query(points, k=1, distance_upper_bound=self.limit)
            return not np.any(dist < self.limit)
        k = min(8, len(self.others))
        dist, idx = self.tree.query(points, k=k, distance_upper_bound=self.limit)
        dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
        hit = idx < len(self.others)
        return not np.any(dist[hit] < self.keep[idx[hit]])

    def all_free(self, moves: list[tuple[np.ndarray, np.ndarray, bool]]) -> list[bool]:
        """:meth:`free` of each move (centroids (k, 2), headings (k,), ``escaping``),
        the same answers from one query of the obstacles for all their points (a
        search's moves from one pose are short: one query costs less than many)."""
        if self.tree is None:
            return [True] * len(moves)
        if sum(len(c) for c, _, _ in moves) * len(self.offsets) > 4 * _CHUNK:
            return [self.free(*move) for move in moves]
        points = _poses(self.offsets, np.concatenate([c for c, _, _ in moves]),
                        np.concatenate([h for _, h, _ in moves]))
        k = min(8, len(self.others))
        dist, idx = self.tree.query(points, k=k, distance_upper_bound=self.limit)
        dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
        full = ~(dist[:, 0] < self.limit)                 # the nearest keeps the limit
        near = ~np.any(dist < np.append(self.keep, -np.inf)[idx], axis=1)
        out, lo = [], 0
        for c, _, escaping in moves:
            hi = lo + len(c) * len(self.offsets)
            out.append(bool(np.all((near if escaping else full)[lo:hi])))
            lo = hi
        return out

    def stands(self, centre: np.ndarray, heading: float) -> bool:
        """Whether the piece at pose ``(centre, heading)`` keeps ``_STAND`` more than the
        full clearance from every other module (a stand the search can reach)."""
        if self.tree is None:
            return True
        dist, _ = self.tree.query(_modules(self.offsets, centre, heading), k=1)
        return bool(np.all(dist >= self.limit + _STAND))

    def turn(self, centre: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
        """The poses (centroids (n, 2), headings (n,)) of the turn in place about
        ``centre`` from heading ``a`` to ``b`` (the short way), ``_SAMPLE`` apart at the
        farthest module."""
        sweep = wrap_angle(b - a)
        n = max(2, int(np.ceil(abs(sweep) * max(self.reach, 1e-3) / _SAMPLE)) + 1)
        return np.repeat(centre[None, :], n, axis=0), a + np.linspace(0.0, sweep, n)

    def drive(self, a: np.ndarray, b: np.ndarray, heading: float
              ) -> tuple[np.ndarray, np.ndarray]:
        """The poses of the straight drive from centroid ``a`` to ``b`` at ``heading``."""
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / _SAMPLE)) + 1)
        t = _fractions(n)
        return a + t * (b - a), np.full(n, heading)

    def turn_free(self, centre: np.ndarray, a: float, b: float) -> bool:
        """The turn in place about ``centre`` from heading ``a`` to ``b`` (the short way)."""
        return self.free(*self.turn(centre, a, b))

    def drive_free(self, a: np.ndarray, b: np.ndarray, heading: float,
                   escaping: bool = False) -> bool:
        """The straight drive from centroid ``a`` to ``b`` at ``heading``."""
        return self.free(*self.drive(a, b, heading), escaping)


@functools.lru_cache(maxsize=4096)
def _fractions(n: int) -> np.ndarray:
    """``np.linspace(0, 1, n)`` as a column (n, 1), kept (a search asks for a few lengths
    of drive many times); read-only."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    t.flags.writeable = False
    return t


def _modules(offsets: np.ndarray, centre: np.ndarray, heading: float) -> np.ndarray:
    """The piece's module centres (m, 2) at pose ``(centre, heading)``."""
    return centre + offsets @ rot_z(heading)[:2, :2].T


def _poses(offsets: np.ndarray, centres: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """The piece's module centres at every pose (centroids (k, 2), headings (k,)), as
    points (k m, 2), pose after pose: :func:`_modules` of each, in one stacked product."""
    c, s = np.cos(headings), np.sin(headings)
    turned = np.empty((len(headings), 2, 2))      # Rz(h)[:2, :2].T of each pose
    turned[:, 0, 0], turned[:, 0, 1], turned[:, 1, 0], turned[:, 1, 1] = c, s, -s, c
    return (centres[:, None, :] + offsets[None] @ turned).reshape(-1, 2)


def plan_legs(others: np.ndarray, offsets: np.ndarray, line: np.ndarray | None,
              start: tuple[np.ndarray, float], goal: tuple[np.ndarray, float],
              spacing: float) -> list[Leg]:
    """The legs (turns in place, straight drives) of a piece from pose ``start`` to pose
    ``goal`` (centroid (2,) [m], heading [rad]), clear of ``others`` (centres (n, 2)
    [m]) all along (module docstring): a hybrid A* with the direct way tried from
    every pose (:func:`_search`), run again with its estimate weighted by ``_INFLATE``
    if it stops at its bound.

    Args:
        offsets: the piece's module centres (m, 2) from its centroid at heading 0 [m].
        line: a straight piece's line (unit (2,), at heading 0): it drives along it
            only; ``None``: it drives in any direction.

    Raises:
        ExecutionError: no way is free.
    """
    space = _Space(np.asarray(others, dtype=float).reshape(-1, 2), offsets, spacing, start)
    (c0, h0), (g, hg) = (np.asarray(start[0], float), start[1]), (np.asarray(goal[0], float),
                                                                  goal[1])
    if not space.free(g[None, :], np.array([hg])):
        near = np.min(np.linalg.norm(space.others[:, None, :] - _modules(offsets, g, hg)[None],
                                     axis=2), axis=1)
        raise ExecutionError(f"the goal place of a piece of {len(offsets)} modules is not free: "
                             f"{int(np.sum(near < space.limit))} other modules lie there")
    grow = max(1.0, space.reach / _REACH)     # a long piece's search is as coarse
    cell, step = _CELL * grow, _STEP * grow
    low = np.minimum(c0, g) - 0.5
    high = np.maximum(c0, g) + 0.5
    if len(space.others):
        low = np.minimum(low, space.others.min(axis=0) - space.reach - spacing)
        high = np.maximum(high, space.others.max(axis=0) + space.reach + spacing)

    ahead = _way_lengths(space, g, low, high)
    for inflate in (1.0, _INFLATE):
        legs, cut = _search(space, (c0, h0), (g, hg), line, lambda c, w=inflate: w * ahead(c),
                            (low, high), cell, step)
        if legs is not None:
            return legs if inflate == 1.0 else _shortcut(space, (c0, h0), legs, line)
        if not cut:             # every pose the lattice reaches was tried
            break
    raise ExecutionError(f"no free way over the floor for a piece of {len(space.offsets)} "
                         "modules")


def _search(space: _Space, start: tuple[np.ndarray, float], goal: tuple[np.ndarray, float],
            line: np.ndarray | None, ahead: Callable[[np.ndarray], float],
            box: tuple[np.ndarray, np.ndarray], cell: float, step: float
            ) -> tuple[list[Leg] | None, bool]:
    """:func:`plan_legs`'s hybrid A* led by ``ahead`` (a centroid's estimate of the way
    left) over poses in ``box`` (low, high (2,)), visited cells of ``cell`` and drives of
    ``step`` [m]: the legs, or ``None`` and whether the search stopped at its bound of
    ``_EXPANSIONS`` poses (else no pose it reaches is left)."""
    (c0, h0), (g, hg), (low, high) = start, goal, box
    weight = max(space.reach, 1e-3)

    def key(c: np.ndarray, h: float) -> tuple[int, int, int, bool]:
        # headings off the goal's lattice (a start a little off it) keep their own
        # sixteenths: one key for all of them would leave each cell one heading
        k = int(np.rint(wrap_angle(h - hg) / _TURN)) % 16
        exact = abs(wrap_angle(h - hg - k * _TURN)) < 1e-6
        return int(np.rint(c[0] / cell)), int(np.rint(c[1] / cell)), k, exact

    # centre, heading, parent, and whether it only drove straight out of the start so far
    nodes: list[tuple[np.ndarray, float, int, bool]] = [(c0, h0, -1, True)]
    moves: list[Leg | None] = [None]
    best = {key(c0, h0): 0.0}
    heap = [(ahead(c0), 0.0, 0)]
    for n in range(_EXPANSIONS):
        if not heap:
            return None, False
        _, cost, i = heapq.heappop(heap)
        c, h, _parent, escaping = nodes[i]
        direct = _direct(space, c, h, g, hg, line) if n % _DIRECT == 0 else None
        if direct is not None:
            return _unwind(nodes, moves, i) + direct, False
        for leg, extra in _moves(space, c, h, line, weight, escaping, step):
            if not np.all((leg.to >= low) & (leg.to <= high)):
                continue
            k, new = key(leg.to, leg.heading), cost + extra
            if new < best.get(k, np.inf) - 1e-9:
                best[k] = new
                nodes.append((leg.to, leg.heading, i, escaping and leg.kind == "drive"))
                moves.append(leg)
                heapq.heappush(heap, (new + ahead(leg.to), new, len(nodes) - 1))
    return None, bool(heap)


def _way_lengths(space: _Space, goal: np.ndarray, low: np.ndarray, high: np.ndarray
                 ) -> Callable[[np.ndarray], float]:
    """The search's estimate of the way left from a centroid (2,) [m] to ``goal`` (2,) [m]
    within the box ``low``-``high``: the length of the centroid's shortest way round the
    other modules, over 8-connected cells of ``_FIELD`` (a diagonal step only between two
    free sides), scaled by ``1 / _OCTILE`` so that on open floor it is never more than the
    straight distance, and never less than that distance.

    A cell is blocked where its centre lies nearer to another module than the full
    clearance less the piece's module nearest its centroid: no pose of the piece, at any
    heading, puts its centroid there (a row of modules one spacing apart is a wall). A
    centroid in a cell no way of cells joins to the goal's (its start, grazing what it
    lay beside) is estimated by the straight distance."""
    def straight(c: np.ndarray) -> float:
        return float(np.hypot(goal[0] - c[0], goal[1] - c[1]))

    keep = space.limit - float(np.min(np.linalg.norm(space.offsets, axis=1)))
    if space.tree is None or keep <= 0.0:
        return straight
    shape = tuple(int(n) for n in np.ceil((high - low) / _FIELD).astype(int) + 1)
    ij = np.stack(np.meshgrid(*(np.arange(n) for n in shape), indexing="ij"), axis=-1)
    dist, _ = space.tree.query((low + _FIELD * ij).reshape(-1, 2), k=1,
                               distance_upper_bound=keep)
    free = (dist >= keep).reshape(shape)
    at = tuple(np.clip(np.rint((goal - low) / _FIELD).astype(int), 0, np.array(shape) - 1))
    free[at] = True
    index = np.arange(free.size).reshape(shape)
    rows, cols, lengths = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        a = (slice(0, shape[0] - di), slice(max(0, -dj), shape[1] - max(0, dj)))
        b = (slice(di, None), slice(max(0, dj), shape[1] + min(0, dj)))
        ok = free[a] & free[b]
        if di and dj:          # no corner cut between two blocked sides
            ok &= free[a[0], b[1]] & free[b[0], a[1]]
        rows.append(index[a][ok])
        cols.append(index[b][ok])
        lengths.append(np.full(int(ok.sum()), _FIELD * np.hypot(di, dj)))
    n = free.size
    graph = coo_array((np.concatenate(lengths), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    field = (dijkstra(graph, directed=False, indices=int(index[at])) / _OCTILE).reshape(shape)

    def ahead(c: np.ndarray) -> float:
        i, j = np.clip(np.rint((c - low) / _FIELD).astype(int), 0, np.array(shape) - 1)
        d = float(field[i, j])
        return max(d, straight(c)) if np.isfinite(d) else straight(c)

    return ahead


def _moves(space: _Space, c: np.ndarray, h: float, line: np.ndarray | None,
           weight: float, escaping: bool, step: float) -> list[tuple[Leg, float]]:
    """The search's moves from pose ``(c, h)`` that are clear, with their costs: turns of
    ``_TURN`` onto the goal's heading lattice, and drives of ``step`` (``escaping``: the
    pose was reached by drives straight out of the start, which may graze what the start
    touches; a turn never does, as it would push it)."""
    legs = [(Leg("turn", c, wrap_angle(h + sign * _TURN)), _TURN * weight,
             (*space.turn(c, h, h + sign * _TURN), False)) for sign in (1.0, -1.0)]
    if line is None:
        directions = [np.array([np.cos(a), np.sin(a)]) for a in np.arange(8) * np.pi / 4]
    else:
        ahead = rot_z(h)[:2, :2] @ line
        directions = [ahead, -ahead]
    ends = c + step * np.array(directions)
    legs += [(Leg("drive", to, h), step, (*space.drive(c, to, h), escaping)) for to in ends]
    free = space.all_free([move for _, _, move in legs])
    return [(leg, cost) for (leg, cost, _), ok in zip(legs, free, strict=True) if ok]


def _direct(space: _Space, c: np.ndarray, h: float, g: np.ndarray, hg: float,
            line: np.ndarray | None) -> list[Leg] | None:
    """Turn to face ``g``, drive there, turn to ``hg``, if all of it is clear (a piece
    that drives in any direction drives first, then turns, or turns first), else ``None``."""
    way = g - c
    if np.linalg.norm(way) < 1e-9:
        return [Leg("turn", g, hg)] if space.turn_free(g, h, hg) else None
    if line is None:
        for first in ("drive", "turn"):
            hd = h if first == "drive" else hg
            if space.turn_free(c if first == "turn" else g, h, hg) \
                    and space.drive_free(c, g, hd):
                return [Leg("drive", g, h), Leg("turn", g, hg)] if first == "drive" else \
                    [Leg("turn", c, hg), Leg("drive", g, hg)]
        return None
    facing = float(np.arctan2(way[1], way[0]) - np.arctan2(line[1], line[0]))
    options = sorted((wrap_angle(facing), wrap_angle(facing + np.pi)),
                     key=lambda a: abs(wrap_angle(a - h)) + abs(wrap_angle(hg - a)))
    for hd in options:
        if space.turn_free(c, h, hd) and space.drive_free(c, g, hd) \
                and space.turn_free(g, hd, hg):
            return [Leg("turn", c, hd), Leg("drive", g, hd), Leg("turn", g, hg)]
    return None


def _shortcut(space: _Space, start: tuple[np.ndarray, float], legs: list[Leg],
              line: np.ndarray | None) -> list[Leg]:
    """``legs`` from ``start`` with stretches between two of their poses replaced by the
    direct way (:func:`_direct`: turn, drive, turn) where that is clear and shorter
    (path shortcutting): from each pose in turn, the farthest later pose so reached. A
    weighted search's way (``_INFLATE``) detours within its bound and zigzags on the
    lattice; the cheapest way is what the unweighted search would have returned."""
    poses = [(np.asarray(start[0], dtype=float), float(start[1]))]
    poses += [(np.asarray(leg.to, dtype=float), leg.heading) for leg in legs]
    out, i = [], 0
    while i < len(legs):
        for j in range(len(legs), i + 1, -1):
            direct = _direct(space, *poses[i], *poses[j], line)
            if direct is not None and _cost(direct, poses[i], space.reach) < _cost(
                    legs[i:j], poses[i], space.reach) - 1e-9:
                out += [leg for leg, (c, h) in zip(direct, [poses[i]] + [
                    (d.to, d.heading) for d in direct[:-1]], strict=True)
                        if leg.kind == "drive" or abs(wrap_angle(leg.heading - h)) > 1e-9]
                i = j
                break
        else:
            out.append(legs[i])
            i += 1
    return out


def _cost(legs: list[Leg], start: tuple[np.ndarray, float], reach: float) -> float:
    """The farthest module's travel along ``legs`` from pose ``start`` [m]: drives'
    lengths, turns' angles times ``reach`` (the search's cost)."""
    (c, h), total = start, 0.0
    for leg in legs:
        total += float(np.linalg.norm(leg.to - c)) + reach * abs(wrap_angle(leg.heading - h))
        c, h = leg.to, leg.heading
    return total


def _unwind(nodes: list[tuple[np.ndarray, float, int, bool]], moves: list[Leg | None],
            i: int) -> list[Leg]:
    """The legs from the start to node ``i``; turns in one sense (less than a half turn
    in all) and drives in one direction merged."""
    path = []
    while i > 0:
        path.append((moves[i], nodes[nodes[i][2]]))
        i = nodes[i][2]
    merged: list[tuple[Leg, np.ndarray, float]] = []    # leg, centre and heading before
    for move, (c, h, _, _) in reversed(path):
        assert move is not None
        if merged and merged[-1][0].kind == move.kind:
            leg, c0, h0 = merged[-1]
            if move.kind == "turn":
                same = wrap_angle(move.heading - h0) * wrap_angle(leg.heading - h0) > 0 \
                    and abs(wrap_angle(leg.heading - h0)) + _TURN < np.pi - 1e-6
            else:
                u, v = leg.to - c0, move.to - leg.to
                same = abs(float(u[0] * v[1] - u[1] * v[0])) < 1e-9 and float(u @ v) > 0
            if same:
                merged[-1] = (move, c0, h0)
                continue
        merged.append((move, c, h))
    return [leg for leg, _, _ in merged]


def poses_along(legs: list[Leg] | tuple[Leg, ...], start: tuple[np.ndarray, float],
                step: float, reach: float) -> list[tuple[np.ndarray, float]]:
    """Poses (centroid (2,), heading) every ``step`` [m] of the farthest module's travel
    (``reach`` [m] from the centroid) along ``legs`` from ``start``: the swept poses."""
    c, h = np.asarray(start[0], dtype=float), float(start[1])
    out = [(c, h)]
    for leg in legs:
        if leg.kind == "turn":
            sweep = wrap_angle(leg.heading - h)
            n = max(1, int(np.ceil(abs(sweep) * max(reach, 1e-3) / step)))
            out += [(c, h + sweep * (k + 1) / n) for k in range(n)]
            h = leg.heading
        else:
            n = max(1, int(np.ceil(np.linalg.norm(leg.to - c) / step)))
            out += [(c + (leg.to - c) * (k + 1) / n, h) for k in range(n)]
            c = np.asarray(leg.to, dtype=float)
    return out


def plan_piece_way(locator: Locator, root: str, target: str,
                   goal: Mapping[str, np.ndarray]) -> PieceWay:
    """The :class:`PieceWay` of the piece led by ``root`` to dock on ``target`` in the
    shape of ``goal`` (centres (3,) of the goal configuration, any frame), from the map of
    ``locator`` (:func:`piece_way`).

    Raises:
        ExecutionError: ``target`` is on no map island with ``root`` (nothing tells where
            it is), or no way is free.
    """
    locator.relative(root)                     # raises if root's island is alone
    here = {m: p[:2] for m, p in locator.position.items()
            if locator.island[m] == locator.island[root]}
    if target not in here:
        raise ExecutionError(f"module {target} was never joined to the piece of {root}: "
                             "no report tells where it is")
    return piece_way(here, locator.piece(root), locator.piece(target), root,
                     locator.pose(root)[1], target, goal, locator.spacing)


def piece_way(here: Mapping[str, np.ndarray], piece: set[str], group: set[str], root: str,
              heading: float, target: str, goal: Mapping[str, np.ndarray],
              spacing: float) -> PieceWay:
    """The :class:`PieceWay` of ``piece`` (led by ``root``, at map heading ``heading``
    [rad]) to dock on ``target`` (of ``group``, which stays), the modules at ``here``
    (centres (2,) [m], one map): where it must end in the shape of ``goal`` (centres (3,),
    any frame; :func:`~msrr.core.freeform.travel.piece_goal`) in the shape it has
    (:func:`_goal_pose`: its root at the root's goal place), a stop ``_SHORT`` short of
    it with a last stretch straight in (along the line of a straight piece, toward the
    target; ``_LAST`` long, or longer to start clear of modules it docks beside:
    :func:`_dock_free`), and the legs there (:func:`plan_legs`).

    Where the goal's place is not free now (modules lie there that a later step moves
    away), the piece docks, in the shape it has, at the free place touching the target
    nearest to the goal's (:func:`_free_docks`); the plan's last move takes the goal's
    shape, as it does for a lone module docked on the free spot nearest to it.

    Raises:
        ExecutionError: no place touching the target is free, or no way is free.
    """
    ms = sorted(piece)
    now = np.array([here[m] for m in ms])
    a = now - now.mean(axis=0)
    offsets = a @ rot_z(heading)[:2, :2]          # at heading 0: Rz(-heading) a
    line = straight_line(now, spacing)
    line0 = None if line is None else rot_z(-heading)[:2, :2] @ line
    centre = np.asarray(here[target], dtype=float)[:2]
    end = piece_goal(goal, {m: here[m] for m in group | piece}, piece, target)
    then = np.array([end[m] for m in ms])
    middle, turn = _goal_pose(a, then, ms.index(root), centre, line, spacing)
    toward = normalized(centre - end[root])
    if line0 is None:
        push = toward
    else:
        along = rot_z(heading + turn)[:2, :2] @ line0
        push = along if float(along @ toward) >= 0 else -along
    names = sorted(m for m in here if m not in piece)
    others = np.array([here[m] for m in names], dtype=float).reshape(-1, 2)
    start = (now.mean(axis=0), heading)
    space = _Space(others, offsets, spacing, start)
    wanted = (middle, wrap_angle(heading + turn), push)
    index = (ms.index(root), others, names.index(target))
    def places() -> Iterator[tuple[np.ndarray, float, np.ndarray, float, bool]]:
        """The goal place if free, then the free places touching the target, searched
        only when no way reaches the goal place (their search is the dear part); each
        with the length of its last stretch in, and whether it is the goal place."""
        back = _dock_free(space, offsets, *index, *wanted, clear_in=False)
        if back is not None:
            yield (*wanted, back, True)
        yield from ((*place, False) for place in _free_docks(space, offsets, *index, line0,
                                                              wanted))

    tried = 0
    for middle, hd, push, back, at_goal in places():
        tried += 1
        finish = middle - _SHORT * push
        try:
            legs = plan_legs(others, offsets, line0, start, (finish - back * push, hd),
                             spacing)
        except ExecutionError:
            continue
        legs.append(Leg("drive", finish, hd))
        return PieceWay(root, target, tuple(ms), now.mean(axis=0), a, heading, tuple(legs),
                        centre, push, line0, at_goal)
    if not tried:
        rise = float(np.asarray(goal[root], dtype=float)[2] - np.asarray(goal[target],
                                                                         dtype=float)[2])
        above = f" (its goal place lies {rise:+.2f} m above {target}, where a piece on the " \
                "floor does not reach)" if abs(rise) > spacing / 2 else ""
        raise ExecutionError(f"no place touching module {target} is free for the piece "
                             f"of {len(ms)} modules led by {root}{above}")
    raise ExecutionError(f"no free way over the floor for the piece of {len(ms)} modules "
                         f"led by {root} to any of {tried} places touching {target}")


def _goal_pose(shape: np.ndarray, then: np.ndarray, root: int, centre: np.ndarray,
               line: np.ndarray | None, spacing: float) -> tuple[np.ndarray, float]:
    """Where a piece docks at its goal place in the shape it has: its centroid (2,) [m]
    and the turn [rad] from now, for its modules at ``shape`` (m, 2) [m] from their
    centroid (map frame) and wanted at ``then`` (m, 2) [m], its row ``root`` docking on
    the target at ``centre`` (2,) [m].

    The root goes to its own goal place (where it latches: a piece fitted by its centroid
    alone docks its root off the target's side when its shape is not the goal's). The
    turn is the least-squares one over the modules, except for a straight piece whose
    goal is bent: it lies straight out from the target through the root's goal place
    (the plan's last move bends it), rather than across the target's other sides. The
    goal's vectors are exact, so its shape is straight only within ``_GOAL_STRAIGHT``
    spacings of a line: a shallow C (within a quarter spacing, straight for a piece on
    the map) is bent, and fitted by least squares it would turn the piece off its root's
    own direction, across the target's neighbours' places.
    """
    turn = best_turn(shape, then - then.mean(axis=0))
    arm = -shape[root]                                   # root -> centroid
    if line is not None and straight_line(then, spacing, _GOAL_STRAIGHT) is None \
            and float(np.linalg.norm(arm)) > 1e-9:
        out = then[root] - centre
        turn = wrap_angle(float(np.arctan2(out[1], out[0]) - np.arctan2(arm[1], arm[0])))
    return then[root] + rot_z(turn)[:2, :2] @ arm, turn


_BACK = 1.5           # a stretch in grows at most this much past _LAST, and the piece's
#                       length (to clear chains as long as itself docked either side) [m]
_BACK_STEP = 0.05     # ... in steps of this [m]
_TRIES = 4            # free docking places tried (nearest the goal's first)
_OVERLAP = SLIDE_OVERLAP   # shells closer than the spacing less this overlap [m]
_DIRECTIONS = 72      # directions of the root about the target tried
_APART = np.pi / 3    # free places tried first lie this far apart about the target [rad]


def normalized(vector: np.ndarray) -> np.ndarray:
    """``vector`` scaled to unit length; zeros for a vector of no length."""
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 1e-12 else np.zeros_like(vector)


def _dock_free(space: _Space, offsets: np.ndarray, root: int, others: np.ndarray,
               target: int, middle: np.ndarray, heading: float, push: np.ndarray, *,
               clear_in: bool = True) -> float | None:
    """The length [m] of the last stretch in if the piece can end docked with its
    centroid at ``middle`` (2,) and heading ``heading``, else ``None``: it stands
    ``_SHORT`` + the stretch back along ``push`` with the way's clearance and ``_STAND``
    more (:meth:`_Space.stands`), and over the
    stretch in, docked at the end, no shell overlaps another (the root touches the
    target, ``others[target]``; nothing else does). ``clear_in``: the stretch, ``_LAST``
    long, keeps the way's clearance too; else it is the shortest from ``_LAST`` up (by
    ``_BACK_STEP``, at most ``_BACK`` more) that starts clear, where the piece can turn
    round in place if there is such a stand (a way reaches it from any side): a piece
    docking beside others, one spacing from them as the goal packs its chains, slides in
    along them from where it is clear of them (none clear that near, its stand beyond
    their ends: the stretch grows by at most the piece's own length more)."""
    def clear_of(backs: np.ndarray | list[float]) -> list[float]:
        return [float(b) for b in backs if space.stands(middle - (_SHORT + b) * push, heading)]

    backs = [_LAST] if clear_in else _LAST + np.arange(0.0, _BACK + 1e-9, _BACK_STEP)
    clear = clear_of(backs)
    if not clear and not clear_in:      # beside docked chains as long as itself
        clear = clear_of(backs[-1] + np.arange(_BACK_STEP, 2.0 * space.reach + 1e-9,
                                               _BACK_STEP))
    if not clear:
        return None
    back = clear[0]
    if not clear_in:      # a stand where it turns round, if there is one
        back = next((b for b in clear if all(space.turn_free(
            middle - (_SHORT + b) * push, heading, heading + s * (np.pi - 1e-6))
            for s in (1, -1))), back)
    pre = middle - (_SHORT + back) * push
    if clear_in and not space.drive_free(pre, middle - _SHORT * push, heading):
        return None
    if space.tree is None:
        return back
    n = int(np.ceil((_SHORT + back) / _SAMPLE)) + 1
    poses = pre + np.linspace(0.0, 1.0, n)[:, None] * (middle - pre)
    points = _poses(offsets, poses, np.full(len(poses), heading))
    k = min(3, len(others))
    gap = space.limit - _CLEARANCE - _OVERLAP
    dist, idx = space.tree.query(points, k=k, distance_upper_bound=gap)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    touching = (np.arange(len(points)) % len(offsets) == root)[:, None] & (idx == target)
    return None if np.any((idx < len(others)) & ~touching) else back


def _free_docks(space: _Space, offsets: np.ndarray, root: int, others: np.ndarray,
                target: int, line: np.ndarray | None,
                wanted: tuple[np.ndarray, float, np.ndarray]
                ) -> list[tuple[np.ndarray, float, np.ndarray, float]]:
    """The free places (centroid (2,), heading, push (2,), the stretch in [m]) where the piece, in its shape
    now (``offsets`` at heading 0, its root the row ``root``), docks on the target at
    ``others[target]``: the root touching it from one of ``_DIRECTIONS`` directions, the piece
    turned so that its centroid lies straight away from the target beyond the root (a
    bent piece also turned ``pi / 8`` and ``pi / 4`` either side), pushing toward the
    target (a straight piece along its line): the ``_TRIES`` nearest to ``wanted``
    (centroid distance plus heading difference times the piece's reach), then up to as
    many more, each the nearest of another side of the target (its direction ``_APART``
    from those before: a way that cannot reach one place seldom reaches its
    neighbours)."""
    arm = -offsets[root]                           # root -> centroid at heading 0
    centre = others[target]
    spacing = space.limit - _CLEARANCE
    found = []
    for phi in np.arange(_DIRECTIONS) * 2 * np.pi / _DIRECTIONS:
        out = np.array([np.cos(phi), np.sin(phi)])
        base = phi - float(np.arctan2(arm[1], arm[0])) if np.linalg.norm(arm) > 1e-9 \
            else phi
        for extra in ((0.0,) if line is not None else (0.0, _TURN, -_TURN, 2 * _TURN,
                                                       -2 * _TURN)):
            heading = wrap_angle(base + extra)
            turn = rot_z(heading)[:2, :2]
            middle = centre + spacing * out + turn @ arm
            push = -out if line is None else turn @ line * (1.0 if float(
                (turn @ line) @ out) <= 0 else -1.0)
            if _dock_free(space, offsets, root, others, target, middle, heading,
                          push) is not None:
                cost = float(np.linalg.norm(middle - wanted[0])) \
                    + space.reach * abs(wrap_angle(heading - wanted[1]))
                found.append((cost, phi, middle, heading, push))
    found.sort(key=lambda f: f[0])
    apart = found[:_TRIES]                # the nearest, then the nearest of other sides
    for f in found[_TRIES:]:
        if len(apart) < 2 * _TRIES and all(abs(wrap_angle(f[1] - g[1])) >= _APART for g in apart):
            apart.append(f)
    return [(m, h, p, _LAST) for _, _, m, h, p in apart]
