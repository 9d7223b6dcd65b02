"""MISO planning with places: among pairings of the fewest changes, pieces of one shape go
to the nearer of their interchangeable places (issue 28, item 6)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.configuration import Configuration
from msrr.core.freeform.miso import (
    FREE,
    MisoProblem,
    fragments,
    goal_in_start_frame,
    heuristic_pairing,
    nearer_pairing,
    pairing_score,
    random_cyclic,
    random_forest,
    random_miso_tree,
    targets,
    travel,
)
from msrr.core.io import load_configuration

HUMAN = Path(__file__).resolve().parents[2] / "plugins" / "freebot" / "configs" / "human"
X, Y = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
MX, MY = [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]


def _cross() -> Configuration:
    """A spine G0-G1-G2 along ``+y``; on G1 an arm of two to ``-x`` (G3, G4) and one to
    ``+x`` (G5, G6)."""
    goal = Configuration("freebot", name="cross")
    for k in range(7):
        goal.add_module(f"G{k}", "freebot")
    for source, target, z in (("G1", "G0", MY), ("G2", "G1", MY), ("G3", "G1", X),
                              ("G4", "G3", X), ("G5", "G1", MX), ("G6", "G5", MX)):
        goal.connect(source, target, z=z)
    return goal


def _three_chains(placed: bool) -> Configuration:
    """The spine's chain S0-S1-S2 where the spine goes; the chain of S3 laid 1 m to the
    right, the chain of S5 1 m to the left (positions only when ``placed``)."""
    start = Configuration("freebot", name="three chains")
    at = {"S0": (0.0, 0.0), "S3": (1.0, 0.1), "S5": (-1.0, 0.1)} if placed else {}
    for k in range(7):
        m = f"S{k}"
        start.add_module(m, "freebot", position=[*at[m], 0.05] if m in at else None)
    for source, target, z in (("S1", "S0", MY), ("S2", "S1", MY), ("S4", "S3", MX),
                              ("S6", "S5", X)):
        start.connect(source, target, z=z)
    return start


def test_two_chains_of_one_length_go_to_the_arms_on_their_own_sides():
    """By topology alone the chain of S3 takes the arm of G3 (to ``-x``), the other the
    arm to ``+x``: they cross. With places, each takes the arm on its side; the same
    changes and steps."""
    planner = plugins.planners("freebot")["miso"]
    by_topology = replace(planner, layout=None).plan(_three_chains(True), _cross())
    assert by_topology.mapping["S3"] == "G3"   # the crossing this test is about
    plan = planner.plan(_three_chains(True), _cross())
    assert (plan.mapping["S3"], plan.mapping["S4"]) == ("G5", "G6")
    assert (plan.mapping["S5"], plan.mapping["S6"]) == ("G3", "G4")
    assert plan.mapping["S0"] == "G0"
    for key in ("changes", "steps"):
        assert plan.stats[key] == by_topology.stats[key] == 2
    assert plan.stats["travel_m"] < 0.8 * plan.stats["travel_m_topology"]
    assert plan.stats["module_metres"] < 0.8 * plan.stats["module_metres_topology"]


def test_a_start_without_places_plans_as_by_topology():
    planner = plugins.planners("freebot")["miso"]
    plan = planner.plan(_three_chains(False), _cross())
    same = replace(planner, layout=None).plan(_three_chains(False), _cross())
    assert plan.mapping == same.mapping
    assert [a.note for a in plan.actions] == [a.note for a in same.actions]
    assert plan.stats == {k: v for k, v in same.stats.items() if not k.endswith("_ms")} | {
        k: v for k, v in plan.stats.items() if k.endswith("_ms")}
    assert "travel_m" not in plan.stats


@pytest.mark.parametrize("kind", ["tree", "forest", "cyclic"])
def test_the_nearer_pairing_keeps_every_kept_connection_and_travels_no_farther(kind):
    rng = np.random.default_rng(11)
    draw = {"tree": random_miso_tree, "cyclic": random_cyclic,
            "forest": lambda n, r: random_forest(n, 4, r)}[kind]
    for n in (12, 40, 90):
        problem = MisoProblem.from_parents(random_forest(n, 5, rng), draw(n, rng))
        pair = heuristic_pairing(problem)
        here, there = rng.uniform(-3, 3, (n, 3)), rng.uniform(-3, 3, (n, 3))
        new = nearer_pairing(problem, pair, here, there)
        assert sorted(new) == list(range(n))
        assert pairing_score(problem, new) >= pairing_score(problem, pair)
        moved = goal_in_start_frame(problem, pair, here, there)   # as the pass moves it
        assert travel(new, here, moved) <= travel(pair, here, moved) + 1e-9


def test_fragments_are_the_pieces_joined_by_kept_connections():
    problem = MisoProblem.from_parents((FREE, 0, 1, FREE, 3), (FREE, 0, 1, 2, 3))
    pair = [0, 1, 2, 3, 4]   # 3 -> 2 is made; 4 -> 3 kept
    assert fragments(problem, pair) == [[0, 1, 2], [3, 4]]
    final = targets(problem, pair)
    assert all(final[f[k]] == f[k - 1] for f in fragments(problem, pair)
               for k in range(1, len(f)))


def test_the_human_example_keeps_its_89_changes_and_its_pieces_move_less():
    start = load_configuration(HUMAN / "human-chains-near.json")
    goal = load_configuration(HUMAN / "human.json")
    plan = plugins.planners("freebot")["miso"].plan(start, goal)
    assert (plan.stats["changes"], plan.stats["steps"]) == (89, 47)
    assert plan.stats["module_metres"] < 0.99 * plan.stats["module_metres_topology"]
    assert plan.stats["travel_m"] < plan.stats["travel_m_topology"]


PLAN_WITH_PLACES = """
import sys
import numpy as np
from msrr.core.configuration import Configuration
from msrr.core.freeform.miso import MisoLimits, plan_miso, random_cyclic, random_forest
from msrr.core.plan import save_plan

def config(parent, placed):
    c = Configuration("freebot")
    for i in range(len(parent)):
        c.add_module(f"F{i}", "freebot", position=[0.0, 0.0, 0.05] if placed and not i else None)
    for i, p in enumerate(parent):
        if p >= 0:
            c.connect(f"F{i}", f"F{p}", z=[1.0, 0.0, 0.0])
    return c

def layout(config):
    rng = np.random.default_rng(len(config.edges()))
    return {m: p for m, p in zip(sorted(config.vertices(), key=lambda v: int(v[1:])),
                                 rng.uniform(-3, 3, (len(config.vertices()), 3)))}

n, out = int(sys.argv[1]), sys.argv[2]
rng = np.random.default_rng(n)
start, goal = config(random_forest(n, 6, rng), True), config(random_cyclic(n, rng), False)
save_plan(plan_miso(start, goal, limits=MisoLimits(6, "child"), layout=layout), out)
"""


def test_plans_by_places_are_the_same_under_any_hash_seed(tmp_path):
    plans = []
    for seed in ("1", "2"):
        out = tmp_path / f"{seed}.json"
        subprocess.run([sys.executable, "-c", PLAN_WITH_PLACES, "250", str(out)], check=True,
                       env={**os.environ, "PYTHONHASHSEED": seed}, timeout=300)
        plan = json.loads(out.read_text())
        plan["stats"] = {k: v for k, v in plan["stats"].items() if not k.endswith("_ms")}
        plans.append(plan)
    assert plans[0] == plans[1]
    assert plans[0]["stats"]["module_metres"] < plans[0]["stats"]["module_metres_topology"]


def test_a_start_the_world_cannot_lay_is_paired_by_topology_and_says_so():
    start = _three_chains(True)
    overlapping = Configuration("freebot", name="overlapping")
    for m in start.vertices():   # the chain of S5 laid over the chain of S3
        at = {"S0": (0.0, 0.0), "S3": (1.0, 0.1), "S5": (1.05, 0.1)}.get(m)
        overlapping.add_module(m, "freebot", position=[*at, 0.05] if at else None)
    for e in start.edges():
        overlapping.connect(e.source, e.target, z=e.z)
    planner = plugins.planners("freebot")["miso"]
    plan = planner.plan(overlapping, _cross())
    assert plan.mapping == replace(planner, layout=None).plan(overlapping, _cross()).mapping
    assert any("topology only" in note and "overlap" in note for note in plan.notes)
    assert "travel_m" not in plan.stats
