"""SnailBot in the MuJoCo freeform world: building, the sucker, recognition, crawling.

The simulator's own state (body positions, ``data.eq_active``) is the judge; the
recognizer gets only the module reports.
"""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.actions import topology_diff
from msrr.core.driver import ModuleCommand
from msrr.core.io import load_configuration
from msrr.core.shape import skeletal_error
from msrr.plugins.snailbot.sim import SnailBotMujocoDriver, controllers, recognizer

from msrr_test_support import ROOT

CONFIGS = ROOT / "plugins" / "snailbot" / "configs"


def _reset(name: str, **options) -> SnailBotMujocoDriver:
    driver = SnailBotMujocoDriver(**options)
    driver.connect()
    driver.reset(load_configuration(CONFIGS / f"{name}.json"))
    return driver


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_snailbot_registers_its_simulation_and_a_sucker_controller():
    assert plugins.drivers.get("snailbot", "mujoco") is SnailBotMujocoDriver
    assert plugins.recognizers.get("snailbot", "snailbot").name == "snailbot"
    sucker = plugins.controllers.get("snailbot", "snailbot.sucker_revolute")
    assert sucker.sucker and not controllers()[0].sucker


@pytest.mark.parametrize("name", sorted(p.stem for p in CONFIGS.glob("*.json")))
def test_every_shipped_configuration_builds_and_holds_for_a_second(name):
    driver = _reset(name)
    world = driver.world
    config = load_configuration(CONFIGS / f"{name}.json")
    driver.step(1.0)
    assert np.isfinite(world.data.qpos).all()
    assert world.constraint_residual() < 1e-3                          # [m]
    assert world.docked_pairs() == {(e.source, e.target) for e in config.edges()}
    assert skeletal_error(world.ground_truth(), config) < np.radians(2.0)


def test_recognizer_rebuilds_a_three_dimensional_tree_from_noisy_reports():
    driver = _reset("tree5", noise=np.radians(1.0), seed=5)      # B1 stands on B3
    config = load_configuration(CONFIGS / "tree5.json")
    recognized = recognizer().recognize(driver.get_observation().sensors)
    assert not topology_diff(recognized, config)
    assert skeletal_error(recognized, config) < np.radians(3.0)


def test_the_sucker_locks_the_crawl_but_not_the_undock():
    driver = _reset("chain5")
    world = driver.world
    turn = np.radians(30.0)
    direction = [-np.cos(turn), -np.sin(turn), 0.0]
    before = world.centre("B1") - world.centre("B2")
    driver.send_action({"B1": ModuleCommand(joints={"sucker": 1.0})})
    driver.send_action({"B1": ModuleCommand(joints=dict(zip(("dir_x", "dir_y", "dir_z"),
                                                            direction, strict=True)))})
    driver.step(2.0)
    locked = world.centre("B1") - world.centre("B2")
    assert world.sucker[0] and _angle(before, locked) < np.radians(0.5)
    driver.send_action({"B1": ModuleCommand(joints={"sucker": 0.0, "dir_x": direction[0],
                                                    "dir_y": direction[1], "dir_z": 0.0})})
    driver.step(3.0)
    free = world.centre("B1") - world.centre("B2")
    # the reaction turns the row a little too: measure against B2 -> B3, as B2 sees it
    onward = world.centre("B3") - world.centre("B2")
    assert np.pi - _angle(free, onward) == pytest.approx(turn, abs=np.radians(2.0))
    driver.send_action({"B1": ModuleCommand(undock=("foot",))})   # the port: whatever it holds
    driver.step(0.1)
    assert ("B1", "B2") not in world.docked_pairs()
