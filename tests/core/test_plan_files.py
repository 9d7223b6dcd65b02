"""Plan files store changes (issue 29, item 5): plan -> file -> plan gives identical
targets for every action, for every built-in robot and planner; the changes between two
configurations rebuild the second exactly; version 1 files (every target whole) still
load, and a file stays small where the old format grew with modules x actions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import plugins
from msrr.core.configuration import Configuration
from msrr.core.delta import DerivedConfiguration, Draft, difference
from msrr.core.freeform.miso import random_miso_tree
from msrr.core.io import configuration_to_model
from msrr.core.plan import Plan, links, load_plan, save_plan
from msrr.core.random_configurations import (
    pointer_configuration,
    random_configuration,
    random_unit,
)
from msrr.plugins.mmrp.random_trees import random_tree

ROOT = Path(__file__).resolve().parents[2]
V1 = Path(__file__).resolve().parent / "plans_v1"
HINGE = ROOT / "examples/msrr-example-hinge/msrr_example_hinge/configs"

PAIRS = {
    "freebot": ("plugins/freebot/configs/chain6.json", "plugins/freebot/configs/star6.json"),
    "snailbot": ("plugins/snailbot/configs/chain5.json", "plugins/snailbot/configs/tree5.json"),
    "mmrp": ("plugins/mmrp/configs/cross.json", "plugins/mmrp/configs/probe.json"),
    "freesn": ("plugins/freesn/configs/library/S6N3-1.1.json",
               "plugins/freesn/configs/library/S6N3-2.1.json"),
    "hinge": (str(HINGE / "chain3.json"), str(HINGE / "chain3-reversed.json")),
}
"""A start and goal per built-in robot (and the example plugin's)."""


def _model(config: Configuration) -> dict:
    """Everything a configuration holds, in order, vectors bit for bit."""
    model = configuration_to_model(config).model_dump(mode="json")
    bits = [(e.id, None if e.z is None else e.z.tobytes(), None if e.x is None else e.x.tobytes())
            for e in config.edges()]
    positions = [(v, None if config.position(v) is None else config.position(v).tobytes())
                 for v in config.vertices()]
    return {**model, "bits": bits, "positions": positions}


def assert_same_plans(again: Plan, plan: Plan) -> None:
    """Identical plans: every target, tree and field."""
    assert (again.robot, again.planner, again.mapping, again.notes, again.stats) == (
        plan.robot, plan.planner, plan.mapping, plan.notes, plan.stats)
    assert _model(again.start) == _model(plan.start)
    assert _model(again.goal) == _model(plan.goal)
    assert len(again.actions) == len(plan.actions)
    for a, b in zip(again.actions, plan.actions, strict=True):
        assert _model(a.target) == _model(b.target), a.label
        assert (a.type, a.modules, a.changes, a.goals, a.cost, a.note, a.behavior, a.reaches,
                a.retrieved) == (b.type, b.modules, b.changes, b.goals, b.cost, b.note,
                                 b.behavior, b.reaches, b.retrieved)
        assert (a.kinematic_tree is None) == (b.kinematic_tree is None)
        if a.kinematic_tree is not None:
            assert a.kinematic_tree.to_dict() == b.kinematic_tree.to_dict()


def assert_docks_read_from_deltas(plan: Plan) -> None:
    """Which changes make and which break a connection, read before any target is built
    (off the targets' deltas where they allow it), equals the links of every built target."""
    fast = [(a.made(), a.broken()) for a in plan.actions]
    for action, (made, broken) in zip(plan.actions, fast, strict=True):
        keys = {key for key, _ in links(action.target)}
        assert made == tuple(c for c in action.changes if c.key in keys), action.label
        assert broken == tuple(c for c in action.changes if c.key not in keys), action.label


def _round_trip(plan: Plan, path: Path) -> Plan:
    save_plan(plan, path)
    again = plugins.load_plan(path)  # validated whole against the robot
    assert_same_plans(again, plan)
    assert_docks_read_from_deltas(plugins.load_plan(path))
    assert_docks_read_from_deltas(plan)
    return again


def _planners() -> list[tuple[str, str]]:
    """Every (robot, planner) installed, but the generic planner for FreeSN (it plans
    vertex modules only and says so)."""
    return [(robot, name) for robot in PAIRS
            for name in plugins.capabilities(robot).planners
            if (robot, name) != ("freesn", "generic")]


@pytest.mark.parametrize("robot, planner", _planners())
def test_every_planner_round_trips_through_its_file(robot: str, planner: str,
                                                   tmp_path: Path) -> None:
    start, goal = (plugins.load_configuration(ROOT / p) for p in PAIRS[robot])
    plan = plugins.planners.get(robot, planner).plan(start, goal, seed=0)
    assert plan.actions
    _round_trip(plan, tmp_path / "plan.json")
    if robot == "freesn" and planner == "library":
        assert any(a.kinematic_tree is not None for a in plan.actions)


@settings(max_examples=8, deadline=None)
@given(n=st.integers(2, 30), seed=st.integers(0, 2**32 - 1))
def test_random_mmrp_plans_round_trip(n: int, seed: int, tmp_path_factory) -> None:
    rng = np.random.default_rng(seed)
    plan = plugins.planners.get("mmrp").plan(random_tree(n, rng), random_tree(n, rng),
                                             seed=seed % 97)
    _round_trip(plan, tmp_path_factory.mktemp("mmrp") / "plan.json")


@settings(max_examples=8, deadline=None)
@given(n=st.integers(2, 30), seed=st.integers(0, 2**32 - 1))
def test_random_freebot_plans_round_trip(n: int, seed: int, tmp_path_factory) -> None:
    rng = np.random.default_rng(seed)
    start, goal = (pointer_configuration("freebot", "freebot",
                                         random_miso_tree(n, rng, max_branching=3), rng)
                   for _ in range(2))
    plan = plugins.planners.get("freebot").plan(start, goal)
    _round_trip(plan, tmp_path_factory.mktemp("freebot") / "plan.json")


def _edit(config: Configuration, rng: np.random.Generator) -> Configuration:
    """``config`` with random connections dropped, vectors and positions changed, edges
    and vertices reordered, a vertex gone or added, and a new name."""
    vertices = config.vertices()
    edges = [e for e in config.edges() if rng.random() > 0.3]
    if rng.random() < 0.5:
        rng.shuffle(edges)
    if rng.random() < 0.5:
        vertices = list(rng.permutation(vertices))
    used = {end for e in edges for end in (e.source, e.target)}
    unused = [v for v in vertices if v not in used]
    if unused and rng.random() < 0.5:
        vertices.remove(unused[0])
    nodes = [(v, config.kind_of(v), rng.normal(size=3) if rng.random() < 0.3 else
              config.position(v)) for v in vertices]
    if rng.random() < 0.5:
        nodes.insert(int(rng.integers(len(nodes) + 1)), ("extra", config.kind_of(
            config.vertices()[0]), None))
    out = Configuration(config.robot, name=f"{config.name}+" if rng.random() < 0.5 else
                        config.name)
    for v, kind, position in nodes:
        out.add_module(v, kind, position=position)
    for e in edges:
        z = e.z if e.z is None or rng.random() < 0.7 else random_unit(rng)
        out.connect(e.source, e.target, id=e.id, kind=e.kind, z=z, x=e.x, ports=e.ports)
    return out


@settings(max_examples=40, deadline=None)
@given(robot=st.sampled_from(["freesn", "freebot", "snailbot", "mmrp"]),
       n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1))
def test_the_changes_between_two_configurations_rebuild_the_second(robot: str, n: int,
                                                                   seed: int) -> None:
    rng = np.random.default_rng(seed)
    before = random_configuration(plugins.robot(robot), plugins.docking_rules(robot), n, rng,
                                  positions=rng.random() < 0.5)
    after = _edit(before, rng)
    delta = difference(before, after)
    draft = Draft(before)
    draft.apply(delta)
    assert _model(draft.build()) == _model(after)
    derived = DerivedConfiguration(before, delta)
    assert difference(before, derived) is delta
    assert _model(derived) == _model(after)
    assert not difference(after, after.copy())


def test_version_1_files_still_load(tmp_path: Path) -> None:
    """Files written before plans stored changes load, validated, and write again as
    version 2 without a change."""
    for path in sorted(V1.glob("*.json")):
        assert json.loads(path.read_text())["schema_version"] == 1
        plan = plugins.load_plan(path)
        assert plan.actions, path
        again = _round_trip(plan, tmp_path / path.name)
        assert json.loads((tmp_path / path.name).read_text())["schema_version"] == 2
        assert again.docks == plan.docks


def test_a_file_holds_changes_not_whole_targets(tmp_path: Path) -> None:
    """A 60-module MMRP plan: its file holds the start whole and then only what changes,
    so it stays within a few times the start's size (version 1 held every target)."""
    rng = np.random.default_rng(5)
    plan = plugins.planners.get("mmrp").plan(random_tree(60, rng), random_tree(60, rng))
    save_plan(plan, tmp_path / "plan.json")
    doc = json.loads((tmp_path / "plan.json").read_text())
    start = len(json.dumps(doc["start"]))
    changes = sum(len(json.dumps(a.get("target", {}))) for a in doc["actions"])
    assert len(plan.actions) > 60 and changes < 2 * start
    assert load_plan(tmp_path / "plan.json").docks == plan.docks
