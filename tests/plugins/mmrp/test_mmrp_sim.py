"""MMRP in PyBullet: geometry, latching tolerance, and the whole cross->probe run."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from msrr.core.app.cli import get_cli
from msrr.core.driver import ModuleCommand
from msrr.core.io import load_configuration
from msrr.core.plan import load_plan
from msrr.core.timeline import summarize_recording
from msrr.plugins.mmrp.representation import from_links
from msrr.plugins.mmrp.sim import MmrpSimDriver
from msrr.plugins.mmrp.sim.geometry import alignment, group_twist, neighbour_pose, track_speeds
from msrr.plugins.mmrp.sim.paths import plan_path, segment_clearance

CONFIGS = Path(__file__).resolve().parents[3] / "plugins/mmrp/configs"


def test_alignment_and_neighbour_pose_agree() -> None:
    pose = (0.2, -0.1, 0.7)
    for face in "TBLR":
        fit = alignment(pose, face, neighbour_pose(pose, face, 0.3), 0.3)
        assert abs(fit.gap) < 1e-12 and abs(fit.lateral) < 1e-12 and fit.yaw == 0
    off = alignment((0, 0, 0), "T", (0.31, 0.02, 0.0), 0.3)
    assert off.gap == pytest.approx(0.01) and off.lateral == pytest.approx(0.02)


def test_group_twist_has_no_lateral_velocity_and_inverts_track_speeds() -> None:
    positions = np.array([[0.0, 0.0], [-0.3, 0.0]])
    tracks = np.array([track_speeds(0.1, 0.5, 0.0, 0.2)] * 2)
    v, omega = group_twist(positions, np.zeros(2), tracks, 0.2)
    assert omega == pytest.approx(0.5) and v[1] == pytest.approx(0.0) and v[0] == pytest.approx(
        0.1)
    sideways = np.array([track_speeds(0.0, 1.0, 0.3, 0.2), track_speeds(0.0, 1.0, -0.3, 0.2)])
    v, _ = group_twist(np.array([[0.0, 0.3], [0.0, -0.3]]), np.zeros(2), sideways, 0.2)
    assert np.allclose(v, 0.0)


def test_path_leaves_clearance_around_obstacles() -> None:
    path = plan_path((0.0, 0.6), (0.85, -0.3), [(0.0, 0.0), (0.3, 0.0), (0.6, 0.0)], 0.32)
    assert path[-1] == (0.85, -0.3)
    points = [(0.0, 0.6), *path]
    for a, b in zip(points, points[1:], strict=False):
        assert segment_clearance(a, b, [(0.3, 0.0), (0.6, 0.0)]) > 0.3


def test_faces_latch_only_within_tolerance_and_groups_move_together() -> None:
    with MmrpSimDriver() as driver:
        driver.reset(load_configuration(CONFIGS / "series.json"))
        world = driver.world
        assert world is not None and len(world.docks) == 3
        driver.send_action({"3": ModuleCommand(undock=("T",))})
        driver.step(0.1)
        assert driver.get_observation().sensors["3"]["T"] is None
        # 4 (with nobody) drives forward 5 cm: out of the 1 cm latch window, no dock
        x0 = driver.witness().poses["4"].position[0]
        driver.send_action({"4": ModuleCommand(wheels={"left": 0.1, "right": 0.1})})
        driver.step(0.5)
        driver.send_action({"4": ModuleCommand(dock=("B",)), "3": ModuleCommand(dock=("T",))})
        driver.step(0.5)
        assert driver.get_observation().sensors["4"]["B"] is None
        x4 = driver.witness().poses["4"].position[0]
        assert x4 - x0 == pytest.approx(0.05, abs=0.005)
        # back into the window: it latches
        driver.send_action({"4": ModuleCommand(wheels={"left": -0.1, "right": -0.1},
                                               dock=("B",))})
        for _ in range(10):
            driver.step(0.05)
            if driver.get_observation().sensors["4"]["B"] is not None:
                break
        assert driver.get_observation().sensors["4"]["B"] == ("3", "T")
        # the docked chain drives as one body, straight ahead, no sideways slip
        driver.reset(load_configuration(CONFIGS / "series.json"))
        before = {m: p.position.copy() for m, p in driver.witness().poses.items()}
        driver.send_action({m: ModuleCommand(wheels={"left": 0.1, "right": 0.1}) for m in "1234"})
        driver.step(1.0)
        after = driver.witness().poses
        moved = {m: after[m].position - before[m] for m in before}
        assert all(d[0] == pytest.approx(0.1, abs=0.005) and abs(d[1]) < 1e-3
                   for d in moved.values())
        assert math.isclose(moved["1"][0], moved["4"][0], abs_tol=2e-3)


def test_platform_run_records_the_run(tmp_path: Path) -> None:
    # series -> t (4 modules, 44 s simulated); the default cross -> probe (9 modules,
    # 178 s simulated, ~12 s wall) runs in benchmarks/mmrp_pairs.py
    out = tmp_path / "run"
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "mmrp", "--scenario", "series-t",
                                            "--out", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] and summary["docks"] >= 1 and summary["undocks"] >= 1
    plan = load_plan(out / "plan.json")
    assert plan.docks == summary["docks"] and plan.undocks == summary["undocks"]
    assert "rerun " + str(out / "run.rrd") in result.output.replace("\n", "")
    verify = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(out / "run.rrd")],
                            capture_output=True, text=True)
    assert verify.returncode == 0, verify.stderr
    recording = summarize_recording(out / "run.rrd")
    assert {"tick", "sim_time"} <= recording.timelines
    assert recording.rows["/events/docks"] == plan.docks
    assert recording.rows["/events/undocks"] == plan.undocks
    assert len(recording.entities("/world/modules/")) == 2 * 4  # bodies and their faces


def test_the_default_run_deadline_grows_by_the_drive_time_the_controller_says_it_needs(
        tmp_path: Path) -> None:
    # series -> t at a 1 s phase timeout: the default deadline, (6 actions + 1) x 1 s, is
    # far shorter than the run (about 21 s, two drives of 12 and 8 s that the controller
    # says it needs); it grows by what each phase is given, a deadline the user sets does not
    def run(*extra: str) -> tuple[int, str]:
        out = tmp_path / f"run{len(extra)}"
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "mmrp", "--scenario",
                                                "series-t", "--timeout", "1", "--no-log",
                                                "--out", str(out), *extra])
        return result.exit_code, result.output

    code, output = run()
    assert code == 0, output
    code, output = run("--deadline", "15")
    assert code == 1 and "run deadline of 15 s of driver time reached" in output


@pytest.mark.parametrize("goal", ["probe.json", "bad-face.json"])
def test_unreachable_goal_fails_before_writing_anything(tmp_path: Path, goal: str) -> None:
    if goal == "bad-face.json":
        data = json.loads((CONFIGS / "series.json").read_text())
        data["connections"][0]["ports"] = ["T", "L"]
        (tmp_path / goal).write_text(json.dumps(data))
        goal_path = tmp_path / goal
    else:
        goal_path = CONFIGS / goal
    out = tmp_path / "run"
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "mmrp", "--from",
                                            str(CONFIGS / "series.json"), "--to", str(goal_path),
                                            "--out", str(out)])
    assert result.exit_code == 1
    assert result.output.count("\n") <= 2 and "Error:" in result.output
    assert "Traceback" not in result.output and not out.exists()


def test_a_sleeping_group_drives_when_commanded_and_idle_ones_stay():
    with MmrpSimDriver() as driver:
        driver.reset(from_links(["a", "b", "c"], [("a", "T", "b", "B"), ("b", "T", "c", "B")]))
        world = driver.world
        assert world is not None
        driver.send_action({"c": ModuleCommand(undock=("B",))})
        driver.step(5.0)  # long enough for Bullet to put every body to sleep
        before = {m: world.pose2(m) for m in world.bodies}
        assert len(world.docks) == 1
        go = {m: ModuleCommand(wheels={"left": -0.1, "right": -0.1}) for m in ("a", "b")}
        driver.send_action(go)
        driver.step(1.0)
        for m in ("a", "b"):
            assert np.subtract(world.pose2(m)[:2], before[m][:2]) @ [1, 0] == pytest.approx(
                -0.1, abs=2e-3)
        assert world.pose2("c") == before["c"]
