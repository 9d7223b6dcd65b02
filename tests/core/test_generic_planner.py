"""The generic planner against an independent brute force, on tiny robots defined here."""

from __future__ import annotations

import itertools
from collections import deque
from dataclasses import replace

import networkx as nx
import numpy as np
import pytest
from tiny_robot import CUBE, ROBOT, SPEC, TinyRules, chain

from msrr.core import Configuration, ModuleKind, RobotDefaults, RobotSpec
from msrr.core.actions import topology_diff
from msrr.core.app.testing import replay_problems
from msrr.core.errors import PlanningError
from msrr.core.generic import GenericPlanner
from msrr.core.plan import ActionType, connection_key
from msrr.core.robot import Robot, tree_violations


class TreeRules(TinyRules):
    """Tiny rules plus "every group is a tree" (a dock may not close a loop)."""

    def check_topology(self, config: Configuration) -> list:
        return super().check_topology(config) + tree_violations(config)


TREE = Robot(SPEC, TreeRules(), ROBOT.joint_modes)
CONNECTED = Robot(replace(SPEC, defaults=RobotDefaults(stay_connected=True)), TinyRules(),
                  ROBOT.joint_modes)


def _state(modules: str, keys: frozenset) -> Configuration:
    config = Configuration(SPEC.name)
    for m in modules:
        config.add_module(m, CUBE.name)
    for key in sorted(keys, key=sorted):
        (a, pa), (b, pb) = sorted(key)
        source, target = ((a, pa), (b, pb)) if pa == "T" else ((b, pb), (a, pa))
        config.connect(source[0], target[0], ports=(source[1], target[1]))
    return config


def _legal(robot: Robot, modules: str, keys: frozenset) -> bool:
    """The problem's definition, checked from scratch: ports used once; each group
    passes the robot's rules; one group if the robot says so."""
    ends = [end for key in keys for end in key]
    if len(ends) != len(set(ends)):
        return False
    config = _state(modules, keys)
    if robot.spec.defaults.stay_connected and not config.is_connected():
        return False
    for group in nx.weakly_connected_components(config.graph):
        part = _state("".join(m for m in modules if m in group),
                      frozenset(k for k in keys if {m for m, _ in k} <= group))
        if robot.violations(part):
            return False
    return True


def brute_force_distances(robot: Robot, modules: str, start: frozenset) -> dict[frozenset, int]:
    """Breadth-first search over every legal link set of ``modules``: fewest steps."""
    links = [connection_key(a, b, "T", "B") for a, b in itertools.permutations(modules, 2)]
    legal = {frozenset(s) for n in range(len(links) + 1)
             for s in itertools.combinations(links, n) if _legal(robot, modules, frozenset(s))}
    distance = {start: 0}
    queue = deque([start])
    while queue:
        state = queue.popleft()
        for link in links:
            child = state ^ {link}
            if child in legal and child not in distance:
                distance[child] = distance[state] + 1
                queue.append(child)
    return distance


def _keys(config: Configuration) -> frozenset:
    return frozenset(connection_key(e.source, e.target, *e.ports) for e in config.edges())


@pytest.mark.parametrize("robot", [ROBOT, TREE, CONNECTED], ids=["loops", "trees", "connected"])
def test_plans_are_as_short_as_brute_force_and_replay(robot: Robot) -> None:
    modules = "abcd"
    start = chain(("a", "b"), ("b", "c"), ("c", "d"), modules=modules)
    distances = brute_force_distances(robot, modules, _keys(start))
    goals = sorted(distances, key=lambda k: sorted(map(sorted, k)))
    rng = np.random.default_rng(7)
    picked = [goals[i] for i in rng.choice(len(goals), min(25, len(goals)), replace=False)]
    assert max(distances[k] for k in picked) >= 2  # not only trivial goals
    planner = GenericPlanner(robot)
    for keys in picked:
        goal = _state(modules, keys)
        plan = planner.plan(start, goal)
        assert len(plan.actions) == distances[keys]
        assert replay_problems(plan) == []
        assert not topology_diff(plan.actions[-1].target if plan.actions else start, goal)
        for action in plan.actions:
            assert action.type in (ActionType.CONNECTION, ActionType.DISCONNECTION)
            assert _legal(robot, modules, _keys(action.target))


def test_a_loop_is_needed_when_the_robot_must_stay_connected() -> None:
    """Turning a-b-c into b-c-a keeps one group only through a temporary loop c-a."""
    start = chain(("a", "b"), ("b", "c"))
    goal = chain(("b", "c"), ("c", "a"))
    plan = GenericPlanner(CONNECTED).plan(start, goal)
    assert [a.type for a in plan.actions] == [ActionType.CONNECTION, ActionType.DISCONNECTION]
    assert all(a.target.is_connected() for a in plan.actions)
    with pytest.raises(PlanningError, match="no sequence of legal dock and undock steps"):
        GenericPlanner(Robot(CONNECTED.spec, TreeRules())).plan(start, goal)


def test_same_configuration_plans_no_action_for_any_robot() -> None:
    start = chain(("a", "b"))
    assert GenericPlanner(TREE).plan(start, start.derive(name="again")).actions == []


def test_goal_with_other_ids_is_refused_not_relabelled() -> None:
    with pytest.raises(PlanningError, match="keeps module ids"):
        GenericPlanner(ROBOT).plan(chain(("a", "b")), chain(("a", "x"), modules="abx"))


def test_beyond_the_size_limit_is_a_planning_error() -> None:
    modules = "abcdefgh"
    start = chain(*itertools.pairwise(modules), modules=modules)
    goal = chain(*((b, a) for a, b in itertools.pairwise(modules)), modules=modules)
    with pytest.raises(PlanningError, match=r"8 modules with 16 ports is beyond the generic "
                                            r"planner's limit \(6 modules, 48 ports\)"):
        GenericPlanner(ROBOT, max_modules=6).plan(start, goal)
    with pytest.raises(PlanningError, match="explored 3 configurations"):
        GenericPlanner(ROBOT, max_expansions=3).plan(start, goal)


def test_connections_that_are_modules_are_not_planned() -> None:
    strut = ModuleKind("bar", "S", "edge")
    spec = RobotSpec("bars", "Bars", (ModuleKind("ball", "N", "vertex"), strut))
    a = Configuration("bars")
    for v in "xyz":
        a.add_module(v, "ball")
    a.connect("x", "y", id="S1", kind="bar", z=[1.0, 0.0, 0.0])
    b = Configuration("bars")
    for v in "xyz":
        b.add_module(v, "ball")
    b.connect("x", "z", id="S1", kind="bar", z=[1.0, 0.0, 0.0])
    planner = GenericPlanner(Robot(spec))
    assert planner.plan(a, a).actions == []
    with pytest.raises(PlanningError, match="docks vertex modules only"):
        planner.plan(a, b)


def test_freeform_links_dock_as_the_goal_has_them() -> None:
    """Port-less connections (one freeform connector per module) keep the goal's z."""
    ball = ModuleKind("ball", "B", "vertex", geometry={"radius": 0.05})
    robot = Robot(RobotSpec("balls", "Balls", (ball,)))
    start, goal = Configuration("balls"), Configuration("balls")
    for config in (start, goal):
        for v in "pqr":
            config.add_module(v, "ball")
    start.connect("p", "q", z=[1.0, 0.0, 0.0])
    goal.connect("r", "q", z=[0.0, 1.0, 0.0])
    plan = GenericPlanner(robot).plan(start, goal)
    assert [a.type for a in plan.actions] == [ActionType.DISCONNECTION, ActionType.CONNECTION]
    (edge,) = plan.actions[-1].target.edges()
    assert (edge.source, edge.target, edge.z.tolist()) == ("r", "q", [0.0, 1.0, 0.0])
