"""Issue 29: the swept area of turning and driving groups, in the router and the checker
(item 1), and groups driving at once (item 2), against an independent reference (the
true square bodies, densely sampled)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core.plan import Action, ActionType, ConnectionChange, Plan
from msrr.plugins.mmrp.check import check_plan
from msrr.plugins.mmrp.motion import (
    CHORD_SAG,
    Arc,
    apart,
    blocked,
    drive_paths,
    leg_paths,
    segments_distance,
    sweep,
    turn_paths,
)
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.random_trees import random_tree
from msrr.plugins.mmrp.representation import from_links, grid_cells
from msrr.plugins.mmrp.robot import MODULE
from msrr.plugins.mmrp.routing import route_groups
from msrr.plugins.mmrp.sim.controller import (
    DRIVE_GAIN,
    MIN_DRIVE_SPEED,
    TURN_GAIN,
    settling_time,
)

HALF = MODULE.geometry["length"] / 2 / MODULE.geometry["pitch"]  # half a body side [cells]


def _corners(x: float, y: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([(x + c * u - s * v, y + s * u + c * v)
                     for u, v in ((HALF, HALF), (-HALF, HALF), (-HALF, -HALF), (HALF, -HALF))])


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating axis test of two convex quadrilaterals."""
    for poly in (a, b):
        for k in range(4):
            edge = poly[(k + 1) % 4] - poly[k]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = a @ axis, b @ axis
            if pa.max() < pb.min() - 1e-9 or pb.max() < pa.min() - 1e-9:
                return False
    return True


def _bodies_along(cells: list[tuple[int, int]], shift: tuple[int, int], samples: int = 60):
    """The true module bodies (squares) at ``samples`` instants of every motion of a leg."""
    cx = sum(c[0] for c in cells) / len(cells)
    cy = sum(c[1] for c in cells) / len(cells)
    dx, dy = shift
    if not dy:
        for k in range(samples + 1):
            t = k / samples
            yield [_corners(x + t * dx, y, 0.0) for x, y in cells]
        return
    for phase in range(3):
        for k in range(samples + 1):
            t = k / samples
            yaw = math.pi / 2 * (t if phase == 0 else 1 - t if phase == 2 else 1)
            shift_y = dy * (0 if phase == 0 else t if phase == 1 else 1)
            c, s = math.cos(yaw), math.sin(yaw)
            yield [_corners(cx + c * (x - cx) - s * (y - cy),
                            cy + shift_y + s * (x - cx) + c * (y - cy), yaw) for x, y in cells]


@settings(max_examples=8, deadline=None)
@given(n=st.integers(2, 6), seed=st.integers(0, 10_000), axis=st.sampled_from(["x", "y"]),
       length=st.integers(1, 2))
def test_cells_outside_the_sweep_are_never_touched_by_a_body(n, seed, axis, length):
    cells = list(grid_cells(random_tree(n, np.random.default_rng(seed))).values())
    shift = (length, 0) if axis == "x" else (0, length)
    sweep = blocked(leg_paths(cells, shift))
    xs = [c[0] for c in cells]
    ys = [c[1] for c in cells]
    reach = max(max(xs) - min(xs), max(ys) - min(ys)) + 2
    outside = [(i, j) for i in range(min(xs) - reach, max(xs) + reach + 1)
               for j in range(min(ys) - reach, max(ys) + reach + length + 1)
               if (i, j) not in sweep]
    squares = {c: _corners(c[0], c[1], 0.0) for c in outside}
    for bodies in _bodies_along(cells, shift, samples=16):
        for body in bodies:
            bx, by = body.mean(axis=0)
            for c, square in squares.items():
                if abs(c[0] - bx) < 1 and abs(c[1] - by) < 1:  # farther never touches
                    assert not _overlap(square, body), (cells, shift, c)


def test_a_long_group_turning_sweeps_beyond_its_translation():
    bar = [(i, 0) for i in range(7)]
    turn = blocked(turn_paths(bar))
    assert (3, 3) in turn and (6, 2) in turn  # a quarter of the disc around the centre
    assert blocked(drive_paths(bar, (1, 0), rotated=False)) == {(i, 0) for i in range(8)}


def test_the_router_turns_a_long_group_clear_of_a_neighbour():
    # a 5-module bar moves up by 4; a module stands where the bar's turn would sweep
    bar = [f"b{i}" for i in range(5)]
    start = {m: (i, 0) for i, m in enumerate(bar)} | {"x": (1, 2)}
    goal = {m: (i, 4) for i, m in enumerate(bar)} | {"x": (1, 2)}
    routing = route_groups([bar, ["x"]], start, goal, links=[frozenset(p) for p in
                                                              zip(bar, bar[1:], strict=False)])
    where = dict(start)
    for route in routing.routes:
        cells = [where[m] for m in route.modules]
        for a, b in zip(route.corners, route.corners[1:], strict=False):
            shift = (b[0] - a[0], b[1] - a[1])
            others = {c for m, c in where.items() if m not in route.modules}
            assert not others & blocked(leg_paths(cells, shift))
            cells = [(c[0] + shift[0], c[1] + shift[1]) for c in cells]
        for m, c in zip(route.modules, cells, strict=True):
            where[m] = c
    assert where == goal


def test_the_checker_finds_a_turn_that_a_translation_check_passes():
    # a bar of five (0..4, 0) with x docked on the left of its middle; x steps up one cell
    # to (2, 2), then the bar drives down three cells: its cells below are free (the
    # translation check of issue 17 passed this), but turning a quarter about its centre
    # (2, 0) swings b4 through (2, 2)
    bar = [f"b{i}" for i in range(5)]
    links = [(u, "T", v, "B") for u, v in zip(bar, bar[1:], strict=False)]
    start = from_links([*bar, "x"], [*links, ("b2", "L", "x", "R")])
    loose = from_links([*bar, "x"], links)
    p = MODULE.geometry["pitch"]
    undock = Action(ActionType.DISCONNECTION, loose, modules=("x", "b2"),
                    changes=(ConnectionChange("x", "b2", "R", "L", start.edges()[-1].id),))
    lay = grid_cells(start)
    here = {m: (c[0] * p, c[1] * p) for m, c in lay.items()}

    def move(modules, dx, dy):
        for m in modules:
            here[m] = (here[m][0] + dx * p, here[m][1] + dy * p)
        return Action(ActionType.MOVING, loose, modules=tuple(modules),
                      goals={m: [*here[m], 0.0] for m in modules})

    plan = Plan("mmrp", "hand", start, loose, [undock, move(["x"], 0, 1), move(bar, 0, -3)])
    problems = check_plan(plan)
    assert len(problems) == 1 and "action 3" in problems[0] and "turning" in problems[0]
    for m in bar:  # a drive along x instead sweeps only the bar's row
        here[m] = (here[m][0], here[m][1] + 3 * p)
    plan.actions[2] = move(bar, -6, 0)
    assert check_plan(plan) == []


def _touch(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    """Whether any body of one set overlaps any body of the other."""
    return any(np.abs(x.mean(axis=0) - y.mean(axis=0)).max() < 1 and _overlap(x, y)
               for x in a for y in b)


@settings(max_examples=12, deadline=None)
@given(n=st.integers(1, 4), m=st.integers(1, 4), seed=st.integers(0, 10_000),
       dx=st.integers(-4, 4), dy=st.integers(-4, 4), axes=st.sampled_from(["xx", "xy", "yy"]))
def test_groups_apart_never_touch_in_any_timing(n, m, seed, dx, dy, axes):
    """The reference: every instant of one leg against every instant of the other."""
    rng = np.random.default_rng(seed)
    a = list(grid_cells(random_tree(n, rng)).values())
    b = [(x + dx, y + dy) for x, y in grid_cells(random_tree(m, rng)).values()]
    if set(a) & set(b):
        return
    shift_a = (2, 0) if axes[0] == "x" else (0, 2)
    shift_b = (-1, 0) if axes[1] == "x" else (0, -1)
    if not apart(sweep(leg_paths(a, shift_a)), sweep(leg_paths(b, shift_b))):
        return
    instants_a = [body for bodies in _bodies_along(a, shift_a, 12) for body in bodies]
    instants_b = [body for bodies in _bodies_along(b, shift_b, 12) for body in bodies]
    assert not _touch(instants_a, instants_b), (a, shift_a, b, shift_b)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 4), m=st.integers(1, 4))
def test_segment_distance_is_the_distance_of_their_densest_samples(seed, n, m):
    """The reference: both sets of segments sampled at 401 points each (a crossing
    included: then the samples come within a sampling gap of each other)."""
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-3, 3, (n, 2, 2)), rng.uniform(-3, 3, (m, 2, 2))
    t = np.linspace(0.0, 1.0, 401)[:, None]
    pa = np.concatenate([s[0] + t * (s[1] - s[0]) for s in a])
    pb = np.concatenate([s[0] + t * (s[1] - s[0]) for s in b])
    sampled = np.linalg.norm(pa[:, None] - pb[None], axis=-1).min()
    gap = max(np.linalg.norm(s[1] - s[0]) for s in [*a, *b]) / 400
    exact = segments_distance(a, b)
    assert exact - 1e-9 <= sampled <= exact + gap


def test_a_turn_is_cut_into_chords_within_its_slack():
    path = sweep(leg_paths([(0, 0), (4, 0), (4, 3)], (0, 2)))  # turns of radius up to 2.4
    assert 0 < path.slack <= CHORD_SAG
    for arc in [a for a in leg_paths([(0, 0), (4, 0), (4, 3)], (0, 2)) if isinstance(a, Arc)]:
        (px, py), (sx, sy), sign = arc
        r = math.hypot(sx - px, sy - py)
        angles = math.atan2(sy - py, sx - px) + sign * np.linspace(0, math.pi / 2, 500)
        points = np.column_stack([px + r * np.cos(angles), py + r * np.sin(angles)])
        farthest = max(segments_distance(np.array([[q, q]]), path.segments) for q in points)
        assert farthest <= path.slack + 1e-9


def test_apart_is_not_vacuous():
    one = sweep(leg_paths([(0, 0)], (3, 0)))
    assert apart(one, sweep(leg_paths([(0, 2)], (3, 0))))
    assert not apart(one, sweep(leg_paths([(3, 1)], (0, -3))))  # crossing paths
    # a turning bar of five swings two cells out: a module driving two rows up is hit
    bar = sweep(leg_paths([(i, 0) for i in range(5)], (0, 1)))
    assert not apart(bar, sweep(leg_paths([(-3, 2)], (8, 0))))
    assert apart(bar, sweep(leg_paths([(-3, 5)], (8, 0))))  # its end turn reaches row 3


def test_random_plans_pack_legs_into_checked_waves():
    rng = np.random.default_rng(7)
    merged = legs = 0
    for _ in range(3):
        plan = plan_hybrid(random_tree(30, rng), random_tree(30, rng)).plan
        assert check_plan(plan) == []
        moves = [a for a in plan.actions if a.type is ActionType.MOVING]
        merged += len(moves)
        legs += sum(a.note.count("(leg ") for a in moves)
    assert merged < legs * 0.75  # legs of different groups do run at once


def test_the_checker_refuses_two_groups_crossing_at_once():
    # a chain a-b-c along x, undocked; c steps up two cells; then a drives up three
    # while c drives left along row 2 (through a's column): their paths cross
    start = from_links(["a", "b", "c"], [("a", "T", "b", "B"), ("b", "T", "c", "B")])
    loose = from_links(["a", "b", "c"], [])
    p = MODULE.geometry["pitch"]
    cells = grid_cells(start)
    (ax, ay), (cx, cy) = cells["a"], cells["c"]
    undocks = [Action(ActionType.DISCONNECTION, from_links(["a", "b", "c"], links),
                      modules=(e.source, e.target),
                      changes=(ConnectionChange(e.source, e.target, *e.ports, e.id),))
               for e, links in zip(start.edges(), ([("b", "T", "c", "B")], []), strict=True)]

    def move(goals):
        return Action(ActionType.MOVING, loose, modules=tuple(goals),
                      goals={m: [x * p, y * p, 0.0] for m, (x, y) in goals.items()})

    up = move({"c": (cx, cy + 2)})
    apart_legs = move({"a": (ax, ay + 3), "c": (cx + 1, cy + 2)})
    assert check_plan(Plan("mmrp", "hand", start, loose, [*undocks, up, apart_legs])) == []
    crossing = move({"a": (ax, ay + 3), "c": (ax - 2, cy + 2)})
    problems = check_plan(Plan("mmrp", "hand", start, loose, [*undocks, up, crossing]))
    assert len(problems) == 1 and "move at once within reach" in problems[0]


def test_a_long_leg_stays_one_action_and_its_controller_asks_for_its_drive_time():
    """A leg across the field is one moving action (the plan file stays small); the
    controller's ``begin`` says how long the group's drive takes at cruise speed and
    turn rate, so the executor does not cut it short (its timeout is slack on top)."""
    from msrr.core.driver import Observation, Pose
    from msrr.core.events import Phase
    from msrr.plugins.mmrp.schedule import concurrent_moves
    from msrr.plugins.mmrp.sim.controller import MmrpController

    start = from_links(["a", "b"], [("a", "T", "b", "B")])
    loose = from_links(["a", "b"], [])
    p = MODULE.geometry["pitch"]
    cells = grid_cells(start)
    undock = Action(ActionType.DISCONNECTION, loose, modules=("a", "b"),
                    changes=(ConnectionChange("a", "b", "T", "B", start.edges()[0].id),))
    far = 45  # cells: 13.5 m, about 110 s at 0.12 m/s
    (ax, ay), (bx, by) = cells["a"], cells["b"]
    legs = [Action(ActionType.MOVING, loose, modules=("a",),
                   goals={"a": [(ax - far) * p, ay * p, 0.0]}),  # a far back along x
            Action(ActionType.MOVING, loose, modules=("b",),
                   goals={"b": [bx * p, (by + far) * p, 0.0]})]  # b far up along y
    actions = concurrent_moves([undock, *legs], cells, p)
    assert [a.type for a in actions] == [ActionType.DISCONNECTION, ActionType.MOVING]
    assert actions[1].goals == {"a": legs[0].goals["a"], "b": legs[1].goals["b"]}  # at once
    assert check_plan(Plan("mmrp", "hand", start, loose, actions)) == []

    controller = MmrpController()
    here = Observation(0.0, {"a": {}, "b": {}},
                       {m: Pose.planar(x * p, y * p, 0.0) for m, (x, y) in cells.items()})
    needed = controller.begin(legs[1], Phase.MOVE, here)
    # b turns a quarter, drives, turns back: each under its bounded proportional law
    turn = settling_time(math.pi / 2, TURN_GAIN, controller.turn_rate, controller.yaw_tolerance)
    drive = settling_time(far * p, DRIVE_GAIN, controller.speed, controller.tolerance,
                          MIN_DRIVE_SPEED)
    assert needed == pytest.approx(drive + 2 * turn, rel=1e-6)
    assert far * p / controller.speed < drive < far * p / controller.speed + 5.0


@settings(max_examples=60, deadline=None)
@given(distance=st.floats(0.0, 3.0), gain=st.floats(0.5, 3.0), limit=st.floats(0.05, 1.0),
       tolerance=st.floats(0.002, 0.02), floor=st.sampled_from([0.0, 0.01, 0.03]))
def test_settling_time_is_the_time_its_law_takes_integrated(distance, gain, limit, tolerance,
                                                           floor):
    x, t, dt = distance, 0.0, 1e-3
    while x > tolerance:
        x -= min(limit, max(gain * x, floor)) * dt
        t += dt
    assert settling_time(distance, gain, limit, tolerance, floor) == pytest.approx(
        t, abs=3 * dt + 2e-3 * t)
