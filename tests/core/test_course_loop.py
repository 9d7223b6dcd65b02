"""The course loop of a straight mapping behavior (issue 31): on a simulated wheeled body
whose travel is off its heading by an unknown crab, the heading loop alone holds the
heading and goes off the line by the crab; with the course loop on top it follows the
commanded line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msrr.core.estimation import Estimate
from msrr.core.executor import CourseLoop, ExecutorOptions, HeadingLoop, course_loop
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
