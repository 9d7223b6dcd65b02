"""The conformance suite over every installed robot, and what it catches."""

from __future__ import annotations

from pathlib import Path

import pytest
from tiny_robot import NAME, LinePlanner, chain, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.testing import ConformanceError, check_robot, robot_parameters
from msrr.core.plan import Plan

KNOWN_FAILURES: dict[str, str] = {}


@robot_parameters(known_failures=KNOWN_FAILURES)
def test_every_installed_robot_conforms(robot: str) -> None:
    check_robot(robot, fail_fast=robot in KNOWN_FAILURES)


def test_the_tiny_robot_conforms_and_its_plans_run(tmp_path: Path) -> None:
    with installed(tmp_path):
        report = check_robot(NAME)
    assert "run start.json -> goal.json in the kinematic driver" in report.passed
    assert "goal.json: planner line to itself" in report.passed
    assert not report.failures and not report.declined


class Restless:
    """A planner that always moves, even to where the robot already is."""

    name = "restless"
    description = "one action, always"

    def plan(self, start, goal, *, seed=0):
        plan = LinePlanner().plan(start, goal)
        plan.actions.insert(0, LinePlanner().plan(start, chain(modules="abc")).actions[0])
        return Plan(NAME, self.name, start, goal, plan.actions)


class RestlessPlugin:
    @hookimpl
    def msrr_planners(self, robot, register):
        if robot == NAME:
            register(Restless())


def test_a_planner_that_moves_to_where_it_is_fails_by_name(tmp_path: Path) -> None:
    with installed(tmp_path), plugins.temporary(RestlessPlugin()), pytest.raises(
            ConformanceError) as failure:
        check_robot(NAME, run=False)
    message = str(failure.value)
    assert "start.json: planner restless to itself: AssertionError: 1 action(s)" in message
    assert "plan start.json -> goal.json (restless) does not replay" not in message


def test_fail_fast_stops_at_the_first_failure(tmp_path: Path) -> None:
    with installed(tmp_path), plugins.temporary(RestlessPlugin()), pytest.raises(
            ConformanceError, match=r"fails \(first failure\): goal.json: planner restless"):
        check_robot(NAME, run=False, fail_fast=True)


def test_a_robot_without_configurations_is_refused() -> None:
    with installed(None), pytest.raises(ConformanceError, match="ships no configuration"):
        check_robot(NAME)
