"""Sections 4.1-4.4: decomposition, matching, plans that reach the goal, vs. the optimum."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.configuration import Configuration
from msrr.core.errors import PlanningError
from msrr.core.io import load_configuration
from msrr.core.plan import ActionType, load_plan, save_plan
from msrr.plugins.mmrp.check import check_plan
from msrr.plugins.mmrp.mcs import decompose, mcs
from msrr.plugins.mmrp.optimum import optimum
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.random_trees import random_tree
from msrr.plugins.mmrp.representation import (
    GRID_STEP,
    edge_set,
    face_links,
    from_links,
    pitch,
)

CONFIGS = Path(__file__).resolve().parents[3] / "plugins" / "mmrp" / "configs"


def _load(name: str) -> Configuration:
    return load_configuration(CONFIGS / f"{name}.json")


def _apply(start: Configuration, actions) -> Configuration:
    """Replay dock/undock actions on ``start`` independently of the action targets."""
    current = start.copy()
    for action in actions:
        for change in action.changes:
            if action.type is ActionType.DISCONNECTION:
                current.disconnect(change.edge_id)
            elif action.type is ActionType.CONNECTION:
                current.connect(change.target, change.source,
                                ports=(change.target_port, change.source_port))
    return current


def _check_plan(start: Configuration, goal: Configuration, seed: int = 0) -> int:
    result = plan_hybrid(start, goal, seed=seed)
    plan = result.plan
    mapping = plan.mapping
    assert sorted(mapping) == sorted(start.vertices())
    assert sorted(mapping.values()) == sorted(goal.vertices())
    inverse = {g: c for c, g in mapping.items()}
    reached = _apply(start, plan.actions)
    assert edge_set(reached) == edge_set(goal.relabel(inverse))
    assert edge_set(plan.goal) == edge_set(reached)
    if plan.actions:
        assert edge_set(plan.actions[-1].target) == edge_set(reached)
    kinds = [a.type for a in plan.actions]
    assert kinds == sorted(kinds, key=[ActionType.DISCONNECTION, ActionType.MOVING,
                                       ActionType.CONNECTION].index)
    assert plan.undocks == plan.docks == result.pairs <= len(start) - 1
    poses = dict(result.goal_poses)
    last = {}
    for action in plan.actions:
        if action.type is ActionType.MOVING:
            assert set(action.goals) == set(action.modules)
            last.update(action.goals)
    for module, pose in last.items():
        assert pose == pytest.approx(list(poses[module]))
    assert check_plan(plan) == []
    for e in reached.edges():
        dx, dy = GRID_STEP[e.ports[0]]
        assert poses[e.target][:2] == pytest.approx(
            (poses[e.source][0] + dx * pitch(), poses[e.source][1] + dy * pitch()))
    return result.pairs


def test_mcs_reproduces_tables_2_and_3():
    cross, probe = face_links(_load("cross")), face_links(_load("probe"))
    assert mcs(cross, probe, "1", "1") == {"1": "1", "5": "7", "2": "2", "6": "3", "3": "4"}
    assert mcs(cross, probe, "4", "8", within_c={"4", "8"}, within_g={"8", "9"}) == {
        "4": "8", "8": "9"}


def test_decomposition_reproduces_figure_13():
    cross, probe = _load("cross"), _load("probe")
    lc, lg = face_links(cross), face_links(probe)
    split = decompose(lc, lg, cross.vertices(), probe.vertices(), mcs(lc, lg, "1", "1"))
    assert [set(s.vertices) for s in split.current] == [{"4", "8"}]
    assert sorted(map(set, (s.vertices for s in split.goal)), key=min) == [{"5", "6"},
                                                                          {"8", "9"}]
    assert set(split.free_current) == {"7", "9"} and split.free_goal == ()


def test_cross_to_probe_needs_the_three_pairs_of_table_4():
    assert _check_plan(_load("cross"), _load("probe")) == 3


def test_series_to_t_needs_at_most_two_pairs_and_maps_2_to_1():
    result = plan_hybrid(_load("series"), _load("t"))
    assert result.pairs <= 2
    assert result.roots == ("2", "1")
    assert result.mapping["2"] == "1" and result.mapping["1"] == "2"
    assert _check_plan(_load("series"), _load("t")) <= 2


def test_a_configuration_plans_to_itself_with_no_actions():
    tree = random_tree(12, np.random.default_rng(5))
    result = plan_hybrid(tree, tree.copy())
    assert result.plan.actions == [] and result.pairs == 0


def _brute_force_kept(start: Configuration, goal: Configuration) -> int:
    lc, lg = face_links(start), face_links(goal)
    best = 0
    for images in itertools.permutations(goal.vertices()):
        f = dict(zip(start.vertices(), images, strict=True))
        best = max(best, sum(lg[f[u]].get(fu) == (f[v], fv)
                             for u, fus in lc.items() for fu, (v, fv) in fus.items()) // 2)
    return best


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 6), seed=st.integers(0, 2**32 - 1))
def test_exact_optimum_equals_brute_force(n, seed):
    rng = np.random.default_rng(seed)
    start, goal = random_tree(n, rng), random_tree(n, rng)
    assert optimum(start, goal).kept == _brute_force_kept(start, goal)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 9), seed=st.integers(0, 2**32 - 1))
def test_plans_reach_the_goal_and_never_beat_the_optimum(n, seed):
    rng = np.random.default_rng(seed)
    start, goal = random_tree(n, rng), random_tree(n, rng)
    best = optimum(start, goal)
    pairs = _check_plan(start, goal, seed=seed % 97)
    assert best.pairs <= pairs <= n - 1
    found = best.mapping
    lg = face_links(goal)
    assert sum(lg[found[e.source]].get(e.ports[0]) == (found[e.target], e.ports[1])
               for e in start.edges()) == best.kept


@settings(max_examples=8, deadline=None)
@given(n=st.integers(10, 40), seed=st.integers(0, 2**32 - 1))
def test_larger_plans_reach_the_goal(n, seed):
    rng = np.random.default_rng(seed)
    _check_plan(random_tree(n, rng), random_tree(n, rng), seed=seed % 13)


def test_a_start_with_a_loop_undocks_the_virtual_connection():
    square = from_links("1234", [("1", "T", "2", "B"), ("2", "L", "3", "R"),
                                 ("3", "B", "4", "T"), ("4", "R", "1", "L")])
    line = from_links("1234", [("1", "T", "2", "B"), ("2", "T", "3", "B"),
                               ("3", "T", "4", "B")])
    result = plan_hybrid(square, line)
    assert result.virtual
    assert edge_set(_apply(square, result.plan.actions)) == edge_set(
        line.relabel({g: c for c, g in result.mapping.items()}))


@pytest.mark.parametrize(("goal", "message"), [
    (from_links("123", [("1", "T", "2", "B"), ("2", "T", "3", "B")]), "modules"),
    (from_links("1234", [("1", "T", "2", "L"), ("2", "T", "3", "B"), ("3", "T", "4", "B")]),
     "goal"),
    (from_links("12345", [("1", "T", "2", "B"), ("2", "L", "3", "R"), ("3", "B", "4", "T"),
                          ("4", "R", "5", "L")]), "same place"),
])
def test_unreachable_goals_raise_planning_error(goal, message):
    start = random_tree(4 if len(goal) == 3 else len(goal), np.random.default_rng(0))
    with pytest.raises(PlanningError, match=message):
        plugins.planners.get("mmrp", "mcs-hybrid").plan(start, goal)


def test_planner_and_scenarios_are_registered():
    planner = plugins.planners.get("mmrp")
    assert planner.name == "mcs-hybrid"
    scenarios = plugins.scenarios("mmrp")
    assert scenarios["cross-probe"].default and set(scenarios) >= {"cross-probe", "series-t"}
    plan = planner.plan(load_configuration(scenarios["series-t"].start),
                        load_configuration(scenarios["series-t"].goal))
    assert plan.docks <= 2


def test_plan_file_round_trip(tmp_path):
    plan = plan_hybrid(_load("cross"), _load("probe")).plan
    save_plan(plan, tmp_path / "plan.json")
    again = load_plan(tmp_path / "plan.json")
    assert again.mapping == plan.mapping and len(again.actions) == len(plan.actions)
    assert [a.goals for a in again.actions] == [a.goals for a in plan.actions]


def test_cli_prints_three_undocks_and_three_docks(tmp_path):
    out = tmp_path / "plan.json"
    result = CliRunner().invoke(get_cli(), ["plan", "--robot", "mmrp", str(CONFIGS / "cross.json"),
                                            str(CONFIGS / "probe.json"), "--json", str(out)])
    assert result.exit_code == 0, result.output
    rows = [line for line in result.output.splitlines() if line.startswith("│")]
    assert sum("Undock" in r for r in rows) == 3 and sum("│ Dock" in r for r in rows) == 3
    assert load_plan(out).docks == 3


def test_cli_reports_bad_input_in_one_line(tmp_path):
    result = CliRunner().invoke(get_cli(), ["plan", "--robot", "mmrp", str(CONFIGS / "cross.json"),
                                            str(CONFIGS / "t.json")])
    assert result.exit_code == 1
    assert "start has 9 modules and goal 4" in result.output
    assert "Traceback" not in result.output
