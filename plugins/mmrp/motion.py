"""How a rigid group of tracked modules drives a leg of its route, and what it sweeps (pure).

Tracks drive a module only along its heading, and every MMRP module keeps heading 0
between moves, so a docked group executes an axis-aligned leg of its route as:

* a leg along x: drive straight, forwards or backwards;
* a leg along y: turn +90 degrees in place about the group's centre (the mean of its
  module centres), drive straight along y, and turn back -90 degrees about the new
  centre. The group ends translated by the leg, at heading 0, on the grid.

A turning group of several modules sweeps arcs around its centre and drives a y-leg
rotated, so it passes over cells that its grid translation never touches (before
issue 29 the planner and the checker modelled translations only and a seven-module
group turning in place could brush a structure out of latch tolerance).

**Body model.** A module's body (a square of side ``length``) lies within the disc
of its half-diagonal ``h`` around its centre, whatever its heading, so two modules
cannot touch while their centres are at least ``CLEARANCE`` = ``2 h`` plus a margin
apart. On the grid, neighbours are one pitch (0.30 m) apart and ``CLEARANCE`` is
0.293 m, so modules may pass alongside each other, and the test is exact for the
paths of centres: straight segments (drives) and circular arcs (turns).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import NamedTuple

import numpy as np

from .robot import MODULE

__all__ = [
    "CHORD_SAG",
    "CLEARANCE",
    "Arc",
    "Segment",
    "Sweep",
    "apart",
    "blocked",
    "centre",
    "distance",
    "distance_to_arc",
    "distance_to_segment",
    "drive_paths",
    "leg_paths",
    "segments_distance",
    "sweep",
    "turn_paths",
    "turned",
]

Point = tuple[float, float]

MARGIN = 0.01
"""Extra clearance between two bodies [m] (a turn's track slip, the latch's play)."""

CLEARANCE = (math.hypot(MODULE.geometry["length"], MODULE.geometry["width"]) + MARGIN) \
    / MODULE.geometry["pitch"]
"""Smallest distance between the centres of two modules that cannot touch [cells]."""


def centre(cells: Sequence[Point]) -> Point:
    """The centre of a group: the mean of its module centres [cells]."""
    return (sum(c[0] for c in cells) / len(cells), sum(c[1] for c in cells) / len(cells))


def turned(cells: Sequence[Point], sign: int = 1) -> list[Point]:
    """Module centres after a quarter turn (``sign`` +1 counter-clockwise) about the centre."""
    cx, cy = centre(cells)
    return [(cx - sign * (y - cy), cy + sign * (x - cx)) for x, y in cells]


class Segment(tuple):
    """A module centre's straight path ``(a, b)`` [cells]."""


class Arc(tuple):
    """A module centre's quarter turn ``(pivot, start, sign)`` about ``pivot`` [cells]."""


def distance_to_segment(p: Point, a: Point, b: Point) -> float:
    """Distance from ``p`` to the segment ``a``-``b``."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy)
                                             / length2))
    return math.hypot(a[0] + t * dx - p[0], a[1] + t * dy - p[1])


def distance_to_arc(p: Point, pivot: Point, start: Point, sign: int) -> float:
    """Distance from ``p`` to the quarter circle that ``start`` traces about ``pivot``
    (counter-clockwise for ``sign`` +1)."""
    rx, ry = start[0] - pivot[0], start[1] - pivot[1]
    r = math.hypot(rx, ry)
    vx, vy = p[0] - pivot[0], p[1] - pivot[1]
    d = math.hypot(vx, vy)
    if r == 0 or d == 0:
        return abs(d - r)
    swept = math.atan2(rx * vy - ry * vx, rx * vx + ry * vy) * sign  # from start, turn-wise
    if 0.0 <= swept <= math.pi / 2:
        return abs(d - r)
    end = (pivot[0] - sign * ry, pivot[1] + sign * rx)
    return min(math.hypot(p[0] - start[0], p[1] - start[1]), math.hypot(p[0] - end[0],
                                                                         p[1] - end[1]))


def turn_paths(cells: Sequence[Point]) -> list[Arc]:
    """The arcs of the module centres while the group at ``cells`` turns +90 degrees about
    its centre (turning back sweeps the same arcs)."""
    pivot = centre(cells)
    return [Arc((pivot, c, 1)) for c in cells]


def drive_paths(cells: Sequence[Point], shift: tuple[int, int], *, rotated: bool
                ) -> list[Segment]:
    """The segments of the module centres while the group at ``cells`` (turned +90
    degrees about its centre if ``rotated``) drives straight by ``shift``."""
    dx, dy = shift
    return [Segment(((x, y), (x + dx, y + dy)))
            for x, y in (turned(cells) if rotated else cells)]


def leg_paths(cells: Sequence[Point], shift: tuple[int, int]) -> list[Segment | Arc]:
    """The paths of the module centres while the group at ``cells`` drives one leg
    ``shift`` (along one axis, whole cells), turns included."""
    if not shift[1]:
        return list(drive_paths(cells, shift, rotated=False))
    end = [(x + shift[0], y + shift[1]) for x, y in cells]
    return [*turn_paths(cells), *drive_paths(cells, shift, rotated=True), *turn_paths(end)]


def distance(p: Point, path: Segment | Arc) -> float:
    """Distance from ``p`` to a module centre's path."""
    if isinstance(path, Arc):
        return distance_to_arc(p, *path)
    return distance_to_segment(p, *path)


def near(paths: Sequence[Segment | Arc]) -> Iterator[tuple[int, int]]:
    """The grid cells within ``CLEARANCE`` of the bounding box of ``paths``."""
    xs, ys = [], []
    for path in paths:
        if isinstance(path, Arc):
            (px, py), (sx, sy), _ = path
            r = math.hypot(sx - px, sy - py)
            xs += [px - r, px + r]
            ys += [py - r, py + r]
        else:
            xs += [path[0][0], path[1][0]]
            ys += [path[0][1], path[1][1]]
    for i in range(math.floor(min(xs) - CLEARANCE), math.ceil(max(xs) + CLEARANCE) + 1):
        for j in range(math.floor(min(ys) - CLEARANCE), math.ceil(max(ys) + CLEARANCE) + 1):
            yield i, j


def blocked(paths: Sequence[Segment | Arc]) -> frozenset[tuple[int, int]]:
    """Every grid cell that must hold no other module while module centres follow
    ``paths``: those whose centre comes closer than ``CLEARANCE`` to a path."""
    return frozenset(c for c in near(paths)
                     if any(distance(c, path) < CLEARANCE - 1e-9 for path in paths))


CHORD_SAG = 0.025
"""Largest distance of a turn's chords from its arc in a :class:`Sweep` [cells]."""


class Sweep(NamedTuple):
    """What a group's leg sweeps: its module centres' paths as straight pieces.

    Attributes:
        segments: drives as they are and turns as chords [cells], shape (k, 2, 2).
        slack: the largest distance of a true path point from the pieces [cells] (0
            without turns, at most ``CHORD_SAG``).
    """

    segments: np.ndarray
    slack: float


def sweep(paths: Sequence[Segment | Arc], sag: float = CHORD_SAG) -> Sweep:
    """``paths`` as a :class:`Sweep`: each quarter turn cut into the fewest equal chords
    that stay within ``sag`` of its arc (a chord of angle ``d`` on radius ``r`` lies
    ``r (1 - cos(d / 2))`` from it)."""
    pieces, slack = [np.zeros((0, 2, 2))], 0.0
    for path in paths:
        if isinstance(path, Arc):
            (px, py), (sx, sy), sign = path
            r = math.hypot(sx - px, sy - py)
            n = 1 if r <= sag else math.ceil(math.pi / 4 / math.acos(1 - sag / r))
            angles = math.atan2(sy - py, sx - px) + sign * np.linspace(0.0, math.pi / 2, n + 1)
            points = np.column_stack([px + r * np.cos(angles), py + r * np.sin(angles)])
            pieces.append(np.stack([points[:-1], points[1:]], axis=1))
            slack = max(slack, r * (1 - math.cos(math.pi / 4 / n)))
        else:
            pieces.append(np.array([path], dtype=float))
    return Sweep(np.concatenate(pieces), slack)


def _to_segments(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances [cells] from every point, shape (p, 2), to every segment, (s, 2, 2):
    shape (p, s)."""
    a, ab = segments[:, 0], segments[:, 1] - segments[:, 0]
    ap = points[:, None, :] - a[None]
    length2 = np.einsum("sk,sk->s", ab, ab)
    t = np.clip(np.einsum("psk,sk->ps", ap, ab) / np.where(length2 > 0, length2, 1.0), 0, 1)
    return np.linalg.norm(ap - t[..., None] * ab, axis=-1)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def segments_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The smallest distance [cells] between a point of a segment of ``a`` and one of
    ``b`` (shapes (n, 2, 2) and (m, 2, 2)): 0 where two cross, else the least distance
    of an end of one to a segment of the other."""
    ends = min(_to_segments(a.reshape(-1, 2), b).min(), _to_segments(b.reshape(-1, 2), a).min())
    a0, a1 = a[:, None, 0], a[:, None, 1]
    b0, b1 = b[None, :, 0], b[None, :, 1]
    crossing = ((_cross(a1 - a0, b0 - a0) * _cross(a1 - a0, b1 - a0) < 0)
                & (_cross(b1 - b0, a0 - b0) * _cross(b1 - b0, a1 - b0) < 0))
    return 0.0 if crossing.any() else float(ends)


def _box(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ends = segments.reshape(-1, 2)
    return ends.min(axis=0), ends.max(axis=0)


def _within(segments: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The segments whose bounding boxes meet the box ``lo``-``hi``."""
    keep = np.all((segments.min(axis=1) <= hi) & (segments.max(axis=1) >= lo), axis=1)
    return segments[keep]


def apart(a: Sweep, b: Sweep) -> bool:
    """Whether two groups moving at the same time, in any timing, keep their bodies apart.

    ``a`` and ``b`` are the :func:`sweep` of the two groups' legs. Every point of a true
    path lies within the sweep's ``slack`` of its pieces, so when the pieces of the two
    are at least ``CLEARANCE`` plus both slacks apart (exact segment distances), every
    pair of path points is at least ``CLEARANCE`` apart: no module of one group comes
    near a module of the other, wherever along its path each is (a sufficient test,
    never optimistic; exact for drives).
    """
    if not len(a.segments) or not len(b.segments):
        return True
    need = CLEARANCE + a.slack + b.slack
    (alo, ahi), (blo, bhi) = _box(a.segments), _box(b.segments)
    near_a = _within(a.segments, blo - need, bhi + need)
    near_b = _within(b.segments, alo - need, ahi + need)
    if not len(near_a) or not len(near_b):
        return True
    chunk = max(1, 1_000_000 // len(near_b))
    return all(segments_distance(near_a[i:i + chunk], near_b) >= need - 1e-9
               for i in range(0, len(near_a), chunk))
