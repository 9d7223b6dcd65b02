"""Solutions (pairing and steps, both metrics) and plans of the MISO problem."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ...alignment import rot_z
from ...configuration import Configuration
from ...errors import ExecutionError, PlanningError
from ...plan import Action, ActionType, ConnectionChange, Plan
from .exact import exact_pairing
from .model import (
    FREE,
    UNLIMITED,
    MisoLimits,
    MisoProblem,
    Step,
    changes,
    count_flows,
    depths,
    is_flow,
    kept,
    mismatches,
    pairing_score,
    pieces,
    step_changes,
    targets,
)
from .order import RiderClash, Riding, order_steps
from .pairing import heuristic_pairing
from .places import (
    class_moves,
    closed_ways,
    goal_in_start_frame,
    heading_turn,
    riding_ways,
    step_travel,
)

__all__ = ["Layout", "MisoPlanner", "MisoSolution", "carries_places", "miso_planners",
           "plan_miso", "solve_exact", "solve_heuristic"]


@dataclass
class MisoSolution:
    """A pairing and the steps that realise it.

    Attributes:
        pairing: goal index of every start module.
        steps: legal steps from the start to the relabelled goal.
        lower_bound: ``d`` of the pairing, the fewest steps it allows.
        optimal: the exact search proved the connection changes fewest and the steps
            fewest among plans with that many changes.
        stats: counters (``time_ms``; the exact search's ``changes_proved``, ...).
    """

    pairing: list[int]
    steps: list[Step]
    lower_bound: int
    optimal: bool = False
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def cost(self) -> int:
        """Steps: connector re-targetings."""
        return len(self.steps)

    @property
    def changes(self) -> int:
        """Connections broken plus made (Luo and Lam's metric)."""
        return step_changes(self.steps)


def _solution(problem: MisoProblem, pair: list[int], t0: float,
              closes: Mapping[int, set[int]] | None = None, riding: Riding | None = None,
              **stats: float) -> MisoSolution:
    goal = targets(problem, pair)
    goal_depth = depths(problem.goal)
    steps = order_steps(problem.start, goal, [goal_depth[b] for b in pair],
                        limits=problem.limits, closes=closes, riding=riding)
    d = mismatches(problem.start, goal)
    return MisoSolution(pair, steps, d, stats={
        "time_ms": 1e3 * (time.perf_counter() - t0), **stats})


def solve_heuristic(problem: MisoProblem) -> MisoSolution:
    """Polynomial: :func:`~.pairing.heuristic_pairing`, then :func:`~.order.order_steps`."""
    t0 = time.perf_counter()
    return _solution(problem, heuristic_pairing(problem), t0)


def solve_exact(problem: MisoProblem, *, time_limit: float = 60.0) -> MisoSolution:
    """The fewest connection changes, proved (:func:`~.exact.exact_pairing`, starting
    from the heuristic's pairing), then the step order.

    The heuristic's own plan is kept instead when its step order makes it better (fewer
    changes, or as many and fewer steps): under ``carries == "nothing"`` the order adds
    releases the pairing's changes do not count.

    ``optimal`` when HiGHS proved the pairing within ``time_limit`` [s] and the plan has
    its changes and needs no release: then no plan has fewer changes, and none with as
    few changes has fewer steps (the pairing has the fewest mismatches among the
    fewest-change ones).
    """
    t0 = time.perf_counter()
    heuristic = heuristic_pairing(problem)
    found = exact_pairing(problem, time_limit=time_limit, start=heuristic)
    fewest = changes(problem.start, targets(problem, found.pair))
    solution = _solution(problem, found.pair, t0, changes_proved=float(found.proved),
                         milp_ms=found.ms,
                         heuristic_changes=float(changes(problem.start,
                                                         targets(problem, heuristic))))
    bound = solution.lower_bound
    other = _solution(problem, heuristic, t0, **{k: v for k, v in solution.stats.items()
                                                 if k != "time_ms"})
    if (other.changes, other.cost) < (solution.changes, solution.cost):
        solution = other
    solution.optimal = found.proved and solution.changes == fewest and solution.cost == bound
    return solution


# -- plans ---------------------------------------------------------------------------------


def _configuration(template: Configuration, ids: tuple[str, ...], parent: list[int],
                   vectors: dict[tuple[int, int], np.ndarray], edge_ids: dict[tuple[int, int], str],
                   name: str) -> Configuration:
    config = Configuration(template.robot, name=name)
    for v in ids:
        config.add_module(v, template.kind_of(v))
    for i, p in enumerate(parent):
        if p != FREE:
            key = (i, p)
            config.connect(ids[i], ids[p], id=edge_ids.get(key),
                           z=vectors.get(key, np.array([0.0, 0.0, 1.0])))
    return config


KEEP_LABELS_LIMIT = 64
"""Largest module count for which :func:`_keep_labels` tries the identity pairing."""


def _rank(problem: MisoProblem, s: MisoSolution) -> tuple[int, int, int]:
    return (s.changes, s.cost, -count_flows(problem.start, s.steps))


def _keep_labels(solution: MisoSolution, problem: MisoProblem) -> MisoSolution:
    """``solution``, or the plan in which every module keeps its own id when the goal
    uses the start's ids and that plan has no more changes, steps, or fewer flows.

    Modules are identical, so the pairing is the planner's choice; but a goal written in
    the system's ids says where each module should end, and an equally short plan that
    relabels two arms of a star would make them swap places physically.
    """
    n = problem.n
    if sorted(problem.start_ids) != sorted(problem.goal_ids) or n > KEEP_LABELS_LIMIT:
        return solution
    index = {m: b for b, m in enumerate(problem.goal_ids)}
    identity = [index[m] for m in problem.start_ids]
    if identity == list(solution.pairing):
        return solution
    other = _solution(problem, identity, time.perf_counter())
    if _rank(problem, other) > _rank(problem, solution):
        return solution
    return MisoSolution(identity, other.steps, other.lower_bound,
                        optimal=solution.optimal and _rank(problem, other)[:2] == _rank(
                            problem, solution)[:2], stats=solution.stats)


Layout = Callable[[Configuration], Mapping[str, np.ndarray]]
"""Where the world lays a configuration: every module's centre (3,) [m]."""


def carries_places(config: Configuration) -> bool:
    """Whether ``config`` says where its modules lie: a module with a ``position`` (a
    lab's layout of the start); without one a configuration is topology and vectors."""
    return any(config.position(v) is not None for v in config.vertices()
               if not config.is_virtual(v))


def _laid(problem: MisoProblem, start: Configuration, goal: Configuration, layout: Layout,
          notes: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """The start's places and the goal's (each (n, 3), in the problem's index orders,
    each in its own frame) [m], or ``None`` with a note when the world cannot lay them."""
    try:
        here, there = layout(start), layout(goal)
    except ExecutionError as error:
        notes.append(f"pieces paired by topology only: the world cannot lay them ({error})")
        return None
    return (np.array([here[m] for m in problem.start_ids], dtype=np.float64),
            np.array([there[m] for m in problem.goal_ids], dtype=np.float64))


def _floor_order(solution: MisoSolution, problem: MisoProblem, s: np.ndarray,
                 laid: np.ndarray) -> MisoSolution:
    """``solution`` with its steps ordered so that no piece docks across a pending
    piece's way in while another move can be made first (:func:`~.places.closed_ways`
    on the goal laid in the start's frame, :func:`~.order.order_steps`' ``closes``; nor
    a rider where it rides, :func:`~.places.riding_ways`),
    kept when it has no more changes or steps and no fewer flows; ``stats`` gain
    ``closed_ways`` (the ways its order still closes: pieces that dock later across a
    piece docked before) and ``closed_ways_topology`` (before), and the travel sums of
    :func:`_nearer` follow the new order."""
    g = goal_in_start_frame(problem, solution.pairing, s, laid)
    closes = closed_ways(problem, solution.pairing, g)
    riding = riding_ways(problem, solution.pairing, s, g)
    try:
        other = _solution(problem, solution.pairing, time.perf_counter(), closes, riding)
    except RiderClash as clash:
        raise PlanningError(clash.describe(problem.start_ids.__getitem__)) from None
    best = other if _rank(problem, other) <= _rank(problem, solution) else solution
    stats = {**solution.stats, "closed_ways_topology": float(_closed(solution.steps, closes)),
             "closed_ways": float(_closed(best.steps, closes))}
    if best.steps != solution.steps and "module_metres" in stats:
        moved = step_travel(problem, best.pairing, best.steps, s, g)
        stats["module_metres"] = sum(n * d for n, d in moved)
        stats["travel_m"] = sum(d for _, d in moved)
    return MisoSolution(best.pairing, best.steps, best.lower_bound, optimal=solution.optimal
                        and _rank(problem, best)[:2] == _rank(problem, solution)[:2],
                        stats=stats)


def _closed(steps: list[Step], closes: Mapping[int, set[int]]) -> int:
    """How many pieces ``steps`` dock after a piece that closes their way (``closes``)."""
    done: set[int] = set()
    closed = 0
    for step in steps:
        closed += len(closes.get(step.module, set()) - done)
        done.add(step.module)
    return closed


def _nearer(solution: MisoSolution, problem: MisoProblem, s: np.ndarray,
            laid: np.ndarray) -> MisoSolution:
    """``solution`` with the moves of :func:`~.places.class_moves` made, class by class,
    each kept when the plan then has no more changes or steps, no fewer flows, and moves
    fewer module-metres step by step (:func:`~.places.step_travel`: each step's piece's
    travel times its modules, the work the world simulates: a rider carried far costs
    as much as its own trip); ``stats`` gain the sums by topology and after
    (``module_metres_topology``, ``module_metres``; the pieces' travel unweighted,
    ``travel_m_topology``, ``travel_m``)."""
    g = goal_in_start_frame(problem, solution.pairing, s, laid)

    def sums(pair: list[int], steps: list[Step]) -> tuple[float, float]:
        moved = step_travel(problem, pair, steps, s, g)
        return sum(n * d for n, d in moved), sum(d for _, d in moved)

    best, score = solution, pairing_score(problem, solution.pairing)
    (work, metres) = before = sums(solution.pairing, solution.steps)
    for move in class_moves(problem, solution.pairing, s, laid):
        pair = list(best.pairing)
        for a, b in move.items():
            pair[a] = b
        if pairing_score(problem, pair) < score:
            continue
        other = _solution(problem, pair, time.perf_counter())
        trial = sums(pair, other.steps)
        if _rank(problem, other) <= _rank(problem, best) and trial[0] < work - 1e-9:
            best, (work, metres) = other, trial
    return MisoSolution(best.pairing, best.steps, best.lower_bound,
                        optimal=solution.optimal and _rank(problem, best)[:2] == _rank(
                            problem, solution)[:2],
                        stats={**solution.stats, "module_metres_topology": before[0],
                               "module_metres": work, "travel_m_topology": before[1],
                               "travel_m": metres})


def _same_shape(a: Configuration, b: Configuration) -> bool:
    """Same connections (by ends) with the same vectors."""
    def links(c: Configuration) -> dict[tuple[str, str], tuple]:
        return {(e.source, e.target): tuple(e.z) for e in c.edges()}
    return links(a) == links(b)


def _actions(problem: MisoProblem, start: Configuration, solution: MisoSolution,
             vectors: dict[tuple[int, int], np.ndarray], edge_ids: dict[tuple[int, int], str],
             goal_vectors: dict[tuple[int, int], np.ndarray]
             ) -> tuple[list[Action], Configuration, dict[str, int]]:
    """One action per step, typed by the core's one rule (:func:`~.model.is_flow`, its
    pointer form, tested against :func:`msrr.core.actions.classify`); the last
    configuration; counts. A step that docks a module carrying others (not a flow) gives
    the connections of the piece that moves with it the goal's vectors (the piece travels
    to its place in the goal's shape, instead of being swung there by the last move), its
    riders turned with it (:func:`_carry`)."""
    ids = problem.start_ids
    parent = list(problem.start)
    current = start.copy()
    actions: list[Action] = []
    counts = {"flows": 0, "reconnections": 0, "connections": 0, "disconnections": 0}
    for t, step in enumerate(solution.steps, 1):
        i = step.module
        broken = (ConnectionChange(ids[i], ids[step.old]),) if step.old != FREE else ()
        made = (ConnectionChange(ids[i], ids[step.new]),) if step.new != FREE else ()
        flow = is_flow(parent, i, step.new)   # the pointer form of actions.flow_move
        parent[i] = step.new
        if made and not flow:      # the module goes over the floor with its piece
            _carry(parent, i, step.old, vectors, goal_vectors)
        after = _configuration(start, ids, parent, vectors, edge_ids, f"step {t}")
        if flow:
            kind, verb, count = ActionType.FLOW, "flow", "flows"
        elif not made:
            kind, verb, count = ActionType.DISCONNECTION, "free", "disconnections"
        elif not broken:
            kind, verb, count = ActionType.CONNECTION, "connect", "connections"
        else:
            kind, verb, count = ActionType.PARALLEL_CONNECTION, "reconnect", "reconnections"
        counts[count] += 1
        old = ids[step.old] if step.old != FREE else "(free)"
        new = ids[step.new] if step.new != FREE else "(free)"
        actions.append(Action(kind, after, tuple(dict.fromkeys(
            m for c in broken + made for m in (c.source, c.target))), broken + made,
            note=f"{verb} {ids[i]}: {old} -> {new} (step {t})"))
        current = after
    return actions, current, counts


def _carry(parent: list[int], module: int, old: int,
           vectors: dict[tuple[int, int], np.ndarray],
           goal_vectors: dict[tuple[int, int], np.ndarray]) -> None:
    """Set the vectors of the piece ``module`` docks with (``parent`` after the step,
    ``old`` its former parent; ``vectors`` changed in place). A module hanging from
    ``module`` by goal connections takes the goal's vectors: the piece travels in the
    goal's shape. A *rider* (hanging by a connection it leaves later) is held as it
    rode: its in-tree keeps its angles to the module it hangs from, turned about ``z``
    with that module's own connection (a rider of a straight chain continues its line),
    never left at the start's directions while its carrier turns under it. A module
    that was free turns with its first child's connection."""
    on: dict[int, list[int]] = {}
    for m, p in enumerate(parent):
        if p != FREE:
            on.setdefault(p, []).append(m)
    kids = sorted(on.get(module, ()))
    before = vectors.get((module, old)) if old != FREE else (
        vectors.get((kids[0], module)) if kids else None)
    turn = {module: 0.0 if before is None else heading_turn(before,
                                                              vectors[(module, parent[module])])}
    placed, todo = {module}, [module]
    while todo:
        m = todo.pop()
        for c in sorted(on.get(m, ())):
            if c == module or c in turn:   # a ring closed by the step is walked once
                continue
            key = (c, m)
            was = vectors.get(key, np.array([0.0, 0.0, 1.0]))
            if m in placed and key in goal_vectors:
                vectors[key] = goal_vectors[key]
                placed.add(c)
                turn[c] = heading_turn(was, vectors[key])
            else:
                turn[c] = turn[m]
                vectors[key] = rot_z(turn[m]) @ was
            todo.append(c)


def plan_miso(start: Configuration, goal: Configuration, *, exact: bool = False,
              planner: str = "miso", limits: MisoLimits = UNLIMITED,
              time_limit: float = 60.0, layout: Layout | None = None) -> Plan:
    """A :class:`~msrr.core.plan.Plan` of MISO connection changes from ``start`` to ``goal``
    (any pieces, cycles allowed), under the robot's ``limits``.

    Each step becomes one action, typed by the one rule of :mod:`msrr.core.actions`: a
    *connection* (a free module connects), a *disconnection* (a module frees itself), a
    *flow* (:func:`~msrr.core.actions.flow_move`: a leaf moves to a neighbour of its
    parent) or, for any other re-targeting, a break-and-make *parallel connection*
    (disconnection first, then connection; the module carries its in-tree). A last
    *moving* action sets the goal's vectors. Kept connections keep their ids and
    vectors, except those of a piece a (break-and-)make step moves, which take the goal's
    then (it travels into the goal's shape; its riders, modules it carries by connections
    they leave later, keep their angles to it, turned with it); new ones take the goal's
    vectors. ``plan.stats`` holds both metrics, ``steps`` and ``changes`` (``broken`` +
    ``made``).

    With a ``layout`` (where the world lays a configuration) and a start that carries
    places (:func:`carries_places`), the pieces of equal shape go to the nearer of their
    interchangeable places (:func:`~.places.class_moves`; same changes and steps);
    ``stats`` then hold ``module_metres`` and ``travel_m`` (and both ``_topology``): the
    straight travel of the pieces the steps move, weighed by their modules and not,
    summed [m]. The steps are then ordered so that no piece docks across the way in of a
    piece still to come (:func:`~.places.closed_ways`), when that costs no step;
    ``stats`` hold ``closed_ways`` (and ``closed_ways_topology``, without that order).

    Raises:
        PlanningError: module counts or kinds differ, or a configuration breaks the
            robot's rules.
    """
    problem = MisoProblem.from_configurations(start, goal, limits)
    solution = solve_exact(problem, time_limit=time_limit) if exact else solve_heuristic(
        problem)
    notes: list[str] = []
    places = _laid(problem, start, goal, layout, notes) if layout is not None and \
        carries_places(start) else None
    if places is not None:
        solution = _nearer(solution, problem, *places)
    solution = _keep_labels(solution, problem)
    if places is not None:
        solution = _floor_order(solution, problem, *places)
    ids = problem.start_ids
    final = targets(problem, solution.pairing)
    goal_index = {v: b for b, v in enumerate(goal.vertices())}
    goal_z = {(goal_index[e.source], goal_index[e.target]): e.z for e in goal.edges()}
    goal_vectors = {(i, final[i]): goal_z[(b, problem.goal[b])]
                    for i, b in enumerate(solution.pairing) if problem.goal[b] != FREE}
    index = {v: i for i, v in enumerate(ids)}
    vectors: dict[tuple[int, int], np.ndarray] = dict(goal_vectors)
    edge_ids: dict[tuple[int, int], str] = {}
    for e in start.edges():
        key = (index[e.source], index[e.target])
        vectors[key], edge_ids[key] = e.z, e.id   # kept connections keep their vectors
    actions, current, counts = _actions(problem, start, solution, vectors, edge_ids,
                                        goal_vectors)
    reached = _configuration(start, ids, final, goal_vectors, edge_ids, goal.name or "goal")
    if actions or not _same_shape(current, reached):   # a step's own motion (a flow
        # ends where the leaf touches its new parent) does not set the goal's vectors
        actions.append(Action(ActionType.MOVING, reached, ids, note="take the goal's shape"))
    mapping = {ids[a]: problem.goal_ids[b] for a, b in enumerate(solution.pairing)}
    if exact and not solution.stats.get("changes_proved", 0.0):
        notes.append(f"exact search stopped after {time_limit:g} s: best plan found, "
                     "optimality not proved")
    broken = sum(s.old != FREE for s in solution.steps)
    made = sum(s.new != FREE for s in solution.steps)
    releases = solution.cost - solution.lower_bound
    return Plan(robot=start.robot, planner=planner, start=start.copy(), goal=reached,
                actions=actions, mapping=mapping, notes=notes,
                stats={"steps": float(solution.cost), "changes": float(broken + made),
                       "broken": float(broken), "made": float(made),
                       "lower_bound": float(solution.lower_bound),
                       "kept": float(kept(problem.start, final)),
                       "releases": float(releases),
                       "pieces_start": float(pieces(problem.start)),
                       "pieces_goal": float(pieces(problem.goal)),
                       **{k: float(v) for k, v in counts.items()},
                       "optimal": float(solution.optimal), **solution.stats})


@dataclass(frozen=True)
class MisoPlanner:
    """The MISO connection planner as a registered ``Planner`` (heuristic or exact),
    under one robot's rules."""

    name: str = "miso"
    description: str = ("MISO connection planning: alignment pairing with swaps, step "
                        "order under the robot's rules (fewest connection changes; Luo and "
                        "Lam 2023's problem)")
    exact: bool = False
    limits: MisoLimits = UNLIMITED
    time_limit: float = 60.0
    layout: Layout | None = None

    def plan(self, start: Configuration, goal: Configuration, *, seed: int = 0) -> Plan:
        """Plan ``start`` -> ``goal``; deterministic (``seed`` unused)."""
        return plan_miso(start, goal, exact=self.exact, planner=self.name, limits=self.limits,
                         time_limit=self.time_limit, layout=self.layout)


def miso_planners(limits: MisoLimits, layout: Layout | None = None
                  ) -> tuple[MisoPlanner, MisoPlanner]:
    """``miso`` and ``miso-exact`` under a robot's rules; with the world's ``layout``,
    pieces of equal shape go to the nearer places when the start carries places."""
    return (MisoPlanner(limits=limits, layout=layout),
            MisoPlanner(name="miso-exact", exact=True, limits=limits, layout=layout,
                        description="MISO connection planning, exact: integer program "
                                    "(scipy milp) for the fewest connection changes, "
                                    "proved"))
