"""The FreeSN control tick's fast paths give the reference path's commands to the bit
(issue 32, item 6: the tick made cheaper without changing behaviour).

A few ticks of S12N6's benchmark edge (``benchmarks/freesn_control.py``) run in MuJoCo
under noise; their observations are then replayed through the reference path: the
support face chosen over every hull face at once (the former vectorised selection), no
FK evaluations kept by the IK problem, a ground op and driving connectors rebuilt every
tick, ``np.clip`` in the yaw alignment. Every command must be equal, float for float.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from msrr.core import alignment, plugins
from msrr.core.closed_loop import PhaseTracker, TrackingOptions, connection_goal, tree_for
from msrr.core.kinematics import GroundModel
from msrr.core.kinematics import ground as ground_module
from msrr.core.kinematics import ik as ik_module
from msrr.core.kinematics.rotations import cross
from msrr.core.library import load_library
from msrr.core.library.check import edge_cases
from msrr.plugins.freesn.sim import FreeSNMujocoDriver
from msrr.plugins.freesn.sim import controller as controller_module
from msrr.plugins.freesn.sim import recognizer as recognizer_module

LIBRARY = Path(__file__).resolve().parents[3] / "plugins" / "freesn" / "libraries" / "S12N6.json"
EDGE = "S12N6:S12N6-4.3->S12N6-4.1"
TICKS = 8


def _reference_support(self, points, com):
    """The support face as chosen before the fast path: orientation and stability of
    every hull face, then a stable lexicographic sort (stable first, most downward)."""
    if len(points) < 3:
        return None
    try:
        hull = ConvexHull(points)
        faces, normals = hull.simplices, hull.equations[:, :3]
    except (QhullError, ValueError):
        return self._planar_support(points, com)
    a, b, c = faces.T.astype(np.intp)
    flip = np.einsum("ij,ij->i", cross(points[b] - points[a], points[c] - points[a]),
                     normals) < 0
    b, c = np.where(flip, c, b), np.where(flip, b, c)
    stable = np.ones(len(a), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        stable &= np.einsum("ij,ij->i", cross(points[v] - points[u], com - points[u]),
                            normals) >= -1e-12
    best = int(np.lexsort((normals[:, 2], ~stable))[0])
    return (int(a[best]), int(b[best]), int(c[best])), bool(stable[best])


def _reference_costs(thetas, p, q, r, w):
    dots = np.cos(thetas)[:, None] * p + np.sin(thetas)[:, None] * q + r
    return (np.arccos(np.clip(dots, -1.0, 1.0)) ** 2) @ w


def _ticks(case, robot, first, observations):
    """Recognize, track and command each observation (the benchmark's tick)."""
    recognizer = plugins.recognizers.get("freesn")
    controller = plugins.controllers.get("freesn")
    current = recognizer.recognize(first.sensors)
    tree = tree_for(current, case.action.kinematic_tree, robot.default_joint_mode())
    tracker = PhaseTracker(tree, connection_goal(current, case.target), TrackingOptions(),
                           seed=0, ground=GroundModel.for_configuration(current, robot.spec))
    out = []
    for observation in observations:
        joint = tracker.step(recognizer.recognize(observation.sensors))
        out.append(controller.commands(joint, observation, yaw=0.0))
    return out


def test_the_fast_tick_commands_what_the_reference_path_commands(monkeypatch):
    robot = plugins.resolve("freesn")
    case = next(c for c in edge_cases(load_library(LIBRARY), robot) if c.key == EDGE)
    recognizer = plugins.recognizers.get("freesn")
    controller = plugins.controllers.get("freesn")
    observations, fast = [], []
    with FreeSNMujocoDriver(noise=math.radians(2.0), slip=0.05, seed=0) as driver:
        driver.reset(case.start)
        first = driver.get_observation()
        current = recognizer.recognize(first.sensors)
        tree = tree_for(current, case.action.kinematic_tree, robot.default_joint_mode())
        tracker = PhaseTracker(tree, connection_goal(current, case.target), TrackingOptions(),
                               seed=0, ground=GroundModel.for_configuration(current,
                                                                            robot.spec))
        for _ in range(TICKS):
            observation = driver.get_observation()
            observations.append(observation)
            joint = tracker.step(recognizer.recognize(observation.sensors))
            fast.append(controller.commands(joint, observation, yaw=0.0))
            driver.send_action(fast[-1])
            driver.step(0.1)
    assert tracker.last is not None and tracker.last.problem is not None
    assert tracker.last.problem._recent, "the fast path keeps FK evaluations"
    assert controller_module._driving_ends.cache_info().hits >= TICKS - 1

    monkeypatch.setattr(ground_module.GroundOp, "_support", _reference_support)
    monkeypatch.setattr(ik_module, "_RECENT", 0)
    monkeypatch.setattr(ik_module, "ground_op", ground_module.GroundOp)
    monkeypatch.setattr(controller_module, "_driving_ends",
                        controller_module._driving_ends.__wrapped__)
    monkeypatch.setattr(alignment, "_costs", _reference_costs)
    reference = _ticks(case, robot, first, observations)
    assert any(c.joints for c in fast[-1].values())
    for tick, (got, want) in enumerate(zip(fast, reference, strict=True)):
        assert got == want, f"tick {tick}: the commands differ from the reference path"


def test_the_recognizers_vector_length_is_numpys_to_the_bit():
    rng = np.random.default_rng(0)
    block = rng.normal(size=(50, 3))
    for v in [*block, *block.T[:, :3].T, block[:, 0]]:   # rows, and strided columns
        assert recognizer_module._length(v) == np.linalg.norm(v)
