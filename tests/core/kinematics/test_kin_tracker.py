"""Iterative IK: tracking with warm starts, and hand-over from the exploration."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from kin_helpers import random_stick, stick_tree, yawed

from msrr.core.kinematics import IKOptions, IKTracker, forward


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
