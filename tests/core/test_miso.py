"""MISO connection planning: exact search vs brute force, legal steps, plans replayed."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.actions import classify
from msrr.core.configuration import Configuration
from msrr.core.errors import PlanningError
from msrr.core.freeform.miso import (
    FREE,
    MisoProblem,
    brute_force_steps,
    canonical_form,
    order_steps,
    plan_miso,
    random_miso_tree,
    solve_exact,
    solve_heuristic,
    step_is_legal,
    targets,
)
from msrr.core.io import load_configuration
from msrr.core.plan import ActionType

from msrr_test_support import ROOT


def instances(seed: int, count: int, low: int, high: int, max_branching: int | None = 3):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n = int(rng.integers(low, high + 1))
        yield MisoProblem.from_parents(random_miso_tree(n, rng, max_branching=max_branching),
                                       random_miso_tree(n, rng, max_branching=max_branching))


def replay(start: tuple[int, ...], steps) -> list[tuple[int, ...]]:
    """Apply steps one by one, checking each against the state it starts from."""
    states, parent = [start], list(start)
    for step in steps:
        assert parent[step.module] == step.old
        parent[step.module] = step.new
        states.append(tuple(parent))
    return states


def connected(parent) -> bool:
    graph = nx.Graph()
    graph.add_nodes_from(range(len(parent)))
    graph.add_edges_from((i, p) for i, p in enumerate(parent) if p != FREE)
    return nx.is_connected(graph)


def test_exact_search_agrees_with_breadth_first_search_over_all_configurations():
    checked = 0
    for problem in instances(seed=1, count=40, low=3, high=6, max_branching=None):
        exact = solve_exact(problem)
        assert exact.optimal
        assert exact.cost == brute_force_steps(problem), (problem.start, problem.goal)
        checked += exact.cost > 0
    assert checked > 30  # most instances need steps


@pytest.mark.parametrize("solver", [solve_heuristic, solve_exact], ids=["miso", "miso-exact"])
def test_steps_are_legal_connected_and_end_in_the_goal_shape(solver):
    for problem in instances(seed=2, count=30, low=2, high=9):
        solution = solver(problem)
        states = replay(problem.start, solution.steps)
        for state in states:
            assert connected(state)                       # one group at every step
            assert sum(p == FREE for p in state) <= 1     # one connector each: n-1 or n links
        assert states[-1] == tuple(targets(problem, solution.pairing))
        assert canonical_form(states[-1]) == canonical_form(problem.goal)
        assert sorted(solution.pairing) == list(range(problem.n))
        assert solution.cost >= solution.lower_bound


def test_heuristic_is_an_upper_bound_and_mostly_optimal():
    optimal = total = 0
    for problem in instances(seed=3, count=40, low=5, high=8):
        heuristic, exact = solve_heuristic(problem), solve_exact(problem)
        assert heuristic.cost >= exact.cost
        optimal += heuristic.cost == exact.cost
        total += 1
    assert optimal >= 0.9 * total


def test_the_goal_depth_order_needs_one_step_per_mismatch_when_the_sinks_agree():
    rng = np.random.default_rng(4)
    for _ in range(40):
        n = int(rng.integers(3, 30))
        start = random_miso_tree(n, rng)
        goal = list(random_miso_tree(n, rng))
        # relabel the goal so that its sink is the start's sink
        s, g = start.index(FREE), goal.index(FREE)
        swap = {s: g, g: s}
        goal = [swap.get(goal[swap.get(i, i)], goal[swap.get(i, i)]) for i in range(n)]
        assert goal.index(FREE) == s
        steps = order_steps(start, goal)
        assert len(steps) == sum(a != b for a, b in zip(start, goal, strict=True))
        assert all(connected(state) for state in replay(start, steps))


def test_step_legality_is_connectivity_of_the_result():
    rng = np.random.default_rng(5)
    for _ in range(30):
        n = int(rng.integers(2, 8))
        parent = list(random_miso_tree(n, rng))
        if rng.random() < 0.5:  # close the one cycle: the sink connects somewhere
            s = parent.index(FREE)
            parent[s] = int(rng.choice([j for j in range(n) if j != s])) if n > 1 else FREE
        for i, k in itertools.product(range(n), range(FREE, n)):
            if k == i or parent[i] == k:
                continue
            after = list(parent)
            after[i] = k
            assert step_is_legal(parent, i, k) == connected(after), (parent, i, k)


def test_brute_force_and_exact_on_a_hand_checked_instance():
    # start: 4 <- {0, 3 <- 1 <- {2, 5}}; goal: 0 <- {2, 4, 3 <- {1, 5}}
    # one step: module 1 moves from 3 to 4 with its two leaves
    problem = MisoProblem.from_parents([4, 3, 1, 4, FREE, 1], [FREE, 3, 0, 0, 0, 3])
    assert brute_force_steps(problem) == 1
    assert solve_exact(problem).cost == 1
    assert solve_heuristic(problem).cost == 1


def test_problems_that_are_not_miso_trees_are_refused():
    with pytest.raises(PlanningError, match="not one connected tree"):
        MisoProblem.from_parents([1, 0, FREE], [FREE, 0, 1])
    with pytest.raises(PlanningError, match="modules"):
        MisoProblem.from_parents([FREE, 0], [FREE, 0, 0])
    config = Configuration("freebot")
    for m in ("F1", "F2", "F3"):
        config.add_module(m, "freebot")
    config.connect("F1", "F2", z=[0, 0, 1])
    config.connect("F1", "F3", z=[1, 0, 0])
    with pytest.raises(PlanningError, match="two out-connections"):
        MisoProblem.from_configurations(config, config)


FREEBOT = ROOT / "plugins" / "freebot" / "configs"


@pytest.mark.parametrize("planner", ["miso", "miso-exact"])
@pytest.mark.parametrize("robot", ["freebot", "snailbot"])
def test_planners_are_registered_for_both_robots(robot, planner):
    found = plugins.planners(robot)
    assert list(found)[:2] == ["miso", "miso-exact"]
    assert found[planner].name == planner


@pytest.mark.parametrize("planner", ["miso", "miso-exact"])
def test_chain_to_star_plan_replays_to_the_goal(planner):
    start = load_configuration(FREEBOT / "chain6.json")
    goal = load_configuration(FREEBOT / "star6.json")
    plan = plugins.planners("freebot")[planner].plan(start, goal)
    assert plan.planner == planner and plan.stats["steps"] == 4
    assert len(plan.actions) == 5 and plan.actions[-1].type == ActionType.MOVING
    current = plan.start
    for action in plan.actions:
        target = action.target
        assert all(target.graph.out_degree(v) <= 1 for v in target.vertices())
        assert target.is_connected(), action.note
        if action.type != ActionType.MOVING:
            assert classify(current, target) == action.type, action.note
        current = target
    assert current == plan.goal
    reached = {(plan.mapping[e.source], plan.mapping[e.target]) for e in current.edges()}
    assert reached == {(e.source, e.target) for e in goal.edges()}
    z = {(plan.mapping[e.source], plan.mapping[e.target]): e.z for e in current.edges()}
    assert all(np.array_equal(z[(e.source, e.target)], e.z) for e in goal.edges())


def test_planning_to_itself_changes_nothing():
    start = load_configuration(FREEBOT / "chain6.json")
    plan = plan_miso(start, start)
    assert plan.actions == [] and plan.stats["steps"] == 0
    assert all(plan.mapping[m] == m for m in start.vertices())
