"""A node wheel whose node only its own strut holds closes its stance through its own
wheel (issue 31, fig. 22(j)'s ``R5``): its correction from the recognized configuration,
on a triangle body with one such wheel strut."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msrr.core.alignment import rot_z
from msrr.core.configuration import Configuration
from msrr.core.plan import Action, ActionType
from msrr.plugins.freesn.robot import STRUT
from msrr.plugins.freesn.sim.controller import (
    LONE_WHEEL_BAND,
    LONE_WHEEL_BOUND,
    LONE_WHEEL_GAIN,
    NODE_ROLLING,
    FreeSNController,
    lone_wheel_corrections,
    lone_wheels,
)

L = STRUT.geometry["length"]
BODY = {"N1": (0.0, 0.0, 0.0), "N2": (L, 0.0, 0.0), "N3": (0.5 * L, 0.5 * math.sqrt(3) * L, 0.0)}
"""A level triangle of struts S1-S3; S4 runs from N1 down to the wheel node W."""


def stance(swing: float = 0.0, turn: float = 0.0, *, wheel_end: str = "b") -> Configuration:
    """The triangle and the wheel strut ``S4`` from ``N1`` to ``W`` at azimuth 210 deg +
    ``swing`` [rad], 30 deg below the level, the whole turned by ``turn`` [rad] about the
    vertical; ``W`` at the strut's end ``wheel_end``."""
    places = {n: np.array(p) for n, p in BODY.items()}
    out = math.radians(210.0) + swing
    places["W"] = places["N1"] + L * np.array([math.cos(out) * math.cos(math.radians(30)),
                                               math.sin(out) * math.cos(math.radians(30)),
                                               -math.sin(math.radians(30))])
    config = Configuration("freesn")
    for node in places:
        config.add_module(node, "node")
    wheel = ("N1", "W") if wheel_end == "b" else ("W", "N1")
    for strut, (a, b) in {"S1": ("N1", "N2"), "S2": ("N2", "N3"), "S3": ("N3", "N1"),
                          "S4": wheel}.items():
        z = rot_z(turn) @ (places[b] - places[a])
        config.connect(a, b, id=strut, kind="strut", z=z / np.linalg.norm(z))
    return config


def swing_rate(end: str, speed: float) -> float:
    """How fast [rad/s] the wheel node swings round ``N1`` at wheel speed ``speed`` [rad/s]:
    the node turns about the strut's ``+z`` (end a to b) and its centre rolls along
    ``+z x e_z`` at ``NODE_ROLLING`` per unit horizontal axis."""
    z = stance(wheel_end=end).edge("S4").z
    velocity = speed * NODE_ROLLING * np.cross(z, [0.0, 0.0, 1.0])
    reach = (z if end == "b" else -z) * L
    return float((reach[0] * velocity[1] - reach[1] * velocity[0]) / (reach[:2] @ reach[:2]))


@pytest.mark.parametrize("end", ["a", "b"])
def test_a_lone_wheel_turns_its_node_back_by_its_azimuth_error(end: str):
    delta = math.radians(8.0)
    wheels = {"S4": {end: 1.5}, "S1": {"b": 0.7}}
    assert lone_wheels(stance(delta, wheel_end=end), wheels) == {("S4", end): "N1"}
    added = lone_wheel_corrections(stance(wheel_end=end), stance(delta, wheel_end=end), wheels)
    assert set(added) == {"S4"}                    # the triangle's wheel is held: not named
    value = added["S4"][end]
    beyond = delta - LONE_WHEEL_BAND
    assert abs(value) == pytest.approx(LONE_WHEEL_GAIN * beyond * L / NODE_ROLLING, rel=1e-6)
    # the swing it drives closes the error beyond the band at the gain's rate
    assert swing_rate(end, value) == pytest.approx(-LONE_WHEEL_GAIN * beyond, rel=1e-6)
    far = lone_wheel_corrections(stance(wheel_end=end), stance(-0.5, wheel_end=end),
                                 wheels)["S4"][end]
    assert abs(far) == pytest.approx(LONE_WHEEL_BOUND) and swing_rate(end, far) > 0.0


def test_a_rigid_turn_of_the_whole_stance_needs_no_correction():
    wheels = {"S4": {"b": 1.5}}
    added = lone_wheel_corrections(stance(), stance(turn=math.radians(40.0)), wheels)
    assert added["S4"]["b"] == pytest.approx(0.0, abs=1e-9)
    moved = lone_wheel_corrections(stance(), stance(0.1, turn=math.radians(40.0)), wheels)
    assert moved["S4"]["b"] == pytest.approx((0.1 - LONE_WHEEL_BAND) * L / NODE_ROLLING,
                                             rel=1e-6)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_an_error_within_the_dead_band_is_left_alone(sign: float):
    wheels = {"S4": {"b": 1.5}}
    inside = lone_wheel_corrections(stance(), stance(sign * 0.9 * LONE_WHEEL_BAND), wheels)
    assert inside["S4"]["b"] == pytest.approx(0.0, abs=1e-12)
    past = lone_wheel_corrections(stance(), stance(sign * (LONE_WHEEL_BAND + 0.01)), wheels)
    assert past["S4"]["b"] == pytest.approx(sign * 0.01 * L / NODE_ROLLING, rel=1e-4)
    assert lone_wheel_corrections(stance(), stance(sign * 0.9 * LONE_WHEEL_BAND), wheels,
                                  band=0.0)["S4"]["b"] != pytest.approx(0.0, abs=1e-3)


def test_gain_zero_leaves_the_behaviors_wheels_as_they_are():
    wheels = {"S4": {"b": 1.5}, "S1": {"b": 0.7}}
    assert lone_wheel_corrections(stance(), stance(0.1), wheels, gain=0.0) == {}
    action = Action(ActionType.BEHAVIOR, stance())
    assert FreeSNController(lone_wheel_gain=0.0).correct_wheels(
        action, stance(0.1), wheels) == wheels
    corrected = FreeSNController().correct_wheels(action, stance(0.1), wheels)
    assert corrected["S1"] == {"b": 0.7}
    assert corrected["S4"]["b"] == pytest.approx(
        1.5 + (0.1 - LONE_WHEEL_BAND) * L / NODE_ROLLING, rel=1e-6)
