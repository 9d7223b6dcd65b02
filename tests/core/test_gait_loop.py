"""A sequence gait's heading loop (issue 31): the FreeSN squirm turned 7.4 deg a loop
unasked, and no loop acted on a gait (a sequence has no ``yaw_rate``). :class:`GaitLoop`
asks each step for a turn of the body about its planted feet
(:func:`~msrr.core.closed_loop.turned_goal`), a :class:`CourseLoop` setting its
reference."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from msrr.core.alignment import align_yaw, rot_z
from msrr.core.closed_loop import turned_goal
from msrr.core.configuration import Configuration
from msrr.core.estimation import Estimate
from msrr.core.executor import (
    ExecutorOptions,
    GaitLoop,
    course_loop,
    ends_loop,
    gait_loop,
    retakes_unturned,
)
from msrr.core.kinematics import FixedNode, KinematicTree
from msrr.core.plan import Action, ActionType, BehaviorCall

sys.path.insert(0, str(Path(__file__).parent / "kinematics"))
from kin_helpers import GimbalJoint, chain  # noqa: E402

OPTIONS = ExecutorOptions()


class Foot(GimbalJoint):
    """A gimbal joint whose far end grips the ground."""

    name = "foot"
    planted = True


def squirm_tree(config, *, planted: bool = True) -> KinematicTree:
    """H1-R1-H2-R2-H3-R3-H4-R4-H5: the root holds R3 (H3, H4), R4 a leg to its foot H5
    (planted or not), R2 and R1 the free half, R1 hanging from R2."""
    leg = Foot if planted else GimbalJoint
    return KinematicTree(config, [FixedNode(["R3"], ["H3", "H4"]), leg(["R4"], ["H5"]),
                                  GimbalJoint(["R2"], ["H2"]), GimbalJoint(["R1"], ["H1"])])


def azimuths(config) -> dict[str, float]:
    return {e.id: math.atan2(e.z[1], e.z[0]) for e in config.edges()}


def test_turned_goal_turns_the_planted_leg_against_the_body():
    goal = chain(4)
    turned = turned_goal(goal, squirm_tree(goal), math.radians(5.0))
    before, after = azimuths(goal), azimuths(turned)
    assert after["R4"] - before["R4"] == pytest.approx(math.radians(-5.0))
    for edge in ("R1", "R2", "R3"):   # the root and the free half are kept
        assert after[edge] == pytest.approx(before[edge])
    # the body (every edge but the foot's) stands turned by +5 deg against the foot
    ids = ["R1", "R2", "R3", "R4"]
    body = align_yaw(turned.vectors(ids[:3]), goal.vectors(ids[:3])).theta
    foot = align_yaw(turned.vectors(ids[3:]), goal.vectors(ids[3:])).theta
    assert math.degrees(wrap(body - foot)) == pytest.approx(5.0)


def wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def test_turned_goal_changes_nothing_without_a_planted_foot_a_root_edge_or_a_turn():
    goal = chain(4)
    assert turned_goal(goal, squirm_tree(goal, planted=False), 0.1) is goal
    assert turned_goal(goal, squirm_tree(goal), 0.0) is goal
    rootless = KinematicTree(goal, [FixedNode([], ["H3"]), GimbalJoint(["R3"], ["H4"]),
                                    Foot(["R4"], ["H5"]), GimbalJoint(["R2"], ["H2"]),
                                    GimbalJoint(["R1"], ["H1"])])
    assert turned_goal(goal, rootless, 0.1) is goal   # the turn would be a gauge



def test_a_gait_loop_turns_a_step_by_at_most_the_step_itself():
    """A gait step is turned by at most its own size (RMS between two stances): the S12N6
    trot's 3.3 deg steps, turned by up to 8 deg, folded its body under noise (stop 48); the
    squirm's 26 deg steps keep ``max_gait_turn``."""
    call = BehaviorCall("trot", "sequence", {}, loops=4, distance=1.0, direction=(1.0, 0.0, 0.0))
    far_off = math.radians(-30.0)
    loop = gait_loop(call, 0.0, OPTIONS)
    assert math.degrees(loop.turn(far_off, step=math.radians(3.3))) == pytest.approx(3.3)
    assert loop.turn(far_off, step=math.radians(26.1)) == pytest.approx(OPTIONS.max_gait_turn)

def trotter() -> Configuration:
    """A body bar R1 from H1 to H2 on two diagonal legs: R2 from H1 down to the foot F1 on
    the left, R3 from H2 down to F2 on the right (the S12N6 trot's planted pair)."""
    config = Configuration("stick", name="trotter")
    for v in ("H1", "H2", "F1", "F2"):
        config.add_module(v, "hub")
    config.connect("H1", "H2", id="R1", kind="rod", z=[-1, 0, 0])
    leg = np.array([0.05, 0.28, -0.96]) / np.linalg.norm([0.05, 0.28, -0.96])
    ahead = np.array([1.0, 0.0, 0.0]) - leg[0] * leg   # a forward vector square to the leg
    config.connect("H1", "F1", id="R2", kind="rod", z=leg, x=ahead / np.linalg.norm(ahead))
    config.connect("F2", "H2", id="R3", kind="rod", z=-leg * [1, -1, 1])  # foot first
    return config


def test_turned_goal_turns_the_body_rigidly_about_two_planted_feet():
    """With a diagonal pair planted (the S12N6 trot) the body turns about the middle of
    the two feet and both feet stay where they stand; turning each leg about its own hip
    (or, before, nothing) leaves the body's heading or the feet's places off."""
    goal = trotter()
    tree = KinematicTree(goal, [FixedNode(["R1"], ["H1", "H2"]), Foot(["R2"], ["F1"]),
                                Foot(["R3"], ["F2"])])
    turn = math.radians(5.0)
    turned = turned_goal(goal, tree, turn)
    assert np.allclose(turned.edge("R1").z, goal.edge("R1").z)   # the body is the frame
    before, after = places(goal), places(turned)
    middle = (before["F1"] + before["F2"]) / 2
    # in the world the body turned by +turn about the feet's middle: the feet stay put
    sank = []
    for foot in ("F1", "F2"):
        world = middle + rot_z(turn) @ (after[foot] - middle)
        assert np.allclose(world[:2], before[foot][:2], atol=1e-12)
        sank.append(world[2] - before[foot][2])   # a leg keeps its length by its height
    assert max(map(abs, sank)) < 0.02 and abs(sank[0] - sank[1]) < 0.005   # near level
    for leg in ("R2", "R3"):
        assert np.linalg.norm(turned.edge(leg).z) == pytest.approx(1.0)
    assert turned.edge("R2").x @ turned.edge("R2").z == pytest.approx(0.0, abs=1e-12)
    line = after["F2"] - after["F1"], before["F2"] - before["F1"]
    seen = math.atan2(line[0][1], line[0][0]) - math.atan2(line[1][1], line[1][0])
    assert math.degrees(wrap(seen)) == pytest.approx(-5.0)


def places(config: Configuration) -> dict[str, np.ndarray]:
    """The trotter's vertices' places (unit rods) from H1."""
    z = {e.id: e.z for e in config.edges()}
    return {"H1": np.zeros(3), "H2": z["R1"], "F1": z["R2"], "F2": z["R1"] - z["R3"]}


def walk(drift: float, crab: float, *, loop: bool, steps: int = 24, heading: float = 0.4,
         authority: float = 0.6, stride: float = 0.025) -> np.ndarray:
    """Where a gait ends [m], shape (2,): it starts at the origin facing ``heading``, each
    step turns its body by ``drift`` [rad] unasked plus ``authority`` times the turn its
    loop asks, then moves ``stride`` [m] ``crab`` [rad] off its heading (the squirm: 7.4
    deg a loop of two steps, about 12 deg of crab)."""
    call = BehaviorCall("squirm", "sequence", {}, loops=steps, distance=1.0,
                        direction=(1.0, 0.0, 0.0))
    estimate = Estimate(position=np.zeros(2), heading=heading)
    gait = gait_loop(call, heading, OPTIONS) if loop else None
    course = course_loop(call, estimate, 0.0, OPTIONS) if loop else None
    place, psi = np.zeros(2), heading
    for _ in range(steps):
        turn = 0.0 if gait is None or course is None else gait.turn(psi, course.offset(place))
        psi += drift + authority * turn
        place = place + stride * np.array([math.cos(psi + crab), math.sin(psi + crab)])
    return place


@pytest.mark.parametrize("drift, crab", [(math.radians(-3.7), math.radians(12.0)),
                                         (math.radians(2.5), math.radians(-8.0))])
def test_the_gait_loop_keeps_a_gait_that_turns_unasked_on_its_line(drift, crab):
    ahead = rot_z(0.4)[:2, 0]
    free = walk(drift, crab, loop=False)
    assert abs(math.degrees(wrap(math.atan2(free[1], free[0]) - 0.4))) > 20.0
    held = walk(drift, crab, loop=True)
    along = float(held @ ahead)
    assert along > 0.85 * 24 * 0.025
    off = math.degrees(math.atan2(float(ahead[0] * held[1] - ahead[1] * held[0]), along))
    assert abs(off) < 5.0


def test_the_gait_turn_is_bounded_and_does_not_wind_up():
    loop = GaitLoop(0.0, gain=0.5, integral_gain=0.2, bound=math.radians(8.0))
    for _ in range(50):   # turned 1 rad left of where it started: it asks to turn right
        assert -math.radians(8.0) - 1e-12 <= loop.turn(1.0) < 0
    assert abs(loop.integral) <= math.radians(8.0) / 0.2 + 1e-12
    assert loop.turn(0.0) < 0   # the error gone, the integral still asks the same way
    assert loop.turn(-1.0) > 0  # and the other way the moment the error turns round


def test_only_a_sequence_that_states_its_direction_gets_a_gait_loop():
    call = BehaviorCall("squirm", "sequence", {}, loops=2, direction=(1.0, 0.0, 0.0))
    assert gait_loop(call, 0.3, OPTIONS) is not None
    assert gait_loop(call, None, OPTIONS) is None
    undirected = BehaviorCall("squirm", "sequence", {}, loops=2)
    assert gait_loop(undirected, 0.3, OPTIONS) is None
    off = ExecutorOptions(gait_gain=0.0, gait_integral=0.0)
    assert gait_loop(call, 0.3, off) is None
    with pytest.raises(Exception, match="gains"):
        ExecutorOptions(max_gait_turn=-1.0)


def test_a_gait_retakes_unturned_only_a_turned_step_it_can_stop_in():
    """A gait stops only at a loop's end: those steps are the ones :func:`ends_loop` names
    (the squirm's loop: squirm-down, then squirm-up, the stance it is judged in), and only
    such a step run turned is taken again unturned when the gait stops after it
    (:func:`retakes_unturned`)."""
    goal = chain(4)
    steps = [Action(ActionType.MOVING, goal)]   # the way to the gait's start
    for loop in range(3):
        call = BehaviorCall("squirm", "sequence", {}, loops=3, loop=loop, distance=0.5,
                            direction=(1.0, 0.0, 0.0))
        steps += [Action(ActionType.MOVING, goal, behavior=call) for _ in range(2)]
    assert [ends_loop(steps, i) for i in range(1, 7)] == [False, True] * 3
    assert [retakes_unturned(steps, i, 0.1) for i in range(1, 7)] == [False, True] * 3
    assert not any(retakes_unturned(steps, i, 0.0) for i in range(1, 7))
