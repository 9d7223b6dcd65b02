"""MISO planning for a robot whose docking module carries nothing (``carries: nothing``,
SnailBot): no step docks a module that others sit on, the plan still reaches the goal,
both metrics are bounded by taking everything apart and building it again, and it is
never worse than the in-tree planner's plan whenever that plan already docks only
modules that carry nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import plugins
from msrr.core.errors import PlanningError, PluginError
from msrr.core.freeform.design import read_miso_rules
from msrr.core.freeform.miso import (
    FREE,
    MisoLimits,
    MisoProblem,
    changes,
    random_cyclic,
    random_forest,
    solve_exact,
    solve_heuristic,
    step_is_legal,
    targets,
)
from msrr.core.io import load_configuration

from msrr_test_support import ROOT

SNAILBOT_RULES = MisoLimits(max_in=6, no_docking_onto="child", carries="nothing")
IN_TREE = MisoLimits(max_in=6, no_docking_onto="child")


def _draw(seed: int, n: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """A start forest (a cyclic configuration one time in three) and a goal forest."""
    rng = np.random.default_rng(seed)
    start = (random_cyclic(n, rng) if seed % 3 == 0
             else random_forest(n, int(rng.integers(1, n + 1)), rng))
    return start, random_forest(n, int(rng.integers(1, n + 1)), rng)


def _docks_only_bare_modules(start, steps) -> bool:
    parent = list(start)
    for step in steps:
        if step.new != FREE and step.module in parent:
            return False
        parent[step.module] = step.new
    return True


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 24))
def test_no_step_docks_a_module_that_carries_others_and_the_goal_is_reached(seed, n):
    start, goal = _draw(seed, n)
    problem = MisoProblem.from_parents(start, goal, SNAILBOT_RULES)
    solution = solve_heuristic(problem)
    parent = list(start)
    for step in solution.steps:
        assert parent[step.module] == step.old
        if step.new != FREE:   # a docking module: nothing sits on it
            assert all(p != step.module for p in parent), (parent, step)
        assert step_is_legal(parent, step.module, step.new, SNAILBOT_RULES)
        parent[step.module] = step.new
        assert not SNAILBOT_RULES.violations(parent)
    final = targets(problem, solution.pairing)
    assert parent == list(final)
    # both metrics: at least the lower bounds, at most taking apart and building again
    rebuild = sum(p != FREE for p in start) + sum(p != FREE for p in goal)
    assert solution.lower_bound <= solution.cost <= rebuild
    assert changes(start, final) <= solution.changes <= rebuild
    assert solution.changes == sum((s.old != FREE) + (s.new != FREE) for s in solution.steps)
    # never worse than the in-tree planner where its plan already obeys the rule
    in_tree = solve_heuristic(MisoProblem.from_parents(start, goal, IN_TREE))
    if _docks_only_bare_modules(start, in_tree.steps):
        assert solution.cost <= in_tree.cost and solution.changes <= in_tree.changes


def test_the_exact_planner_obeys_the_rule_too():
    for seed in range(6):
        start, goal = _draw(seed, 9)
        problem = MisoProblem.from_parents(start, goal, SNAILBOT_RULES)
        solution = solve_exact(problem, time_limit=10)
        assert _docks_only_bare_modules(start, solution.steps)
        parent = list(start)
        for step in solution.steps:
            parent[step.module] = step.new
        assert parent == list(targets(problem, solution.pairing))


def test_a_ring_can_be_opened_but_not_built():
    ring = [1, 2, 0]
    solution = solve_heuristic(MisoProblem.from_parents(ring, [FREE, 0, 1], SNAILBOT_RULES))
    assert solution.steps[0].new == FREE and solution.cost >= 1
    with pytest.raises(PlanningError, match="close a ring"):
        MisoProblem.from_parents([FREE, 0, 1], ring, SNAILBOT_RULES)
    MisoProblem.from_parents([FREE, 0, 1], ring, IN_TREE)   # FreeBOT can


def test_the_rule_is_read_from_the_description_and_bad_values_are_named():
    rules = json.loads((ROOT / "plugins" / "snailbot" / "robot.json").read_text())["miso"]
    assert rules["carries"] == "nothing"
    assert plugins.planners("snailbot")["miso"].limits.carries == "nothing"
    assert plugins.planners("freebot")["miso"].limits.carries == "in-tree"
    text = json.dumps({"miso": {"max_in": 6, "no_docking_onto": "child", "carries": "all"}})
    with pytest.raises(PluginError, match=r"^x/robot.json: miso.carries must be") as err:
        read_miso_rules(text, "x/robot.json")
    assert "\n" not in str(err.value)
    with pytest.raises(PluginError, match="missing miso.carries"):
        read_miso_rules(json.dumps({"miso": {"max_in": 6, "no_docking_onto": "child"}}), "x")


def _stages(robot: str, name: str):
    configs = ROOT / "plugins" / robot / "configs" / "forest20"
    return [load_configuration(configs / f"{name}.json") for name in
            (name, f"{name}-forest", f"{name}-tree")]


def _docking_loads(robot: str) -> list[int]:
    """Modules each docking module of the pieces-to-tree plans carries (its in-tree)."""
    planner = plugins.planners(robot)["miso"]
    stages = _stages(robot, "forest20")
    loads = []
    for start, goal in zip(stages, stages[1:], strict=False):
        plan = planner.plan(start, goal)
        current = plan.start
        for action in plan.actions:
            for change in action.changes:
                module = change.source
                if not current.graph.has_edge(change.source, change.target) and \
                        action.target.graph.has_edge(change.source, change.target):
                    loads.append(len(_in_tree(current, module)))
            current = action.target
    return loads


def _in_tree(config, module: str) -> set[str]:
    found, todo = set(), [module]
    while todo:
        m = todo.pop()
        for source, _ in config.graph.in_edges(m):
            if source not in found:
                found.add(source)
                todo.append(source)
    return found


def test_pieces_to_tree_plans_move_pieces_as_each_robot_can():
    assert sorted(_docking_loads("freebot")) == [3, 3]   # two rows of four travel
    snail = _docking_loads("snailbot")
    assert len(snail) == 8 and set(snail) == {0}         # each module crawls alone
