"""Reconfiguration action generation from the module mapping (paper section 4.4, Table 4).

Under the mapping f: V_c -> V_g a connection ``connect(uF_u, vF_v)`` of the start is
kept when the goal has ``connect(f(u)F_u, f(v)F_v)``; every other start connection
is undocked and every goal connection without a kept preimage is docked. The
executable order is: all undocks, then the moves of the rigid groups (matched
subconfigurations and free modules) to their goal poses, then the docks in
breadth-first order of the goal tree, so each dock attaches one more group to the
part that holds the goal root.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from msrr.core import Configuration
from msrr.core.plan import Action, ActionType, ConnectionChange

from .centre import parents
from .mcs import components
from .representation import FaceLinks, face_links

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


def _rounded(pose: Pose) -> list[float]:
    return [round(float(c), 9) for c in pose]


def generate_actions(start: Configuration, goal: Configuration, mapping: Mapping[str, str],
                     start_poses: Mapping[str, Pose], goal_poses: Mapping[str, Pose], *,
                     start_root: str, goal_root: str, priority: Sequence[str] = ()
                     ) -> list[Action]:
    """Undock, move and dock actions that take ``start`` to ``goal`` (start ids).

    Args:
        start: the start configuration (loop edges included, they are undocked too).
        goal: the goal tree, in goal ids.
        mapping: the bijection f, start id -> goal id.
        start_poses: pose of every start module [m, m, rad].
        goal_poses: goal pose of every start module, same frame.
        start_root: tau_c; an undock names the end farther from it first.
        goal_root: tau_g; docks follow the goal tree breadth-first from it.
        priority: module order for the moves (matched subconfigurations, then free
            modules in the order they reached their targets).

    Returns:
        The actions; each one's ``target`` is the configuration after it.
    """
    links_g = face_links(goal)
    inverse = {g: c for c, g in mapping.items()}
    kept = kept_edge_ids(start, links_g, mapping)
    keep = set(kept)
    start_adj: dict[str, list[str]] = {v: [] for v in start.vertices()}
    for e in start.edges():
        start_adj[e.source].append(e.target)
        start_adj[e.target].append(e.source)
    start_parent = parents(start_adj, start_root)
    current = start.copy()
    actions: list[Action] = []
    for e in start.edges():
        if e.id in keep:
            continue
        current.disconnect(e.id)
        child_first = start_parent.get(e.source) == e.target
        change = (ConnectionChange(e.source, e.target, e.ports[0], e.ports[1], e.id)
                  if child_first else
                  ConnectionChange(e.target, e.source, e.ports[1], e.ports[0], e.id))
        actions.append(Action(ActionType.DISCONNECTION, current.copy(),
                              modules=(change.source, change.target), changes=(change,),
                              note=f"undock {change}"))
    rank = {m: i for i, m in enumerate(priority)}
    groups = sorted(rigid_groups(start, kept),
                    key=lambda g: min(rank.get(m, len(rank)) for m in g))
    for group in groups:
        moved = any(abs(a - b) > 1e-9 for m in group
                    for a, b in zip(start_poses[m], goal_poses[m], strict=True))
        if not moved:
            continue
        distance = max(((goal_poses[m][0] - start_poses[m][0]) ** 2
                        + (goal_poses[m][1] - start_poses[m][1]) ** 2) ** 0.5 for m in group)
        what = "module" if len(group) == 1 else "subconfiguration"
        actions.append(Action(ActionType.MOVING, current.copy(), modules=tuple(group),
                              goals={m: _rounded(goal_poses[m]) for m in group},
                              cost=distance,
                              note=f"move {what} {','.join(group)} to its goal pose"))
    goal_adj: dict[str, list[str]] = {v: [] for v in goal.vertices()}
    for e in goal.edges():
        goal_adj[e.source].append(e.target)
        goal_adj[e.target].append(e.source)
    goal_parent = parents(goal_adj, goal_root)
    for child, parent in goal_parent.items():
        if parent is None:
            continue
        child_face = next(f for f, (w, _) in links_g[child].items() if w == parent)
        parent_face = links_g[child][child_face][1]
        u, v = inverse[parent], inverse[child]
        if any(e.id in keep and {e.source, e.target} == {u, v} for e in start.incident(v)):
            continue
        edge_id = current.connect(u, v, ports=(parent_face, child_face))
        change = ConnectionChange(v, u, child_face, parent_face, edge_id)
        actions.append(Action(ActionType.CONNECTION, current.copy(), modules=(v, u),
                              changes=(change,), note=f"dock {change}"))
    return actions
