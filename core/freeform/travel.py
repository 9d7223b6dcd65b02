"""Free single-connector modules on the floor: where they are, from their reports alone,
and the way to the module they are to dock on.

**Dead reckoning** (:class:`Locator`). The reports give each group's shape: breadth-first
from the group's root, ``p_j = p_i + s z_{i->j}`` (``s`` the centre spacing, ``z`` the
recognized connection vectors, root horizontal frame), with each module's heading
``psi_i`` in that frame. They do not say where the groups are relative to each other;
that comes from the modules' odometry ``(x, y, yaw)``
(:class:`~msrr.core.freeform.world.ModuleReport`: the gyro's yaw, and the travel its
drive senses while free or while its piece travels, in its own odometry frame ``O``).
The locator keeps a map: every module's position and the map yaw ``f_m`` of its ``O``.
Each tick each group is placed on it as a rigid body: its yaw the circular mean over its
modules of what their gyros say (``f_m + yaw_m - psi_m``), its offset the mean of where
their odometry says they went (``p_m + Rz(f_m) (o_m(t) - o_m(t - 1))``, less their place
in the group). So a module or a piece that lets go and travels is followed by the travel
its own shells sense, averaged over its modules, while the rest, which holds, stays; a
dock joins the two on the map. Groups never seen joined (the pieces of a start that is a
forest) are islands whose relative places are unknown, until a dock joins them.

**The way** (:func:`floor_path`). The module goes to a *spot* touching the target (at
the spacing from its centre, level), the free spot nearest to it; other modules at floor
level are discs it keeps clear of. A* over a 1 cm grid (8-connected, Euclidean cost and
heuristic) finds the way; :func:`pursue` follows it (a point ``lookahead`` ahead, speed
proportional to the distance left, bounded).
"""

from __future__ import annotations

import heapq
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.spatial import cKDTree

from ..alignment import best_turn, rot_z, rot_zs
from ..errors import ExecutionError
from .layout import lay_out_pieces
from .mujoco import yaw_of

__all__ = ["Locator", "best_turn", "floor_path", "link_vectors", "piece_goal", "pursue",
           "straight_line", "twist_velocities"]

_CELL = 0.01          # grid of the floor path [m]
_CLEARANCE = 0.008    # kept between shells on the way [m]
_BACK_OFF = 0.015     # a module touching others first moves this far away from them [m]
_GRAZE = 0.003        # kept from a module the start touches, beyond where the start is [m]
_SPOTS = 72           # directions tried for the docking spot
_LEVEL = 0.5          # a module is on the floor level within this many spacings in z


def link_vectors(reports: Mapping[str, object], links: Mapping[str, str],
                 heading: Mapping[str, float]) -> dict[str, np.ndarray]:
    """The unit vector (3,) of each link ``i -> links[i]`` in its group's root frame: the
    connector's axis (column 2 of ``i``'s reported tilt) turned by ``i``'s heading. All
    at once, each to the bit as ``rot_z(heading[i]) @ tilt[:, 2]`` normalised alone."""
    if not links:
        return {}
    sources = list(links)
    axes = np.array([reports[i].tilt[:, 2] for i in sources])  # type: ignore[attr-defined]
    z = (rot_zs(np.array([heading[i] for i in sources])) @ axes[:, :, None])[..., 0]
    z /= np.sqrt([row.dot(row) for row in z])[:, None]     # each norm as ``norm(row)``
    return dict(zip(sources, z, strict=True))


def _turned(yaw: float | np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``vectors`` (n, 3) each turned about ``z`` by ``yaw`` [rad] (one, or (n,)): each
    to the bit as ``rot_z(yaw) @ vector``."""
    turns = rot_zs(np.broadcast_to(yaw, len(vectors)))
    return (turns @ vectors[:, :, None])[..., 0]


def centres_of(reports: Mapping[str, object], links: Mapping[str, str],
               heading: Mapping[str, float], spacing: float
               ) -> tuple[dict[str, np.ndarray], dict[str, float], list[set[str]]]:
    """Centres (3,) [m] and headings [rad] of every reporting module in its group's root
    frame, and the groups (sets of modules joined by docks), from the reports, their
    links (``module -> the module its connector holds``) and the modules' headings in
    their groups' root frames (:func:`~msrr.core.freeform.recognition.links_of`,
    :func:`~msrr.core.freeform.recognition.module_headings`)."""
    heading = dict(heading)
    neighbours: dict[str, list[tuple[str, np.ndarray]]] = {m: [] for m in reports}
    vectors = link_vectors(reports, links, heading)
    for i, j in links.items():
        z = vectors[i]
        neighbours[i].append((j, z))
        neighbours[j].append((i, -z))
    pieces = lay_out_pieces(neighbours, sorted(reports, key=lambda m: (m in links, m)), spacing)
    centres = {m: p for piece in pieces for m, p in piece.items()}
    return centres, heading, [set(piece) for piece in pieces]


class Locator:
    """Where every module is, on a map kept from the module reports alone (module
    docstring): each group's pose on the map from its modules' odometry and gyros, its
    shape from the recognized connections.

    Args:
        spacing: centre distance of two docked modules [m].
    """

    def __init__(self, spacing: float):
        self.spacing = spacing
        self.position: dict[str, np.ndarray] = {}   # map position (3,) [m]
        self.frame: dict[str, float] = {}            # map yaw of its odometry frame [rad]
        self.island: dict[str, int] = {}             # modules whose relative place is known
        self._odometry: dict[str, np.ndarray] = {}
        self._groups: list[set[str]] = []
        self._islands = 0
        self._start: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._start_island = 0

    def start(self, layout: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> None:
        """Where the modules were put at the start: ``layout[m]`` is ``m``'s centre (3,)
        [m] and its connector's frame (3, 3), one frame for all (the start file's layout,
        as a lab places its modules). A group seen first whose modules are all in it is
        put there (:meth:`_place`), so separate start pieces share one island."""
        self._start = {m: (np.asarray(c, dtype=float), np.asarray(r, dtype=float))
                       for m, (c, r) in layout.items()}

    def update(self, reports: Mapping[str, object], links: Mapping[str, str],
               heading: Mapping[str, float]) -> None:
        """Read one tick's reports (with their links and headings, see
        :func:`centres_of`) and move every group on the map (:meth:`_place`)."""
        centres, heading, groups = centres_of(reports, links, heading, self.spacing)
        self._groups = groups
        odometry = {m: np.asarray(r.odometry, dtype=float)  # type: ignore[attr-defined]
                    for m, r in reports.items()}
        for group in groups:
            if self._start and not any(m in self.position for m in group) \
                    and all(m in self._start for m in group):
                self._place_at_start(sorted(group), centres, heading, reports, odometry)
            self._place(sorted(group), centres, heading, odometry)
        self._odometry.update(odometry)

    def _place_at_start(self, group: list[str], centres: Mapping[str, np.ndarray],
                        heading: Mapping[str, float], reports: Mapping[str, object],
                        odometry: Mapping[str, np.ndarray]) -> None:
        """Put ``group`` where the start layout has it, on the start's island: its yaw the
        circular mean over its modules of ``yaw(R_m T_m^T) - heading_m`` (``R_m`` the
        layout's connector frame, ``T_m`` the reported tilt: ``R = Rz(psi) T``), its
        offset the mean of ``c_m`` (the layout's centre) less ``Rz(psi)`` of its centre in
        the group's frame. :meth:`_place` then sets each module's odometry frame."""
        yaws = [yaw_of(self._start[m][1] @ reports[m].tilt.T) - heading[m]  # type: ignore[attr-defined]
                for m in group]
        psi = float(np.arctan2(np.mean(np.sin(yaws)), np.mean(np.cos(yaws))))
        turn = rot_z(psi)
        t = np.mean([self._start[m][0] - turn @ centres[m] for m in group], axis=0)
        if not self._start_island:
            self._islands += 1
            self._start_island = self._islands
        for m in group:
            self.position[m] = t + turn @ centres[m]
            self.frame[m] = psi + heading[m] - float(odometry[m][2])
            self.island[m] = self._start_island
            self._odometry[m] = odometry[m]

    def _place(self, group: list[str], centres: Mapping[str, np.ndarray],
               heading: Mapping[str, float], odometry: Mapping[str, np.ndarray]) -> None:
        """Put ``group`` on the map: its yaw ``psi`` the circular mean over its placed
        modules of ``frame_m + yaw_m - heading_m`` (each gyro's), its offset ``t`` the
        mean of ``p_m + Rz(frame_m) (o_m(t) - o_m(t-1)) - Rz(psi) c_m`` (each
        odometry's travel since the last tick, ``c_m`` its centre in the group's frame);
        a group with no placed module starts an island of its own. Modules of other
        islands joined to it (a dock) bring their islands along, moved by the same
        rigid motion."""
        known = [m for m in group if m in self.position]
        if not known:
            psi, t = 0.0, np.zeros(3)
            self._islands += 1
            island = self._islands
        else:
            island = min(self.island[m] for m in known)
            home = [m for m in known if self.island[m] == island]
            yaws = [self.frame[m] + odometry[m][2] - heading[m] for m in home]
            psi = float(np.arctan2(np.mean(np.sin(yaws)), np.mean(np.cos(yaws))))
            moved = np.zeros((len(home), 3))       # each odometry's travel, its frame
            moved[:, :2] = np.array([odometry[m][:2] - self._odometry[m][:2] for m in home])
            t = np.mean(np.array([self.position[m] for m in home])
                        + _turned(np.array([self.frame[m] for m in home]), moved)
                        - _turned(psi, np.array([centres[m] for m in home])), axis=0)
            for other in sorted({self.island[m] for m in known} - {island}):
                m = next(m for m in known if self.island[m] == other)
                self._join(other, island, m, t + rot_z(psi) @ centres[m],
                           psi + heading[m] - float(odometry[m][2]))
        positions = t + _turned(psi, np.array([centres[m] for m in group]))
        for m, position in zip(group, positions, strict=True):
            self.position[m] = position
            self.frame[m] = psi + heading[m] - float(odometry[m][2])
            self.island[m] = island

    def _join(self, other: int, island: int, module: str, position: np.ndarray,
              frame: float) -> None:
        """Move island ``other`` into ``island`` so that ``module`` lands at ``position``
        (3,) with its odometry frame at map yaw ``frame``."""
        delta = frame - self.frame[module]
        turn, anchor = rot_z(delta), self.position[module]
        for m in [m for m, i in self.island.items() if i == other]:
            self.position[m] = position + turn @ (self.position[m] - anchor)
            self.frame[m] += delta
            self.island[m] = island

    def pose(self, module: str) -> tuple[np.ndarray, float]:
        """``module``'s map position (3,) [m] and the map heading [rad] of its horizontal
        frame (the frame of its travel commands)."""
        return self.position[module], self.frame[module] + float(self._odometry[module][2])

    def piece(self, module: str) -> set[str]:
        """The modules joined to ``module`` by docks now (itself included)."""
        return next(g for g in self._groups if module in g)

    def alone(self, module: str) -> bool:
        """Whether ``module`` is free and carries no module (a group of its own)."""
        return self.piece(module) == {module}

    def relative(self, module: str) -> dict[str, np.ndarray]:
        """Every other module whose place relative to ``module`` is known, as a vector
        (3,) from ``module``'s centre in its horizontal frame now [m].

        Raises:
            ExecutionError: no module shares ``module``'s island (no report ever placed
                another module relative to it).
        """
        island = self.island[module]
        turn = rot_z(-(self.frame[module] + float(self._odometry[module][2])))
        out = {m: turn @ (p - self.position[module]) for m, p in self.position.items()
               if m != module and self.island[m] == island}
        if not out:
            raise ExecutionError(f"module {module} was never docked in a group: no report "
                                 "tells where it is")
        return out


_OUTLIER = 0.25      # a module farther than this from its goal place is not yet in its
#                      goal's shape (a piece the plan's last move bends later) [m]


def piece_goal(goal: Mapping[str, np.ndarray], here: Mapping[str, np.ndarray],
               piece: set[str], target: str) -> dict[str, np.ndarray]:
    """Where the modules of ``piece`` must be (2,) [m] for ``goal``'s shape with the
    module they dock on, ``target``, which stays: ``goal``'s centres (3,) of ``piece``
    turned by the yaw that best brings ``goal``'s other modules onto ``here`` (the
    centres now of the modules that stay, the target's group: one frame; least squares,
    weighted alike; :func:`_group_turn`) and put so that ``target`` is where it is now."""
    fixed = sorted(m for m in goal if m not in piece and m in here)
    a = np.array([np.asarray(goal[m], dtype=float)[:2] for m in fixed])
    b = np.array([np.asarray(here[m], dtype=float)[:2] for m in fixed])
    origin = np.asarray(goal[target], dtype=float)[:2]
    centre = np.asarray(here[target], dtype=float)[:2]
    turn = rot_z(_group_turn(a - origin, b - centre))[:2, :2]
    return {m: centre + turn @ (np.asarray(goal[m], dtype=float)[:2] - origin) for m in piece}


def _group_turn(a: np.ndarray, b: np.ndarray) -> float:
    """The yaw [rad] from the goal's centres ``a`` (n, 2) to those now, ``b`` (n, 2),
    both about the target: :func:`best_turn` over all of them, or, when some lie more
    than ``_OUTLIER`` from where the median turn about the target puts them (a piece
    docked straight whose goal is bent, not yet bent: its far modules metres off, which
    would turn the fit), over the others only."""
    turn = best_turn(a, b)
    far = np.linalg.norm(a, axis=1) > 2 * _OUTLIER
    if not np.any(far):
        return turn
    each = np.arctan2(b[far, 1], b[far, 0]) - np.arctan2(a[far, 1], a[far, 0])
    median = turn + float(np.median(np.angle(np.exp(1j * (each - turn)))))
    keep = np.linalg.norm(a @ rot_z(median)[:2, :2].T - b, axis=1) <= _OUTLIER
    return turn if np.all(keep) or np.sum(keep) < 2 else best_turn(a[keep], b[keep])


_STRAIGHT = 0.25      # a piece is straight within this many spacings of its line


def straight_line(points: np.ndarray, spacing: float, within: float = _STRAIGHT
                  ) -> np.ndarray | None:
    """The unit direction (2,) of the line through ``points`` (n, 2+) [m] if every point
    is within ``within`` ``spacing`` of it (by default a quarter: a straight piece, which
    moves along its line only: :meth:`~msrr.core.freeform.world.FreeformWorld.command_travel`),
    else ``None``; ``None`` for a single point."""
    flat = np.asarray(points, dtype=float)[:, :2]
    if len(flat) < 2:
        return None
    flat = flat - flat.mean(axis=0)
    line = np.linalg.svd(flat)[2][0]
    across = flat - np.outer(flat @ line, line)
    return None if np.max(np.linalg.norm(across, axis=1)) > within * spacing else line


def twist_velocities(centres: Mapping[str, np.ndarray], headings: Mapping[str, float],
                     velocity: np.ndarray, turn: float, about: np.ndarray, *,
                     speed: float) -> tuple[dict[str, np.ndarray], float]:
    """Each module's centre velocity (2,) [m/s] in its own horizontal frame when its piece
    moves as one rigid body, ``v_k = v + w e_z x (p_k - p)``, and the turn [rad/s]; both
    scaled down together so that no centre goes faster than ``speed`` [m/s] (a shell
    rolls at ``|v_k| / r``: its motors' rate bounds it).

    Args:
        centres: the piece's centres (3,) [m], one frame. headings: the modules' headings
            in it [rad]. velocity: ``v`` (2,) of the point ``about`` (2,) [m/s], same
            frame. turn: ``w`` [rad/s].
    """
    ms = sorted(centres)
    arm = np.array([np.asarray(centres[m], dtype=float)[:2] for m in ms]) - about
    v = np.asarray(velocity, dtype=float) + turn * np.column_stack([-arm[:, 1], arm[:, 0]])
    fastest = float(np.max(np.linalg.norm(v, axis=1)))
    scale = min(1.0, speed / fastest) if fastest > 0 else 1.0
    return ({m: scale * (rot_z(-float(headings[m]))[:2, :2] @ v[i]) for i, m in enumerate(ms)},
            scale * turn)


def floor_path(others: Mapping[str, np.ndarray], target: str, spacing: float
               ) -> list[np.ndarray]:
    """The way (points (2,) [m], from the module at the origin to the spot where it
    touches ``target``) around the other modules at floor level; ``others`` are their
    centres relative to the module (3,) [m].

    Raises:
        ExecutionError: ``target`` is not at the module's level, or no spot or no way is
            free.
    """
    goal = np.asarray(others[target], dtype=float)
    if abs(goal[2]) > _LEVEL * spacing:
        raise ExecutionError(f"module {target} is {goal[2]:+.3f} m above the moving module's "
                             "centre: it is not reached over the floor")
    level = [np.asarray(c, dtype=float)[:2] for m, c in others.items()
             if m != target and abs(c[2]) < 2 * spacing]
    angles = np.linspace(0.0, 2 * np.pi, _SPOTS, endpoint=False)
    spots = goal[:2] + spacing * np.column_stack([np.cos(angles), np.sin(angles)])
    free = [s for s in spots if all(np.linalg.norm(s - c) >= spacing + _CLEARANCE
                                    for c in level)]
    # first straight away from the modules it touches: a shell grazing a row while it
    # starts to roll pushes the row, which rolls away sideways like a rolling pin
    touching = [c for c in [*level, goal[:2]] if np.linalg.norm(c) < spacing + _CLEARANCE]
    away = -sum((c / np.linalg.norm(c) for c in touching), np.zeros(2))
    start = _BACK_OFF * away / np.linalg.norm(away) if np.linalg.norm(away) > 1e-9 \
        else np.zeros(2)
    for spot in sorted(free, key=lambda s: float(np.linalg.norm(s))):
        path = _astar(start, spot, [*level, goal[:2]],
                      [spacing + _CLEARANCE] * len(level) + [spacing - 0.5 * _CLEARANCE])
        if path is not None:
            return [start, *path] if np.any(start) else path
    raise ExecutionError(f"no free way over the floor to module {target}")


def _astar(start: np.ndarray, end: np.ndarray, centres: Sequence[np.ndarray],
           radii: Sequence[float]) -> list[np.ndarray] | None:
    """A* over a grid of ``_CELL`` from ``start`` to ``end`` (2,) [m], avoiding the discs
    (``centres``, ``radii``); the cells' centres along the way, ``end`` last."""
    points = np.array([start, end, *centres]) if len(centres) else np.array([start, end])
    margin = 3 * max(radii, default=0.1)
    low = points.min(axis=0) - margin
    shape = np.ceil((points.max(axis=0) + margin - low) / _CELL).astype(int) + 1
    xs = low[0] + _CELL * np.arange(shape[0])
    ys = low[1] + _CELL * np.arange(shape[1])
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    blocked = np.zeros(shape, dtype=bool)
    # a module the start already touches: the way never comes closer to it than the
    # start is (grazing a shell while rolling pushes its group away)
    discs = np.array(centres, dtype=float).reshape(-1, 2)
    reach = np.minimum(np.asarray(radii, dtype=float),
                       np.linalg.norm(discs - start, axis=1) + _GRAZE)
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    for r in np.unique(reach):      # one nearest-disc query per radius
        near, _ = cKDTree(discs[reach == r]).query(cells, distance_upper_bound=r)
        blocked |= (near < r).reshape(shape)

    def cell(p: np.ndarray) -> tuple[int, int]:
        i, j = np.rint((p - low) / _CELL).astype(int)
        return int(i), int(j)

    first, last = cell(start), cell(end)
    blocked[first] = blocked[last] = False
    steps = [(di, dj, float(np.hypot(di, dj))) for di in (-1, 0, 1) for dj in (-1, 0, 1)
             if di or dj]
    cost = {first: 0.0}
    came: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(0.0, first)]
    while heap:
        _, here = heapq.heappop(heap)
        if here == last:
            way = [end]
            while here in came:
                here = came[here]
                way.append(np.array([xs[here[0]], ys[here[1]]]))
            return way[::-1][1:] or [end]
        for di, dj, step in steps:
            there = (here[0] + di, here[1] + dj)
            if not (0 <= there[0] < shape[0] and 0 <= there[1] < shape[1]) or blocked[there]:
                continue
            new = cost[here] + step
            if new < cost.get(there, np.inf):
                cost[there] = new
                came[there] = here
                heapq.heappush(heap, (new + float(np.hypot(last[0] - there[0],
                                                           last[1] - there[1])), there))
    return None


def pursue(path: Sequence[np.ndarray], position: np.ndarray, *, speed: float,
           lookahead: float = 0.03, gain: float = 1.0) -> tuple[np.ndarray, float]:
    """The velocity (2,) [m/s] that follows ``path`` (points (2,)) from ``position``
    (same frame): toward the first point at least ``lookahead`` [m] beyond the nearest
    one, at ``min(speed, gain * distance left)``; and that distance left [m] (along the
    path from the nearest point)."""
    pts = np.asarray(path, dtype=float)
    near = int(np.argmin(np.linalg.norm(pts - position, axis=1)))
    left = float(np.linalg.norm(pts[near] - position)
                 + np.sum(np.linalg.norm(np.diff(pts[near:], axis=0), axis=1)))
    ahead = next((p for p in pts[near:] if np.linalg.norm(p - position) >= lookahead), pts[-1])
    direction = ahead - position
    norm = float(np.linalg.norm(direction))
    if norm < 1e-9:
        return np.zeros(2), left
    return direction / norm * min(speed, gain * left), left
