"""Issue 17: collision-free routes, the plan checker, lazy targets, the certified optimum."""

from __future__ import annotations

import itertools
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from msrr.core.plan import Action, ActionType, ConnectionChange, Plan
from msrr.plugins.mmrp.check import check_plan
from msrr.plugins.mmrp.exact import certified_optimum
from msrr.plugins.mmrp.mcs import common_candidates, mcs
from msrr.plugins.mmrp.optimum import optimum
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.potential_field import assign_free_vertices
from msrr.plugins.mmrp.random_trees import random_tree
from msrr.plugins.mmrp.representation import edge_set, face_links, from_links, pitch
from msrr.plugins.mmrp.routing import route_groups
from msrr.plugins.mmrp.targets import DerivedConfiguration

P = pitch()


def _replay(groups, start, goal, routing):
    """Independent replay of routes on the grid: every unit cell swept must be free."""
    where = dict(start)
    for route in routing.routes:
        first = route.modules[0]
        assert where[first] == route.corners[0]
        for a, b in itertools.pairwise(route.corners):
            assert (a[0] == b[0]) != (a[1] == b[1]), "legs are axis-aligned and non-empty"
            step = ((b[0] > a[0]) - (b[0] < a[0]), (b[1] > a[1]) - (b[1] < a[1]))
            others = {c for m, c in where.items() if m not in route.modules}
            for _ in range(abs(b[0] - a[0]) + abs(b[1] - a[1])):
                for m in route.modules:
                    where[m] = (where[m][0] + step[0], where[m][1] + step[1])
                    assert where[m] not in others, f"{m} runs into another module"
    assert len(set(where.values())) == len(where)
    assert where == dict(goal)


def _line(*cells):
    return {str(i): c for i, c in enumerate(cells)}


def test_two_modules_that_swap_cells_are_parked_in_turn():
    start = _line((0, 0), (1, 0))
    goal = {"0": (1, 0), "1": (0, 0)}
    groups = [["0"], ["1"]]
    routing = route_groups(groups, start, goal)
    assert any(r.parking for r in routing.routes) and not routing.cut
    _replay(groups, start, goal, routing)


def test_a_pocket_is_filled_before_it_closes():
    # goal: a plus sign around (0, 0); the centre module must arrive before the ring
    ring = [(1, 0), (-1, 0), (0, 1), (0, -1)]
    start = {f"r{i}": (10 + 2 * i, 0) for i in range(4)} | {"c": (20, 5)}
    goal = {f"r{i}": ring[i] for i in range(4)} | {"c": (0, 0)}
    groups = [[m] for m in start]
    routing = route_groups(groups, start, goal)
    order = [r.modules[0] for r in routing.routes]
    assert order.index("c") < max(order.index(f"r{i}") for i in range(4))
    _replay(groups, start, goal, routing)


def test_a_module_inside_a_closed_still_group_gets_out_through_a_cut():
    ring = [(0, 0), (1, 0), (2, 0), (2, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    wall = [f"w{i}" for i in range(8)]
    start = dict(zip(wall, ring, strict=True)) | {"x": (1, 1)}
    goal = dict(zip(wall, ring, strict=True)) | {"x": (6, 6)}
    groups = [wall, ["x"]]
    links = [frozenset(p) for p in itertools.pairwise(wall)]
    routing = route_groups(groups, start, goal, links=links)
    # no translation takes x out of the ring or the ring away from x: the ring opens
    assert len(routing.cut) == 1 and routing.cut[0] in links
    assert ("x",) in {r.modules for r in routing.routes}
    _replay(groups, start, goal, routing)


def test_a_module_walled_in_by_still_groups_gets_out_and_the_walls_return():
    walls = {"n": (1, 2), "s": (1, 0), "e": (2, 1), "w": (0, 1)}
    start = walls | {"x": (1, 1)}
    goal = walls | {"x": (6, 6)}
    groups = [[m] for m in start]
    routing = route_groups(groups, start, goal)
    assert not routing.cut and ("x",) in {r.modules for r in routing.routes}
    assert len(routing.routes) > 1
    _replay(groups, start, goal, routing)


def test_hooked_groups_that_no_translation_separates_are_split():
    # two interlocked combs: a's teeth sit between b's, each closed by a back bar
    a = [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (0, 1), (2, 1), (4, 1), (4, 2), (4, 3),
         (3, 3), (2, 3), (1, 3), (0, 3)]
    b = [(1, 1), (1, 2), (2, 2), (3, 2), (3, 1)]
    start = {f"a{i}": c for i, c in enumerate(a)} | {f"b{i}": c for i, c in enumerate(b)}
    goal = dict(start) | {f"b{i}": (c[0] + 20, c[1]) for i, c in enumerate(b)}
    ga, gb = [f"a{i}" for i in range(len(a))], [f"b{i}" for i in range(len(b))]
    links = [frozenset(p) for p in itertools.pairwise(ga)] + \
        [frozenset(p) for p in itertools.pairwise(gb)]
    routing = route_groups([ga, gb], start, goal, links=links, direct=False)
    assert routing.cut and all(edge in links for edge in routing.cut)
    pieces = {frozenset(r.modules) for r in routing.routes}
    assert all(len(p) < len(ga) for p in pieces if p & set(ga))


def _plan(start, actions, goal):
    return Plan(robot="mmrp", planner="test", start=start, goal=goal, actions=actions)


def _undock(config, u, v):
    e = next(e for e in config.edges() if {e.source, e.target} == {u, v})
    return Action(ActionType.DISCONNECTION, config,
                  changes=(ConnectionChange(e.source, e.target, *e.ports, e.id),))


def _move(config, goals):
    return Action(ActionType.MOVING, config, modules=tuple(goals),
                  goals={m: [x * P, y * P, 0.0] for m, (x, y) in goals.items()})


def _dock(config, u, fu, v, fv):
    return Action(ActionType.CONNECTION, config,
                  changes=(ConnectionChange(u, v, fu, fv, f"{u}{fu}-{v}{fv}"),))


LINE = from_links("abc", [("a", "T", "b", "B"), ("b", "T", "c", "B")])  # a(-1,0) b(0,0) c(1,0)


def test_checker_accepts_a_valid_hand_made_plan():
    loose = from_links("abc", [("a", "T", "b", "B")])
    plan = _plan(LINE, [_undock(LINE, "b", "c"), _move(LINE, {"c": (1, 1)}),
                        _move(LINE, {"c": (0, 1)}), _dock(LINE, "c", "R", "b", "L")],
                 from_links("abc", [("a", "T", "b", "B"), ("c", "R", "b", "L")]))
    assert check_plan(plan) == []
    assert check_plan(_plan(LINE, plan.actions, loose)) == [
        "the replayed connections differ from the plan's goal"]


@pytest.mark.parametrize(("actions", "expected"), [
    ([_undock(LINE, "a", "b"), _undock(LINE, "b", "c"), _move(LINE, {"a": (2, 0)})],
     "sweeps over b"),
    ([_undock(LINE, "b", "c"), _move(LINE, {"c": (2, 1)})], "not along one grid axis"),
    ([_undock(LINE, "b", "c"), _move(LINE, {"b": (0, 1)})], "without the modules docked"),
    ([_undock(LINE, "b", "c"), _move(LINE, {"c": (1, 2)}), _dock(LINE, "c", "B", "b", "T")],
     "is not next to"),
    ([_dock(LINE, "c", "B", "b", "T")], "already connected"),
    ([_undock(LINE, "b", "c"), _dock(LINE, "c", "T", "b", "L")], "cannot dock"),
    ([_undock(LINE, "b", "c"), _undock(LINE, "b", "c")], "no connection"),
])
def test_checker_finds_invalid_steps(actions, expected):
    problems = check_plan(_plan(LINE, actions, LINE))
    assert any(expected in p for p in problems), problems


def test_checker_finds_a_loop():
    square = from_links("1234", [("1", "T", "2", "B"), ("2", "L", "3", "R"),
                                 ("3", "B", "4", "T")])
    problems = check_plan(_plan(square, [_dock(square, "4", "R", "1", "L")], square))
    assert any("closes a loop" in p for p in problems)


def test_old_direct_moves_collide_and_new_plans_do_not():
    rng = np.random.default_rng(17)
    start, goal = random_tree(40, rng), random_tree(40, rng)
    result = plan_hybrid(start, goal, seed=1)
    assert check_plan(result.plan) == []
    # one move per group straight to its goal (the old plans): the checker objects
    final: dict[str, list[float]] = {}
    direct = [a for a in result.plan.actions if a.type is not ActionType.MOVING]
    for action in result.plan.actions:
        if action.type is ActionType.MOVING:
            final.update(action.goals)
    groups = {a.modules for a in result.plan.actions if a.type is ActionType.MOVING}
    moves = [Action(ActionType.MOVING, start, modules=g, goals={m: final[m] for m in g})
             for g in groups]
    undocks = [a for a in direct if a.type is ActionType.DISCONNECTION]
    docks = [a for a in direct if a.type is ActionType.CONNECTION]
    old = _plan(result.plan.start, [*undocks, *moves, *docks], result.plan.goal)
    assert check_plan(old)


@pytest.mark.parametrize("n", [120, 300])
def test_large_plans_replay_without_a_collision(n):
    rng = np.random.default_rng(n)
    result = plan_hybrid(random_tree(n, rng), random_tree(n, rng))
    assert check_plan(result.plan) == []
    assert result.plan.docks == result.pairs


def test_derived_targets_equal_a_replay_and_pickle_as_configurations():
    rng = np.random.default_rng(3)
    start, goal = random_tree(15, rng), random_tree(15, rng)
    plan = plan_hybrid(start, goal).plan
    current = start.copy()
    for action in plan.actions:
        for ch in action.changes:
            if action.type is ActionType.DISCONNECTION:
                current.disconnect(ch.edge_id)
            else:
                current.connect(ch.target, ch.source, id=ch.edge_id,
                                ports=(ch.target_port, ch.source_port))
        assert edge_set(action.target) == edge_set(current)
    again = pickle.loads(pickle.dumps(plan.actions[-1].target))
    assert type(again).__name__ == "Configuration" and edge_set(again) == edge_set(current)
    late = DerivedConfiguration(start, [("disconnect", start.edge_ids()[0], "", "", "", "")])
    late.name = "kept"
    assert len(late.edges()) == len(start.edges()) - 1 and late.name == "kept"


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 8), seed=st.integers(0, 2**32 - 1))
def test_certified_optimum_equals_the_exhaustive_optimum(n, seed):
    rng = np.random.default_rng(seed)
    start, goal = random_tree(n, rng), random_tree(n, rng)
    exact = certified_optimum(start, goal)
    assert exact.certified and exact.pairs == optimum(start, goal).pairs == exact.bound
    lg = face_links(goal)
    assert len(goal.edges()) - sum(lg[exact.mapping[e.source]].get(e.ports[0]) == (
        exact.mapping[e.target], e.ports[1]) for e in start.edges()) == exact.pairs


def test_certified_optimum_at_twenty_modules_bounds_the_planner():
    rng = np.random.default_rng(20)
    for _ in range(3):
        start, goal = random_tree(20, rng), random_tree(20, rng)
        exact = certified_optimum(start, goal, time_limit=30)
        assert exact.certified
        assert exact.pairs <= plan_hybrid(start, goal).pairs <= exact.pairs + 1


def test_planner_is_optimal_on_nearly_every_small_pair():
    rng = np.random.default_rng(99)
    excess = []
    for n in (5, 6, 7, 8, 9) * 20:
        start, goal = random_tree(n, rng), random_tree(n, rng)
        excess.append(plan_hybrid(start, goal).pairs - optimum(start, goal).pairs)
    assert min(excess) == 0 and max(excess) <= 1 and sum(excess) <= 1


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 14), seed=st.integers(0, 2**32 - 1))
def test_common_candidates_are_the_mcs_of_their_first_pair(n, seed):
    rng = np.random.default_rng(seed)
    start, goal = random_tree(n, rng), random_tree(n, rng)
    lc, lg = face_links(start), face_links(goal)
    found = common_candidates(lc, lg, start.vertices(), goal.vertices(), limit=1000)
    best = max(len(mcs(lc, lg, a, b)) for a in start.vertices() for b in goal.vertices())
    assert len(found[0]) == best
    assert [len(f) for f in found] == sorted((len(f) for f in found), reverse=True)
    for f in found:
        assert f == mcs(lc, lg, *next(iter(f.items())))


def _crosses(p, q, r, s) -> bool:
    def orient(a, b, c):
        return np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    return orient(p, q, r) * orient(p, q, s) < 0 and orient(r, s, p) * orient(r, s, q) < 0


def test_assignment_mapping_is_minimal_and_crossing_free():
    rng = np.random.default_rng(4)
    free = {f"m{i}": tuple(rng.uniform(-5, 5, 2)) for i in range(25)}
    targets = {f"t{i}": tuple(rng.uniform(-5, 5, 2)) for i in range(25)}
    result = assign_free_vertices(free, targets)
    cost = np.array([[np.hypot(*np.subtract(free[m], targets[t])) for t in targets]
                     for m in free])
    rows, cols = linear_sum_assignment(cost)
    assert sum(result.travelled.values()) == pytest.approx(cost[rows, cols].sum())
    segments = [(free[m], targets[t]) for m, t in result.mapping.items()]
    assert not any(_crosses(*a, *b) for a, b in itertools.combinations(segments, 2))
    assert not result.stalled and list(result.arrival) == sorted(
        result.arrival, key=lambda m: result.travelled[m])


def test_the_random_30_scenario_plans_a_checked_plan():
    from msrr.core import plugins
    from msrr.core.io import load_configuration

    scenario = plugins.scenarios("mmrp")["random-30"]
    start, goal = load_configuration(scenario.start), load_configuration(scenario.goal)
    assert len(start) == len(goal) == 30
    plan = plugins.planners.get("mmrp", "mcs-hybrid").plan(start, goal)
    assert check_plan(plan) == [] and plan.docks == plan.undocks


@settings(max_examples=25, deadline=None)
@given(n=st.integers(8, 60), seed=st.integers(0, 2**32 - 1))
def test_evacuate_and_assemble_plans_replay_without_a_collision(n, seed):
    import msrr.plugins.mmrp.routing as routing

    rng = np.random.default_rng(seed)
    start, goal = random_tree(n, rng), random_tree(n, rng)
    limit = routing.DIRECT_LIMIT
    routing.DIRECT_LIMIT = 0  # force the staged order on small systems
    try:
        plan = plan_hybrid(start, goal).plan
    finally:
        routing.DIRECT_LIMIT = limit
    assert check_plan(plan) == []


def test_resumed_peels_with_cuts_replay_without_a_collision():
    # seed 4 at 200 modules hooks groups: the peels stop, a group is split, and they
    # resume where they stopped (issue 29)
    rng = np.random.default_rng(4)
    result = plan_hybrid(random_tree(200, rng), random_tree(200, rng), seed=4)
    assert result.plan.stats["cut_for_motion"] >= 1
    assert check_plan(result.plan) == []
    assert result.plan.docks == result.pairs


@settings(max_examples=60, deadline=None)
@given(cells=st.dictionaries(st.tuples(st.integers(-9, 9), st.integers(-9, 9)),
                             st.integers(0, 3), max_size=80),
       sweep=st.sets(st.tuples(st.integers(-4, 4), st.integers(-4, 4)), min_size=1,
                     max_size=20),
       at=st.tuples(st.integers(-12, 12), st.integers(-12, 12)))
def test_a_sweep_tested_by_rows_counts_the_cells_held_by_others(cells, sweep, at):
    import msrr.plugins.mmrp.routing as routing

    occupied = routing._Occupied(cells)
    for cell in list(cells)[::3]:  # some groups moved away
        del occupied[cell]
    me = 0
    own = [c for c, g in occupied.items() if g == me]
    rows, base = occupied.others(me, own)
    held = sum(occupied.get((at[0] + dx, at[1] + dy), me) != me for dx, dy in sweep)
    masks = routing._masks(tuple(sorted(sweep)))
    assert routing._hits(masks, at, rows, base, True) == held
    assert routing._hits(masks, at, rows, base, False) == min(held, 1)


def test_a_standing_module_that_blocks_only_a_turn_moves_out_instead_of_a_cut():
    # a bar of three in a slot of standing walls can leave only by turning to go up;
    # its turn sweeps (0, -1), where x stands (no translation of the bar upwards touches
    # it; downwards, the bar would have to cross the walls); x can leave through a gap
    def block(xs, ys, tag):
        return {f"{tag}{x},{y}": (x, y) for x in xs for y in ys}

    bar = {f"b{i}": (i, 0) for i in range(3)}
    walls = [block(range(-3, 0), range(-1, 3), "l"), block(range(3, 6), range(-1, 3), "r"),
             block(range(-3, 2), range(-4, -1), "bl"), block(range(3, 6), range(-4, -1), "br")]
    start = bar | {"x": (0, -1)}
    for wall in walls:
        start |= wall
    goal = dict(start) | {m: (c[0], c[1] + 8) for m, c in bar.items()}
    groups = [list(bar), ["x"], *(list(w) for w in walls)]
    routing = route_groups(groups, start, goal, links=[frozenset(p) for p in
                                                        itertools.pairwise(bar)], direct=False)
    assert not routing.cut
    assert ("x",) in {r.modules for r in routing.routes}  # out of the way and back
    _replay(groups, start, goal, routing)
