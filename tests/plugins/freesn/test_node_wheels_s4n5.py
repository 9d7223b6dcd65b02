"""Fig. 18(a)-(c)'s node wheels in MuJoCo (issue 31, item 2): the S4N5 star's hub shell
under 4 deg of noise, judged on the simulator's bodies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from freesn_held import WHEELS_FROM, held_commands
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


def _held_integrals(seconds: float, noise: float = 2.0, wound: bool = False,
                    near: float = 0.9, **options: float) -> np.ndarray:
    """The S4N5 standup held still by the controller every 0.1 s (filtered reports, as the
    executor's; no wheel turning) at ``noise`` [deg] (2), seed 12: per tick, the fraction of
    its driven connectors whose integral is at ``near`` of its bound or more. ``wound``:
    every integral set to its bound at 1 s, each in a direction of its own (seeded), as a
    transient leaves them."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    controller = FreeSNController()
    at_bound = []
    directions = np.random.default_rng(3).normal(size=(8, 3))
    with FreeSNMujocoDriver(noise=np.radians(noise), seed=12, **options) as driver:
        driver.reset(start)
        world = driver.world
        reports = controller._recognizer.report_filter()
        yaw = None
        for tick in range(round(seconds / 0.1)):
            observation = reports.update(driver.get_observation())
            commands, yaw = held_commands(controller, start, observation, {}, tick, yaw)
            driver.send_action(commands)
            ks = np.flatnonzero(world._has_target)
            if wound and tick == 10:
                pushes = directions[:len(ks)]
                world._integral[ks] = world._integral_bound * pushes / np.linalg.norm(
                    pushes, axis=1)[:, None]
            driver.step(0.1)
            size = np.linalg.norm(world._integral[ks], axis=1)
            at_bound.append(np.mean(size >= near * world._integral_bound))
    return np.array(at_bound)


def test_held_connectors_leave_their_estimates_wander_to_the_position_loop():
    """Held still at 2 deg of noise, the servo errors are the connectors' own estimates'
    wander (fused at 0.05: ~2 s long); integrated, each connector pushed to its bound
    against the others (8 % of the connector-ticks here) for seconds at a time, and
    fig18's node wheels went 16-22 deg off their heading through the feet (issue 31,
    stop 48). Within ``integral_band`` (2) times that wander's rms the integral takes
    nothing: none reaches its bound, at fusion 0.05, where it was found, and at the
    default 0.02 since stop 49 (without the band 3.5 % of the connector-ticks there)."""
    assert _held_integrals(6.0, integral_band=0.0, fusion=0.05)[10:].mean() > 0.03
    assert _held_integrals(6.0, fusion=0.05)[10:].max() == 0.0
    assert _held_integrals(6.0)[10:].max() == 0.0


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


def test_an_integral_a_transient_wound_unwinds_within_the_band():
    """An integral at its bound pushes its connector at the roll rate, which the position
    loop balances at the roll rate over its gain (2.1 deg): within the band at 4 deg of
    noise (3.1 deg), so with the band stopping all integration such an integral was never
    unwound, and held its connector that far off in the transient's direction (fig21 at 4
    deg: 24 % of the connector-ticks, its open ring's closing dock missed; stop 49). The
    error within the band takes back what it opposes: the S4N5 standup held at 4 deg with
    every integral wound at 1 s has none at half its bound 3 s later."""
    at_bound = _held_integrals(4.0, noise=4.0, wound=True, near=0.5)
    assert at_bound[10] > 0.5          # wound (0.1 s after)
    assert at_bound[-5:].max() == 0.0


def test_the_band_gives_back_what_an_integral_holds_and_a_press_takes_the_whole_error():
    """``_beyond_band`` with the integrals: an error within the band opposing its
    connector's integral takes back its part along it, one along it takes nothing; the
    connectors of a structure pressing a dock (an extended free magnet: ``_pressing``)
    take their whole error, those of another structure, or of none pressing, the band."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    noisy = FreeSNWorld(start, SPEC, SimOptions(noise=np.radians(2.0)))
    error = np.array([[0.01, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.01]])
    integral = np.array([[-2e-3, 0.0, 0.0], [2e-3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    taken = noisy._beyond_band(error, integral)
    assert taken[0] == pytest.approx([0.01, 0.0, 0.0])
    assert np.all(taken[1:] == 0.0)
    ks = np.array([0, 2, 4])
    assert not noisy._pressing(ks).any()
    assert np.all(noisy._beyond_band(error, integral, ks)[1:] == 0.0)
    foot = next(k for k, n in enumerate(noisy.docked) if noisy.docked.count(n) == 1)
    noisy._release(foot, "undock")
    noisy.command_dock(*noisy.ends[foot])
    assert noisy._pressing(ks).all()
    assert np.array_equal(noisy._beyond_band(error, integral, ks), error)
    alone = noisy.ends[foot][0]
    noisy._release(foot ^ 1, "undock")          # the strut off the star: its own structure
    assert not noisy._pressing(ks[[noisy.ends[k][0] != alone for k in ks]]).any()


def _leg_integrals(seconds: float, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """The S4N5 standup held by the controller every 0.1 s (filtered reports), its node
    wheels at the library's gains for 0.03 m/s from 1 s on, at ``noise`` [deg], seed 15:
    per tick, the largest integral [rad s] of the hub's connectors (the legs) and of the
    leaf connectors (the wheels)."""
    library = load_library(FREESN / "libraries" / "S4N5.json").sublibraries["S4N5"]
    wheels = {c.module: {c.connector: c.value({"speed": 0.03, "yaw_rate": 0.0})}
              for c in library.behaviors["node-wheels"].commands}
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    controller = FreeSNController()
    legs, feet = [], []
    with FreeSNMujocoDriver(noise=np.radians(noise), slip=0.05, seed=15) as driver:
        driver.reset(start)
        world = driver.world
        hub = max(world.nodes, key=world.docked.count)
        on_hub = np.array([n == hub for n in world.docked])
        reports = controller._recognizer.report_filter()
        yaw = None
        for tick in range(round(seconds / 0.1)):
            observation = reports.update(driver.get_observation())
            commands, yaw = held_commands(controller, start, observation, wheels, tick, yaw)
            driver.send_action(commands)
            driver.step(0.1)
            size = np.linalg.norm(world._integral, axis=1)
            legs.append(size[on_hub].max())
            feet.append(size[~on_hub].max())
    return np.array(legs), np.array(feet)


def test_the_legs_of_node_wheels_leave_the_wheels_load_to_the_stance_under_noise():
    """A stance on four node wheels carries its weight in a split the legs' loops set;
    under noise each leg's integral acted on its estimates' wander and held one diagonal
    pair of wheels at 6.7 N, the other at 4.9 N, for fig18's whole behavior (2 deg + 5 %,
    seed 15): the loaded pair gripped more and the body crabbed 14-22 deg off the travel
    the odometry, the mean of the feet's rolling, showed, its heading estimate within
    1.1 deg; it ended 16.1 deg off (issue 31, stop 50). Under noise, while its foot's
    wheels run, a leg integrates nothing (the wheels' own connectors still do); exact,
    where the integral takes the true error, it keeps it."""
    legs, feet = _leg_integrals(3.0, noise=2.0)
    assert legs[WHEELS_FROM:].max() == 0.0
    assert feet[WHEELS_FROM:].max() > 0.0
    exact, _ = _leg_integrals(3.0, noise=0.0)
    assert exact[WHEELS_FROM:].max() > 0.0


def test_only_a_stance_on_four_node_wheels_or_more_has_wheel_legs():
    """``_wheel_legs``: under noise, the S4N5 standup's four hub connectors while its four
    node wheels run (not before, nor the wheels' own connectors); fig22(j) on its three
    node wheels has none (three wheels carry the split the floor sets)."""
    start = load_configuration(FREESN / "configs" / "library" / "S4N5-1.2.json")
    world = FreeSNWorld(start, SPEC, SimOptions(noise=np.radians(2.0)))
    ks = np.arange(len(world.ends))
    hub = max(world.nodes, key=world.docked.count)
    assert not world._wheel_legs(ks).any()
    feet = [k for k in ks if world.docked[k] != hub]
    world._wheel[feet] = 1.0
    assert list(ks[world._wheel_legs(ks)]) == [k for k in ks if world.docked[k] == hub]
    assert not FreeSNWorld(start, SPEC, SimOptions())._wheel_legs(ks).any()
    kiwi = load_configuration(FREESN / "configs" / "library" / "S12N6-5.1.json")
    world = FreeSNWorld(kiwi, SPEC, SimOptions(noise=np.radians(2.0)))
    for strut in ("R1", "R3", "R5"):
        world._wheel[world._end_index[(strut, "b")]] = 1.0
    assert not world._wheel_legs(np.arange(len(world.ends))).any()
