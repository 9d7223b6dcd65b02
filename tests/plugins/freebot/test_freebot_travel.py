"""A FreeBOT piece travels over the floor as one rigid body (every shell rolls under its
arm, every module drives): ground truth judges the travel, the turn and the shape; the
commands come from the module reports only."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.freeform.recognition import links_of, module_headings
from msrr.core.freeform.travel import centres_of, twist_velocities
from msrr.core.io import load_configuration
from msrr.core.shape import skeletal_error
from msrr.plugins.freebot.plugin import plugin

from msrr_test_support import ROOT

SPEED = 0.02        # [m/s], under a shell's rolling bound r * max_speed = 0.025


def _l8() -> Configuration:
    """Eight in an L: F1..F5 along x, F6..F8 along y from F5 (F5 carries F4 and F6)."""
    config = Configuration("freebot", name="l8")
    for i in range(1, 9):
        config.add_module(f"F{i}", "freebot")
    for i in range(1, 5):
        config.connect(f"F{i}", f"F{i + 1}", z=[1.0, 0.0, 0.0])
    for i in range(6, 9):
        config.connect(f"F{i}", f"F{i - 1}", z=[0.0, -1.0, 0.0])
    return config


def _pose(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Centroid (2,) and yaw [rad] of ``points`` (n, 3) (the yaw of its first-to-last line)."""
    line = points[-1, :2] - points[0, :2]
    return points[:, :2].mean(axis=0), float(np.arctan2(line[1], line[0]))


@pytest.mark.parametrize("start", ["chain6", "l8"])
def test_a_piece_travels_half_a_metre_and_turns_a_right_angle_keeping_its_shape(start):
    config = _l8() if start == "l8" else load_configuration(
        ROOT / "plugins" / "freebot" / "configs" / "chain6.json")
    driver = plugin.driver_factory()()
    driver.connect()
    driver.reset(config)
    world = driver.world
    before = world.ground_truth()
    first = np.array([world.centre(m) for m in world.modules])
    reports = driver.get_observation().sensors
    links = links_of(reports)
    centres, headings, _ = centres_of(reports, links, module_headings(reports, links),
                                      world.length)
    # a constant twist in the piece's frame: an arc of radius R through a quarter turn
    # moves the centroid by sqrt(2) R = 0.5 m
    radius = 0.5 / np.sqrt(2.0)
    about = np.mean([c[:2] for c in centres.values()], axis=0)
    velocities, turn = twist_velocities(centres, headings, np.array([radius, 0.0]), 1.0,
                                        about, speed=SPEED)
    driver.send_action({m: ModuleCommand(joints={"roll_x": float(v[0]), "roll_y": float(v[1]),
                                                 "turn": turn})
                        for m, v in velocities.items()})
    driver.step(0.5 * np.pi / turn)
    driver.send_action({})
    driver.step(0.5)
    last = np.array([world.centre(m) for m in world.modules])
    (c0, yaw0), (c1, yaw1) = _pose(first), _pose(last)
    assert np.linalg.norm(c1 - c0) == pytest.approx(0.5, abs=0.02)
    assert np.degrees(yaw1 - yaw0) == pytest.approx(90.0, abs=3.0)
    assert np.all(np.abs(last[:, 2] - first[:, 2]) < 0.002)      # on the floor all along
    assert world.docked_pairs() == {(e.source, e.target) for e in config.edges()}
    assert np.degrees(skeletal_error(world.ground_truth(), before)) < 1.0
    # each module's odometry (its rolling shell) saw its own centre's travel
    odometry = {m: r.odometry[:2] for m, r in driver.get_observation().sensors.items()}
    for k, m in enumerate(world.modules):
        assert np.linalg.norm(odometry[m]) == pytest.approx(
            np.linalg.norm(last[k, :2] - first[k, :2]), abs=0.02)


def test_a_snailbot_piece_is_refused_travel():
    from msrr.core.errors import ExecutionError
    from msrr.plugins.snailbot.plugin import plugin as snailbot

    config = Configuration("snailbot")
    config.add_module("S1", "snailbot")
    config.add_module("S2", "snailbot")
    config.connect("S1", "S2", z=[1.0, 0.0, 0.0])
    driver = snailbot.driver_factory()()
    driver.connect()
    driver.reset(config)
    with pytest.raises(ExecutionError, match="only alone"):
        driver.send_action({"S1": ModuleCommand(joints={"roll_x": 0.01, "roll_y": 0.0})})
