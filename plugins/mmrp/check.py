"""Plan-level checker: replay an MMRP plan on the grid and report every invalid step.

Independent of the planner: it reads only the plan (start, actions, goal) and the
MMRP rules of section 3.1. The start is laid out on the grid of docked positions
from its centre (:func:`~msrr.plugins.mmrp.representation.grid_cells`, the frame of
the plan's goal poses); then every action is replayed:

* undock -- the connection exists, with these faces;
* dock -- the faces form a legal pair (T-B or L-R), neither is in use, the two
  modules sit on neighbouring cells in the direction of the face, and the
  connection joins two different components (the structure stays a forest);
* move -- the modules are whole components (one group, or several driving at once:
  :mod:`.schedule`), each at heading 0 and translated rigidly along one grid axis by
  whole cells, driven as :mod:`.motion` says (a leg along y turns a quarter about the
  group's centre first and back after); no still module's centre comes within
  ``CLEARANCE`` of a path of the moving module centres, turns included (no swept
  overlap), and groups moving at once keep their paths apart in any timing
  (:func:`~.motion.apart`);

and after each action no two modules share a cell. At the end, the connections
must equal the plan's goal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

from msrr.core.plan import Action, ActionType, Plan

from .centre import root_of
from .motion import CLEARANCE, Arc, apart, distance, leg_paths, near, sweep
from .representation import GRID_STEP, edge_set, pitch, to_tree
from .rules import LEGAL_PAIRS

__all__ = ["check_plan"]


def _cell(value: float, unit: float, where: str, problems: list[str]) -> int:
    cells = value / unit
    if abs(cells - round(cells)) > 1e-6:
        problems.append(f"{where}: {value} m is not on the grid of pitch {unit} m")
    return round(cells)


@dataclass(frozen=True)
class _Replay:
    """The plan as replayed so far; each step updates the dicts and adds its problems.

    Attributes:
        unit: the grid pitch [m].
        cells: module -> grid cell.
        holder: grid cell -> the module on it.
        links: module -> face -> (module, face) across it.
        edges: connection id -> ``(u, F_u, v, F_v)``.
        problems: what was found invalid, in order.
    """

    unit: float
    cells: dict[str, tuple[int, int]]
    holder: dict[tuple[int, int], str]
    links: dict[str, dict[str, tuple[str, str]]]
    edges: dict[str, tuple[str, str, str, str]]
    problems: list[str]

    def component(self, m: str) -> set[str]:
        """The modules docked to ``m``, directly or not, ``m`` included."""
        seen, todo = {m}, [m]
        while todo:
            for w, _ in self.links[todo.pop()].values():
                if w not in seen:
                    seen.add(w)
                    todo.append(w)
        return seen


def _start(plan: Plan) -> _Replay:
    """The start laid out on the grid from its centre (the frame of the goal poses)."""
    problems: list[str] = []
    tree = to_tree(plan.start).tree
    cells: dict[str, tuple[int, int]] = {}
    root = root_of(tree)
    cells[root] = (0, 0)
    stack = [root]
    links: dict[str, dict[str, tuple[str, str]]] = {v: {} for v in plan.start.vertices()}
    for e in plan.start.edges():
        links[e.source][e.ports[0]] = (e.target, e.ports[1])
        links[e.target][e.ports[1]] = (e.source, e.ports[0])
    edges: dict[str, tuple[str, str, str, str]] = {
        e.id: (e.source, e.ports[0], e.target, e.ports[1]) for e in plan.start.edges()}
    while stack:
        u = stack.pop()
        for e in tree.incident(u):
            face, v = (e.ports[0], e.target) if e.source == u else (e.ports[1], e.source)
            if v not in cells:
                cells[v] = (cells[u][0] + GRID_STEP[face][0], cells[u][1] + GRID_STEP[face][1])
                stack.append(v)
    holder: dict[tuple[int, int], str] = {}
    for m, c in cells.items():
        if c in holder:
            problems.append(f"start: modules {holder[c]} and {m} on one cell {c}")
        holder[c] = m
    return _Replay(pitch(), cells, holder, links, edges, problems)


def _undock(grid: _Replay, action: Action, where: str) -> None:
    """An undock: the connection exists, with these faces."""
    for ch in action.changes:
        edge = grid.edges.pop(ch.edge_id, None)
        if edge is None:
            grid.problems.append(f"{where}: no connection {ch.edge_id} to undock")
            continue
        a, fa, b, fb = edge
        if {(a, fa), (b, fb)} != {(ch.source, ch.source_port), (ch.target, ch.target_port)}:
            grid.problems.append(f"{where}: connection {ch.edge_id} is {a}{fa}-{b}{fb}, "
                                 f"not {ch}")
        grid.links[a].pop(fa, None)
        grid.links[b].pop(fb, None)


def _dock(grid: _Replay, action: Action, where: str) -> None:
    """A dock: a legal pair of free faces of neighbouring modules in two components."""
    cells, links = grid.cells, grid.links
    for ch in action.changes:
        a, fa, b, fb = ch.source, ch.source_port, ch.target, ch.target_port
        if frozenset({fa, fb}) not in LEGAL_PAIRS:
            grid.problems.append(f"{where}: faces {fa}-{fb} cannot dock")
            continue
        if fa in links[a] or fb in links[b]:
            grid.problems.append(f"{where}: a face of {ch} is already connected")
            continue
        step = GRID_STEP[fa]
        if (cells[a][0] + step[0], cells[a][1] + step[1]) != cells[b]:
            grid.problems.append(f"{where}: {b} is not next to face {fa} of {a} "
                                 f"({cells[a]} -> {cells[b]})")
        if b in grid.component(a):
            grid.problems.append(f"{where}: {ch} closes a loop (not a forest)")
        if ch.edge_id in grid.edges:
            grid.problems.append(f"{where}: connection id {ch.edge_id} already used")
        links[a][fa] = (b, fb)
        links[b][fb] = (a, fa)
        grid.edges[ch.edge_id or f"{a}{fa}-{b}{fb}"] = (a, fa, b, fb)


def _shift(grid: _Replay, goals: dict[str, list[float]], where: str) -> tuple[int, int] | None:
    """The one translation [cells] of the group moved to ``goals``: heading 0, on the grid;
    None (the problem noted) if the goals are no such translation."""
    problems = grid.problems
    shift = set()
    for m, (x, y, yaw) in goals.items():
        if abs(math.remainder(yaw, 2 * math.pi)) > 1e-6:
            problems.append(f"{where}: module {m} heading {yaw} rad, not 0")
        target = (_cell(x, grid.unit, where, problems), _cell(y, grid.unit, where, problems))
        shift.add((target[0] - grid.cells[m][0], target[1] - grid.cells[m][1]))
    if len(shift) != 1:
        problems.append(f"{where}: the modules do not translate together")
        return None
    (dx, dy), = shift
    if dx and dy:
        problems.append(f"{where}: move ({dx}, {dy}) is not along one grid axis")
        return None
    return dx, dy


def _groups(grid: _Replay, action: Action, where: str) -> list[list[str]]:
    """The whole components an action moves (several move at once), each sorted."""
    movers = set(action.modules)
    if set(action.goals) != movers:
        grid.problems.append(f"{where}: goals for {sorted(action.goals)} but modules "
                             f"{sorted(movers)}")
        return []
    groups, seen = [], set()
    for m in sorted(movers):
        if m in seen:
            continue
        group = grid.component(m)
        seen |= group
        if not group <= movers:
            grid.problems.append(f"{where}: {m} moves without the modules docked to it")
            return []
        groups.append(sorted(group))
    return groups


def _sweeps_clear(grid: _Replay, order: list[str], paths: list, where: str) -> None:
    """No still module's centre within ``CLEARANCE`` of the paths of ``order``'s centres."""
    movers = order * (len(paths) // len(order))  # path k is module k mod n's
    for c in near(paths):
        other = grid.holder.get(c)
        if other is None:
            continue
        hit = next((k for k, path in enumerate(paths) if distance(c, path) < CLEARANCE - 1e-9),
                   None)
        if hit is not None:
            what = "turning" if isinstance(paths[hit], Arc) else "driving"
            grid.problems.append(f"{where}: {movers[hit]} sweeps over {other} at {c} while "
                                 f"{what}")
            return


def _move(grid: _Replay, action: Action, where: str) -> None:
    """A move: each group a rigid translation along one grid axis, over cells free of
    the still modules, and clear of every group moving at the same time in any timing."""
    legs = []
    for group in _groups(grid, action, where):
        shift = _shift(grid, {m: action.goals[m] for m in group}, where)
        if shift is not None:
            legs.append((group, shift))
    cells, holder = grid.cells, grid.holder
    for group, _ in legs:
        for m in group:
            del holder[cells[m]]
    swept = []
    for group, shift in legs:
        paths = leg_paths([cells[m] for m in group], shift)
        _sweeps_clear(grid, group, paths, where)
        swept.append(sweep(paths))
    for i, j in combinations(range(len(legs)), 2):
        if not apart(swept[i], swept[j]):
            grid.problems.append(f"{where}: groups {','.join(legs[i][0])} and "
                                 f"{','.join(legs[j][0])} move at once within reach")
    for group, (dx, dy) in legs:
        for m in group:
            cells[m] = (cells[m][0] + dx, cells[m][1] + dy)
            if cells[m] in holder:
                grid.problems.append(f"{where}: {m} and {holder[cells[m]]} on one cell")
            holder[cells[m]] = m


_STEPS: dict[ActionType, Callable[[_Replay, Action, str], None]] = {
    ActionType.DISCONNECTION: _undock,
    ActionType.CONNECTION: _dock,
    ActionType.MOVING: _move,
}
"""The replay of each action type MMRP plans have."""


def check_plan(plan: Plan, *, limit: int = 20) -> list[str]:
    """Replay ``plan`` on the grid; the problems found, at most ``limit`` (empty: valid).

    Args:
        plan: an MMRP plan whose moving actions carry ``goals`` ``{id: [x, y, yaw]}``
            [m, m, rad] in the start's root frame (its centre at the origin).
        limit: stop after this many problems.
    """
    grid = _start(plan)
    problems = grid.problems
    for k, action in enumerate(plan.actions):
        if len(problems) >= limit:
            break
        where = f"action {k + 1} ({action.type.value})"
        step = _STEPS.get(action.type)
        if step is None:
            problems.append(f"{where}: MMRP plans have no {action.type.value} actions")
        else:
            step(grid, action, where)
    if len(problems) < limit:
        final = frozenset(frozenset({(a, fa), (b, fb)}) for a, fa, b, fb in grid.edges.values())
        if final != edge_set(plan.goal):
            problems.append("the replayed connections differ from the plan's goal")
    return problems[:limit]
