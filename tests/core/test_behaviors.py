"""Scenario stages, behavior actions and what the executor reports about them (issue 13).

Everything runs on the tiny robot's point driver (modules move along x at the wheel
speed ``v`` they are sent), so the expected distances are exact: ``speed * time``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from tiny_robot import (
    NAME,
    SPEC,
    GoalController,
    LinePlanner,
    LinkRecognizer,
    PointDriver,
    chain,
    installed,
)

from msrr.core import plugins
from msrr.core.app.run import parse_parameters, plan_stages
from msrr.core.errors import ConfigurationError, UnknownNameError
from msrr.core.estimation import Estimate
from msrr.core.events import Phase, Run
from msrr.core.executor import (
    Executor,
    ExecutorOptions,
    behavior_commands,
    ends_loop,
    phases_of,
)
from msrr.core.judge import Judge, JudgeOptions, asked_distance, judge_behavior
from msrr.core.plan import (
    Action,
    ActionType,
    BehaviorCall,
    CommandGain,
    Plan,
    join_plans,
    load_plan,
    save_plan,
)
from msrr.core.scenario import Scenario, Stage

DRIVE = (CommandGain("a", "v", (("speed", 2.0),)), CommandGain("b", "v", (("speed", 2.0),)),
         CommandGain("c", "v", (("speed", 2.0), ("yaw_rate", 0.5))))
"""Every module's wheel ``v`` = 2 speed (+ 0.5 yaw_rate for c)."""


class TruthDriver(PointDriver):
    """The point driver with a ground truth: its own latch state, recognized."""

    def ground_truth(self):
        return LinkRecognizer().recognize(self.get_observation().sensors)


def execute(plan: Plan, driver: PointDriver | None = None, **options):
    """Execute ``plan`` and judge it, as ``platform run`` does."""
    run = Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points")
    with driver or PointDriver() as world:
        world.reset(plan.start)
        judge = Judge(run, world)
        executor = Executor(run, world, LinkRecognizer(), GoalController(),
                            ExecutorOptions(rate=10.0, action_timeout=5.0, **options),
                            sink=judge)
        return judge.conclude(executor.execute()), world


def drive(duration: float | None = 2.0, distance: float | None = None, speed: float = 0.5,
          direction=(1.0, 0.0, 0.0)) -> Action:
    here = chain(("a", "b"))
    call = BehaviorCall("drive", "mapping", {"speed": speed, "yaw_rate": 0.0}, DRIVE,
                        duration=duration, distance=distance, direction=direction)
    return Action(ActionType.BEHAVIOR, here, behavior=call)


def test_a_mapping_behavior_sends_the_linear_map_every_tick_for_its_duration():
    action = drive()
    assert behavior_commands(action) == {"a": {"v": 1.0}, "b": {"v": 1.0}, "c": {"v": 1.0}}
    start = chain(("a", "b"))
    result, world = execute(Plan(NAME, "test", start, start, [action]), TruthDriver())
    assert result.success, result.reason
    assert result.ticks == 20 and math.isclose(world.time, 2.0)      # 2 s at 10 Hz
    (moved,) = result.locomotion
    assert moved.actions == 1 and math.isclose(moved.duration, 2.0)
    assert math.isclose(moved.distance, 2.0, abs_tol=1e-9)            # 1 m/s for 2 s
    assert moved.heading_error == pytest.approx(0.0, abs=1e-9)        # along +x as told


class HalvingController(GoalController):
    """A :class:`~msrr.core.control.WheelCorrector`: every behavior wheel at half its value,
    with what it was shown noted."""

    def __init__(self):
        self.seen: list[tuple[str, int]] = []

    def correct_wheels(self, action, configuration, wheels):
        self.seen.append((action.behavior.name, len(configuration.vertices())))
        return {m: {k: 0.5 * v for k, v in values.items()} for m, values in wheels.items()}


def test_a_wheel_corrector_controller_corrects_a_behaviors_wheels_each_tick():
    start = chain(("a", "b"))
    plan = Plan(NAME, "test", start, start, [drive()])
    run = Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points")
    controller = HalvingController()
    with TruthDriver() as world:
        world.reset(start)
        judge = Judge(run, world)
        result = judge.conclude(Executor(run, world, LinkRecognizer(), controller,
                                         ExecutorOptions(rate=10.0), sink=judge).execute())
    assert result.success, result.reason
    assert controller.seen == [("drive", len(start.vertices()))] * 20   # each tick, recognized
    (moved,) = result.locomotion
    assert math.isclose(moved.distance, 1.0, abs_tol=1e-9)  # half of 1 m/s for 2 s


def test_distance_ends_a_mapping_behavior_and_a_wrong_way_shows_as_heading_error():
    start = chain(("a", "b"))
    action = drive(duration=None, distance=0.75, speed=-0.5)
    result, world = execute(Plan(NAME, "test", start, start, [action]), TruthDriver())
    assert result.actions_done == 1
    (moved,) = result.locomotion
    assert 0.75 <= moved.distance < 0.75 + 0.1 + 1e-9                 # stops at the first tick past it
    assert moved.heading_error == pytest.approx(math.pi)              # -x, commanded +x
    assert moved.along == pytest.approx(-moved.distance)
    assert not result.success and "covered -0.800 m along the commanded direction of the " \
        "0.750 m asked" in result.reason                              # it went the wrong way


def test_a_behavior_that_does_not_move_fails_with_the_distance_it_covered():
    start = chain(("a", "b"))
    still = BehaviorCall("drive", "mapping", {"speed": 0.5}, (), duration=2.0,
                         direction=(1.0, 0.0, 0.0))
    result, _ = execute(Plan(NAME, "test", start, start,
                             [Action(ActionType.BEHAVIOR, start, behavior=still)]),
                        TruthDriver())
    (moved,) = result.locomotion
    assert (moved.distance, moved.asked) == (0.0, 1.0) and not moved.success
    assert not result.success and result.reason == (
        "drive covered 0.000 m along the commanded direction of the 1.000 m asked (0%; at "
        "least 20% is needed), judged on ground truth")


def test_a_turn_in_place_asks_no_distance_and_a_short_drive_is_judged_on_what_it_asked():
    assert asked_distance(BehaviorCall("turn", "mapping", {"yaw_rate": 0.3}, (),
                                       duration=5.0)) is None
    assert asked_distance(BehaviorCall("go", "mapping", {"speed": -0.1}, (),
                                       duration=5.0)) == pytest.approx(0.5)
    assert asked_distance(BehaviorCall("go", "mapping", {"speed": 0.1}, (), duration=5.0,
                                       distance=0.3)) == 0.3
    call = BehaviorCall("go", "mapping", {"speed": 0.1}, (), duration=5.0)
    kept = judge_behavior(call, first_action=0, actions=1, duration=5.0,
                          shift=np.array([0.1, 0.0]), direction=np.array([1.0, 0.0]),
                          basis="ground truth", options=JudgeOptions())
    assert kept.success and kept.along == pytest.approx(0.1)          # 20% of 0.5 m
    veered = judge_behavior(call, first_action=0, actions=1, duration=5.0,
                            shift=np.array([0.3, 0.4]), direction=np.array([1.0, 0.0]),
                            basis="ground truth", options=JudgeOptions())
    assert not veered.success and "53 deg off the commanded direction" in veered.reason


def sequence_plan(loops: int, distance: float | None, direction=None) -> Plan:
    """A sequence behavior of one step per loop: every module 0.6 m further along x."""
    start = chain(("a", "b"))
    actions = []
    for k in range(loops):
        call = BehaviorCall("creep", "sequence", {}, loops=loops, loop=k, distance=distance,
                            direction=direction)
        goals = {m: [i + 0.6 * (k + 1), 0.0, 0.0] for i, m in enumerate(start.vertices())}
        actions.append(Action(ActionType.MOVING, start, tuple(goals), goals=goals, behavior=call))
    return Plan(NAME, "test", start, start, actions)


def test_a_sequence_behavior_skips_its_loops_once_the_distance_is_covered():
    result, _ = execute(sequence_plan(5, distance=1.0))
    assert result.success, result.reason
    assert (result.actions_done, result.actions_skipped) == (2, 3)    # 1.2 m after two loops
    (moved,) = result.locomotion
    assert moved.actions == 2 and moved.distance == pytest.approx(1.2, abs=2e-3)
    full, _ = execute(sequence_plan(3, distance=None))
    assert (full.actions_done, full.actions_skipped) == (3, 0)
    assert full.locomotion[0].distance == pytest.approx(1.8, abs=3e-3)


def test_the_gait_loop_turns_a_loops_last_step_too():
    """Issue 31: asked of the squirm-down step alone, the squirm's turn moved the body
    about 1 deg of the 8 asked and each squirm-up step (a loop's last) turned it -5 to -9
    deg back: the loop now turns every step but the behavior's first."""
    plan = sequence_plan(3, distance=None, direction=(1.0, 0.0, 0.0))
    steps = plan.actions
    run = Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points")
    with PointDriver() as world:
        world.reset(plan.start)
        executor = Executor(run, world, LinkRecognizer(), GoalController(), ExecutorOptions())
        executor.estimate = Estimate(position=np.zeros(2), heading=0.3)
        assert executor._gait_turn(0, steps[0], None) == 0.0       # the loop starts at 0.3
        executor.estimate = Estimate(position=np.zeros(2), heading=0.1)
        assert ends_loop(steps, 2)
        assert executor._gait_turn(2, steps[2], steps[1]) > 0.0    # turned 0.2 rad right


def test_the_gait_loop_starts_where_the_behavior_starts_not_after_its_first_step():
    """Issue 31: the squirm's first squirm-up step turned the body -5.6 deg (exact) and
    moved it 50 mm; a loop started after that step took both for its reference and its
    course line, and no step took them out. It starts before the first step now, where
    the judge takes the commanded direction."""
    plan = sequence_plan(3, distance=None, direction=(1.0, 0.0, 0.0))
    steps = plan.actions
    run = Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points")
    with PointDriver() as world:
        world.reset(plan.start)
        for moved, sign in ((Estimate(position=np.zeros(2), heading=-0.1), 1.0),
                            (Estimate(position=np.array([0.5, 0.1]), heading=0.0), -1.0)):
            executor = Executor(run, world, LinkRecognizer(), GoalController(),
                                ExecutorOptions())
            executor.estimate = Estimate(position=np.zeros(2), heading=0.0)
            assert executor._gait_turn(0, steps[0], None) == 0.0   # the first step: none
            executor.estimate = moved   # the first step turned right, or went off left
            assert sign * executor._gait_turn(1, steps[1], steps[0]) > 0.0   # taken out



def test_a_gaits_course_loop_asks_no_more_than_a_gait_can_turn():
    """Issue 31: a squirm-up step that slid put the estimated place 110 mm left of the line;
    the course loop's offset went to -45 deg (the mapping behaviors' bound is 60), a turn
    the squirm could not make in its run, and the gait loop turned the body after it.
    A gait's course offset is bounded by ``max_gait_course_offset`` (20 deg)."""
    plan = sequence_plan(3, distance=None, direction=(1.0, 0.0, 0.0))
    steps = plan.actions
    run = Run(robot=NAME, scenario="test", plan=plan, spec=SPEC, driver="points")
    options = ExecutorOptions(gait_gain=1.0, gait_integral=0.0, max_gait_turn=1.5)
    with PointDriver() as world:
        world.reset(plan.start)
        executor = Executor(run, world, LinkRecognizer(), GoalController(), options)
        executor.estimate = Estimate(position=np.zeros(2), heading=0.0)
        executor._gait_turn(0, steps[0], None)
        executor.estimate = Estimate(position=np.array([0.05, 0.11]), heading=0.0)
        turn = executor._gait_turn(1, steps[1], steps[0])   # the heading error: the offset
        assert math.radians(-20.0) - 1e-9 <= turn < 0.0   # was -60 deg

def test_a_gait_stopped_after_a_turned_step_takes_that_step_again_unturned(monkeypatch):
    """The judge measures the stance a gait stops in: a loop's last step whose goal was
    turned is run again with no turn when the gait stops after it (:func:`~msrr.core.executor.retakes_unturned`); a
    step whose tree could not be turned (no single planted foot) is not."""
    runs = []
    pivots = [True]
    execute_action = Executor._execute_action

    def recorded(self, index, action):
        runs.append((index, self._turn))
        self._turned = pivots[0] and bool(self._turn)   # what turned_goal did to its goal
        return execute_action(self, index, action)

    monkeypatch.setattr(Executor, "_execute_action", recorded)
    monkeypatch.setattr(Executor, "_gait_turn", lambda self, index, action, last: 0.1)
    result, _ = execute(sequence_plan(5, distance=1.0))
    assert result.success, result.reason
    assert (result.actions_done, result.actions_skipped) == (2, 3)
    assert runs == [(0, 0.1), (1, 0.1), (1, 0.0)]     # 1.2 m after two loops: stopped
    runs.clear()
    assert execute(sequence_plan(2, distance=None))[0].success
    assert runs == [(0, 0.1), (1, 0.1), (1, 0.0)]     # the plan's last step
    pivots[0] = False
    runs.clear()
    assert execute(sequence_plan(5, distance=1.0))[0].success
    assert runs == [(0, 0.1), (1, 0.1)]               # nothing turned: nothing repeated


def test_a_goal_is_judged_on_the_ground_truth_topology():
    class Broken(TruthDriver):
        def ground_truth(self):
            return chain()                                            # says nothing is docked

    start = chain(("a", "b"))
    still = Action(ActionType.MOVING, start, ("c",), goals={"c": [2.0, 0.0, 0.0]},
                   reaches="ab")
    ok, _ = execute(Plan(NAME, "test", start, start, [still]), TruthDriver())
    assert ok.success and [t.name for t in ok.targets] == ["ab"] and ok.targets[0].topology
    assert ok.targets[0].shape is None                                # a robot without vectors
    assert ok.targets[0].basis == "ground truth" and ok.goal is not None and ok.goal.success
    bad, _ = execute(Plan(NAME, "test", start, start, [still]), Broken())
    assert not bad.success and "goal ab (action 1)" in bad.reason and "topology" in bad.reason


def test_behavior_phase_and_plan_file_round_trip(tmp_path: Path):
    action = drive(duration=3.0)
    assert phases_of(action, None, tracking=True) == [Phase.BEHAVIOR]  # type: ignore[arg-type]
    start = chain(("a", "b"))
    plan = Plan(NAME, "test", start, start, [action])
    save_plan(plan, tmp_path / "plan.json")
    again = load_plan(tmp_path / "plan.json").actions[0]
    assert again.type is ActionType.BEHAVIOR and again.behavior == action.behavior
    assert str(again) == "behavior drive(speed=0.5, yaw_rate=0)"


def test_behavior_calls_refuse_what_cannot_run():
    with pytest.raises(ConfigurationError, match="duration or a distance"):
        BehaviorCall("drive", "mapping", {}, DRIVE)
    with pytest.raises(ConfigurationError, match="finite number > 0"):
        BehaviorCall("drive", "mapping", {}, DRIVE, duration=-1.0)
    with pytest.raises(ConfigurationError, match="either a goal or a behavior"):
        Stage(goal=Path("a.json"), behavior="drive")
    with pytest.raises(ConfigurationError):
        Scenario("empty", "nothing", Path("a.json"))
    assert parse_parameters(["speed=0.05", "yaw_rate=0"]) == (("speed", 0.05), ("yaw_rate", 0.0))
    for bad in ("speed", "speed=fast", "=1", "speed=nan"):
        with pytest.raises(ConfigurationError, match="NAME=NUMBER"):
            parse_parameters([bad])


def test_stages_are_planned_from_the_previous_goal_and_joined():
    ab, bc = chain(("a", "b"), name="ab"), chain(("b", "c"), name="bc")
    calls = []

    class Recording(LinePlanner):
        def plan(self, start, goal, *, seed=0):
            calls.append((start.name, goal.name))
            plan = super().plan(start, goal, seed=seed)
            plan.goal = goal
            return plan

    with installed():
        tiny = plugins.capabilities(NAME)
    plan = plan_stages(tiny, Recording(), ab, [(Stage(goal=Path("bc.json")), bc),
                                               (Stage(goal=Path("ab.json"), name="back"), ab)])
    assert calls == [("ab", "bc"), ("bc", "ab")]                      # stage 2 from stage 1's goal
    first = len(LinePlanner().plan(ab, bc).actions)
    assert [a.reaches for a in plan.actions if a.reaches] == ["bc", "back"]
    assert plan.actions[first - 1].reaches == "bc" and plan.goal is ab
    with pytest.raises(UnknownNameError, match="planner of behaviors"):
        plan_stages(tiny, Recording(), ab, [(Stage(behavior="drive"), None)])


def test_join_plans_keeps_the_order_and_refuses_a_gap():
    ab, bc, ca = chain(("a", "b")), chain(("b", "c")), chain(("c", "a"))
    one, two = LinePlanner().plan(ab, bc), LinePlanner().plan(bc, ca)
    one.stats, two.stats = {"time_ms": 1.0}, {"time_ms": 2.5}
    joined = join_plans([one, two])
    assert joined.actions == one.actions + two.actions
    assert joined.start is ab and joined.goal is two.goal and joined.stats == {"time_ms": 3.5}
    other = chain(("a", "b"), modules="abd")
    with pytest.raises(ConfigurationError, match="other modules"):
        join_plans([one, LinePlanner().plan(other, other)])
