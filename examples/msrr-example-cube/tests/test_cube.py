"""The cube robot keeps the platform's contract and reconfigures in physics from its
description alone."""

from msrr.core import plugins
from msrr.core.app.testing import check_robot, run_physics
from msrr.core.generic.planner import GenericPlanner


def test_cube_conforms() -> None:
    report = check_robot("cube")
    assert any("mujoco" in p for p in report.passed)  # check 6: one plan in physics


def test_the_l_becomes_a_t_in_physics() -> None:
    scenario = plugins.capabilities("cube").scenarios["l-t"]
    start, goal = (plugins.load_configuration(p) for p in (scenario.start, scenario.goal))
    plan = GenericPlanner(plugins.capabilities("cube").robot).plan(start, goal)
    result = run_physics(plan, plugins.robot("cube"), seed=3)
    assert result.success, result.reason
    assert result.goal.basis == "ground truth" and result.goal.shape.within
