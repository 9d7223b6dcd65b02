"""Iterative IK: tracking with warm starts, and hand-over from the exploration."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from kin_helpers import GimbalJoint, TwistJoint, random_stick, stick_tree, yawed

from msrr.core import Configuration
from msrr.core.alignment import align_yaw, rot_z
from msrr.core.kinematics import FixedNode, IKOptions, IKTracker, KinematicTree, forward
from msrr.core.kinematics.tracker import held_yaw, pinned_edges
from msrr.core.plugins import robot


def test_tracking_follows_a_robot_that_moves_towards_the_target():
    config = random_stick(10, 4, free=1)
    tree = stick_tree(config)
    target = yawed(forward(tree, config, np.random.default_rng(4).normal(size=tree.dim) * 0.3
                           ).configuration, 0.7)
    current = config
    with IKTracker(tree, target, IKOptions(seed=1), tick_budget=None, explore=False) as tracker:
        first = tracker.step(current)
        assert first.success
        costs = []
        for _ in range(12):   # the robot executes a third of the solution per tick
            solution = tracker.step(current)
            assert solution.success and solution.restarts == 0
            costs.append(solution.motion_cost)
            current = forward(tree, current, solution.sigma / 3).configuration
    assert costs[-1] < 0.05 * costs[0]              # less and less left to do
    assert solution.rms_angle < np.deg2rad(0.5)


def _star(azimuths: list[float]) -> Configuration:
    """A hub H0 with level rods R1.. to hubs H1.. at ``azimuths`` [deg]; x up."""
    config = Configuration("stick", name="star")
    config.add_module("H0", "hub")
    for i, a in enumerate(np.radians(azimuths)):
        config.add_module(f"H{i + 1}", "hub")
        config.connect("H0", f"H{i + 1}", id=f"R{i + 1}", kind="rod",
                       z=[np.cos(a), np.sin(a), 0.0], x=[0.0, 0.0, 1.0])
    return config


def test_tracking_does_not_turn_the_body_along_the_free_yaw():
    """The root holds no rod, so turning every joint about the vertical with the yaw is
    free in eq. 6 but for the motion cost. The robot carries out part of each command
    while its frame turns (a root node's shell spinning, a slip): the commands must not
    turn the body after that frame. With the yaw free (the last ``sigma`` repeating the
    motion already carried out) they turned it by 1 deg at the first step, 19 deg after
    30."""
    config = _star([0.0, 120.0, 240.0])
    target = yawed(_star([0.0, 100.0, 260.0]), 0.7)     # the shape changes by 20 deg
    tree = stick_tree(config)
    assert not tree.nodes[0].edges                      # the root holds no rod
    ids = list(tree.edges)
    for share, spin in ((1 / 3, 2.0), (0.2, 5.0), (0.5, -3.0)):
        current = config
        with IKTracker(tree, target, IKOptions(seed=1), tick_budget=None,
                       explore=False) as tracker:
            for _ in range(30):
                solution = tracker.step(current)
                assert solution.success
                # the net turn about the vertical the command asks of the body
                turn = align_yaw(solution.configuration.vectors(ids), current.vectors(ids))
                assert abs(np.degrees(turn.theta)) < 0.5, (share, spin)
                current = yawed(forward(tree, current, share * solution.sigma).configuration,
                                np.radians(spin))
        assert solution.rms_angle < np.deg2rad(0.5)


def test_the_held_yaw_is_the_roots_where_its_edges_pin_it():
    """A root rod cannot move, so a solution has its yaw: the held yaw is that rod's,
    whatever the others ask; without a root rod it is eq. 8 over every rod."""
    config = _star([0.0, 120.0, 240.0])
    target = yawed(_star([0.0, 100.0, 240.0]), 0.7)   # only R2 moves
    rooted = KinematicTree(config, [FixedNode(["R1"], ["H0", "H1"]),
                                    GimbalJoint(["R2"], ["H2"]), GimbalJoint(["R3"], ["H3"])])
    assert held_yaw(rooted, config, target, IKOptions(), near=0.0) == pytest.approx(-0.7, abs=1e-3)
    free = stick_tree(config)
    everything = align_yaw(config.vectors(free.edges), target.vectors(free.edges)).theta
    assert held_yaw(free, config, target, IKOptions(), near=0.0) == pytest.approx(everything)
    assert abs(everything + 0.7) > 0.05      # the two differ: the root's rod decides


def _twist_rooted(config: Configuration) -> KinematicTree:
    """The star with a root that holds no rod, R1 on a twist joint (its rod never moves)."""
    return KinematicTree(config, [FixedNode([], ["H0"]), TwistJoint(["R1"], ["H1"]),
                                  GimbalJoint(["R2"], ["H2"]), GimbalJoint(["R3"], ["H3"])])


def test_the_held_yaw_is_that_of_the_rods_no_joint_moves():
    """A rod whose joint only turns what hangs beyond it (a twist about the rod; a
    SnailBot crawling on a substrate the tree reaches through it) cannot move in the
    root's frame either, though the root does not hold it: the held yaw is its own. With
    eq. 8 over every rod instead, R1 stayed 7 deg from its target and the step's residual
    all fell on it (SnailBot pieces-to-tree's final move, B6-B7, broke under noise)."""
    config = _star([0.0, 120.0, 240.0])
    target = yawed(_star([0.0, 100.0, 240.0]), 0.7)   # only R2 moves
    tree = _twist_rooted(config)
    assert pinned_edges(tree, config) == ("R1",)
    assert pinned_edges(stick_tree(config), config) == ()
    assert held_yaw(tree, config, target, IKOptions(), near=0.0) == pytest.approx(-0.7, abs=1e-3)
    with IKTracker(tree, target, IKOptions(seed=1), tick_budget=None, explore=False) as tracker:
        tracker.step(config)
        solution = tracker.step(config)      # a tracking step: the yaw held
    assert solution.rms_angle < np.deg2rad(0.5)
    assert solution.yaw == pytest.approx(-0.7, abs=1e-3)


def _azimuth(config: Configuration, rod: str) -> float:
    z = config.edge(rod).z
    return float(np.degrees(np.arctan2(z[1], z[0])))


def _lagging_tracking(median: bool, ticks: int = 10) -> float:
    """How far [deg] the star's R1 turns over ``ticks`` tracking steps (after the first
    solve) toward a goal in which R2 swings 20 deg, the robot carrying out every command
    but R2's swing: R2 keeps its angle to R1 (a chain dragged over the floor lags)."""
    config = _star([0.0, 120.0, 240.0])
    target = yawed(_star([0.0, 100.0, 240.0]), 0.7)    # only R2 moves
    tree = stick_tree(config)
    current, turned = config, []
    with IKTracker(tree, target, IKOptions(seed=1), tick_budget=None, explore=False,
                   median_yaw=median) as tracker:
        for _ in range(ticks + 1):
            moved = forward(tree, current, tracker.step(current).sigma).configuration
            lag = np.radians(_azimuth(current, "R2") - _azimuth(current, "R1"))
            r2 = rot_z(lag) @ moved.edge("R1").z
            current = moved.with_vectors(z={e.id: e.z for e in moved.edges()} | {"R2": r2},
                                         x={e.id: e.x for e in moved.edges()})
            turned.append(_azimuth(current, "R1"))
    return turned[-1] - turned[0]


def test_a_median_held_yaw_stays_with_the_rods_in_place_while_one_lags():
    """Eq. 8 again on every tick's configuration: a rod that lags its goal pulls the held
    yaw toward it each tick, and the rods in place are told to turn by that pull each tick,
    without end (FreeBOT chains-to-tree's final move turned its tree -85 deg in 2 s, one
    chain 9 deg short of its goal, until F3-F4 broke). The median of the rods' turns stays
    with the rods in place; the freeform robots hold it (FreeSN keeps eq. 8)."""
    config = _star([0.0, 120.0, 240.0])
    target = yawed(_star([0.0, 100.0, 240.0]), 0.7)
    free = stick_tree(config)
    assert held_yaw(free, config, target, IKOptions(), near=0.0,
                    median=True) == pytest.approx(-0.7)
    assert abs(_lagging_tracking(median=False)) > 30.0     # eq. 8: R1 turns on and on
    assert abs(_lagging_tracking(median=True)) < 0.5
    assert robot("freebot").defaults.median_yaw and robot("snailbot").defaults.median_yaw
    assert not robot("freesn").defaults.median_yaw


def test_exploration_hands_over_a_better_start():
    config = random_stick(8, 6)
    tree = stick_tree(config)
    target = forward(tree, config, np.random.default_rng(6).normal(size=tree.dim) * 0.4
                     ).configuration
    tracker = IKTracker(tree, target, IKOptions(seed=2), tick_budget=None, explore=False)
    assert not tracker.explore_once()               # nothing to explore before a step
    assert tracker.step(config).success
    # the tracked solution goes bad (a slip, a wrong estimate): exploration recovers
    lo, hi = tree.bounds
    tracker.last = replace(tracker.last, sigma=np.clip(tracker.last.sigma + 1.5, lo, hi))
    for _ in range(5):
        if tracker.explore_once() and tracker.offer is not None:
            break
    assert tracker.offer is not None
    solution = tracker.step(config)
    assert tracker.handovers == 1 and solution.success and tracker.offer is None


def test_the_exploration_thread_starts_with_a_step_and_stops_on_close():
    config = random_stick(5, 8)
    tree = stick_tree(config)
    tracker = IKTracker(tree, config, IKOptions(seed=3), explore=True)
    assert tracker._thread is None
    tracker.step(config)
    assert tracker._thread is not None and tracker._thread.is_alive()
    tracker.close()
    assert tracker._thread is None


def test_a_new_target_keeps_the_warm_start():
    config = random_stick(5, 8)
    tree = stick_tree(config)
    first = forward(tree, config, np.full(tree.dim, 0.1)).configuration
    second = forward(tree, config, np.full(tree.dim, 0.12)).configuration
    with IKTracker(tree, first, tick_budget=None, explore=False) as tracker:
        tracker.step(config)
        tracker.set_target(second)
        assert tracker.target is second
        assert tracker.step(config).success
