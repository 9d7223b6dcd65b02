"""Grid A* for a group's centroid around static modules (pure).

Cells closer than ``clearance`` to an obstacle are not forbidden but cost
``penalty`` each, so a module that starts next to its former neighbours can leave.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

__all__ = ["plan_path", "segment_clearance"]

Point = tuple[float, float]


def segment_clearance(a: Point, b: Point, obstacles: Sequence[Point]) -> float:
    """Smallest distance [m] from the segment ``a``-``b`` to any obstacle centre (inf if none)."""
    if not obstacles:
        return math.inf
    pa, pb = np.asarray(a, float), np.asarray(b, float)
    d = pb - pa
    length2 = float(d @ d)
    best = math.inf
    for o in obstacles:
        po = np.asarray(o, float)
        t = 0.0 if length2 == 0 else min(1.0, max(0.0, float((po - pa) @ d) / length2))
        best = min(best, float(np.linalg.norm(pa + t * d - po)))
    return best


def plan_path(start: Point, goal: Point, obstacles: Sequence[Point], clearance: float, *,
              resolution: float = 0.05, margin: float = 1.0, penalty: float = 25.0
              ) -> list[Point]:
    """Waypoints [m] from ``start`` to ``goal`` keeping ``clearance`` from obstacle centres.

    Args:
        start: centroid now [m].
        goal: centroid wanted [m].
        obstacles: centres of the modules to avoid [m].
        clearance: wanted distance from every obstacle centre [m].
        resolution: grid cell size [m].
        margin: free border around the bounding box of all points [m].
        penalty: extra cost per cell inside the clearance (in cells).

    Returns:
        Waypoints after the start, ending exactly at ``goal``.
    """
    points = np.array([start, goal, *obstacles], dtype=float)
    low = points.min(axis=0) - margin
    shape = np.ceil((points.max(axis=0) + margin - low) / resolution).astype(int) + 1
    xs = low[0] + np.arange(shape[0]) * resolution
    ys = low[1] + np.arange(shape[1]) * resolution
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    cost = np.zeros(shape)
    for ox, oy in obstacles:
        cost[np.hypot(gx - ox, gy - oy) < clearance] = penalty

    def cell(p: Point) -> tuple[int, int]:
        i = int(round((p[0] - low[0]) / resolution))
        j = int(round((p[1] - low[1]) / resolution))
        return min(max(i, 0), shape[0] - 1), min(max(j, 0), shape[1] - 1)

    s, g = cell(start), cell(goal)
    steps = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)]
    best = {s: 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    frontier = [(0.0, s)]
    while frontier:
        _, c = heapq.heappop(frontier)
        if c == g:
            break
        for di, dj in steps:
            n = (c[0] + di, c[1] + dj)
            if not (0 <= n[0] < shape[0] and 0 <= n[1] < shape[1]):
                continue
            new = best[c] + math.hypot(di, dj) + cost[n]
            if new < best.get(n, math.inf):
                best[n] = new
                parent[n] = c
                heapq.heappush(frontier, (new + math.hypot(g[0] - n[0], g[1] - n[1]), n))
    cells = [g]
    while cells[-1] != s and cells[-1] in parent:
        cells.append(parent[cells[-1]])
    cells.reverse()
    path = [(float(xs[i]), float(ys[j])) for i, j in cells[1:-1]]
    return [*path, (float(goal[0]), float(goal[1]))]
