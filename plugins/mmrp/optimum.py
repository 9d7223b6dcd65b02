"""Exact optimum for small systems: the bijection that keeps the most connections.

The reference for tests and the benchmark (not part of the paper). Minimising
dock/undock pairs equals maximising the start connections ``connect(uF_u, vF_v)``
whose image ``connect(f(u)F_u, f(v)F_v)`` is a goal connection. Branch and bound
over all bijections: start modules are assigned in breadth-first order, so only the
connection to the parent can become kept at each step; the branch that keeps it is
tried first; a branch is cut when the kept connections plus an upper bound on what
is left (per face-pair type, T-B or L-R, the smaller of the undecided start
connections and the goal connections not yet kept) cannot beat the best found.
"""

from __future__ import annotations

from dataclasses import dataclass

from msrr.core import Configuration
from msrr.core.errors import PlanningError

from .centre import adjacency, parents, root_of
from .representation import face_links

__all__ = ["MAX_MODULES", "Optimum", "optimum"]

MAX_MODULES = 9
"""Largest system the exhaustive search accepts."""


@dataclass(frozen=True)
class Optimum:
    """The optimal bijection and its cost.

    Attributes:
        mapping: start id -> goal id.
        kept: connections kept.
        pairs: dock/undock pairs, ``|E_g| - kept``.
        nodes: search nodes expanded.
    """

    mapping: dict[str, str]
    kept: int
    pairs: int
    nodes: int


def _kind(face: str) -> int:
    return 0 if face in ("T", "B") else 1


def optimum(start: Configuration, goal: Configuration, *, limit: int = MAX_MODULES) -> Optimum:
    """The bijection start -> goal that keeps the most connections, by exhaustive search.

    Raises:
        PlanningError: module counts differ or there are more than ``limit`` modules.
    """
    n = len(start)
    if n != len(goal):
        raise PlanningError(f"start has {n} modules and goal {len(goal)}")
    if n > limit:
        raise PlanningError(f"the exact optimum is limited to {limit} modules, got {n}")
    links_c, links_g = face_links(start), face_links(goal)
    root = root_of(start)
    parent = parents(adjacency(start), root)
    order = list(parent)
    edge_face: dict[str, tuple[str, str]] = {}
    for v, p in parent.items():
        if p is not None:
            face = next(f for f, (w, _) in links_c[p].items() if w == v)
            edge_face[v] = (face, links_c[p][face][1])
    remaining_c = [0, 0]
    for face, _ in edge_face.values():
        remaining_c[_kind(face)] += 1
    goal_left = [0, 0]
    for e in goal.edges():
        goal_left[_kind(e.ports[0])] += 1
    goal_ids = goal.vertices()
    assign: dict[str, str] = {}
    used: set[str] = set()
    best: list = [-1, {}]
    nodes = 0

    def bound() -> int:
        return min(remaining_c[0], goal_left[0]) + min(remaining_c[1], goal_left[1])

    def search(i: int, kept: int) -> None:
        nonlocal nodes
        nodes += 1
        if i == n:
            if kept > best[0]:
                best[0], best[1] = kept, dict(assign)
            return
        v = order[i]
        p = parent[v]
        keep_image = None
        if p is not None:
            face, child_face = edge_face[v]
            kind = _kind(face)
            remaining_c[kind] -= 1
            mate = links_g[assign[p]].get(face)
            if mate is not None and mate[1] == child_face and mate[0] not in used:
                keep_image = mate[0]
                goal_left[kind] -= 1
                assign[v] = keep_image
                used.add(keep_image)
                if kept + 1 + bound() > best[0]:
                    search(i + 1, kept + 1)
                used.discard(keep_image)
                del assign[v]
                goal_left[kind] += 1
        if kept + bound() > best[0]:
            for b in goal_ids:
                if b in used or b == keep_image:
                    continue
                assign[v] = b
                used.add(b)
                search(i + 1, kept)
                used.discard(b)
                del assign[v]
                if kept + bound() <= best[0]:
                    break
        if p is not None:
            remaining_c[_kind(edge_face[v][0])] += 1

    search(0, 0)
    kept = int(best[0])
    return Optimum(best[1], kept, len(goal.edges()) - kept, nodes)
