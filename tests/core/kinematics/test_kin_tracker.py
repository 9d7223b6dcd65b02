"""Iterative IK: tracking with warm starts, and hand-over from the exploration thread."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from kin_helpers import freesn_tree, random_freesn, yawed

from msrr.core.kinematics import IKOptions, IKTracker, forward


def test_tracking_follows_a_robot_that_moves_towards_the_target():
    config = random_freesn(10, 4, free=1)
    tree = freesn_tree(config)
    target = yawed(forward(tree, config, np.random.default_rng(4).normal(size=tree.dim) * 0.3
                           ).configuration, 0.7)
    current = config
    with IKTracker(tree, target, IKOptions(seed=1), explore=False) as tracker:
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
    config = random_freesn(8, 6)
    tree = freesn_tree(config)
    target = forward(tree, config, np.random.default_rng(6).normal(size=tree.dim) * 0.4
                     ).configuration
    tracker = IKTracker(tree, target, IKOptions(seed=2, time_budget=1.0), explore=True)
    try:
        assert tracker.step(config).success
        # the tracked solution goes bad (a slip, a wrong estimate): exploration recovers
        lo, hi = tree.bounds
        tracker.last = replace(tracker.last, sigma=np.clip(tracker.last.sigma + 1.5, lo, hi))
        deadline = time.monotonic() + 20.0
        while tracker._offer is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert tracker._offer is not None
        solution = tracker.step(config)
        assert tracker.handovers == 1 and solution.success
    finally:
        tracker.close()
    assert tracker._thread is None


def test_a_new_target_keeps_the_warm_start():
    config = random_freesn(5, 8)
    tree = freesn_tree(config)
    first = forward(tree, config, np.full(tree.dim, 0.1)).configuration
    second = forward(tree, config, np.full(tree.dim, 0.12)).configuration
    with IKTracker(tree, first, explore=False) as tracker:
        tracker.step(config)
        tracker.set_target(second)
        assert tracker.target is second
        assert tracker.step(config).success
