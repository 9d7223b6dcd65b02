"""Flow actions (FreeSN paper, section 4.1): the classifier against a brute-force
reference, the slide geometry, the kinematic driver's slide, and flows run end to end
on a tiny freeform robot defined here."""

from __future__ import annotations

import itertools
import math

import networkx as nx
import numpy as np
import pytest

from msrr.core import Configuration, ModuleKind, PortSpec, RobotSpec
from msrr.core.actions import classify, detect_action, flow_move, flow_of, topology_diff
from msrr.core.app.testing import run_kinematic
from msrr.core.errors import ExecutionError, PlanningError
from msrr.core.events import Phase
from msrr.core.executor import phases_of
from msrr.core.freeform.miso import (
    FREE,
    MisoLimits,
    MisoProblem,
    count_flows,
    heuristic_pairing,
    is_flow,
    order_steps,
    plan_miso,
    random_miso_tree,
    targets,
)
from msrr.core.freeform.miso.order import greedy_order
from msrr.core.generic.driver import KinematicDriver
from msrr.core.generic.geometry import BodyPose, slide_toward, touching_direction
from msrr.core.plan import Action, ActionType, Plan, load_plan, save_plan

BALL = ModuleKind(name="ball", symbol="O", role="vertex", ports=(PortSpec("magnet"),),
                  geometry={"radius": 0.05})
SPHERES = RobotSpec("spheres", "Freeform test spheres", (BALL,),
                    description="balls whose one magnet docks anywhere on another ball")


# -- classification against the definition ---------------------------------------------------


def reference_is_flow(before: set[frozenset], after: set[frozenset]) -> bool:
    """Section 4.1 read directly on two link sets (each link a frozenset of its two ends,
    an end ``(module, port)``): one link {L, P} goes, one link {L, Q} comes, L is in no
    other link (a leaf), and P and Q share a link."""
    gone, new = before - after, after - before
    if len(gone) != 1 or len(new) != 1:
        return False
    (g,), (n,) = gone, new
    g_modules, n_modules = {m for m, _ in g}, {m for m, _ in n}
    if len(g_modules & n_modules) != 1:
        return False
    (leaf,) = g_modules & n_modules
    (parent,) = g_modules - {leaf}
    (other,) = n_modules - {leaf}
    if sum(1 for link in before if leaf in {m for m, _ in link}) != 1:
        return False
    return any({m for m, _ in link} == {parent, other} for link in before)


def configuration(modules: str, links: set[frozenset], robot: str = "spheres") -> Configuration:
    config = Configuration(robot)
    for m in modules:
        config.add_module(m, "ball")
    for link in sorted(links, key=sorted):
        (u, pu), (v, pv) = sorted(link)
        config.connect(u, v, ports=None if pu is None else (pu, pv))
    return config


def all_link_sets(ends: list[tuple[str, str | None]], one_per_end: bool) -> list[set[frozenset]]:
    candidates = [frozenset({a, b}) for a, b in itertools.combinations(ends, 2) if a[0] != b[0]]
    found = []
    for r in range(len(candidates) + 1):
        for subset in itertools.combinations(candidates, r):
            used = [end for link in subset for end in link]
            if one_per_end and len(used) != len(set(used)):
                continue
            found.append(set(subset))
    return found


def test_every_pair_of_four_module_graphs_is_a_flow_exactly_when_the_definition_says():
    """All 64 x 64 pairs of simple graphs on four modules without ports."""
    graphs = all_link_sets([(m, None) for m in "abcd"], one_per_end=False)
    assert len(graphs) == 64
    configs = [configuration("abcd", g) for g in graphs]
    flows = 0
    for (g1, c1), (g2, c2) in itertools.product(zip(graphs, configs, strict=True), repeat=2):
        expected = reference_is_flow(g1, g2)
        assert (classify(c1, c2) is ActionType.FLOW) == expected, (g1, g2)
        flows += expected
    assert flows > 50  # the enumeration does reach flows


def test_every_pair_of_three_module_port_matchings_is_a_flow_exactly_when_the_definition_says():
    """Modules with two ports each, a port holding one link: flows may change the
    leaf's port; a change of ports between the same two modules is no flow."""
    sets = all_link_sets([(m, p) for m in "abc" for p in "TB"], one_per_end=True)
    configs = [configuration("abc", s) for s in sets]
    flows = 0
    for (s1, c1), (s2, c2) in itertools.product(zip(sets, configs, strict=True), repeat=2):
        expected = reference_is_flow(s1, s2)
        assert (classify(c1, c2) is ActionType.FLOW) == expected, (s1, s2)
        flows += expected
    assert flows > 0
    same_pair = configuration("abc", {frozenset({("a", "T"), ("b", "B")})})
    other_ports = configuration("abc", {frozenset({("a", "B"), ("b", "T")})})
    assert classify(same_pair, other_ports) is ActionType.PARALLEL_CONNECTION


def test_random_five_module_pairs_one_link_apart_agree_with_the_definition():
    rng = np.random.default_rng(5)
    candidates = [frozenset({(a, None), (b, None)}) for a, b in itertools.combinations("abcde", 2)]
    for _ in range(400):
        before = {c for c in candidates if rng.random() < 0.4}
        gone = list(before)[int(rng.integers(len(before)))] if before else None
        new = candidates[int(rng.integers(len(candidates)))]
        after = (before - {gone}) | {new}
        expected = reference_is_flow(before, after)
        got = classify(configuration("abcde", before), configuration("abcde", after))
        assert (got is ActionType.FLOW) == expected, (before, after)


def test_a_flow_names_its_leaf_parents_and_links_and_runs_as_flow_then_handover():
    chain = configuration("abc", {frozenset({("a", None), ("b", None)}),
                                  frozenset({("b", None), ("c", None)})})
    moved = configuration("abc", {frozenset({("a", None), ("c", None)}),
                                  frozenset({("b", None), ("c", None)})})
    action = detect_action(chain, moved)
    assert action.type is ActionType.FLOW
    flow = flow_of(action)
    assert (flow.leaf, flow.parent, flow.new_parent) == ("a", "b", "c")
    assert flow == flow_move(chain, topology_diff(chain, moved))
    assert phases_of(action, topology_diff(chain, moved)) == [Phase.FLOW, Phase.HANDOVER]
    with pytest.raises(PlanningError, match="not a flow"):
        flow_of(detect_action(chain, configuration("abc", set())))


# -- geometry ----------------------------------------------------------------------------------


def ball(radius: float) -> ModuleKind:
    return ModuleKind(name=f"r{radius}", symbol="R", role="vertex", geometry={"radius": radius})


@pytest.mark.parametrize(("rp", "rl", "rq", "gap"), [(0.05, 0.05, 0.05, 0.0),
                                                     (0.05, 0.03, 0.08, 0.0),
                                                     (0.05, 0.05, 0.05, 0.04)])
def test_touching_direction_is_the_law_of_cosines_for_balls(rp, rl, rq, gap):
    parent, other = BodyPose(np.zeros(3)), BodyPose(np.array([rp + rq + gap, 0.0, 0.0]))
    d = touching_direction(ball(rp), parent, ball(rl), 0.0, ball(rq), other,
                           np.array([0.0, 0.0, 1.0]))
    a, b, c = rp + rq + gap, rp + rl, rq + rl
    expected = math.acos((a * a + b * b - c * c) / (2 * a * b))
    assert d is not None and d[2] > 0
    assert math.acos(d[0]) == pytest.approx(expected, abs=1e-9)
    leaf = d * (rp + rl)
    assert float(np.linalg.norm(leaf - other.position)) == pytest.approx(rq + rl, abs=1e-9)


def test_touching_direction_for_a_box_touches_both_and_none_when_too_far():
    box = ModuleKind(name="box", symbol="X", role="vertex",
                     geometry={"length": 0.1, "width": 0.06, "height": 0.04})
    parent, other = BodyPose(np.zeros(3)), BodyPose(np.array([0.1, 0.0, 0.0]))
    d = touching_direction(box, parent, ball(0.02), 0.0, box, other, np.array([0, 1.0, 0]))
    assert d is not None
    # independent check: the leaf ball's centre sits where its ray from the parent leaves
    # the parent's box, plus its radius; it is then one radius from the other box
    t = min(0.05 / abs(d[0]) if d[0] else math.inf, 0.03 / abs(d[1]) if d[1] else math.inf)
    leaf = d * (t + 0.02)
    toward = (leaf - other.position) / np.linalg.norm(leaf - other.position)
    s = min(0.05 / abs(toward[0]) if toward[0] else math.inf,
            0.03 / abs(toward[1]) if toward[1] else math.inf)
    assert float(np.linalg.norm(leaf - other.position)) == pytest.approx(s + 0.02, abs=1e-9)
    far = BodyPose(np.array([1.0, 0.0, 0.0]))
    assert touching_direction(box, parent, ball(0.02), 0.0, box, far, np.array([0, 1.0, 0])) \
        is None


def test_slide_toward_turns_by_the_step_on_the_great_circle_and_lands_on_the_goal():
    u, g = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])
    v = slide_toward(u, g, 0.1)
    assert float(np.linalg.norm(v)) == pytest.approx(1.0)
    assert math.acos(float(u @ v)) == pytest.approx(0.1)
    assert float(np.cross(u, g) @ v) == pytest.approx(0.0, abs=1e-12)  # in the u-g plane
    assert np.array_equal(slide_toward(v, g, 3.0), g)
    over = slide_toward(u, -u, 0.2)  # opposite: turns over the top
    assert over[2] > 0 and math.acos(float(u @ over)) == pytest.approx(0.2)


# -- the kinematic driver's slide ---------------------------------------------------------------


def chain3() -> Configuration:
    config = Configuration("spheres")
    for m in "abc":
        config.add_module(m, "ball")
    config.connect("a", "b", z=[1.0, 0.0, 0.0])
    config.connect("b", "c", z=[1.0, 0.0, 0.0])
    return config


def test_a_slide_keeps_contact_and_the_latch_and_a_rigid_latch_cannot_slide():
    from msrr.core.driver import ModuleCommand

    with KinematicDriver(SPHERES) as world:
        world.reset(chain3())
        goal = np.array([0.0, 0.0, 1.0])
        for _ in range(20):
            world.send_action({"a": ModuleCommand(joints=dict(zip(
                ("slide_x", "slide_y", "slide_z"), goal, strict=True)))})
            world.step(0.05)
            gap = world.poses["a"].position - world.poses["b"].position
            assert float(np.linalg.norm(gap)) == pytest.approx(0.1, abs=1e-12)
            assert any({lk.source, lk.target} == {"a", "b"} for lk in world.links)
        assert np.allclose(world.poses["a"].position - world.poses["b"].position, 0.1 * goal)
        with pytest.raises(ExecutionError, match="has 2 links"):
            world.send_action({"b": ModuleCommand(joints={"slide_x": 0.0, "slide_y": 0.0,
                                                          "slide_z": 1.0})})
    hinge = ModuleKind(name="ball", symbol="O", role="vertex",
                       ports=(PortSpec("T", "active", (1.0, 0.0, 0.0)),
                              PortSpec("B", "passive", (-1.0, 0.0, 0.0))),
                       geometry={"radius": 0.05})
    rigid = RobotSpec("spheres", "rigid", (hinge,))
    config = Configuration("spheres")
    for m in "ab":
        config.add_module(m, "ball")
    config.connect("a", "b", ports=("T", "B"))
    with KinematicDriver(rigid) as world:
        world.reset(config)
        with pytest.raises(ExecutionError, match="rigid latch"):
            world.send_action({"a": ModuleCommand(joints={"slide_x": 0.0, "slide_y": 0.0,
                                                          "slide_z": 1.0})})


# -- end to end ----------------------------------------------------------------------------------


class ContactWatcher(KinematicDriver):
    """The kinematic driver that records, after every step, the largest gap between two
    latched contact modules (0 when every latched pair touches) and every module that
    was latched to nothing."""

    def __init__(self, spec: RobotSpec):
        super().__init__(spec)
        self.worst = 0.0
        self.steps = 0
        self.freed: set[str] = set()

    def step(self, dt: float) -> None:
        super().step(dt)
        self.steps += 1
        for link in self.links:
            gap = float(np.linalg.norm(self.poses[link.source].position
                                       - self.poses[link.target].position))
            self.worst = max(self.worst, abs(gap - 0.1))
        self.freed |= set(self.poses) - {m for lk in self.links for m in (lk.source, lk.target)}


def star_goal(n: int) -> Configuration:
    config = Configuration("spheres")
    ids = [f"m{i}" for i in range(1, n + 1)]
    for m in ids:
        config.add_module(m, "ball")
    directions = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]
    for m, z in zip(ids[:-1], directions, strict=False):
        config.connect(m, ids[-1], z=z)
    return config


def line(n: int) -> Configuration:
    config = Configuration("spheres")
    ids = [f"m{i}" for i in range(1, n + 1)]
    for m in ids:
        config.add_module(m, "ball")
    for a, b in itertools.pairwise(ids):
        config.connect(a, b, z=[-1.0, 0.0, 0.0])
    return config


def test_a_miso_chain_to_star_runs_its_flows_without_letting_go():
    """Five spheres, chain -> star: the MISO plan ends with a flow (the module next to the
    centre, once a leaf); the kinematic world slides it over its parent and hands it
    over; the flowing leaf is never free, every latched pair always touches, and the
    flows are counted from what the driver reported."""
    plan = plan_miso(line(5), star_goal(5))
    leaves = [flow_of(a).leaf for a in plan.actions if a.type is ActionType.FLOW]
    assert leaves == ["m3"] and plan.flows == 1
    watcher = ContactWatcher(SPHERES)
    result = run_kinematic(plan, SPHERES, driver=watcher)
    assert result.success, result.reason
    assert result.flows == plan.flows
    assert (result.docks, result.undocks) == (plan.docks, plan.undocks) == (3, 3)
    assert watcher.worst < 1e-9 and watcher.steps > 10
    assert "m3" not in watcher.freed and {"m1", "m2"} <= watcher.freed  # reconnections let go
    assert nx.is_isomorphic(result.final.graph.to_undirected(),
                            star_goal(5).graph.to_undirected())


def test_a_flow_whose_leaf_is_not_a_leaf_any_more_fails_the_action():
    chain = chain3()
    moved = Configuration("spheres")
    for m in "abc":
        moved.add_module(m, "ball")
    moved.connect("a", "c", z=[1.0, 0.0, 0.0])
    moved.connect("b", "c", z=[1.0, 0.0, 0.0])
    flow = detect_action(chain, moved)
    assert flow.type is ActionType.FLOW
    # replayed from a start where 'a' carries another link, the step is no flow
    start = chain.copy()
    start.connect("c", "a", z=[0.0, 0.0, 1.0])
    plan = Plan("spheres", "hand", start, moved, [flow])
    result = run_kinematic(plan, SPHERES, action_timeout=2.0)
    assert not result.success and "is not a flow" in result.reason


# -- MISO planners emit flows --------------------------------------------------------------------


def miso_configuration(parent: tuple[int, ...]) -> Configuration:
    config = Configuration("spheres")
    for i in range(len(parent)):
        config.add_module(f"m{i}", "ball")
    for i, p in enumerate(parent):
        if p != FREE:
            config.connect(f"m{i}", f"m{p}", z=[1.0, 0.0, 0.0])
    return config


def test_flows_first_costs_no_step_and_finds_flows_the_plain_order_misses():
    rng = np.random.default_rng(3)
    more = 0
    for _ in range(120):
        n = int(rng.integers(5, 13))
        problem = MisoProblem.from_parents(random_miso_tree(n, rng, max_branching=3),
                                           random_miso_tree(n, rng, max_branching=3))
        goal = targets(problem, heuristic_pairing(problem))
        depth = [0] * n  # every order equal: the preference alone decides
        plain = greedy_order(problem.start, goal, depth, MisoLimits(), flows_first=False)
        chosen = order_steps(problem.start, goal, depth)
        assert len(chosen) <= len(plain)
        assert count_flows(problem.start, chosen) >= count_flows(problem.start, plain)
        more += count_flows(problem.start, chosen) > count_flows(problem.start, plain)
    assert more > 0


@pytest.mark.parametrize("exact", [False, True])
def test_every_miso_step_is_typed_by_the_one_classifier(exact):
    """The pointer-array flow test (``miso.is_flow``) and the planner's action types agree
    with ``actions.classify`` on every step of random plans."""
    rng = np.random.default_rng(11)
    flows = 0
    for _ in range(12 if exact else 40):
        n = int(rng.integers(4, 8 if exact else 12))
        start = random_miso_tree(n, rng, max_branching=2)
        plan = plan_miso(miso_configuration(start), miso_configuration(
            random_miso_tree(n, rng, max_branching=2)), exact=exact)
        current, parent = plan.start, list(start)
        index = {f"m{i}": i for i in range(n)}
        for action in plan.actions:
            assert classify(current, action.target) is action.type, action.note
            if action.type is not ActionType.MOVING:
                module = index[action.note.split()[1].rstrip(":")]
                new = next((index[e.target] for e in action.target.edges()
                            if e.source == f"m{module}"), FREE)
                assert is_flow(parent, module, new) == (action.type is ActionType.FLOW)
                parent[module] = new
            current = action.target
        flows += plan.flows
    assert flows > 0


def test_a_flow_round_trips_through_a_plan_file(tmp_path):
    plan = plan_miso(line(5), star_goal(5))
    save_plan(plan, tmp_path / "plan.json")
    again = load_plan(tmp_path / "plan.json")
    assert [a.type for a in again.actions] == [a.type for a in plan.actions]
    assert again.flows == plan.flows == 1
    (flow,) = [a for a in again.actions if a.type is ActionType.FLOW]
    assert str(flow_of(flow)) == "m3: m4 -> m5"
    assert (again.docks, again.undocks) == (plan.docks, plan.undocks)


def test_a_leaf_on_a_rigid_latch_flows_by_release_and_carry():
    """Ports with normals cannot slide: the flow phase is reached at once and the
    handover releases the leaf and carries it to its new parent's port, docking there."""
    cube = ModuleKind(name="cube", symbol="C", role="vertex",
                      ports=(PortSpec("T", "active", (1.0, 0.0, 0.0)),
                             PortSpec("B", "passive", (-1.0, 0.0, 0.0))),
                      geometry={"length": 0.1, "width": 0.1, "height": 0.1})
    spec = RobotSpec("cubes", "Cubes", (cube,))

    def config(*links: tuple[str, str, str, str]) -> Configuration:
        out = Configuration("cubes")
        for m in "abc":
            out.add_module(m, "cube")
        for u, pu, v, pv in links:
            out.connect(u, v, ports=(pu, pv))
        return out

    start = config(("a", "T", "b", "B"), ("b", "T", "c", "B"))
    goal = config(("c", "T", "a", "B"), ("b", "T", "c", "B"))
    action = detect_action(start, goal)
    assert action.type is ActionType.FLOW
    plan = Plan("cubes", "hand", start, goal, [action])
    result = run_kinematic(plan, spec)
    assert result.success, result.reason
    assert (result.flows, result.docks, result.undocks) == (1, 1, 1)
    assert not topology_diff(result.final, goal)


def test_a_flow_without_its_changes_in_the_plan_file_still_runs():
    """A hand-written plan may give a flow's target only: the executor completes the
    changes from the topology difference before the controller reads them."""
    plan = plan_miso(line(3), star_goal(3))
    (flow,) = plan.actions[:1]
    assert flow.type is ActionType.FLOW
    bare = Plan("spheres", "hand", plan.start, flow.target,
                [Action(ActionType.FLOW, flow.target)])
    result = run_kinematic(bare, SPHERES)
    assert result.success and result.flows == 1, result.reason
