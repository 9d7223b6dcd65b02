"""FreeSN connectors as differential drives (issue 32, item 6; paper Fig. 11).

One strut docked to one node, gravity off, so only the connector's wheels and grip act
between the two bodies; the simulator's state is the judge.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from msrr.core import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.freeform.mujoco import quat_conj, quat_mul
from msrr.core.io import load_configuration
from msrr.core.library import load_library
from msrr.core.shape import skeletal_errors
from msrr.plugins.freesn.plugin import CONFIGS, STARTS
from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim import FreeSNMujocoDriver
from msrr.plugins.freesn.sim.controller import FreeSNController
from msrr.plugins.freesn.sim.options import SimOptions
from msrr.plugins.freesn.sim.world import FreeSNWorld


def _one_strut(**options: object) -> FreeSNWorld:
    """N1 with strut S1 docked by end a along +x, its wheels' forward axis (strut x) up."""
    config = Configuration("freesn")
    config.add_module("N1", "node")
    config.add_virtual("S1:b")
    config.connect("N1", "S1:b", id="S1", kind="strut", z=np.array([1.0, 0.0, 0.0]),
                   x=np.array([0.0, 0.0, 1.0]))
    world = FreeSNWorld(config, SPEC, SimOptions(connector_drive="differential", **options))
    world.model.opt.gravity[:] = 0.0
    return world


def _on_node(world: FreeSNWorld) -> tuple[np.ndarray, np.ndarray]:
    """The strut's axis and its ``x`` (the wheels' forward direction) in the node frame."""
    node = world.data.xmat[world._node_body[0]].reshape(3, 3)
    strut = world.data.xmat[world._strut_body[0]].reshape(3, 3)
    return node.T @ strut[:, 2], node.T @ strut[:, 0]


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v),
                                              -1.0, 1.0))))


def _aim(world: FreeSNWorld, degrees: float, axis: tuple[float, float, float]
         ) -> tuple[np.ndarray, np.ndarray]:
    """Command S1's docked end toward its axis turned ``degrees`` about ``axis`` (node
    frame); the axis before and the target."""
    start, _ = _on_node(world)
    target = Rotation.from_rotvec(np.radians(degrees) * np.array(axis)).apply(start)
    world.command_target("S1", "a", (target, None, 1.0))
    return start, target


def test_a_connector_turns_before_it_rolls_sideways():
    """A target 60 deg to the side of the wheels' heading: the strut first turns about
    its axis (the contact point stays), then rolls there; a driving wheel stays within
    the top speed (a braking one may be overrun by the strut's spin), every torque within
    the motor's bound."""
    world = _one_strut()
    phys = world.phys
    _, heading0 = _on_node(world)
    start, target = _aim(world, 60.0, (0.0, 0.0, 1.0))
    turned_in_place = fastest = strongest = 0.0
    for _ in range(150):
        world.step(0.02)
        axis, heading = _on_node(world)
        if _angle(axis, start) < 1.0:
            turned_in_place = max(turned_in_place, _angle(heading, heading0))
        speed = world.data.actuator_velocity[world._motor[0]]
        driving = world._torque[0] * speed > 0.0   # motoring, not braking a spinning strut
        fastest = max(fastest, float(np.abs(speed[driving]).max(initial=0.0)))
        strongest = max(strongest, float(np.abs(world._torque[0]).max()))
    assert turned_in_place > 45.0, "the wheels rolled sideways instead of turning first"
    assert _angle(_on_node(world)[0], target) < 1.0
    assert fastest <= 1.02 * phys.max_wheel_speed
    assert strongest <= 0.5 * phys.wheel_torque + 1e-9


@pytest.mark.parametrize("load, slides", [(0.5, False), (2.0, True)])
def test_the_wheels_grip_sideways_until_the_load_beats_friction(load, slides):
    """A torque about the wheels' axis of travel (the strut's x, which would slide the
    wheels along their axles) on a braked connector: under the grip (friction x magnet
    pull, at the node radius) the contact point stays; twice over it, the wheels skid."""
    world = _one_strut()
    world.command_brake("S1", "a")
    start, _ = _on_node(world)
    torque = load * world.phys.grip * world.phys.node_radius
    dofs = world._dadr[0] + np.arange(3)
    for _ in range(50):
        ball = world._ball(np.array([0]))[0]
        lateral = Rotation.from_quat(ball, scalar_first=True).inv().apply([1.0, 0.0, 0.0])
        world.data.qfrc_applied[dofs] = torque * lateral   # on the connector, child frame
        world.step(0.01)
    moved = _angle(_on_node(world)[0], start)
    if slides:
        assert moved > 5.0
    else:
        assert moved < 0.5


def _push(world: FreeSNWorld, axis: np.ndarray, torque: float, seconds: float) -> float:
    """Apply ``torque`` [N m] about strut-frame ``axis`` on the connector for ``seconds``:
    how far the strut moved on its node [deg] (axis and heading, the larger)."""
    start, heading0 = _on_node(world)
    dofs = world._dadr[0] + np.arange(3)
    for _ in range(round(seconds / 0.01)):
        ball = world._ball(np.array([0]))[0]
        world.data.qfrc_applied[dofs] = torque * Rotation.from_quat(
            ball, scalar_first=True).inv().apply(axis)   # on the connector, child frame
        world.step(0.01)
    axis_now, heading = _on_node(world)
    return max(_angle(axis_now, start), _angle(heading, heading0))


@pytest.mark.parametrize("load, slides", [(0.5, False), (2.0, True)])
def test_a_stopped_connector_holds_rolling_and_turning_until_its_wheels_skid(load, slides):
    """A stopped connector's wheels are braked (a gear train the load does not back-drive):
    a torque about the wheels' axle (rolling, strut y) of half the wheels' friction at the
    node radius, or about the strut axis (turning) of half their friction couple, moves it
    < 0.5 deg in 0.5 s; twice over, the wheels skid. Before the brakes only the position
    loop held it: rolling up to the motors' torque, turning with the turn's weak torque
    (0.8 deg under the half load)."""
    p = _one_strut().phys
    for axis, hold in (([0.0, 1.0, 0.0], p.grip * p.node_radius),
                       ([0.0, 0.0, 1.0], p.grip * 0.5 * p.wheel_base)):
        world = _one_strut()
        world.command_brake("S1", "a")
        world.step(0.05)
        moved = _push(world, np.array(axis), load * hold, 0.5)
        assert (moved > 5.0) if slides else (moved < 0.5), (axis, moved)


def test_a_braked_turn_holds_the_firmwares_share_of_the_rolling_grip():
    """The turn about the strut axis is the rolling's weaker twin by ``b / 2R``, which the
    firmware's encoder ratios fix at ``ENCODER_ALPHA / ENCODER_BETA`` = 0.17151 / 0.36727
    (docs/freesn.md, Hardware parameters): a braked connector holds 0.85 of that share of
    its rolling grip about the strut axis (< 0.5 deg in 0.5 s). With the assumed 0.03 m
    wheel base (a share of 0.30) it skidded."""
    world = _one_strut()
    world.command_brake("S1", "a")
    world.step(0.05)
    share = 0.17151 / 0.36727
    rolling_grip = world.phys.grip * world.phys.node_radius
    assert _push(world, np.array([0.0, 0.0, 1.0]), 0.85 * share * rolling_grip, 0.5) < 0.5


def test_a_connector_turning_in_place_still_grips_in_its_rolling_direction():
    """Turning toward a target 90 deg to the side, the connector's rolling channel is
    stopped: a rolling torque of half the wheels' friction does not roll it (< 1 deg off
    the start while the strut turns; 3.3 deg before the brakes)."""
    world = _one_strut()
    start, _ = _aim(world, 30.0, (0.0, 0.0, 1.0))
    world.step(0.02)
    assert world._turning[0]
    p = world.phys
    _push(world, np.array([0.0, 1.0, 0.0]), 0.5 * p.grip * p.node_radius, 0.1)
    assert world._turning[0]
    assert _angle(_on_node(world)[0], start) < 1.0


def test_an_unknown_connector_drive_is_refused():
    with pytest.raises(ExecutionError, match="connector_drive"):
        SimOptions(connector_drive="tracked")


def test_a_triangle_on_the_floor_held_in_shape_stands_still():
    """S6N3-2.1 (its three nodes on the floor) held in shape by the controller every 0.1 s:
    its nodes creep < 3 mm/s from 1 s to 3 s (issue 32: 60 mm/s before the stopped
    connectors braked their wheels, every connector chasing a node that rolled under it;
    the holonomic model 7 mm/s)."""
    start = load_configuration(CONFIGS / "S6N3-2.1.json")
    controller = FreeSNController()
    centres = []
    with FreeSNMujocoDriver(connector_drive="differential") as driver:
        driver.reset(start)
        world = driver.world
        yaw = None
        for _ in range(30):
            observation = driver.get_observation()
            if yaw is None:
                yaw = skeletal_errors(controller._recognizer.recognize(observation.sensors),
                                      start)[2]
            driver.send_action(controller.commands(start, observation, yaw=yaw))
            driver.step(0.1)
            centres.append(world.data.xpos[world._node_body].copy())
    creep = np.linalg.norm(centres[-1] - centres[9], axis=1) / 2.0
    assert creep.max() < 0.003, creep


def _spider(behavior: str) -> tuple[list[float], bool, float]:
    """S4N1 on its library ``behavior`` at 0.03 m/s with differential connectors for 7 s:
    its centre's x every 0.5 s [m], whether a leg's connector turned, and the largest
    swing of a leg off its target on the node [deg] (the simulator's state)."""
    library = load_library(CONFIGS.parents[1] / "libraries" / "S4N1.json")
    chosen = library.sublibraries["S4N1"].behaviors[behavior]
    wheels: dict[str, dict[str, float]] = {}
    for command in chosen.commands:
        wheels.setdefault(command.module, {})[command.connector] = command.value({"speed": 0.03})
    with FreeSNMujocoDriver(connector_drive="differential") as driver:
        driver.reset(load_configuration(CONFIGS / f"{chosen.start}.json"))
        driver.step(0.5)
        world = driver.world
        legs = np.flatnonzero(world._eq >= 0)
        centre = [float(world.data.xpos[world._node_body].mean(axis=0)[0])]
        driver.send_action({m: ModuleCommand(wheels=w) for m, w in wheels.items()})
        turned, swing = False, 0.0
        for _ in range(14):
            driver.step(0.5)
            turned |= bool(world._turning[legs].any())
            centre.append(float(world.data.xpos[world._node_body].mean(axis=0)[0]))
            error = quat_mul(world._ball_target[legs], quat_conj(world._ball(legs)))
            tilt = 1.0 - 2.0 * (error[:, 1] ** 2 + error[:, 2] ** 2)
            swing = max(swing, float(np.degrees(np.arccos(np.clip(tilt, -1.0, 1.0))).max()))
    return centre, turned, swing


def test_strut_wheels_legs_do_not_turn_their_wheels_off_course_for_a_sideways_creep():
    """Fig. 18(d)-(f) with differential connectors: the legs' free-end wheels drive the
    spider while the node's load creeps the legs sideways on it (~0.1 deg/s, which
    rolling cannot remove). A leg turned toward that creep (past 0.6 deg) would steer its
    wheels across their course: before, every leg turned 25-100 deg at 5 s and the body
    stopped. Now no leg turns for it, and the body drives on at one speed."""
    centre, turned, _ = _spider("strut-wheels")
    first, last = centre[7] - centre[0], centre[14] - centre[7]
    assert not turned
    assert first > 0.03 and last == pytest.approx(first, rel=0.2)


def test_struts_as_wheels_legs_hold_their_aim_while_their_wheels_spin_them():
    """Fig. 18(g)-(i) with differential connectors: a leg's docked wheels spin it about its
    axis, so they cannot turn it toward an error; it rolls out the part of its swing along
    its heading as the spin sweeps the heading round. Before it rolled only while heading
    within 15 deg of the error, and the legs drifted 8 deg off their aim in 5 s (a
    connection broke at 56 s in the scenario); now they stay within 2 deg."""
    centre, _, swing = _spider("struts-as-wheels")
    assert swing < 2.0
    assert centre[14] - centre[0] > 0.07



def test_a_loaded_connector_rolling_on_its_heading_keeps_its_torque_for_the_roll():
    """A connector whose heading is within 1 deg of its way rolls and asks its wheels for
    no turn (their turn braked), so both wheels push the roll: against a
    rolling load of 0.6 of its torque and a twisting load of 0.3 of its wheels' friction
    couple it rolls 30 deg to its target within 1 s (< 1 deg left). Before, the turn loop
    held the heading with the wheels' torque, the roll stalled 17.6 deg short; fig20's
    last move (a leg lifting the body, its foot twisting it) stalled at 32 deg so."""
    world = _one_strut()
    start, target = _aim(world, -30.0, (0.0, 1.0, 0.0))
    p = world.phys
    load = np.array([0.0, 0.6 * p.max_torque, 0.3 * p.grip * 0.5 * p.wheel_base])
    _push(world, load / np.linalg.norm(load), float(np.linalg.norm(load)), 0.05)
    assert world._turning[0]
    _push(world, load / np.linalg.norm(load), float(np.linalg.norm(load)), 0.95)
    assert _angle(_on_node(world)[0], target) < 1.0


def test_a_roller_keeps_its_commanded_spin_against_a_load_while_it_holds_its_aim():
    """A roller (its wheels commanded, its strut free at the other end: fig22(e)'s chords)
    spun at 4 rad/s of wheel speed against 0.3 N m about its axis, pressed 0.3 N m
    sideways on its node (half of what its aim may take), spins at its command (0.9 of it
    at least over the second second) and stays within 1 deg of its aim. Before, the spin
    was the motors' voltage alone, scaled with the aim's roll within the top speed: it
    turned at 0.20 of its command (fig22(e)'s rollers at a third, the structure at 16 %
    of the asked speed)."""
    world = _one_strut()
    start, _ = _on_node(world)
    world.command_target("S1", "a", (start, None, 1.0))
    world.command_wheels("S1", "a", 4.0)
    dofs = world._dadr[0] + np.arange(3)
    spun, off = [], []
    for i in range(200):
        ball = world._ball(np.array([0]))[0]
        axis = Rotation.from_quat(ball, scalar_first=True).inv().apply([0.0, 0.0, 1.0])
        world.data.qfrc_applied[dofs] = 0.3 * np.array([0.0, 1.0, 0.0]) - 0.3 * axis
        world.step(0.01)
        if i >= 100:
            v = world.data.actuator_velocity[world._motor[0]]
            spun.append(0.5 * (v[1] - v[0]) / 4.0)
            off.append(_angle(_on_node(world)[0], start))
    assert np.mean(spun) > 0.9
    assert max(off) < 1.0


def test_a_leg_turning_when_its_free_wheels_start_stops_turning():
    """A leaf strut whose free end drives its wheels (the strut wheels, Fig. 18(d)-(f))
    does not turn about its axis: the turn steers those wheels. One turning toward a
    sideways error when its wheels start (the move to the behavior's start left the
    spider's legs so) stops at once, the error left to its rolling. Before, the turn ran
    on until the swing was within 0.3 deg, which a loaded leg never reached: on the
    scenario the legs turned 50-90 % of the time, their twist up to 180 deg off, the
    wheels' axles 30 deg off level, and the spider covered 8 % of its course."""
    world = _one_strut()
    _aim(world, 20.0, (0.0, 0.0, 1.0))
    world.step(0.1)
    assert world._turning[0]
    up = np.array([0.0, 0.0, 1.0])   # the wheels' forward vector the target keeps
    world.command_wheels("S1", "b", 2.0)
    world.step(0.02)
    turned = _angle(_on_node(world)[1], up)
    assert turned > 5.0
    furthest = 0.0
    for _ in range(50):
        world.step(0.02)
        assert not world._turning[0]
        furthest = max(furthest, _angle(_on_node(world)[1], up))
    assert furthest <= turned + 0.5
    assert _angle(_on_node(world)[1], up) < 2.0


def test_strut_wheels_legs_stand_where_the_shape_asks_after_driving_from_a_tilted_start():
    """Fig. 18(d)-(f) with differential connectors from the scenario's start (the spider as
    a new system reports it, its node tilted): held in shape by the controller every
    0.1 s while its free wheels drive. Its legs cannot move sideways on the node (a turn
    would steer their wheels), so they roll only, and the body's tilt is free. Aimed
    through the node's IMU attitude, the body sagged 5 deg and the legs, fixed on the
    node since the move, stood 4-7 deg sideways of their aims: the shape was 6.8 deg RMS
    off after 4.5 s (the scenario ended 5.19 deg off, over its 5 deg tolerance). Aimed
    through the frame that fits the legs' places on the node to their aims, the rolls
    bring the body to the tilt at which they stand as asked: 0.5 deg."""
    library = load_library(CONFIGS.parents[1] / "libraries" / "S4N1.json")
    chosen = library.sublibraries["S4N1"].behaviors["strut-wheels"]
    start = load_configuration(STARTS / "fig18-strut-wheels-start.json")
    designed = load_configuration(CONFIGS / f"{chosen.start}.json")
    goal, legs = min(((designed.relabel({"N0": "n0", **{f"S{i + 1}:b": f"s{j}:b" for i, j in
                                                          enumerate(order)}},
                                         {f"S{i + 1}": f"s{j}" for i, j in enumerate(order)}),
                       order) for order in itertools.permutations(range(4))),
                     key=lambda pair: skeletal_errors(start, pair[0])[0])
    controller = FreeSNController()
    with FreeSNMujocoDriver(connector_drive="differential") as driver:
        driver.reset(start)
        world = driver.world
        current = controller._recognizer.recognize(driver.get_observation().sensors)
        yaw = skeletal_errors(current, goal)[2]
        for tick in range(45):
            commands = controller.commands(goal, driver.get_observation(), yaw=yaw)
            if tick >= 5:   # the move first, then the wheels drive
                for command in chosen.commands:
                    leg = f"s{legs[int(command.module[1:]) - 1]}"
                    commands[leg] = replace(commands.get(leg, ModuleCommand()), wheels={
                        command.connector: command.value({"speed": 0.03})})
            driver.send_action(commands)
            driver.step(0.1)
        error = np.degrees(skeletal_errors(world.ground_truth(), goal)[0])
    assert error < 1.5, error


def _hung() -> FreeSNWorld:
    """N1 held by S0 alone (docked at N2 too, along +x) and carrying S1, free at its
    other end (along +y); gravity off."""
    config = Configuration("freesn")
    config.add_module("N1", "node")
    config.add_module("N2", "node")
    config.add_virtual("S1:b")
    up = np.array([0.0, 0.0, 1.0])
    config.connect("N1", "N2", id="S0", kind="strut", z=np.array([1.0, 0.0, 0.0]), x=up)
    config.connect("N1", "S1:b", id="S1", kind="strut", z=np.array([0.0, 1.0, 0.0]), x=up)
    world = FreeSNWorld(config, SPEC, SimOptions(connector_drive="differential"))
    world.model.opt.gravity[:] = 0.0
    return world


def test_a_free_strut_on_a_node_one_strut_holds_keeps_its_aim_while_the_node_turns():
    """A node that one docked strut alone holds turns under its free struts (fig22 after
    the undock of ``n0-s0b``: ``n4`` on ``s11`` turned at 71 deg/s under ``s0`` and ``s1``
    by their reaction). A free strut's aim, commanded once in the horizontal frame, stays
    there while the node (and its holder) turn 18-38 deg under it: within 2 deg after
    1-1.4 s. Before, its target was fixed on the shell between commands and it turned with
    the node, 13-26 deg off; its aims ran away on the shell and the connectors chased them
    (the undock's move took 24 s, then a connection broke)."""
    world = _hung()
    up = np.array([0.0, 0.0, 1.0])
    aim = np.array([0.0, 1.0, 0.0])
    world.command_target("S1", "a", (aim, None, 1.0))
    node, strut = world._node_body[0], world._strut_body[1]
    dofs = world._node_rate[0] + np.arange(3)
    off = []
    for step in range(35):
        turn = world.data.xmat[node].reshape(3, 3)
        world.data.qfrc_applied[dofs] = turn.T @ (0.005 * up)   # about the vertical
        world.step(0.04)
        if step >= 24:
            off.append(_angle(world.data.xmat[strut].reshape(3, 3)[:, 2], aim))
    turn = world.data.xmat[node].reshape(3, 3)
    assert np.degrees(np.arctan2(turn[1, 0], turn[0, 0])) > 15.0   # the node turned
    assert max(off) < 2.0, off


def test_a_free_strut_waits_while_the_one_strut_that_holds_its_node_turns():
    """A node that one docked strut alone holds turns with that strut when its connector
    there turns about the strut's axis (nothing else holds the node about it), and its
    free struts chased their aims round it: after fig22's undock of ``n0-s0b`` ``n4``
    turned at 44-93 deg/s under ``s0:a``, ``s1:a`` and its holder ``s11:b``, the free
    struts' swings never shrinking. A free strut's connector therefore holds still, its
    wheels braked, while the holder turns (< 1 deg on the node; 7.9 deg in 0.1 s before,
    the holder then turning in place for a 10 deg sideways target), and goes on when it
    stops (its aim < 2 deg off at 4 s; gravity off, the two nodes float)."""
    world = _hung()
    holder, free = world._end("S0", "a"), world._end("S1", "a")

    def on_node(k: int) -> np.ndarray:
        node = world.data.xmat[world._node_body[0]].reshape(3, 3)
        return node.T @ (world.data.xmat[world._strut_body[k // 2]].reshape(3, 3)[:, 2]
                         * world._sign[k])

    start = on_node(free)
    world.command_target("S0", "a", (Rotation.from_rotvec(np.radians(10.0) * np.array(
        [0.0, 0.0, 1.0])).apply([1.0, 0.0, 0.0]), None, 1.0))   # sideways: turns first
    aim = Rotation.from_rotvec(np.radians(20.0) * np.array([1.0, 0.0, 0.0])).apply(
        [0.0, 1.0, 0.0])
    world.command_target("S1", "a", (aim, None, 1.0))
    world.step(0.1)
    assert world._turning[holder]
    assert _angle(on_node(free), start) < 1.0
    world.step(3.9)
    assert _angle(world.data.xmat[world._strut_body[1]].reshape(3, 3)[:, 2], aim) < 2.0


def test_the_far_end_of_a_strut_wheeling_a_node_with_free_struts_does_not_turn():
    """In fig22's node wheels ``n4`` hangs on ``s11``, whose end there spins it as a
    wheel and so cannot turn against a turn of the far end: ``s11:a``'s turn on ``n2``
    spun ``n4`` and its free struts at 144 deg/s and broke ``s11:b``. The far end of such
    a strut therefore does not turn: given a 10 deg sideways target it never enters the
    turn mode in 0.5 s (before, it turned in place for it)."""
    world = _hung()
    far = world._end("S0", "b")
    world.command_target("S1", "a", (np.array([0.0, 1.0, 0.0]), None, 1.0))
    world.command_wheels("S0", "a", 2.0)
    world.command_target("S0", "b", (Rotation.from_rotvec(np.radians(10.0) * np.array(
        [0.0, 0.0, 1.0])).apply([-1.0, 0.0, 0.0]), None, 1.0))
    for _ in range(25):
        world.step(0.02)
        assert not world._turning[far]


def test_a_node_wheel_spins_its_node_at_its_command_under_load_while_its_far_end_holds():
    """A node wheel (Fig. 22(j)): S0 docked at N1 and N2 (gravity off), its end on N1
    spinning N1 at 2 rad/s of wheel speed (1.03 rad/s) against 0.3 N m about the strut's
    axis, N2 held by as much the other way, its aim 10 deg to the side (which a connector
    that is not wheeling turns toward). It does not turn, its far end holds (the strut
    turns on N2 at < 0.2 of the spin; 0.10) and N1 spins at its command (0.9 of it at least
    over the second second). Before, the wheeling end turned and handed its turn to the
    far end (``_common_turn``), which spun the strut at 1.4 times the asked spin, and
    the wheels' motors, a voltage within the top speed, drove N1 at 0.60 of it: fig22(j)'s
    node wheels spun their nodes at -14 %, 6 % and -14 % of their command and the body
    turned 35 deg in 28 s."""
    config = Configuration("freesn")
    config.add_module("N1", "node")
    config.add_module("N2", "node")
    x = np.array([1.0, 0.0, 0.0])
    config.connect("N1", "N2", id="S0", kind="strut", z=x, x=np.array([0.0, 0.0, 1.0]))
    world = FreeSNWorld(config, SPEC, SimOptions(connector_drive="differential"))
    world.model.opt.gravity[:] = 0.0
    wheel, far = world._end("S0", "a"), world._end("S0", "b")
    world.command_target("S0", "a", (Rotation.from_rotvec(np.radians(10.0) * np.array(
        [0.0, 0.0, 1.0])).apply(x), None, 1.0))
    world.command_target("S0", "b", (-x, None, 1.0))
    world.command_wheels("S0", "a", 2.0)
    asked = 2.0 / world.phys.turn_ratio
    spun, held = [], []
    for i in range(100):
        for n, sign in ((0, -1.0), (1, 1.0)):   # about the strut's axis, in node frames
            turn = world.data.xmat[world._node_body[n]].reshape(3, 3)
            world.data.qfrc_applied[world._node_rate[n] + np.arange(3)] = turn.T @ (
                sign * 0.3 * x)
        world.step(0.02)
        assert not world._turning[wheel]
        if i >= 50:
            rates = [float(world.data.qvel[world._dofs[k]] @ Rotation.from_quat(
                world._ball(np.array([k]))[0], scalar_first=True).inv().apply([0, 0, 1.0]))
                for k in (wheel, far)]   # about the strut's axis, relative to it
            spun.append(abs(rates[0]) / asked)
            held.append(abs(rates[1]) / asked)
    assert np.mean(spun) > 0.9, np.mean(spun)
    assert np.mean(held) < 0.2, np.mean(held)


def _sideways(world: FreeSNWorld, degrees: float, azimuth: float) -> None:
    """S1:a's target ``degrees`` off its pose about the strut-frame axis at ``azimuth``
    from ``x`` (0: sideways, the heading to turn +-90 deg; 90: straight ahead)."""
    k = np.array([0])
    a = np.radians(azimuth)
    error = Rotation.from_rotvec(np.radians(degrees) * np.array([np.cos(a), np.sin(a), 0.0]))
    world._ball_target[k] = quat_mul(error.as_quat(scalar_first=True)[None], world._ball(k))


def test_a_turn_toward_a_small_sideways_error_keeps_its_sense_as_the_errors_direction_swings():
    """A connector 1.6 deg off sideways turns toward the error (heading +84 deg, forwards);
    the error's direction then swings 18 deg (heading +102 deg forwards, -78 deg
    backwards). It keeps turning the same way: before, the way flipped to backwards and
    the turn's sense with it (fig22's s7:a, -96 deg then +73 deg at the wheels' top speed,
    broke off n2 at 79.0 s; stop 51)."""
    world = _one_strut()
    world._holder = world._hung_once()
    _sideways(world, 1.6, 6.0)
    speed, _ = world._steer(np.array([0]))
    assert world._turning[0] and not world._backwards[0]
    first = np.sign(speed[0, 1] - speed[0, 0])
    _sideways(world, 1.6, -12.0)
    speed, _ = world._steer(np.array([0]))
    assert world._turning[0]
    assert np.sign(speed[0, 1] - speed[0, 0]) == first
    assert not world._backwards[0]


def _two_strut_node(s0: tuple[np.ndarray, np.ndarray], s1: tuple[np.ndarray, np.ndarray]
                    ) -> FreeSNWorld:
    """A differential world of node N1 between strut S0 (to N2) and strut S1 (to N3), each
    given as its axis ``z`` and heading ``x`` from N1; gravity off, N2 and N3 held by
    1000 kg."""
    config = Configuration("freesn")
    for node in ("N1", "N2", "N3"):
        config.add_module(node, "node")
    for sid, far, (z, x) in (("S0", "N2", s0), ("S1", "N3", s1)):
        config.connect("N1", far, id=sid, kind="strut", z=z, x=x)
    world = FreeSNWorld(config, SPEC, SimOptions(connector_drive="differential"))
    world.model.opt.gravity[:] = 0.0
    for node in ("N2", "N3"):
        body = world._node_body[world._node_index[node]]
        world.model.body_mass[body] = 1000.0
        world.model.body_inertia[body] = 1000.0
    mujoco.mj_setConst(world.model, world.data)
    return world


def test_a_follower_turns_with_the_node_a_node_wheel_spins_and_its_strut_keeps_its_twist():
    """A node wheel's node with a second strut docked at both ends (fig22(j)'s floor nodes
    B1, B2: ``R1:b`` wheels B1, ``R2:a`` follows): N1 between S0 (to N2, along +x, its end
    on N1 spinning N1 at 2 rad/s of wheel speed) and S1 (to N3, 60 deg from S0), both
    axles in the struts' plane (x up), so neither grip holds the spin (gravity off; N2
    and N3 held by 1000 kg). A third of N1's spin about S0 is about S1's axis; S1's
    connector on N1 follows it by turning, its strut keeping its twist (< 0.1 of the spin
    about its axis over the second second) and N1 spins at its command (0.9 at least).
    Before, S1's aim alone commanded, its twist was left free and its turn braked: it held
    N1's spin with its brake's friction couple, which its far end's equal couple could not
    hold, so the strut turned with N1 at 0.26 of the spin and N1 spun at 0.89 of its
    command; in fig22(j) such a strut twisted at up to 3.4 rad/s and swung its node's
    rolling direction 100 deg in a second (stop 52)."""
    up, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    u1 = np.array([0.5, np.sqrt(3.0) / 2.0, 0.0])
    world = _two_strut_node((x, up), (u1, up))
    world.command_target("S0", "b", (-x, None, 1.0))
    world.command_target("S1", "a", (u1, None, 0.25))   # a loop's soft follower
    world.command_target("S1", "b", (-u1, None, 1.0))
    world.command_wheels("S0", "a", 2.0)
    asked = 2.0 / world.phys.turn_ratio
    wheel = world._end("S0", "a")
    spun, twisted = [], []
    for i in range(50):
        world.step(0.04)
        if i >= 25:
            rate = float(world.data.qvel[world._dofs[wheel]] @ Rotation.from_quat(
                world._ball(np.array([wheel]))[0], scalar_first=True).inv().apply([0, 0, 1.0]))
            strut = world._strut_body[world._strut_index["S1"]]
            w = np.zeros(6)
            mujoco.mj_objectVelocity(world.model, world.data, mujoco.mjtObj.mjOBJ_BODY,
                                     int(strut), w, 0)
            spun.append(abs(rate) / asked)
            twisted.append(abs(float(w[:3] @ world.data.xmat[strut].reshape(3, 3)[:, 2])) / asked)
    assert np.mean(spun) > 0.9, np.mean(spun)
    assert np.mean(twisted) < 0.1, np.mean(twisted)


def _held_node(travel: float) -> tuple[FreeSNWorld, np.ndarray]:
    """N1 held by two struts docked at both ends, their axles built level (a fixed wheel):
    S0 (to N2, 45 deg up toward +x) spins N1 from its end a at 0.1 rad/s of wheel speed,
    which alone rolls N1 along -+y; S1 (to N3, 45 deg up at azimuth 120 deg) follows. N1
    is commanded to travel at azimuth ``travel`` [deg]
    (:mod:`~msrr.plugins.freesn.sim.commands`); gravity off, N2 and N3 held by 1000 kg.
    The world and the travel (3,)."""
    up = np.array([0.0, 0.0, 1.0])
    a = np.radians(120.0)
    u0 = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    u1 = np.array([np.cos(a), np.sin(a), 1.0]) / np.sqrt(2.0)
    def level(u: np.ndarray) -> np.ndarray:
        x = up - (up @ u) * u
        return x / np.linalg.norm(x)

    world = _two_strut_node((u0, level(u0)), (u1, level(u1)))
    world.command_target("S0", "b", (-u0, None, 1.0))
    world.command_target("S1", "a", (u1, None, 0.25))   # a loop's soft follower
    world.command_target("S1", "b", (-u1, None, 1.0))
    t = np.array([np.cos(np.radians(travel)), np.sin(np.radians(travel)), 0.0])
    d = np.cross(u0, up) / np.linalg.norm(np.cross(u0, up))   # how S0 rolls N1: -y
    along, across = float(t @ d), float(t @ np.cross(up, d))
    world.command_wheels("S0", "a", 0.1 * np.sign(along))
    world.command_travel("S0", "a", along, across)
    return world, t


def test_a_node_two_struts_hold_is_steered_to_roll_along_its_commanded_travel():
    """fig22(j)'s floor nodes B1, B2 (stop 52): a node held by two struts docked at both
    ends turns relative to them only about ``n = x_W x x_F`` (each connector grips about
    its heading), so it rolls one way only, ``n x up``, set by the struts' twists. As
    built (:func:`_held_node`) N1 rolls along -30/150 deg; commanded to travel at 60 deg,
    90 deg off that line, the follower S1 turns at both ends until N1's line is the
    travel, like a swerve wheel: within 3 deg of it from 0.6 s to 2 s (the struts' true
    axes). Before (no swerve), the line stayed 89-90 deg off."""
    world, t = _held_node(60.0)
    up = np.array([0.0, 0.0, 1.0])
    off = []
    for i in range(50):
        world.step(0.04)
        if i >= 14:
            x0, x1 = (world.data.xmat[world._strut_body[world._strut_index[s]]].reshape(3, 3)
                      [:, 0] for s in ("S0", "S1"))
            line = np.cross(np.cross(x0, x1), up)
            off.append(_angle(line, t) if line @ t >= 0 else _angle(-line, t))
    assert max(off) < 3.0, max(off)


def test_node_travel_and_swerve_heading_set_the_follower_so_the_node_rolls_along_the_travel():
    """The pure maths (:func:`node_travel`, :func:`swerve_heading`): the travel from the
    wheel speed and the travel across is the direction asked; the follower's heading it
    gives leaves ``x_W x x_F`` at right angles to it; none without a travel."""
    from msrr.plugins.freesn.sim.world import node_travel, swerve_heading
    up = np.array([0.0, 0.0, 1.0])
    u0 = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    a = np.radians(120.0)
    u1 = np.array([np.cos(a), np.sin(a), 1.0]) / np.sqrt(2.0)
    x0, x1 = up - (up @ u0) * u0, up - (up @ u1) * u1
    x0, x1 = x0 / np.linalg.norm(x0), x1 / np.linalg.norm(x1)
    follower = np.column_stack([x1, np.cross(u1, x1), u1])
    for azimuth in (20.0, 60.0, 100.0, 200.0):
        t = np.array([np.cos(np.radians(azimuth)), np.sin(np.radians(azimuth)), 0.0])
        d = np.array([0.0, -1.0, 0.0])
        travel = node_travel(u0, up, 3.0 * float(t @ d), 3.0 * float(t @ np.cross(up, d)))
        assert np.allclose(travel, t, atol=1e-9)
        heading = follower @ swerve_heading(x0, follower, travel)
        assert abs(float(heading @ u1)) < 1e-9
        assert abs(float(np.cross(x0, heading) @ t)) < 1e-9
        assert float(heading @ x1) >= 0.0
    assert not node_travel(u0, up, 0.0, 0.0).any()
    assert swerve_heading(x0, follower, np.zeros(3)) is None


def test_a_swerved_strut_keeps_its_twist_when_its_far_end_is_left_a_small_sideways_error():
    """fig22(j), stop 53: the follower's far end (``s8:b`` on the top node ``n5``), left
    a degree or two off its aim sideways by the structure's motion, turned toward that
    error (a sideways error alone, over 0.6 deg: the turn mode), up to 90 deg about the
    strut's axis at the wheels' top speed. That turn undid the swerve's twist (the floor
    node's line 40-90 deg off the travel), the near end turned it back, and each turn on
    the top node pushed its other connectors off their aims; they rolled back against the
    structure and ``s9`` (``n5``-``n2``) broke at 20 N. A connector whose twist the swerve
    sets never turns toward an error: it rolls out the part along its heading and keeps
    its twist. Here (:func:`_held_node`) S1:b is aimed 2 deg sideways once N1 rolls along
    its travel; the line stays within 3 deg of it. Before, it went 30-90 deg off."""
    world, t = _held_node(60.0)
    up = np.array([0.0, 0.0, 1.0])
    strut = world._strut_body[world._strut_index["S1"]]
    for _ in range(20):
        world.step(0.04)
    rot = world.data.xmat[strut].reshape(3, 3)
    node = world.data.xmat[world._node_body[world._node_index["N3"]]].reshape(3, 3)
    aside = Rotation.from_rotvec(np.radians(2.0) * rot[:, 0]).apply(-rot[:, 2])
    world.command_target("S1", "b", (node.T @ aside, None, 1.0))
    off = []
    for _ in range(30):
        world.step(0.04)
        x0, x1 = (world.data.xmat[world._strut_body[world._strut_index[s]]].reshape(3, 3)
                  [:, 0] for s in ("S0", "S1"))
        line = np.cross(np.cross(x0, x1), up)
        off.append(_angle(line, t) if line @ t >= 0 else _angle(-line, t))
    assert max(off) < 3.0, max(off)


def _fight(hub: bool) -> tuple[FreeSNWorld, float]:
    """S0 docked at both ends from N1 to N2, its end b (on N2, full effort) aimed where it
    is, its end a (on N1, effort 0.25) 3 deg off where it is: a fight (the strut cannot
    serve both). With ``hub``, S1 and S2 also hold N1 (three docked connectors), their
    ends aimed where they are at full effort. Every node 1000 kg, gravity off. The world
    and the bound of an integral."""
    config = Configuration("freesn")
    struts = {"S0": np.array([1.0, 0.0, 1.0]), "S1": np.array([-1.0, 1.0, 1.0]),
              "S2": np.array([-1.0, -1.0, 1.0])}
    if not hub:
        struts = {"S0": struts["S0"]}
    config.add_module("N1", "node")
    for i, (sid, z) in enumerate(struts.items()):
        config.add_module(f"N{i + 2}", "node")
        config.connect("N1", f"N{i + 2}", id=sid, kind="strut", z=z / np.linalg.norm(z),
                       x=np.cross(z, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(z, [0, 0, 1])))
    world = FreeSNWorld(config, SPEC, SimOptions(connector_drive="differential"))
    world.model.opt.gravity[:] = 0.0
    for body in world._node_body:
        world.model.body_mass[body] = 1000.0
        world.model.body_inertia[body] = 1000.0
    mujoco.mj_setConst(world.model, world.data)
    for sid, z in struts.items():
        u = z / np.linalg.norm(z)
        aim = Rotation.from_rotvec(np.radians(3.0) * np.array([0.0, 1.0, 0.0])).apply(u)
        world.command_target(sid, "a", (aim if sid == "S0" else u, None,
                                        0.25 if sid == "S0" else 1.0))
        world.command_target(sid, "b", (-u, None, 1.0))
    return world, world._integral_bound


def test_a_soft_end_on_a_hub_winds_its_integral_to_its_effort_share_alone():
    """A soft follower (reduced effort, ``driving_ends``) on a node three or more docked
    connectors hold winds its integral at most to its effort's share of the bound: whole,
    two ends of fig20's loop wound against each other to their bounds and spent them when
    they moved again, and its last move stalled at 31 deg (stops 53-54). On a node only
    its strut holds (a chain's), it keeps the whole bound: it carries a load there, and
    capped, the squirm ended 29 deg off its heading (stop 54). Here S0's soft end a is
    aimed 3 deg off what its end b holds; after 3 s on a hub its integral is within a
    quarter of the bound (before: the whole of it), and beyond it alone on its node."""
    world, bound = _fight(hub=True)
    world.step(3.0)
    soft = np.abs(world._integral[world._end("S0", "a"), 1:]).max() / bound
    assert 0.2 < soft <= 0.25 + 1e-9, soft   # a fight: it winds to its share
    world, bound = _fight(hub=False)
    world.step(3.0)
    alone = np.abs(world._integral[world._end("S0", "a"), 1:]).max() / bound
    assert alone > 0.9, alone
