"""The MCS hybrid reconfiguration planner (paper section 4).

1. Decompose (section 4.1): the largest common subconfiguration of G_c and G_g (the
   MCS over root pairs, the centres tau_c, tau_g winning ties) and the remaining
   subconfigurations and free vertices, ``CS(G_c, tau_c, G_g, tau_g)``.
2. Match subconfigurations by the height-adjacent rule, decomposing again (4.2).
3. Map the free vertices by the artificial potential field of eqs. 2-5 (4.3),
   with a minimum-total-distance fallback if the field stalls.
4. Generate undock, move and dock actions from the mapping (4.4).

Poses are in the start's root frame: tau_c at the origin with heading 0. The goal is
placed so that the modules of the first common subconfiguration do not move.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from msrr.core import Configuration, plugins
from msrr.core.console import plural
from msrr.core.errors import ConfigurationError, PlanningError
from msrr.core.io import check_configuration
from msrr.core.plan import Action, ActionType, Plan

from .actions import Pose, generate_actions, kept_edge_ids
from .centre import root_of
from .matching import HEIGHT_WINDOW, SubconfigurationMatching, match_subconfigurations
from .mcs import Decomposition, Subconfiguration, common_candidates, decompose
from .potential_field import (
    FieldParameters,
    FieldResult,
    assign_free_vertices,
    map_free_vertices,
)
from .recognition import Recognition, observe, recognize_with_stats
from .representation import (
    FaceLinks,
    Link,
    face_links,
    grid_cells,
    overlapping_cells,
    pitch,
    to_tree,
)
from .robot import SPEC
from .schedule import concurrent_moves
from .targets import DerivedConfiguration

__all__ = ["LOOKAHEAD", "HybridResult", "McsHybridPlanner", "plan_hybrid"]

LOOKAHEAD = 4
"""Fewest common subconfigurations tried as the first decomposition (see :func:`plan_hybrid`)."""

LOOKAHEAD_BUDGET = 1024
"""Adaptive lookahead: ``max(LOOKAHEAD, LOOKAHEAD_BUDGET // n)`` first decompositions
for n modules, so small systems try every one and large ones stay O(n^2)."""

FIELD_LIMIT = 12
"""Most free modules mapped by simulating the potential field (see :func:`plan_hybrid`)."""

ALTERNATIVES = 4
"""Decompositions (those keeping the most connections) carried through to actions: the
plan with the fewest dock/undock pairs, cuts for motion included, wins."""


@dataclass(frozen=True)
class HybridResult:
    """Everything the hybrid planner found, for the CLI and for tests.

    Attributes:
        plan: the plan (start ids).
        roots: (tau_c, tau_g), the centres of start and goal.
        virtual: loop edges of the start made virtual (section 3.1); undocked unless kept.
        decomposition: CS(G_c, tau_c, G_g, tau_g).
        matching: the subconfiguration matching of section 4.2.
        field: the potential-field mapping of the free vertices (section 4.3).
        mapping: the bijection f, start id -> goal id.
        kept: start connections kept.
        pairs: dock/undock pairs (docks; equal to undocks for trees).
        goal_poses: goal pose of every start module in the start's root frame.
    """

    plan: Plan
    roots: tuple[str, str]
    virtual: tuple[Link, ...]
    decomposition: Decomposition
    matching: SubconfigurationMatching
    field: FieldResult
    mapping: dict[str, str]
    kept: int
    pairs: int
    goal_poses: dict[str, Pose]


def _arrows(mapping: dict[str, str]) -> str:
    return ", ".join(f"{a}->{b}" for a, b in mapping.items())


def _subs(subs: tuple[Subconfiguration, ...]) -> str:
    return ", ".join(f"{{{','.join(s.vertices)}}} root {s.root} h={s.height}"
                     for s in subs) or "none"


def _kept_ceiling(links_c: FaceLinks, links_g: FaceLinks) -> int:
    """No bijection keeps more: per face pair (T-B, L-R), the fewer connections."""
    def count(links: FaceLinks, face: str) -> int:
        return sum(face in faces for faces in links.values())
    return min(count(links_c, "T"), count(links_g, "T")) + min(count(links_c, "L"),
                                                               count(links_g, "L"))


def _checked(start: Configuration, goal: Configuration) -> Configuration:
    """The start as a tree (loops made virtual); raises PlanningError for unreachable goals."""
    if start.robot != SPEC.name or goal.robot != SPEC.name:
        raise PlanningError(f"the mcs-hybrid planner plans for robot {SPEC.name!r}, got "
                            f"{start.robot!r} -> {goal.robot!r}")
    if len(start) != len(goal):
        raise PlanningError(f"start has {len(start)} modules and goal {len(goal)}: "
                            "MMRP keeps its module count")
    try:
        check_configuration(goal, plugins.resolve(SPEC.name))
        cells = grid_cells(goal)
    except ConfigurationError as exc:
        raise PlanningError(f"goal {goal.name or '(unnamed)'}: {exc}") from None
    clash = overlapping_cells(cells)
    if clash:
        raise PlanningError(f"goal {goal.name or '(unnamed)'}: modules {clash[0][0]} and "
                            f"{clash[0][1]} would occupy the same place")
    try:
        return to_tree(start).tree
    except ConfigurationError as exc:
        raise PlanningError(f"start {start.name or '(unnamed)'}: {exc}") from None


def _decompositions(links_c: FaceLinks, links_g: FaceLinks, all_c: list[str],
                    all_g: list[str], prefer: tuple[str, str], *, window: int,
                    lookahead: int) -> list[tuple[int, Decomposition, SubconfigurationMatching]]:
    """Sections 4.1-4.2 for each of the ``lookahead`` largest common subconfigurations:
    the decomposition, its matching and the connections they keep, in candidate order;
    the search stops once one keeps as many connections as any bijection can."""
    ceiling = _kept_ceiling(links_c, links_g)
    found: list[tuple[int, Decomposition, SubconfigurationMatching]] = []
    for common in common_candidates(links_c, links_g, all_c, all_g, prefer=prefer,
                                    limit=lookahead):
        if found and max(f[0] for f in found) >= ceiling:
            break
        split = decompose(links_c, links_g, all_c, all_g, common)
        matched_subs = match_subconfigurations(links_c, links_g, split.current, split.goal,
                                               split.free_current, split.free_goal,
                                               window=window)
        found.append((split.kept + sum(len(p.mapping) - 1 for p in matched_subs.pairs),
                      split, matched_subs))
    return found


@dataclass(frozen=True)
class _Layout:
    """Start and goal on one grid, the start's root frame (tau_c at (0, 0)).

    Attributes:
        unit: the grid pitch [m].
        start_cells: start id -> cell.
        placed: goal id -> cell, shifted so the first common pair shares its cell.
    """

    unit: float
    start_cells: dict[str, tuple[int, int]]
    placed: dict[str, tuple[int, int]]

    def point(self, goal_id: str) -> tuple[float, float]:
        """Where goal module ``goal_id`` sits [m]."""
        i, j = self.placed[goal_id]
        return (i * self.unit, j * self.unit)


def _layout(tree: Configuration, goal: Configuration, roots: tuple[str, str],
            common: dict[str, str]) -> _Layout:
    """Place the goal so that the modules of the first common subconfiguration do not move."""
    unit = pitch()
    start_cells = grid_cells(tree, roots[0])
    goal_grid = grid_cells(goal, roots[1])
    anchor_c, anchor_g = next(iter(common.items()))
    di = start_cells[anchor_c][0] - goal_grid[anchor_g][0]
    dj = start_cells[anchor_c][1] - goal_grid[anchor_g][1]
    placed = {g: (i + di, j + dj) for g, (i, j) in goal_grid.items()}
    return _Layout(unit, start_cells, placed)


def _map_free(layout: _Layout, matching: SubconfigurationMatching, matched: dict[str, str], *,
              field: FieldParameters | None, field_limit: int, seed: int) -> FieldResult:
    """Section 4.3: map the free vertices by the potential field of eqs. 2-5 (up to
    ``field_limit`` of them, the matched modules as obstacles), else by
    :func:`assign_free_vertices`."""
    unit, cells = layout.unit, layout.start_cells
    free_c = {m: (cells[m][0] * unit, cells[m][1] * unit) for m in matching.free_current}
    free_g = {g: layout.point(g) for g in matching.free_goal}
    if len(free_c) <= field_limit:
        return map_free_vertices(free_c, free_g, [layout.point(g) for g in matched.values()],
                                 unit=unit, params=field, seed=seed)
    return assign_free_vertices(free_c, free_g)


def _notes(recognition: Recognition, roots: tuple[str, str], decomposition: Decomposition,
           matching: SubconfigurationMatching, result: FieldResult,
           virtual: tuple[Link, ...]) -> list[str]:
    """What each step of section 4 found, one line per step, for the plan's notes."""
    tau_c, tau_g = roots
    common = decomposition.common
    notes = [
        f"recognition (section 3.2): started at {recognition.starter}, "
        f"{plural(recognition.rounds, 'message round')}, {plural(recognition.messages, 'message')}",
        f"roots: tau_c={tau_c}, tau_g={tau_g}",
        f"MCS({decomposition.roots[0]}, {decomposition.roots[1]}): {_arrows(common)} "
        f"({plural(decomposition.kept, 'connection')} kept)",
        "CS subconfigurations: current " + _subs(decomposition.current) + "; goal "
        + _subs(decomposition.goal) + "; free vertices: current "
        + (", ".join(decomposition.free_current) or "none") + "; goal "
        + (", ".join(decomposition.free_goal) or "none"),
    ]
    notes += [f"matched MCS({p.current.root}, {p.goal.root}) under the height-adjacent rule: "
              f"{_arrows(p.mapping)}" for p in matching.pairs]
    if matching.dissolved_current or matching.dissolved_goal:
        notes.append("unmatched subconfigurations disconnected into free vertices: current "
                     + _subs(matching.dissolved_current) + "; goal "
                     + _subs(matching.dissolved_goal))
    notes.append("free vertices mapped: " + (_arrows(result.mapping) or "none"))
    if virtual:
        notes.append("loop edges made virtual connections: "
                     + ", ".join(f"connect({u}{fu}, {v}{fv})" for u, fu, v, fv in virtual))
    if result.stalled:
        notes.append(f"potential field stalled; modules {', '.join(result.fallback)} assigned "
                     "by minimum total distance")
    else:
        notes.append("potential field mapped every free vertex")
    return notes


def _stats(start: Configuration, actions: list[Action], matching: SubconfigurationMatching,
           result: FieldResult, recognition: Recognition, *, pairs: int, kept: int,
           mcs_modules: int, cut: int, elapsed: float) -> dict[str, float]:
    """The plan's numbers: action counts, sizes of each step's result, time [ms]."""
    return {"pairs": float(pairs), "kept": float(kept), "docks": float(pairs),
            "undocks": float(len(start.edges()) - kept),
            "mcs_modules": float(mcs_modules), "matched_pairs": float(len(matching.pairs)),
            "free_vertices": float(len(matching.free_current)),
            "fallback_modules": float(len(result.fallback)),
            "cut_for_motion": float(cut),
            "parking_moves": float(sum(a.type is ActionType.MOVING and "parking" in a.note
                                       for a in actions)),
            "field_steps": float(result.steps), "matching_attempts": float(matching.attempts),
            "recognition_rounds": float(recognition.rounds),
            "recognition_messages": float(recognition.messages),
            "plan_ms": elapsed}


@dataclass(frozen=True)
class _Mapped:
    """One decomposition carried through section 4.3: the bijection and what it keeps.

    Attributes:
        decomposition: CS(G_c, tau_c, G_g, tau_g) of this alternative.
        matching: its subconfiguration matching (section 4.2).
        field: the mapping of its free vertices (section 4.3).
        mapping: the bijection f, start id -> goal id.
        layout: start and goal on one grid.
        goal_cells: goal cell of every start module.
        priority: module order for the moves (matched first, then by arrival).
        kept: start connections the goal keeps under ``mapping``.
    """

    decomposition: Decomposition
    matching: SubconfigurationMatching
    field: FieldResult
    mapping: dict[str, str]
    layout: _Layout
    goal_cells: dict[str, tuple[int, int]]
    priority: list[str]
    kept: int


def _map(start: Configuration, tree: Configuration, goal: Configuration,
         roots: tuple[str, str],
         decomposition: Decomposition, matching: SubconfigurationMatching, *,
         field: FieldParameters | None, field_limit: int, seed: int) -> _Mapped:
    """Section 4.3 for one decomposition: map the free vertices, count what is kept."""
    common = decomposition.common
    matched = dict(common)
    for pair in matching.pairs:
        matched.update(pair.mapping)
    layout = _layout(tree, goal, roots, common)
    result = _map_free(layout, matching, matched, field=field, field_limit=field_limit,
                       seed=seed)
    mapping = {**matched, **result.mapping}
    all_c, all_g = tree.vertices(), goal.vertices()
    if sorted(mapping) != sorted(all_c) or sorted(mapping.values()) != sorted(all_g):
        raise AssertionError("the hybrid mapping is not a bijection")  # an internal bug
    priority = [*common, *(m for p in matching.pairs for m in p.mapping), *result.arrival,
                *result.fallback]
    return _Mapped(decomposition, matching, result, mapping, layout,
                   {m: layout.placed[mapping[m]] for m in all_c}, priority,
                   len(kept_edge_ids(start, face_links(goal), mapping)))


def _fewest_pairs(start: Configuration, tree: Configuration, goal: Configuration,
                  roots: tuple[str, str],
                  found: list[tuple[int, Decomposition, SubconfigurationMatching]], *,
                  field: FieldParameters | None, field_limit: int, seed: int
                  ) -> tuple[_Mapped, list[Action], int]:
    """Of the ``ALTERNATIVES`` decompositions whose matchings keep the most connections,
    the plan with the fewest dock/undock pairs (cuts for motion included) and its
    mapping. Lazily: one is mapped (section 4.3) only while it could keep more than the
    best plan so far (the start connections its matched modules keep, plus every one at
    a free vertex), and routed (section 4.4) only while its mapping could need fewer
    pairs, and given up once its cuts for motion would make it need as many as the best.
    """
    links_g = face_links(goal)
    ceiling = len(goal.edges())

    def upper(k: int) -> int:
        _, decomposition, matching = found[k]
        matched = dict(decomposition.common)
        for pair in matching.pairs:
            matched.update(pair.mapping)
        could = 0
        for e in start.edges():
            u, v = e.source, e.target
            if u not in matched or v not in matched:
                could += 1  # a free vertex: its mapping is not known yet
            elif links_g[matched[u]].get(e.ports[0]) == (matched[v], e.ports[1]):
                could += 1
        return min(ceiling, could)

    ranked = sorted(range(len(found)), key=lambda k: -found[k][0])[:ALTERNATIVES]
    best: tuple[_Mapped, list[Action], int] | None = None
    for k in sorted(ranked, key=lambda k: -upper(k)):
        if best is not None and ceiling - upper(k) >= best[2]:
            break
        candidate = _map(start, tree, goal, roots, found[k][1], found[k][2], field=field,
                         field_limit=field_limit, seed=seed)
        if best is not None and ceiling - candidate.kept >= best[2]:
            continue
        actions = generate_actions(
            start, goal, candidate.mapping, candidate.layout.start_cells, candidate.goal_cells,
            start_root=roots[0], goal_root=roots[1], unit=candidate.layout.unit,
            priority=candidate.priority,
            max_cuts=None if best is None else best[2] - (ceiling - candidate.kept) - 1)
        if actions is None:  # its cuts alone would need as many pairs as the best
            continue
        pairs = sum(a.type is ActionType.CONNECTION for a in actions)
        if best is None or pairs < best[2]:
            best = (candidate, actions, pairs)
    assert best is not None  # there is always a first decomposition
    return best


def plan_hybrid(start: Configuration, goal: Configuration, *, seed: int = 0,
                window: int = HEIGHT_WINDOW, lookahead: int | None = None,
                field: FieldParameters | None = None,
                field_limit: int = FIELD_LIMIT, alternative: int | None = None) -> HybridResult:
    """Plan the reconfiguration from ``start`` to ``goal`` (section 4).

    Args:
        start: current configuration, its own ids (loops allowed: made virtual).
        goal: goal configuration, its own ids; must be a legal MMRP tree.
        seed: seed of the potential-field start perturbation.
        window: the height-adjacent rule's largest height difference.
        lookahead: how many of the largest common subconfigurations to try as the
            first decomposition (1 = the paper's single MCS). Default adaptive:
            ``max(LOOKAHEAD, LOOKAHEAD_BUDGET // n)``; the search stops early once a
            decomposition keeps as many connections as any bijection can (per face
            pair T-B / L-R, the fewer of start and goal connections). The
            ``ALTERNATIVES`` whose matchings keep the most connections are mapped
            (section 4.3) and, while one could still need fewer pairs, routed
            (section 4.4): the plan with the fewest dock/undock pairs, cuts for
            motion included, wins (the paper's centre pair on ties).
        field: potential-field gains and distances.
        field_limit: most free modules mapped by simulating the field; more are
            mapped by :func:`assign_free_vertices` (the field's intent, no stall).
        alternative: plan only with this decomposition (an index into the
            candidates, largest common subconfiguration first); for benchmarks.

    Raises:
        PlanningError: different module counts, an illegal goal, or no such
            ``alternative``.
    """
    began = time.perf_counter()
    tree = _checked(start, goal)
    virtual = to_tree(start).virtual
    links_c, links_g = face_links(tree), face_links(goal)
    roots = tau_c, tau_g = root_of(tree), root_of(goal)
    all_c, all_g = tree.vertices(), goal.vertices()
    if lookahead is None:
        lookahead = max(LOOKAHEAD, LOOKAHEAD_BUDGET // max(len(all_c), 1))
    found = _decompositions(links_c, links_g, all_c, all_g, roots, window=window,
                            lookahead=lookahead)
    if alternative is not None:
        if not 0 <= alternative < len(found):
            raise PlanningError(f"alternative {alternative} of {len(found)} decompositions")
        found = [found[alternative]]
    best = _fewest_pairs(start, tree, goal, roots, found, field=field, field_limit=field_limit,
                         seed=seed)
    chosen, actions, pairs = best
    decomposition, matching, result, mapping = (chosen.decomposition, chosen.matching,
                                                chosen.field, chosen.mapping)
    common = decomposition.common
    kept = len(goal.edges()) - pairs
    cut = chosen.kept - kept
    unit = chosen.layout.unit
    goal_poses = {m: (i * unit, j * unit, 0.0) for m, (i, j) in chosen.goal_cells.items()}
    elapsed = (time.perf_counter() - began) * 1e3
    recognition = recognize_with_stats(observe(start), seed=seed)
    final = DerivedConfiguration(actions[-1].target if actions else start)
    final.name, final.description = goal.name, goal.description
    plan = Plan(
        robot=SPEC.name, planner=McsHybridPlanner.name, start=start.copy(), goal=final,
        actions=concurrent_moves(actions, chosen.layout.start_cells, unit), mapping=mapping,
        notes=_notes(recognition, roots, decomposition, matching, result, virtual),
        stats=_stats(start, actions, matching, result, recognition, pairs=pairs, kept=kept,
                     mcs_modules=len(common), cut=cut, elapsed=elapsed),
    )
    return HybridResult(plan, roots, virtual, decomposition, matching, result,
                        mapping, kept, pairs, goal_poses)


class McsHybridPlanner:
    """The graph-based hybrid planner of Wei et al. (2023), section 4."""

    name = "mcs-hybrid"
    description = ("MCS decomposition, height-adjacent subconfiguration matching and "
                   "potential-field mapping of free modules (Wei et al. 2023)")

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """Plan from ``start`` to ``goal``; see :func:`plan_hybrid`."""
        return plan_hybrid(start, goal, seed=seed).plan
