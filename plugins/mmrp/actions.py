"""Reconfiguration action generation from the module mapping (paper section 4.4, Table 4).

Under the mapping f: V_c -> V_g a connection ``connect(uF_u, vF_v)`` of the start is
kept when the goal has ``connect(f(u)F_u, f(v)F_v)``; every other start connection
is undocked and every goal connection without a kept preimage is docked. The
executable order is: all undocks, then the moves of the rigid groups (matched
subconfigurations and free modules) to their goal poses in a collision-free order,
routed through free cells and parked where needed (:mod:`.routing`), then the docks
in breadth-first order of the goal tree, so each dock attaches one more group to the
part that holds the goal root.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from msrr.core import Configuration
from msrr.core.plan import Action, ActionType, ConnectionChange

from .centre import adjacency, parents
from .mcs import components
from .representation import FaceLinks, face_links
from .routing import Cell, Route, route_groups
from .targets import DerivedConfiguration

__all__ = ["Pose", "generate_actions", "kept_edge_ids", "rigid_groups"]

Pose = tuple[float, float, float]
"""Planar pose ``(x, y, yaw)`` [m, m, rad]."""


def kept_edge_ids(start: Configuration, links_g: FaceLinks, mapping: Mapping[str, str]
                  ) -> list[str]:
    """Ids of the start connections that the goal keeps under ``mapping``."""
    kept = []
    for e in start.edges():
        u, fu, v, fv = e.source, e.ports[0], e.target, e.ports[1]
        if links_g[mapping[u]].get(fu) == (mapping[v], fv):
            kept.append(e.id)
    return kept


def rigid_groups(start: Configuration, kept: Sequence[str]) -> list[list[str]]:
    """Modules that stay docked together once every other connection is undocked."""
    keep = set(kept)
    links: FaceLinks = {v: {} for v in start.vertices()}
    for e in start.edges():
        if e.id in keep:
            links[e.source][e.ports[0]] = (e.target, e.ports[1])
            links[e.target][e.ports[1]] = (e.source, e.ports[0])
    return components(links, start.vertices())


def _fresh_id(base: str, taken: set[str]) -> str:
    candidate, n = base, 1
    while candidate in taken:
        n += 1
        candidate = f"{base}#{n}"
    taken.add(candidate)
    return candidate


def generate_actions(start: Configuration, goal: Configuration, mapping: Mapping[str, str],
                     start_cells: Mapping[str, Cell], goal_cells: Mapping[str, Cell], *,
                     start_root: str, goal_root: str, unit: float,
                     priority: Sequence[str] = (), max_cuts: int | None = None
                     ) -> list[Action] | None:
    """Undock, move and dock actions that take ``start`` to ``goal`` (start ids).

    Args:
        start: the start configuration (loop edges included, they are undocked too).
        goal: the goal tree, in goal ids.
        mapping: the bijection f, start id -> goal id.
        start_cells: grid cell of every start module (the start's root frame).
        goal_cells: goal cell of every start module, same frame.
        start_root: tau_c; an undock names the end farther from it first.
        goal_root: tau_g; docks follow the goal tree breadth-first from it.
        unit: the grid pitch [m].
        priority: module order for the moves (matched subconfigurations, then free
            modules in the order they reached their targets); see
            :func:`~msrr.plugins.mmrp.routing.route_groups`.
        max_cuts: most kept connections the routing may cut for motion.

    Returns:
        The actions. Each moving action is one straight, axis-aligned translation of
        a rigid group through free cells (its path: from where the group is to
        ``goals``); a route with turns or a parking stop is several moving actions.
        Targets are :class:`~msrr.plugins.mmrp.targets.DerivedConfiguration` s, each
        the previous one plus this action's change; moving actions share theirs.
        None when the moves would need more than ``max_cuts`` cuts.

    Raises:
        PlanningError: no collision-free order of the moves exists (see routing).
    """
    links_g = face_links(goal)
    kept = kept_edge_ids(start, links_g, mapping)
    keep = set(kept)
    links = [frozenset({e.source, e.target}) for e in start.edges() if e.id in keep]
    routing = route_groups(rigid_groups(start, kept), start_cells, goal_cells, links=links,
                           priority=priority, max_cuts=max_cuts)
    if routing is None:
        return None
    cut = set(routing.cut)
    keep = {e.id for e in start.edges()
            if e.id in keep and frozenset({e.source, e.target}) not in cut}
    current, actions = _undocks(start, keep, start_root)
    moved = current if current is not start else DerivedConfiguration(start)
    actions += _moves(routing.routes, moved, start_cells, unit)
    kept_pairs = {frozenset({e.source, e.target}) for e in start.edges() if e.id in keep}
    actions += _docks(goal, links_g, mapping, goal_root, kept_pairs, current,
                      set(start.edge_ids()))
    return actions


def _undocks(start: Configuration, keep: set[str], start_root: str
             ) -> tuple[Configuration, list[Action]]:
    """Section 4.4, first: undock every start connection not in ``keep``, the end farther
    from ``start_root`` named first; the configuration they leave and the actions."""
    start_parent = parents(adjacency(start), start_root)
    current: Configuration = start
    actions: list[Action] = []
    for e in start.edges():
        if e.id in keep:
            continue
        current = DerivedConfiguration(current, [("disconnect", e.id, "", "", "", "")])
        child_first = start_parent.get(e.source) == e.target
        change = (ConnectionChange(e.source, e.target, e.ports[0], e.ports[1], e.id)
                  if child_first else
                  ConnectionChange(e.target, e.source, e.ports[1], e.ports[0], e.id))
        actions.append(Action(ActionType.DISCONNECTION, current,
                              modules=(change.source, change.target), changes=(change,),
                              note=f"undock {change}"))
    return current, actions


def _moves(routes: Sequence[Route], moved: Configuration, start_cells: Mapping[str, Cell],
           unit: float) -> list[Action]:
    """Section 4.4, then: one moving action per straight leg of every route (the routed
    rigid groups), all sharing the target ``moved``."""
    actions = []
    for route in routes:
        first = route.modules[0]
        offsets = {m: (start_cells[m][0] - start_cells[first][0],
                       start_cells[m][1] - start_cells[first][1]) for m in route.modules}
        what = f"module {first}" if len(route.modules) == 1 else \
            f"the {len(route.modules)} modules of {first}'s group"
        legs = len(route.corners) - 1
        for leg, (a, b) in enumerate(zip(route.corners, route.corners[1:], strict=False), 1):
            # rounded to the nanometre: the grid's places, not their float noise, in files
            goals = {m: [round((b[0] + dx) * unit, 9), round((b[1] + dy) * unit, 9), 0.0]
                     for m, (dx, dy) in offsets.items()}
            where = "a parking place" if route.parking else "its goal pose"
            actions.append(Action(
                ActionType.MOVING, moved, modules=route.modules, goals=goals,
                cost=round((abs(b[0] - a[0]) + abs(b[1] - a[1])) * unit, 9),
                note=f"move {what} toward {where} (leg {leg}/{legs}, cell {a} -> {b})"))
    return actions


def _docks(goal: Configuration, links_g: FaceLinks, mapping: Mapping[str, str], goal_root: str,
           kept_pairs: set[frozenset[str]], current: Configuration, taken: set[str]
           ) -> list[Action]:
    """Section 4.4, last: dock every goal connection without a kept preimage, breadth-first
    from ``goal_root``, each with a fresh edge id (not in ``taken``)."""
    inverse = {g: c for c, g in mapping.items()}
    actions = []
    for child, parent in parents(adjacency(goal), goal_root).items():
        if parent is None:
            continue
        child_face = next(f for f, (w, _) in links_g[child].items() if w == parent)
        parent_face = links_g[child][child_face][1]
        u, v = inverse[parent], inverse[child]
        if frozenset({u, v}) in kept_pairs:
            continue
        edge_id = _fresh_id(f"{u}{parent_face}-{v}{child_face}", taken)
        current = DerivedConfiguration(current, [("connect", u, v, parent_face, child_face,
                                                  edge_id)])
        change = ConnectionChange(v, u, child_face, parent_face, edge_id)
        actions.append(Action(ActionType.CONNECTION, current, modules=(v, u),
                              changes=(change,), note=f"dock {change}"))
    return actions
