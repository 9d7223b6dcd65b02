"""The kinematic driver, latch recognizer and controller of the generic runtime."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from tiny_robot import CUBE, NAME, SPEC, chain, installed

from msrr.core import Configuration, DockingRules, ModuleKind, PortSpec, RobotSpec
from msrr.core.actions import detect_action, topology_diff
from msrr.core.app.cli import get_cli
from msrr.core.app.testing import FakeDriver, run_kinematic
from msrr.core.driver import ModuleCommand
from msrr.core.errors import ExecutionError
from msrr.core.generic import GenericPlanner, KinematicDriver, LatchRecognizer
from msrr.core.generic.geometry import BodyPose, place_for_ports, port_frame
from msrr.core.plan import Plan
from msrr.core.random_configurations import random_configuration
from msrr.core.robot import Robot, port_reuse_violations, tree_violations

BALL = ModuleKind("ball", "B", "vertex", ports=(PortSpec("magnet"),), geometry={"radius": 0.05})
BALLS = RobotSpec("balls", "Balls", (BALL,))
NODE = ModuleKind("node", "N", "vertex", geometry={"radius": 0.05})
BAR = ModuleKind("bar", "S", "edge", ports=(PortSpec("a"), PortSpec("b")),
                 geometry={"length": 0.2, "radius": 0.02})
BARS = RobotSpec("bars", "Bars", (BAR, NODE))
LINK = ModuleKind("link", "L", "vertex", ports=(PortSpec("head", "active", (1.0, 0.0, 0.0)),
                                              PortSpec("tail", "passive", (-1.0, 0.0, 0.0))),
                  geometry={"length": 0.1})
LINKS = RobotSpec("links", "Links", (LINK,))


class Chains(DockingRules):
    """Head to tail, each port once, one chain per group."""

    def ports_compatible(self, source_kind: str, source_port: str | None,
                         target_kind: str, target_port: str | None) -> bool:
        return {source_port, target_port} == {"head", "tail"}

    def check_topology(self, config: Configuration) -> list:
        return port_reuse_violations(config) + tree_violations(config)


def _placed(*xs: float) -> Configuration:
    """Tiny cubes a, b, ... at the given x [m], not docked."""
    config = Configuration(SPEC.name)
    for name, x in zip("abcd", xs, strict=False):
        config.add_module(name, CUBE.name, position=[x, 0.0, 0.0])
    return config


def _recognized(spec: RobotSpec, config: Configuration) -> Configuration:
    with KinematicDriver(spec) as driver:
        driver.reset(config)
        return LatchRecognizer(spec).recognize(driver.get_observation().sensors)


def test_start_layout_is_recognized_as_the_start() -> None:
    """Ports (tiny), freeform connectors (balls) and connections that are modules (bars)."""
    tiny = chain(("a", "b"), ("b", "c"), ("d", "a"), modules="abcd")
    assert not topology_diff(_recognized(SPEC, tiny), tiny)
    balls = Configuration("balls")
    for v in "pqr":
        balls.add_module(v, "ball")
    balls.connect("p", "q", z=[0.0, 0.0, -1.0])
    balls.connect("r", "q", z=[1.0, 0.0, 0.0])
    seen = _recognized(BALLS, balls)
    assert not topology_diff(seen, balls)
    assert {(e.source, e.target): e.z.round(9).tolist() for e in seen.edges()} == {
        ("p", "q"): [0.0, 0.0, -1.0], ("r", "q"): [1.0, 0.0, 0.0]}
    bars = Configuration("bars")
    for v in ("x", "y"):
        bars.add_module(v, "node")
    bars.add_virtual("free")
    bars.connect("x", "y", id="S1", kind="bar", z=[1.0, 0.0, 0.0])
    bars.connect("y", "free", id="S2", kind="bar", z=[0.0, 1.0, 0.0])
    assert not topology_diff(_recognized(BARS, bars), bars)


def test_ports_latch_within_the_tolerance_only() -> None:
    """Cubes are 0.4 m long: a's T port is at x = 0.2, b's B port at b's x - 0.2."""
    for gap, latched in ((0.004, True), (0.006, False)):
        with KinematicDriver(SPEC, tolerance=0.005) as driver:
            driver.reset(_placed(0.0, 0.4 + gap))
            driver.send_action({"a": ModuleCommand(dock=("T",)), "b": ModuleCommand(dock=("B",))})
            driver.step(0.1)
            seen = LatchRecognizer(SPEC).recognize(driver.get_observation().sensors)
            assert [(e.source, e.target, e.ports) for e in seen.edges()] == (
                [("a", "b", ("T", "B"))] if latched else [])


def test_a_group_moves_rigidly_at_bounded_speed_and_releases_on_command() -> None:
    with KinematicDriver(SPEC, speed=0.5, turn_rate=2.0) as driver:
        driver.reset(chain(("a", "b"), modules="ab"))
        start = driver.witness().poses
        driver.send_action({"a": ModuleCommand(joints={"x": 10.0, "yaw": np.pi / 2})})
        driver.step(0.1)
        moved = driver.witness().poses
        shift = moved["a"].position - start["a"].position
        assert shift.tolist() == pytest.approx([0.05, 0.0, 0.0])
        assert moved["a"].yaw == pytest.approx(0.2)
        offset = moved["b"].position - moved["a"].position
        before = start["b"].position - start["a"].position
        assert offset[:2] == pytest.approx([np.cos(0.2) * before[0], np.sin(0.2) * before[0]])
        driver.send_action({"b": ModuleCommand(undock=("B",))})
        driver.step(0.1)
        assert not LatchRecognizer(SPEC).recognize(driver.get_observation().sensors).edges()


def test_overlaps_are_refused_and_named() -> None:
    with KinematicDriver(SPEC) as driver, pytest.raises(ExecutionError,
                                                        match="modules a and b overlap"):
        driver.reset(_placed(0.0, 0.05))
    with KinematicDriver(SPEC, speed=1.0) as driver:
        driver.reset(_placed(0.0, 0.5))
        driver.send_action({"a": ModuleCommand(joints={"x": 0.45})})
        with pytest.raises(ExecutionError, match="moving a toward .* would overlap b"):
            driver.step(1.0)
        assert driver.witness().poses["a"].position.tolist() == [0.0, 0.0, 0.0]


def test_port_placement_faces_the_ports() -> None:
    fixed = BodyPose(np.array([1.0, 2.0, 0.0]), 0.7)
    pose = place_for_ports(CUBE, "T", fixed, CUBE, "B", 0.0)
    (p, n), (q, m) = port_frame(CUBE, "T", fixed), port_frame(CUBE, "B", pose)
    assert np.allclose(p, q) and np.allclose(n, -m)


def test_generic_plans_run_to_the_goal_and_a_jammed_port_fails_the_run() -> None:
    robot = Robot(SPEC)
    start = chain(("a", "b"), ("b", "c"), modules="abc")
    goal = chain(("c", "a"), ("a", "b"), modules="abc")
    plan = GenericPlanner(robot).plan(start, goal)
    result = run_kinematic(plan, SPEC)
    assert result.success, result.reason
    assert (result.docks, result.undocks) == (plan.docks, plan.undocks) == (1, 1)
    assert not topology_diff(result.final, goal)
    jammed = FakeDriver(SPEC, jammed={("c", "T"), ("a", "B")})
    failed = run_kinematic(plan, SPEC, action_timeout=3.0, driver=jammed)
    assert not failed.success and "still missing: +aB-cT" in failed.reason
    assert any(cmd.dock for sent in jammed.sent for cmd in sent.values())


def test_freeform_modules_dock_by_contact() -> None:
    start, goal = Configuration("balls"), Configuration("balls")
    for config in (start, goal):
        for v in "pqr":
            config.add_module(v, "ball")
    start.connect("p", "q", z=[0.0, 0.0, -1.0])
    start.connect("r", "q", z=[1.0, 0.0, 0.0])
    goal.connect("p", "q", z=[0.0, 0.0, -1.0])
    goal.connect("r", "p", z=[0.0, -1.0, 0.0])
    plan = GenericPlanner(Robot(BALLS)).plan(start, goal)
    result = run_kinematic(plan, BALLS)
    assert result.success, result.reason
    assert not topology_diff(result.final, goal)


def test_moving_actions_reach_their_planar_goals() -> None:
    start = chain(modules="ab")
    plan = Plan(SPEC.name, "test", start, start, [])
    plan.actions.append(detect_action(start, start))
    plan.actions[0].goals = {"b": [2.0, 1.0, np.pi / 2]}
    driver = FakeDriver(SPEC)
    result = run_kinematic(plan, SPEC, driver=driver)
    assert result.success, result.reason
    pose = driver.poses["b"]
    assert pose.position.tolist() == pytest.approx([2.0, 1.0, 0.0])
    assert pose.yaw == pytest.approx(np.pi / 2)


def test_platform_run_with_the_kinematic_driver_uses_its_companions(tmp_path: Path) -> None:
    """A robot with its own controller and recognizer (tiny's read PointDriver sensors)
    runs with ``--driver kinematic``: the driver names the ones that read it."""
    with installed(tmp_path):
        result = CliRunner().invoke(get_cli(), [
            "run", "--robot", NAME, "--scenario", "swap", "--driver", "kinematic",
            "--planner", "generic", "--no-log", "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert "by generic" in result.output and "driver kinematic" in result.output
    assert '"success": true' in (tmp_path / "run/summary.json").read_text()


def test_random_plans_of_a_port_robot_run_including_parking() -> None:
    """Undocked modules stay where they were; a dock whose place they take parks them
    first (without parking, 4 of these 6 seeded pairs of 0.1 m links fail)."""
    robot = Robot(LINKS, Chains())
    planner = GenericPlanner(robot)
    rng = np.random.default_rng(0)
    for _ in range(6):
        n = int(rng.integers(4, 7))
        start = random_configuration(LINKS, robot.rules, n, rng)
        goal = random_configuration(LINKS, robot.rules, n, rng)
        result = run_kinematic(planner.plan(start, goal), LINKS)
        assert result.success, result.reason
        assert not topology_diff(result.final, goal)
