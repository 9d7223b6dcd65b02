"""The course loop of a straight mapping behavior (issue 31): on a simulated wheeled body
whose travel is off its heading by an unknown crab, the heading loop alone holds the
heading and goes off the line by the crab; with the course loop on top it follows the
commanded line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.estimation import Estimate
from msrr.core.executor import (
    CourseLoop,
    ExecutorOptions,
    HeadingLoop,
    course_loop,
    heading_loop,
    held_heading,
    slid,
    slides,
    steered,
    turn_bound,
)
from msrr.core.plan import BehaviorCall, CommandGain

OPTIONS = ExecutorOptions()


def drive(crab: float, *, course: bool, heading: float = 0.3, speed: float = 0.03,
          duration: float = 60.0, dt: float = 0.1) -> np.ndarray:
    """Where a unicycle ends [m], shape (2,): it starts at the origin facing ``heading``
    [rad], asked to go straight ahead at ``speed`` [m/s]; it travels ``crab`` [rad] off
    its heading and turns at the ``yaw_rate`` its loops ask."""
    ahead = np.array([math.cos(heading), math.sin(heading)])
    call = BehaviorCall("wheels", "mapping", {"speed": speed, "yaw_rate": 0.0},
                        (CommandGain("S1", "wheel_speed", (("speed", 1.0), ("yaw_rate", 1.0))),),
                        duration=duration, direction=(1.0, 0.0, 0.0))
    loop = HeadingLoop(heading, 0.0, OPTIONS.heading_gain, OPTIONS.heading_integral,
                       OPTIONS.max_heading_correction)
    outer = course_loop(call, Estimate(position=np.zeros(2), heading=heading), 0.0, OPTIONS) \
        if course else None
    if course:
        assert outer is not None and np.allclose(outer.direction, math.copysign(1.0, speed) * ahead)
    place, psi = np.zeros(2), heading
    for step in range(round(duration / dt)):
        offset = 0.0 if outer is None else outer.offset(place)
        psi += dt * loop.correction(psi, step * dt, dt, offset)
        travel = psi + crab * math.copysign(1.0, speed)
        place = place + dt * speed * np.array([math.cos(travel), math.sin(travel)])
    return place


@pytest.mark.parametrize("crab", [math.radians(40.0), math.radians(-25.0)])
def test_the_course_loop_follows_the_commanded_line_whatever_the_crab(crab):
    ahead = np.array([math.cos(0.3), math.sin(0.3)])
    held = drive(crab, course=False)
    off = math.degrees(math.acos(held @ ahead / np.linalg.norm(held)))
    assert off == pytest.approx(abs(math.degrees(crab)), abs=1.0)  # heading held, course not
    followed = drive(crab, course=True)
    along = float(followed @ ahead)
    assert along > 0.9 * 1.8                        # covers its distance (0.03 m/s x 60 s)
    side = float(ahead[0] * followed[1] - ahead[1] * followed[0])
    assert abs(side) < 0.01                         # back on the line
    assert abs(math.degrees(math.atan2(side, along))) < 1.0


def test_backwards_the_line_is_behind_and_the_loop_still_follows_it():
    ended = drive(math.radians(30.0), course=True, speed=-0.03)
    behind = -np.array([math.cos(0.3), math.sin(0.3)])
    assert float(ended @ behind) > 0.9 * 1.8
    assert abs(float(behind[0] * ended[1] - behind[1] * ended[0])) < 0.01


def test_the_course_offset_is_bounded_and_does_not_wind_up():
    loop = CourseLoop(np.zeros(2), np.array([1.0, 0.0]), gain=6.0, integral_gain=9.0,
                      bound=1.0)
    assert loop.offset(np.array([0.0, 0.0])) == 0.0
    assert loop.offset(np.array([0.1, 0.05])) == pytest.approx(-6.0 * 0.05 - 9.0 * 0.05 * 0.1
                                                               * math.hypot(1.0, 0.5))
    for x in range(1, 500):
        assert loop.offset(np.array([0.1 + 0.01 * x, 5.0])) == -1.0   # far left: turn right
    assert loop.integral_gain * abs(loop.integral) <= 1.0 + 1e-12


def test_only_a_straight_behavior_with_a_direction_and_a_known_place_has_one():
    gains = (CommandGain("S1", "wheel_speed", (("speed", 1.0), ("yaw_rate", 1.0))),)
    known = Estimate(position=np.zeros(2), heading=0.0)
    turning = BehaviorCall("w", "mapping", {"speed": 0.03, "yaw_rate": 0.1}, gains,
                           duration=10.0, direction=(1.0, 0.0, 0.0))
    undirected = BehaviorCall("w", "mapping", {"speed": 0.03}, gains, duration=10.0)
    straight = BehaviorCall("w", "mapping", {"speed": 0.03}, gains, duration=10.0,
                            direction=(0.0, 1.0, 0.0))
    assert course_loop(turning, known, 0.0, OPTIONS) is None
    assert course_loop(undirected, known, 0.0, OPTIONS) is None
    assert course_loop(straight, Estimate(), 0.0, OPTIONS) is None
    turned = course_loop(straight, Estimate(position=np.ones(2), heading=0.5), 0.25, OPTIONS)
    assert turned is not None
    assert np.allclose(turned.direction, [-math.sin(0.75), math.cos(0.75)])
    assert np.allclose(turned.origin, [1.0, 1.0])


ROLLERS = (CommandGain("C2", "wheel_speed", (("speed", -62.5), ("yaw_rate", 15.027129644))),
           CommandGain("C4", "wheel_speed", (("speed", 62.5), ("yaw_rate", 11.418690462))),
           CommandGain("C6", "wheel_speed", (("speed", 62.5), ("yaw_rate", 11.418690462))))
"""fig22's wheeled move (S12N6 library): three chords rolled as rollers."""


def test_the_heading_loop_asks_no_roller_to_turn_harder_than_it_rolls_forward():
    """At 0.05 m/s the rollers turn 3.1 rad/s; the old 0.5 rad/s bound asked 7.5 rad/s of
    C2 to turn, and fig22's wheeled move spun on the spot (issue 31)."""
    call = BehaviorCall("wheeled-move", "mapping", {"speed": 0.05, "yaw_rate": 0.0}, ROLLERS,
                        duration=60.0, direction=(1.0, 0.0, 0.0))
    bound = turn_bound(call)
    assert bound == pytest.approx(62.5 * 0.05 / 15.027129644)          # C2 is the tightest
    for command in ROLLERS:   # every roller: its turn within its travel, C2 at its limit
        gains = dict(command.gains)
        assert abs(gains["yaw_rate"] * bound) <= abs(gains["speed"] * 0.05) + 1e-12
    loop = heading_loop(call, 0.0, OPTIONS)
    assert loop is not None and loop.bound == pytest.approx(bound)
    assert abs(loop.correction(-3.0, 0.0, 0.1)) == pytest.approx(bound)
    slow = BehaviorCall("wheeled-move", "mapping", {"speed": 0.5}, ROLLERS, duration=6.0)
    assert heading_loop(slow, 0.0, OPTIONS).bound == OPTIONS.max_heading_correction
    turn = BehaviorCall("turn", "mapping", {"yaw_rate": 0.2}, ROLLERS, duration=6.0)
    assert turn_bound(turn) == math.inf          # a turn on the spot: the turn is all it asks


def _star(turn: float) -> Configuration:
    """Three struts from a hub, as recognized in a frame turned by ``-turn`` [rad]."""
    config = Configuration("freesn")
    config.add_module("H", "node")
    for k in range(3):
        config.add_module(f"N{k}", "node")
        z = rot_z(turn + 2.0 * k) @ np.array([1.0, 0.0, -0.1 * k])
        config.connect("H", f"N{k}", id=f"S{k}", kind="strut", z=z / np.linalg.norm(z))
    return config


@pytest.mark.parametrize("spin", [0.4, -1.7, 3.0])
def test_the_held_heading_does_not_turn_when_the_root_frame_turns_under_the_body(spin):
    """The root's frame turns by ``spin`` under a body that keeps still: the estimated
    heading turns by ``spin`` and the body, recognized in that frame, by ``-spin``."""
    target = _star(0.0)
    before = held_heading(0.25, _star(0.1), target)
    after = held_heading(0.25 + spin, _star(0.1 - spin), target)
    assert math.remainder(after - before, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)
    assert before == pytest.approx(0.35, abs=1e-6)


KIWI = (CommandGain("R1", "wheel_speed", (("speed", 1.0), ("yaw_rate", -0.1),
                                          ("sideways", 1.7))),
        CommandGain("R3", "wheel_speed", (("speed", -2.0), ("yaw_rate", -0.1))),
        CommandGain("R5", "wheel_speed", (("speed", 1.0), ("yaw_rate", -0.1),
                                          ("sideways", -1.7))))
"""A kiwi drive (fig22(j)'s node wheels, S12N6 library): three wheels rolling 120 deg
apart, every one asked the same small share of a turn."""


def creep(call: BehaviorCall, *, turns: float = 1.0 / 30.0, duration: float = 60.0,
          dt: float = 0.1) -> tuple[np.ndarray, float]:
    """Where a holonomic body ends [m], shape (2,), and its heading [rad]: it starts at the
    origin facing +x, asked ``call``; it travels as its ``speed`` and ``sideways`` ask (body
    frame) plus a creep of half its speed toward -y (world frame), and turns at
    ``turns`` of the ``yaw_rate`` asked (every wheel scrubs a turn; fig22(j) under noise)."""
    speed = call.parameters["speed"]
    loop = heading_loop(call, 0.0, OPTIONS)
    outer = course_loop(call, Estimate(position=np.zeros(2), heading=0.0), 0.0, OPTIONS)
    assert loop is not None and outer is not None
    place, psi = np.zeros(2), 0.0
    for step in range(round(duration / dt)):
        asked = steered(call, loop, outer, psi, place, step * dt, dt)
        ahead, left = asked["speed"], asked.get("sideways", 0.0)
        place = place + dt * (rot_z(psi)[:2, :2] @ np.array([ahead, left])
                              + np.array([0.0, -speed / 2.0]))
        psi += dt * turns * asked["yaw_rate"]
    return place, psi


def test_a_body_that_slides_follows_the_line_through_a_creep_it_cannot_turn_against():
    """fig22(j)'s node wheels at 2 deg of noise (issue 31): a creep sideways; the body
    turns at a thirtieth of what the loop asks. Steered by its heading, it goes 13 deg off
    the line; slid, it stays on the line and keeps its heading."""
    call = BehaviorCall("node-wheels", "mapping", {"speed": 0.03}, KIWI, duration=60.0,
                        direction=(1.0, 0.0, 0.0))
    assert slides(call)
    turned = BehaviorCall("node-wheels", "mapping", {"speed": 0.03},
                          tuple(CommandGain(c.module, c.command,
                                            tuple((p, g) for p, g in c.gains if p != "sideways"))
                                for c in KIWI), duration=60.0, direction=(1.0, 0.0, 0.0))
    assert not slides(turned)
    off, _ = creep(turned)
    assert abs(math.degrees(math.atan2(off[1], off[0]))) > 10.0
    ended, heading = creep(call)
    assert ended[0] > 0.8 * 1.8                     # some of its speed goes against the creep
    assert abs(math.degrees(math.atan2(ended[1], ended[0]))) < 1.0
    assert abs(math.degrees(heading)) < 1.0


def test_sliding_turns_the_travel_asked_and_nothing_else():
    asked = slid({"speed": 0.03, "yaw_rate": 0.1}, math.radians(90.0))
    assert asked["speed"] == pytest.approx(0.0, abs=1e-12)
    assert asked["sideways"] == pytest.approx(0.03)
    assert asked["yaw_rate"] == 0.1
    back = slid({"speed": -0.03, "sideways": 0.01}, math.pi)
    assert (back["speed"], back["sideways"]) == pytest.approx((0.03, -0.01))


RADIAL = tuple(CommandGain(f"S{i + 1}", "wheel_speed",
                           (("speed", math.cos(a)), ("sideways", math.sin(a))), connector="target")
               for i, a in enumerate(np.radians([45.0, 135.0, 225.0, 315.0])))
"""fig18(d)'s strut wheels: four radial wheels, no ``yaw_rate`` (they exert no yaw)."""


def test_a_base_that_cannot_turn_keeps_its_travel_in_the_world_as_it_yaws():
    """fig18(d)'s strut wheels at 2 deg of noise (issue 31): the body yaws by what the
    floor does (here 0.5 deg/s) and nothing it can command turns it back; with no place
    known there is no course loop. Its travel, turned back by the yaw the gyros measure,
    keeps the direction asked in the world frame where the behavior began; a loop that
    asked for a turn would ask for nothing the wheels carry out."""
    call = BehaviorCall("strut-wheels", "mapping", {"speed": 0.03}, RADIAL, duration=60.0,
                        direction=(1.0, 0.0, 0.0))
    assert slides(call) and turn_bound(call) == math.inf
    loop = heading_loop(call, 0.2, OPTIONS)
    assert loop is not None and loop.bound == 0.0
    place, psi, dt = np.zeros(2), 0.2, 0.1
    for step in range(600):
        asked = steered(call, loop, None, psi, None, step * dt, dt)
        assert asked["yaw_rate"] == 0.0
        wheels = np.array([command.value(asked) for command in call.commands])
        body = np.linalg.lstsq(np.array([[math.cos(a), math.sin(a)] for a in
                                         np.radians([45.0, 135.0, 225.0, 315.0])]),
                               wheels, rcond=None)[0]           # the travel the wheels roll
        place = place + dt * (rot_z(psi)[:2, :2] @ body)
        psi += dt * math.radians(0.5)
    assert math.degrees(psi - 0.2) > 25.0
    assert np.linalg.norm(place) == pytest.approx(1.8, rel=1e-6)
    assert abs(math.degrees(math.atan2(place[1], place[0]) - 0.2)) < 0.5
