"""The single-connector freeform robots (FreeBOT, SnailBot): what their plugins get from
the family's factory (:class:`msrr.core.freeform.FreeformPlugin`) and how every shipped
configuration stands in the MuJoCo world.

The simulator's own state (body positions, ``data.eq_active``) is the judge.
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import import_module

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.actions import topology_diff
from msrr.core.errors import PluginError
from msrr.core.freeform import read_freeform_robot
from msrr.core.io import load_configuration
from msrr.core.robot import MisoRules
from msrr.core.shape import skeletal_error

from msrr_test_support import ROOT

FAMILY = ("freebot", "snailbot")
HEAVY = ("numpy", "scipy", "networkx", "mujoco")

CONFIGURATIONS = [(robot, path.stem) for robot in FAMILY
                  for path in sorted((ROOT / "plugins" / robot / "configs").glob("*.json"))]


def _plugin(robot: str):
    return import_module(f"msrr.plugins.{robot}.plugin").plugin


def test_loading_a_family_plugin_imports_nothing_heavy():
    code = ("import json, sys\n"
            + "".join(f"import msrr.plugins.{robot}.plugin\n" for robot in FAMILY)
            + "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    loaded = {name.split(".")[0] for name in json.loads(done.stdout)}
    assert not loaded & set(HEAVY), f"loading the plugins imported {sorted(loaded & set(HEAVY))}"


def test_registering_the_plugin_objects_imports_nothing_heavy():
    code = ("import json, sys, pluggy\n"
            "from msrr.core import hookspecs\n"
            "pm = pluggy.PluginManager('msrr')\n"
            "pm.add_hookspecs(hookspecs)\n"
            + "".join(f"from msrr.plugins.{robot}.plugin import plugin\npm.register(plugin)\n"
                      for robot in FAMILY)
            + "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    loaded = {name.split(".")[0] for name in json.loads(done.stdout)}
    assert not loaded & set(HEAVY), f"registering imported {sorted(loaded & set(HEAVY))}"


@pytest.mark.parametrize("robot", FAMILY)
def test_the_factory_registers_the_family_capabilities(robot):
    plugin = _plugin(robot)
    modes = list(plugin.joint_modes())
    assert plugin.spec.name == robot and plugin.__name__ == f"msrr.plugins.{robot}.plugin"
    resolved = plugins.resolve(robot)
    assert isinstance(resolved.rules, MisoRules)
    assert [resolved.joint_modes[m.name] for m in modes] == modes
    assert resolved.default_joint_mode() is modes[0]
    assert list(plugins.planners.items(robot))[:2] == ["miso", "miso-exact"]
    assert plugins.drivers.get(robot, "mujoco") is plugin.driver_factory()
    assert plugin.driver_factory().design == plugin.design and plugin.design.robot == robot
    assert plugins.recognizers.get(robot, robot).name == robot
    assert [c.name for c in plugin.controllers()] == [m.controller for m in modes]
    assert list(plugins.scenarios.items(robot)) == [
        s.name for s in import_module(f"msrr.plugins.{robot}.scenarios").SCENARIOS]


@pytest.mark.parametrize("robot", FAMILY)
def test_the_robot_description_is_read_from_robot_json(robot):
    path = ROOT / "plugins" / robot / "robot.json"
    spec = read_freeform_robot(path.read_text(), str(path))
    assert spec == plugins.robot(robot)
    (kind,) = spec.module_kinds
    assert kind.role == "vertex" and [p.role for p in kind.ports] == ["neutral"]
    assert spec.defaults.joint_mode == _plugin(robot).joint_modes()[0].name


@pytest.mark.parametrize(("change", "message"), [
    ({"port": None}, r"robot.json: missing port \(fields: name, title"),
    ({"colour": "red"}, r"robot.json: unknown colour"),
    ({"title": 3}, r"robot.json: title must be a string, got 3"),
    ({"geometry": {"radius": 0.05}}, r"robot.json: robot 'freebot': geometry 'mass' must be a "
                                     r"number > 0, got None"),
])
def test_a_wrong_robot_json_is_refused_in_one_line_naming_the_field(change, message):
    data = json.loads((ROOT / "plugins" / "freebot" / "robot.json").read_text())
    data.update(change)
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(PluginError, match=message):
        read_freeform_robot(json.dumps(data), "freebot/robot.json")
    with pytest.raises(PluginError, match="not JSON"):
        read_freeform_robot("{", "freebot/robot.json")


def test_only_the_sucker_joint_engages_the_sucker():
    assert not any(c.sucker for c in _plugin("freebot").controllers())
    assert [c.sucker for c in _plugin("snailbot").controllers()] == [False, True]
    assert plugins.controllers.get("snailbot", "snailbot.sucker_revolute").sucker
    assert _plugin("snailbot").design.sucker and not _plugin("freebot").design.sucker
    assert _plugin("freebot").design.bearing and not _plugin("snailbot").design.bearing


@pytest.mark.parametrize(("robot", "name"), CONFIGURATIONS,
                         ids=[f"{r}-{n}" for r, n in CONFIGURATIONS])
def test_every_shipped_configuration_builds_and_holds_for_a_second(robot, name, mujoco_driver):
    driver = mujoco_driver(robot, name)
    world = driver.world
    config = load_configuration(ROOT / "plugins" / robot / "configs" / f"{name}.json")
    driver.step(1.0)
    assert np.isfinite(world.data.qpos).all()
    assert world.constraint_residual() < 1e-3                          # [m]
    assert world.docked_pairs() == {(e.source, e.target) for e in config.edges()}
    truth = world.ground_truth()
    assert not topology_diff(truth, config)
    assert skeletal_error(truth, config) < np.radians(2.0)
