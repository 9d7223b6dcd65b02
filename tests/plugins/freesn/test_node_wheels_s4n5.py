"""Fig. 18(a)-(c)'s node wheels in MuJoCo (issue 31, item 2): the S4N5 star's hub shell
under 4 deg of noise, judged on the simulator's bodies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from freesn_held import held_commands
from scipy.spatial.transform import Rotation

from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim import FreeSNMujocoDriver, FreeSNWorld, SimOptions
from msrr.plugins.freesn.sim.controller import FreeSNController
from msrr.plugins.freesn.sim.world import _LEVEL_STEP

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"


def _hub_tilts(seconds: float, bias: float = 0.0, **options: float) -> np.ndarray:
    """The S4N5 standup held in shape by the controller every 0.1 s, its node wheels at
    the library's gains for 0.03 m/s from 1 s on: the hub's shell tilt [deg] (the angle of
    its z axis from the vertical) after every tick. ``bias`` [rad]: an error about x set
    in the hub's attitude estimate before every command (its fusion keeps 0.8 of it)."""
    library = load_library(FREESN / "libraries" / "S4N5.json").sublibraries["S4N5"]
    behavior = library.behaviors["node-wheels"]
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    wheels = {c.module: {c.connector: c.value({"speed": 0.03, "yaw_rate": 0.0})}
              for c in behavior.commands}
    controller = FreeSNController()
    tilts = []
    with FreeSNMujocoDriver(**options) as driver:
        driver.reset(start)
        world = driver.world
        centre = world._node_index[max(world.nodes, key=world.docked.count)]
        hub = world._node_body[centre]
        yaw = None
        for tick in range(round(seconds / 0.1)):
            commands, yaw = held_commands(controller, start, driver.get_observation(),
                                          wheels, tick, yaw)
            world._attitude[centre] = [bias, 0.0, 0.0]
            driver.send_action(commands)
            driver.step(0.1)
            tilts.append(np.degrees(np.arccos(np.clip(world.data.xmat[hub][8], -1.0, 1.0))))
    return np.array(tilts)


def test_the_hub_shell_does_not_roll_over_on_its_estimates_errors():
    """The hub's connectors aim by its IMU's attitude estimate, so its shell, free under
    them, takes each estimate's error for good (and the wheels' reaction torque): it rolled
    over, 80 deg in 8 s at 4 deg of noise (fig18 seed 13), and near upside down its
    horizontal frame, the frame every command is in, spun and a hub connection broke. Here
    an estimate 2.3 deg off at every command (noise itself negligible) rolls it over in
    8 s unless levelled past ``_LEVEL_FROM`` (the world's ``_node_tilt``, 100 deg)."""
    tilts = _hub_tilts(10.0, bias=np.radians(2.9), noise=1e-6)
    assert tilts.max() < 115.0


def test_only_a_held_shell_tilted_past_the_bound_is_levelled():
    """The hub (four connectors) tilted 150 deg is turned ``_LEVEL_STEP`` toward upright;
    tilted 95 deg it is not (exact runs keep their physics: fig20's nodes tilt up to 91
    deg), nor is a wheel node (one connector: rolling its shell would move it), nor the
    hub while a wheel on it spins."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    world = FreeSNWorld(start, SPEC, SimOptions())
    degree = {n: world.docked.count(n) for n in world.nodes}
    hub = world._node_index[max(degree, key=degree.get)]
    wheel = world._node_index[min(degree, key=degree.get)]
    tilted = Rotation.from_rotvec([np.radians(150.0), 0.0, 0.0]).as_matrix()
    turn = world._levelled(hub, tilted)
    up = (turn @ tilted)[:, 2]
    assert np.degrees(np.arccos(up[2])) == pytest.approx(150.0 - np.degrees(_LEVEL_STEP))
    slight = Rotation.from_rotvec([np.radians(95.0), 0.0, 0.0]).as_matrix()
    assert np.allclose(world._levelled(hub, slight), np.eye(3))
    assert np.allclose(world._levelled(wheel, tilted), np.eye(3))
    spun = world.docked.index(world.nodes[hub])
    world._wheel[spun] = 1.0
    assert np.allclose(world._levelled(hub, tilted), np.eye(3))


def test_a_chain_node_on_two_connectors_is_not_levelled():
    """The squirm's chain root ``n0`` (two connectors, the group's root by id) tilted 150
    deg keeps its frame: it lies on the floor and rolls, so the levelling turn only swung
    the hump strut its connector drives sideways (issue 31, stop 49: the hump bent 10-24
    deg at the raised node while ``n0`` was past 100 deg, and the body turned with it)."""
    start = load_configuration(FREESN / "configs" / "scenarios" / "fig19-squirm-start.json")
    world = FreeSNWorld(start, SPEC, SimOptions())
    degree = {n: world.docked.count(n) for n in world.nodes}
    root = min(degree, key=lambda n: (-degree[n], n))
    assert (root, degree[root]) == ("n0", 2)
    tilted = Rotation.from_rotvec([np.radians(150.0), 0.0, 0.0]).as_matrix()
    assert np.allclose(world._levelled(world._node_index[root], tilted), np.eye(3))


def _held_integrals(seconds: float, **options: float) -> np.ndarray:
    """The S4N5 standup held still by the controller every 0.1 s (filtered reports, as the
    executor's; no wheel turning) at 2 deg of noise, seed 12: per tick, the fraction of its
    driven connectors whose integral is at 0.9 of its bound or more."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    controller = FreeSNController()
    at_bound = []
    with FreeSNMujocoDriver(noise=np.radians(2.0), seed=12, **options) as driver:
        driver.reset(start)
        world = driver.world
        reports = controller._recognizer.report_filter()
        yaw = None
        for tick in range(round(seconds / 0.1)):
            observation = reports.update(driver.get_observation())
            commands, yaw = held_commands(controller, start, observation, {}, tick, yaw)
            driver.send_action(commands)
            driver.step(0.1)
            ks = np.flatnonzero(world._has_target)
            size = np.linalg.norm(world._integral[ks], axis=1)
            at_bound.append(np.mean(size >= 0.9 * world._integral_bound))
    return np.array(at_bound)


def test_held_connectors_leave_their_estimates_wander_to_the_position_loop():
    """Held still at 2 deg of noise, the servo errors are the connectors' own estimates'
    wander (fused at 0.05: ~2 s long); integrated, each connector pushed to its bound
    against the others (8 % of the connector-ticks here) for seconds at a time, and
    fig18's node wheels went 16-22 deg off their heading through the feet (issue 31,
    stop 48). Within ``integral_band`` (2) times that wander's rms the integral takes
    nothing: none reaches its bound. At fusion 0.05, where it was found; at the default
    0.02 since stop 49 the wander is slower and smaller, and one connector of the eight
    sits at its bound from 0.8 to 2.0 s with the band or without it (band 0: 3.5 % of
    the connector-ticks), a real error of the noisy commands, not the wander."""
    assert _held_integrals(6.0, integral_band=0.0, fusion=0.05)[10:].mean() > 0.03
    assert _held_integrals(6.0, fusion=0.05)[10:].max() == 0.0


def test_the_integral_band_is_the_estimates_rms_and_nothing_without_noise():
    """``_beyond_band``: an error within the band is not integrated, one beyond it loses the
    band's length; exact (noise 0) the whole error, so exact runs keep their physics."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    error = np.array([[0.001, 0.0, 0.0], [0.0, 0.05, 0.0]])
    assert np.array_equal(FreeSNWorld(start, SPEC, SimOptions())._beyond_band(error), error)
    noisy = FreeSNWorld(start, SPEC, SimOptions(noise=np.radians(2.0)))
    b = noisy.options.fusion
    band = 2.0 * np.sqrt(6.0) * np.radians(2.0) * b / np.sqrt(1.0 - (1.0 - b) ** 2)
    beyond = noisy._beyond_band(error)
    assert np.all(beyond[0] == 0.0)
    assert beyond[1] == pytest.approx([0.0, 0.05 - band, 0.0])
