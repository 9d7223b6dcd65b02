"""The hinge robot keeps the platform's contract, with and without its extras, and runs
in physics from its description alone."""

import importlib
import json
import math
import subprocess
import sys
from pathlib import Path

from msrr.core import plugins
from msrr.core.app.testing import check_robot, run_physics
from msrr.core.generic.planner import GenericPlanner


def test_hinge_conforms() -> None:
    report = check_robot("hinge")
    assert any("mujoco" in p for p in report.passed)  # check 6: the fold, in physics


def test_hinge_with_its_extras_conforms() -> None:
    extras = importlib.import_module("msrr_example_hinge.extras")
    joints = importlib.import_module("msrr_example_hinge.joints")
    with plugins.temporary(extras, "hinge-extras"):
        assert plugins.capabilities("hinge").robot.joint_modes["hinge"] is joints.HingeJoint
        check_robot("hinge")


def _bent(tmp_path, angle: float):
    """chain3 with its second hinge bent by ``angle`` [rad] (only the vectors differ)."""
    half = angle / 2  # the direction between two centres turns by half the hinge angle
    data = {"schema_version": 1, "robot": "hinge", "name": "bent", "modules": [
        {"id": f"h{i}", "kind": "hinge"} for i in (1, 2, 3)], "connections": [
        {"source": "h1", "target": "h2", "ports": ["head", "tail"], "z": [1.0, 0.0, 0.0]},
        {"source": "h2", "target": "h3", "ports": ["head", "tail"],
         "z": [math.cos(half), math.sin(half), 0.0]}]}
    path = tmp_path / "bent.json"
    path.write_text(json.dumps(data))
    return plugins.load_configuration(path)


def test_a_goal_that_only_bends_a_hinge_is_executed_and_judged_by_shape(tmp_path) -> None:
    start = plugins.load_configuration(plugins.capabilities("hinge").scenarios["reverse"].start)
    goal = _bent(tmp_path, math.radians(26))
    plan = GenericPlanner(plugins.capabilities("hinge").robot).plan(start, goal)
    assert len(plan.actions) == 1 and not plan.actions[0].changes  # a move, not nothing
    spec = plugins.robot("hinge")
    physics = run_physics(plan, spec)
    assert physics.success, physics.reason
    assert physics.goal.basis == "ground truth" and physics.goal.shape.error < math.radians(5)
    # the kinematic world has no joints: the run fails with the shape error, as a user sees it
    out = subprocess.run([str(Path(sys.executable).parent / "platform"), "run", "--robot", "hinge", "--from", str(
        plugins.capabilities("hinge").scenarios["reverse"].start), "--to", str(tmp_path / "bent.json"),
        "--driver", "kinematic", "--no-log", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=120)
    assert out.returncode != 0
    assert "shape outside the tolerance, 6.50 deg RMS" in out.stderr  # 13 deg on one of two
