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
    MisoLimits,
    MisoProblem,
    fragments,
    goal_in_start_frame,
    heuristic_pairing,
    nearer_pairing,
    pairing_score,
    random_cyclic,
    random_forest,
    random_miso_tree,
    riding_ways,
    targets,
    travel,
)
from msrr.core.freeform.piece_way import piece_way
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
    """The pieces travel less than by topology, and the order leaves every way open; that
    order makes F301's piece carry F326's 15 (F326 waits for the lower ribs, and its
    target F133 has not arrived), so the module-metres are no longer below topology's
    (F326's 15 turn with F301's piece: 3,127 module-metres with riders shifted, 3,150
    held as the plan holds them, topology 3,111)."""
    start = load_configuration(HUMAN / "human-chains-near.json")
    goal = load_configuration(HUMAN / "human.json")
    plan = plugins.planners("freebot")["miso"].plan(start, goal)
    assert (plan.stats["changes"], plan.stats["steps"]) == (89, 47)
    assert plan.stats["travel_m"] < 0.97 * plan.stats["travel_m_topology"]
    assert plan.stats["module_metres"] < 1.02 * plan.stats["module_metres_topology"]
    assert (plan.stats["closed_ways_topology"], plan.stats["closed_ways"]) == (13, 0)


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


OUT_66 = [float(np.cos(np.radians(-66.0))), float(np.sin(np.radians(-66.0))), 0.0]


def _pocket(prefix: str, placed: bool) -> Configuration:
    """A spine ``{prefix}S0``..``S6`` along ``+x`` (its root S3); in the goal a rib of four,
    ``A``, straight down (``-y``) from S5 and a rib of nine, ``B``, leaving S2 at -66 deg,
    which passes 0.25 m below A's end, across the stretch A slides in along; at the start
    both ribs lie apart to the right, upright (positions only when ``placed``)."""
    c = Configuration("freebot", name="pocket start" if placed else "pocket")
    at = {"S0": (0.0, 0.0), "A0": (1.3, -0.3), "B0": (1.7, -0.3)}
    for name, n in (("S", 7), ("A", 4), ("B", 9)):
        for k in range(n):
            m = f"{name}{k}"
            c.add_module(prefix + m, "freebot",
                         position=[*at[m], 0.05] if placed and m in at else None)
    into = Y if placed else [-v for v in OUT_66]
    links = [(f"S{k}", f"S{k + 1}", X) for k in range(3)] \
        + [(f"S{k}", f"S{k - 1}", MX) for k in range(4, 7)] \
        + [(f"A{k + 1}", f"A{k}", Y) for k in range(3)] \
        + [(f"B{k + 1}", f"B{k}", into) for k in range(8)]
    if not placed:
        links += [("A0", "S5", Y), ("B0", "S2", into)]
    for source, target, z in links:
        c.connect(prefix + source, prefix + target, z=z)
    return c


def test_a_piece_docks_before_one_whose_docked_body_would_close_its_way_in():
    """By goal depth B (on S2) docks before A (on S5); docked, B crosses the stretch A
    must slide in along, and A finds no way to its goal place (on the floor, below). With
    the places the order docks A first; the same changes and steps."""
    start, goal = _pocket("", True), _pocket("G", False)
    planner = plugins.planners("freebot")["miso"]
    plans = {"topology": replace(planner, layout=None).plan(start, goal),
             "places": planner.plan(start, goal)}
    docks = {k: [a.note.split()[1] for a in p.actions if a.changes] for k, p in plans.items()}
    assert docks["topology"] == ["B0:", "A0:"]     # the order this test is about
    assert docks["places"] == ["A0:", "B0:"]
    for key in ("changes", "steps"):
        assert plans["places"].stats[key] == plans["topology"].stats[key] == 2
    assert (plans["places"].stats["closed_ways_topology"],
            plans["places"].stats["closed_ways"]) == (1, 0)
    # on the floor: A's way from where it lies, B at its start place or docked
    here = {m: np.asarray(p)[:2] for m, p in planner.layout(start).items()}
    laid = planner.layout(goal)
    shift = np.append(here["S0"] - np.asarray(laid["GS0"])[:2], 0.0)
    goal_here = {m: np.asarray(laid[g]) + shift for m, g in plans["places"].mapping.items()}
    spine, rib_b = {f"S{k}" for k in range(7)}, {f"B{k}" for k in range(9)}
    ways = {}
    for b_docked in (False, True):
        pos = dict(here) | ({m: goal_here[m][:2] for m in rib_b} if b_docked else {})
        ways[b_docked] = piece_way(pos, {f"A{k}" for k in range(4)},
                                   spine | (rib_b if b_docked else set()), "A0", 0.0, "S5",
                                   goal_here, 0.101)
    assert ways[False].at_goal
    assert not ways[True].at_goal


def test_a_piece_waits_while_a_rider_lies_across_its_way_until_the_rider_has_left():
    """C0-C1 docks on S1 (a rib down) carrying its riders R0-R1, whose target E1 comes
    with E's piece; held as they rode, the riders lie on A's goal place (A docks on U3
    along +x under C's rib). By goal depth A docked next, onto the riders (stop 53); at
    stop 54 A waited until they had left for E1; now C waits too, and the riders leave
    for E1 from where C lies, before C moves (the same changes and steps)."""
    # C's riders: held as they rode, on A's goal place; C docks first all the same (A's
    # docked body would close C's way in)
    from msrr.core.freeform.miso.planner import _floor_order, _solution

    s = 0.101
    names = ["S0", "S1", "U1", "U2", "U3", "C0", "C1", "A0", "A1", "A2", "R0", "R1", "E0",
             "E1"]
    start = [FREE, 0, 0, 2, 3, FREE, 5, FREE, 7, 8, 6, 10, FREE, 12]
    goal = [FREE, 0, 0, 2, 3, 1, 5, 4, 7, 8, 13, 10, 2, 12]
    corner = [(0, 0), (s, 0), (0, -s), (0, -2 * s), (0, -3 * s)]
    here = corner + [(0.5 + s * k, 0.5) for k in range(2)] + [
        (0.5 + s * k, -0.8) for k in range(3)] + [(0.5 + s * k, 0.5) for k in (2, 3)] + [
        (-0.5 - s * k, 0.5) for k in range(2)]
    there = corner + [(s, -s), (s, -2 * s)] + [(s * k, -3 * s) for k in (1, 2, 3)] + [
        (-3 * s, -s), (-4 * s, -s), (-s, -s), (-2 * s, -s)]
    problem = MisoProblem.from_parents(start, goal, plugins.planners("freebot")["miso"].limits)
    pair = list(range(len(names)))
    here3, there3 = (np.array([[x, y, 0.05] for x, y in p]) for p in (here, there))
    solution = _floor_order(_solution(problem, pair, 0.0), problem, here3, there3)
    moved = [names[step.module] for step in solution.steps]
    assert moved == ["E0", "R0", "C0", "A0"]      # stop 53: C0, E0, A0, R0; 54: C0, E0, R0, A0
    ride = riding_ways(problem, pair, here3, there3)[5][10]   # C0's rider R0
    assert ride.bodies == ride.ways == {7}                    # on A0's goal body
    assert (solution.changes, solution.cost) == (5, 4)


# A carrier C0-C1 with its rider R (on C1, its target E1 in E's piece, which docks later)
# and another piece A0-A1; S, U and T stay. ``closes``: R's docked body would close A's
# way in. Scenes of the order alone: the riders' places are given (as ``riding_ways``
# gives them from the floor).
_S, _C0, _C1, _R, _A0, _A1, _E0, _E1 = range(8)
_RIDER_START = [FREE, FREE, _C0, _C1, FREE, _A0, FREE, _E0]
_RIDER_GOAL = [FREE, _S, _C0, _E1, _S, _A0, _S, _E0]


def _moved(riding: dict) -> list[int]:
    from msrr.core.freeform.miso import order_steps

    steps = order_steps(_RIDER_START, _RIDER_GOAL, limits=MisoLimits(max_in=6),
                        closes={_R: {_A0}}, riding=riding)
    return [s.module for s in steps]


def test_a_carrier_whose_rider_would_lie_on_a_piece_docks_after_its_rider_has_left():
    """R, carried by C, would lie on A's docked body; R docks after A (its body would
    close A's way). By goal depth C docked first and A then docked onto R; now A docks
    first, then E (R's target), R leaves from where C lies, and C docks last."""
    from msrr.core.freeform.miso import Ride

    ride = Ride(ways=frozenset({_A0}), bodies=frozenset({_A0}))
    assert _moved({_C0: {_R: ride}}) == [_A0, _E0, _R, _C0]   # before: C0, E0, A0, R


def test_a_carrier_whose_rider_would_cross_a_piece_s_way_docks_once_that_piece_is_in():
    """R, carried by C, would lie across A's way in (not on its body): C waits until A
    has docked, then brings R over A's spent way; R leaves after E docks."""
    from msrr.core.freeform.miso import Ride

    ride = Ride(ways=frozenset({_A0}), bodies=frozenset())
    assert _moved({_C0: {_R: ride}}) == [_A0, _C0, _E0, _R]   # before: C0, E0, A0, R


def test_an_order_that_cannot_keep_a_rider_clear_is_refused_naming_the_step():
    """One connection a module (``max_in`` 1): C0 must leave U before A0 can dock there;
    R, on C, lies on A's way and can leave only for T, which A0 holds until it moves. C
    first, then every legal move would dock A across R: refused, naming step 2."""
    from msrr.core.errors import PlanningError
    from msrr.core.freeform.miso import Ride, order_steps

    s, u, t, c0, c1, r, a0, a1 = range(8)
    start = [FREE, FREE, FREE, u, c0, c1, t, a0]
    goal = [FREE, FREE, FREE, s, c0, t, u, a0]
    riding = {c0: {r: Ride(ways=frozenset({a0}), bodies=frozenset())}}
    with pytest.raises(PlanningError, match=r"riders clear: at step 2 .* 6 would dock "
                                            r"across 5, which rides 3") as refused:
        order_steps(start, goal, limits=MisoLimits(max_in=1), riding=riding)
    names = ["S", "U", "T", "C0", "C1", "R", "A0", "A1"]
    assert refused.value.describe(names.__getitem__).endswith(   # as the plan says it
        "first A0 would dock across R, which rides C0 until its own step")
    assert len(order_steps(start, goal, limits=MisoLimits(max_in=1))) == 3   # by depth


def test_a_rider_on_a_carrier_that_turns_is_estimated_where_the_plan_puts_it():
    """C0-C1 lies along +x with its rider R beyond C1; C docks on S along +y and R's
    target comes with E (later). The plan holds R on C's line (its vector turned with
    C1's); the travel estimate lays it there too, the piece turned a quarter turn."""
    from msrr.core.freeform.miso import hold, order_steps, step_travel

    s = 0.101
    names = ["S", "C0", "C1", "R", "E0", "E1"]
    start, goal = [FREE, FREE, 1, 2, FREE, 4], [FREE, 0, 1, 5, 0, 4]
    here = np.array([[0, 1], [0, 0], [s, 0], [2 * s, 0], [-1, -1], [-1 - s, -1]])
    there = np.array([[0, 1], [0, 1 + s], [0, 1 + 2 * s], [-3 * s, 1], [-s, 1],
                      [-2 * s, 1]])
    here3, there3 = (np.column_stack([p, np.full(6, 0.05)]) for p in (here, there))
    problem = MisoProblem.from_parents(start, goal, MisoLimits(max_in=6))
    steps = order_steps(start, goal, limits=problem.limits)
    assert [(names[x.module], x.old) for x in steps][0] == ("C0", FREE)   # R rides
    n, travel_m = step_travel(problem, list(range(6)), steps, here3, there3)[0]
    assert n == 3     # before: R shifted with C1 to (s, 1 + 2s), off C's line
    assert travel_m == pytest.approx(np.hypot(s, 1 + 2 * s) + s * np.pi / 2)
    # the plan's vector of R on C1 after that step (``_carry``), and the estimate's R
    from msrr.core.freeform.miso.planner import _carry

    after = [FREE, 0, 1, 2, FREE, 4]
    vectors = {(1, 0): np.array(MY), (2, 1): np.array(MX), (3, 2): np.array(MX),
               (5, 4): np.array(X)}
    _carry(after, 1, FREE, vectors, {(1, 0): np.array(MY), (2, 1): np.array(MY)})
    piece, places = hold(here3, after, [[1], [2], [3], [], [5], []], goal, there3, 1, FREE)
    at = dict(zip(piece, places, strict=True))
    assert np.allclose(at[3], at[2] - s * vectors[(3, 2)])
    assert np.allclose(at[3], [0, 1 + 3 * s, 0.05])
