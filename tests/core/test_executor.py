"""The executor on a hand-made plan and an in-memory driver."""

from __future__ import annotations

from typing import Any

import pytest
from tiny_robot import GoalController, LinkRecognizer, PointDriver, chain, make_run, swap_plan

from msrr.core import hookimpl, plugins
from msrr.core.actions import detect_action
from msrr.core.errors import ExecutionError
from msrr.core.executor import Executor, ExecutorOptions
from msrr.core.plan import ActionType, Plan


class Recorder:
    def __init__(self) -> None:
        self.events: list[tuple[str, Any]] = []

    @hookimpl
    def msrr_on_action(self, run: Any, action: Any, status: str) -> None:
        self.events.append(("action", f"{action} {status}"))

    @hookimpl
    def msrr_on_topology_change(self, run: Any, change: Any) -> None:
        self.events.append(("topology", str(change)))

    @hookimpl
    def msrr_on_tick(self, run: Any, tick: Any) -> None:
        self.events.append(("tick", tick.index))


def execute(plan, options=None, reach=1.05):
    run = make_run(plan)
    with PointDriver(reach) as driver, plugins.temporary(Recorder()) as listener:
        driver.reset(plan.start)
        result = Executor(run, driver, LinkRecognizer(), GoalController(),
                          options or ExecutorOptions(), sink=plugins.emit).execute()
    return result, listener.events


def test_plan_runs_closed_loop_and_counts_what_the_driver_did() -> None:
    result, events = execute(swap_plan())
    assert result.success, result.reason
    assert (result.docks, result.undocks, result.actions_done) == (1, 1, 3)
    assert [e for k, e in events if k == "topology"] == ["undock aT-bB", "dock bT-cB"]
    statuses = [e for k, e in events if k == "action"]
    assert statuses[0] == "undock aT-bB started" and statuses[-1].endswith("succeeded")
    ticks = [e for k, e in events if k == "tick"]
    assert ticks == list(range(result.ticks)) and result.sim_time == pytest.approx(
        result.ticks * 0.1)


def test_unreachable_dock_times_out_retries_and_names_the_action() -> None:
    result, events = execute(swap_plan(goal_x=9.0), ExecutorOptions(action_timeout=2.0),
                             reach=1.05)
    assert not result.success
    assert result.failed_action == 1 and result.retries == 1
    assert "action 2 (move c)" in result.reason and "within 2 s" in result.reason
    assert ("action", "move c retrying") in events and ("action", "move c failed") in events


class TimedGoalController(GoalController):
    """:class:`GoalController` that says how long its drive takes (1 m/s, plus ``said``)."""

    def __init__(self, said: object = 0.0):
        self.said = said

    def begin(self, action, phase, observation):
        if isinstance(self.said, float):
            return self.said + sum(abs(g[0] - float(observation.tracked[m].position[0]))
                                   for m, g in action.goals.items())
        return self.said


def run_with(controller, plan, options):
    with PointDriver(1.05) as driver:
        driver.reset(plan.start)
        return Executor(make_run(plan), driver, LinkRecognizer(), controller, options,
                        sink=plugins.emit).execute()


def test_a_phase_gets_the_time_its_controller_says_it_needs_on_top_of_the_timeout() -> None:
    # c drives 7 m at 1 m/s; a 2 s timeout alone cuts the move (action 2) short
    options = ExecutorOptions(action_timeout=2.0, retries=0)
    plain = run_with(GoalController(), swap_plan(goal_x=9.0), options)
    assert plain.failed_action == 1 and "within 2 s" in plain.reason
    # told 7 s, the move is done; the dock then fails (c is out of b's reach at x = 9)
    timed = run_with(TimedGoalController(), swap_plan(goal_x=9.0), options)
    assert timed.failed_action == 2, timed.reason
    assert "action 3" in timed.reason and "within 2 s" in timed.reason


@pytest.mark.parametrize("said", [-1.0, float("nan"), float("inf"), "7 s", True])
def test_a_controller_that_says_a_nonsense_time_is_named(said) -> None:
    controller = TimedGoalController(said)
    with pytest.raises(ExecutionError, match="controller 'goal': begin returned"):
        run_with(controller, swap_plan(goal_x=9.0), ExecutorOptions(action_timeout=2.0))


def test_dock_out_of_reach_fails_with_missing_change() -> None:
    result, _ = execute(swap_plan(goal_x=2.5), ExecutorOptions(action_timeout=1.0), reach=0.2)
    assert not result.success and result.failed_action == 2
    assert "still missing: +bT-cB" in result.reason


def test_options_are_checked() -> None:
    with pytest.raises(ExecutionError, match="rate"):
        ExecutorOptions(rate=0)
    with pytest.raises(ExecutionError, match="not connected"):
        Executor(make_run(swap_plan()), PointDriver(), LinkRecognizer(),
                 GoalController(), sink=plugins.emit).execute()


def test_a_face_swap_runs_as_one_parallel_connection() -> None:
    """a-b, c-d -> a-d, c-b, detected as one action: release both, approach, dock both."""
    start = chain(("a", "b"), ("c", "d"), modules="abcd")
    goal = chain(("a", "d"), ("c", "b"), modules="abcd")
    action = detect_action(start, goal)
    assert action.type is ActionType.PARALLEL_CONNECTION
    action.goals = {"d": [-1.0, 0.0, 0.0], "b": [3.0, 0.0, 0.0]}     # modules start at x = 0..3
    result, events = execute(Plan("tiny", "test", start, goal, [action]))
    assert result.success, result.reason
    assert (result.undocks, result.docks, result.actions_done) == (2, 2, 1)
    topology = [e for k, e in events if k == "topology"]
    assert sorted(topology[:2]) == ["undock aT-bB", "undock cT-dB"]
    assert sorted(topology[2:]) == ["dock aT-dB", "dock bB-cT"]
