"""FreeSN wheels in MuJoCo (issue 13): a ``wheel_speed`` command moves the robot through
contact forces, judged on the simulator's ground truth (body positions)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.app.run import RunRequest, prepare_run, resolve_scenario
from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.core.plan import ActionType
from msrr.plugins.freesn.robot import NODE, STRUT
from msrr.plugins.freesn.sim import FreeSNMujocoDriver
from msrr.plugins.freesn.sim.commands import parse_wheels

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
R_WHEEL = STRUT.geometry["wheel_radius"]
WHEEL_BASE = STRUT.geometry["wheel_base"]
R_NODE = NODE.geometry["radius"]


def _tripod(tilt: float = np.radians(55.0)) -> Configuration:
    """One node on three free legs pointing down, each leg's wheel axle perpendicular to
    world x, so every free connector's wheels roll along x (Fig. 18(d)-(f))."""
    config = Configuration("freesn")
    config.add_module("N1", "node")
    for i, azimuth in enumerate(np.radians([0.0, 120.0, 240.0])):
        z = np.array([np.cos(azimuth) * np.cos(tilt), np.sin(azimuth) * np.cos(tilt),
                      -np.sin(tilt)])
        axle = np.cross([1.0, 0.0, 0.0], z)
        axle /= np.linalg.norm(axle)
        config.add_virtual(f"S{i}:b")
        config.connect("N1", f"S{i}:b", id=f"S{i}", kind="strut", z=z, x=np.cross(axle, z))
    return config


def _centre(driver: FreeSNMujocoDriver) -> np.ndarray:
    world = driver.world
    return world.data.xpos[world._node_body].mean(axis=0).copy()


@pytest.mark.parametrize("speed", [4.0, -3.0])
def test_free_strut_wheels_drive_the_body_at_omega_r(speed):
    with FreeSNMujocoDriver() as driver:
        driver.reset(_tripod())
        driver.step(0.3)                       # settle on the three wheels
        before = _centre(driver)
        driver.send_action({s: ModuleCommand(wheels={"b": speed}) for s in ("S0", "S1", "S2")})
        driver.step(1.0)
        moved = _centre(driver) - before
    # positive speed turns the wheels about the strut's +y (their axle): here +x
    assert moved[0] == pytest.approx(speed * R_WHEEL, rel=0.2)
    assert abs(moved[1]) < 0.005 and abs(moved[2]) < 0.005


def test_node_wheels_roll_the_s4n5_standup_forward_without_losing_its_shape():
    """Fig. 18(a)-(c): the leaf connectors turn the leaf nodes about the leg axes.

    No-slip reference: each leaf node turns at ``w r / (b/2)`` about its leg's axis
    ``z``, and a sphere turning at ``Omega`` rolls its centre at ``Omega x (R e_z)``; the
    four legs' sideways parts cancel, so the body moves at their mean.
    """
    library = load_library(FREESN / "libraries" / "S4N5.json")
    behavior = library.sublibraries["S4N5"].behaviors["node-wheels"]
    start = load_configuration(FREESN / "configs" / "library" / f"{behavior.start}.json")
    params = {"speed": 0.03}
    wheels = {c.module: {c.connector: c.value(params)} for c in behavior.commands}
    with FreeSNMujocoDriver() as driver:
        driver.reset(start)
        driver.step(0.3)
        world = driver.world
        axes = world.data.xmat[world._strut_body].reshape(-1, 3, 3)[:, :, 2].copy()
        reference = []
        for j, strut in enumerate(world.struts):
            turn = wheels[strut]["target"] * R_WHEEL / (0.5 * WHEEL_BASE) * axes[j]
            reference.append(np.cross(turn, [0.0, 0.0, R_NODE]))
        expected = np.mean(reference, axis=0)
        before = _centre(driver)
        driver.send_action({m: ModuleCommand(wheels=w) for m, w in wheels.items()})
        driver.step(1.5)
        moved = (_centre(driver) - before) / 1.5
        after = world.data.xmat[world._strut_body].reshape(-1, 3, 3)[:, :, 2]
        faults = driver.faults()
    assert expected[0] > 0.02 and abs(expected[1]) < 1e-3       # the library means +x
    assert 0.5 * expected[0] < moved[0] < 1.1 * expected[0]
    assert abs(moved[1]) < 0.3 * moved[0]
    # the connection vectors stay under the position loop while the wheels spin
    angles = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", axes, after), -1, 1)))
    assert angles.max() < 5.0 and not faults


def test_wheel_names_and_values_are_checked():
    assert parse_wheels("S1", ModuleCommand(wheels={"source": 1.0, "b": -2.0})) == \
        {"a": 1.0, "b": -2.0}
    for wheels, message in (({"c": 1.0}, "unknown wheel"), ({"a": 1.0, "source": 2.0}, "twice"),
                            ({"b": float("nan")}, "finite")):
        with pytest.raises(ExecutionError, match=message):
            parse_wheels("S1", ModuleCommand(wheels=wheels))


@pytest.mark.parametrize("name, behavior", [("S4N1", "strut-wheels"),
                                            ("S4N1", "struts-as-wheels"),
                                            ("S6N3", "wheeled-move")])
def test_wheel_behaviors_drive_along_the_library_x(name, behavior):
    """Fig. 18(d)-(i), Fig. 15: the library's gains (from the design's geometry) drive the
    simulated spider, and the S6N3 triangle standing on its legs' wheels (fig20a), along
    their ``+x`` -- the sign and rough size of ``speed`` hold."""
    library = load_library(FREESN / "libraries" / f"{name}.json")
    chosen = library.sublibraries[name].behaviors[behavior]
    start = load_configuration(FREESN / "configs" / "library" / f"{chosen.start}.json")
    speed = 0.03
    wheels: dict[str, dict[str, float]] = {}
    for command in chosen.commands:
        wheels.setdefault(command.module, {})[command.connector] = command.value({"speed": speed})
    with FreeSNMujocoDriver() as driver:
        driver.reset(start)
        driver.step(0.5)
        before = _centre(driver)
        driver.send_action({m: ModuleCommand(wheels=w) for m, w in wheels.items()})
        driver.step(2.0)
        moved = (_centre(driver) - before) / 2.0
    assert 0.25 * speed < moved[0] < 1.5 * speed
    assert abs(moved[1]) < 0.2 * moved[0]


@pytest.mark.parametrize("name", ["fig18-node-wheels", "fig18-strut-wheels",
                                  "fig18-struts-as-wheels"])
def test_locomotion_scenarios_plan_a_path_then_their_behavior(name, tmp_path):
    """Planning only: a new system (relabelled) retrieves the path to the behavior's start
    and ends in one mapping behavior whose wheel commands name its own struts."""
    scenario = resolve_scenario("freesn", name)
    start = plugins.load_configuration(scenario.start)
    prepared = prepare_run(RunRequest(robot="freesn", scenario=name, out=tmp_path / "run",
                                      log=False))
    actions = prepared.run.plan.actions
    assert all(a.type is ActionType.MOVING for a in actions[:-1])
    last = actions[-1]
    assert last.type is ActionType.BEHAVIOR and last.behavior is not None
    assert last.behavior.parameters == {"speed": 0.03} and last.behavior.duration == 60.0
    assert {c.module for c in last.behavior.commands} <= set(start.edge_ids())
