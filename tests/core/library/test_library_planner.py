"""The core's ``library`` planner over the FreeSN libraries (issue 13, items 1, 5, 6).

Retrieval across frames is checked against the library's own geometry: the triangle
struts of S6N3 do not move along a retrieved path, so between consecutive targets they
must keep their direction (within numerical noise) even when library configurations
are stored in other yaw frames; and the frame turn is compared with a brute-force
search over yaw.
"""

from __future__ import annotations

import importlib
import math
from pathlib import Path

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.alignment import angles_between, rot_z
from msrr.core.configuration import Configuration
from msrr.core.errors import PlanningError
from msrr.core.kinematics import KinematicTree
from msrr.core.library import load_library
from msrr.core.library.planner import LibraryPlanner
from msrr.core.library.retrieve import INLIER, frame_turn, retrieve
from msrr.core.plan import ActionType, save_plan
from msrr.core.random_configurations import newly_built
from msrr.core.shape import skeletal_error

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"
CONFIGS = FREESN / "configs" / "library"
retrieve_module = importlib.import_module("msrr.core.library.retrieve")


@pytest.fixture(scope="module")
def planner() -> LibraryPlanner:
    found = plugins.planners.get("freesn", "library")
    assert isinstance(found, LibraryPlanner)
    return found


def library_config(key: str) -> Configuration:
    return plugins.load_configuration(CONFIGS / f"{key}.json")


def unseen(key: str, seed: int, tilt_deg: float = 5.0) -> Configuration:
    return newly_built(library_config(key), np.random.default_rng(seed),
                       noise=math.radians(tilt_deg), name="unseen")


def test_hook_msrr_libraries(planner):
    names = [p.name for p in plugins.libraries("freesn")]
    assert {"S12N6.json", "S4N5.json", "S6N3.json"} <= set(names)
    assert not [n for n in names if n.endswith(".check.json")]      # check files go beside
    assert next(iter(plugins.planners("freesn"))) == "library"      # the robot's default
    assert "library" not in plugins.planners("mmrp")                # no libraries, no planner
    assert planner.library_for(library_config("S6N3-1.1")).name == "S6N3"
    lonely = Configuration("freesn")
    lonely.add_module("N1", "node")
    with pytest.raises(PlanningError, match="no freesn library for N1"):
        planner.library_for(lonely)


def node_pairs(config: Configuration, rename: dict[str, str]) -> list[frozenset[str]]:
    """The node pairs each strut between two nodes joins, renamed, sorted."""
    return sorted((frozenset({rename[e.source], rename[e.target]}) for e in config.edges()
                   if not (config.is_virtual(e.source) or config.is_virtual(e.target))),
                  key=sorted)


def closed(config: Configuration) -> set[str]:
    """Struts docked at both ends."""
    return {e.id for e in config.edges()
            if not (config.is_virtual(e.source) or config.is_virtual(e.target))}


def reframed(turns: dict[str, float]):
    """The S6N3 library with the given configurations stored in other yaw frames."""
    library = load_library(FREESN / "libraries" / "S6N3.json")
    sub = library.sublibrary("S6N3")
    for key, yaw in turns.items():
        entry = sub.configurations[key]
        entry.configuration = entry.configuration.derive(rotation=rot_z(math.radians(yaw)))
    return library


def docking(before: Configuration, after: Configuration) -> list[str]:
    """Struts with a free end in ``before`` and none in ``after``."""
    def free(config: Configuration, edge: str) -> bool:
        e = config.edge(edge)
        return config.is_virtual(e.source) or config.is_virtual(e.target)

    return [e for e in after.edge_ids() if free(before, e) and not free(after, e)]


def frame_jumps(library, start: Configuration, robot) -> tuple[float, float]:
    """Largest change [deg] of a strut docked at both ends all along (S3, the triangle's
    side that never opens) between consecutive retrieved targets (after the approach),
    and largest angle between a docking strut's aim and its docked direction."""
    found = retrieve(library, start, robot, to="S6N3-4.1")
    ids = sorted(closed(start).intersection(*(closed(s.target) for s in found.steps)))
    assert ids
    jump = aim = 0.0
    for before, after in zip(found.steps, found.steps[1:], strict=False):
        moved = angles_between(before.target.vectors(ids), after.target.vectors(ids))
        jump = max(jump, float(np.degrees(moved.max())))
        if after.action is ActionType.CONNECTION:
            for strut in docking(before.target, after.target):
                docked = angles_between(before.target.vectors([strut]),
                                        after.target.vectors([strut]))
                aim = max(aim, float(np.degrees(docked.max())))
    return jump, aim


def test_retrieved_targets_share_one_frame(planner, monkeypatch):
    start = unseen("S6N3-1.1", seed=3)
    library = reframed({"S6N3-2.1": 120.0, "S6N3-3.1": -120.0, "S6N3-4.1": 120.0})
    jump, aim = frame_jumps(library, start, planner.robot)
    assert jump < 0.5 and aim < 0.5                 # the closed side holds still
    monkeypatch.setattr(retrieve_module, "frame_turn", lambda config, previous: 0.0)
    jump, aim = frame_jumps(library, start, planner.robot)
    assert jump > 100.0 and aim > 100.0             # without it: the stored frames show


def test_frame_turn_against_brute_force():
    base = library_config("S6N3-2.3")
    rng = np.random.default_rng(0)
    for yaw in rng.uniform(-np.pi, np.pi, 5):
        swung = {e.id: rot_z(2.6) @ e.z if e.id == "S5" else e.z for e in base.edges()}
        moved = base.with_vectors(z=swung).derive(rotation=rot_z(yaw))
        ids = base.edge_ids()
        old, new = base.vectors(ids), moved.vectors(ids)
        grid = np.radians(np.arange(-180.0, 180.0, 0.05))             # every yaw, 0.05 deg apart
        turned = np.einsum("tij,jn->tin", np.stack([rot_z(t) for t in grid]), new)
        angles = np.arccos(np.clip(np.einsum("in,tin->tn", old, turned), -1.0, 1.0))
        inliers = angles < INLIER
        spread = np.sum(np.where(inliers, angles, INLIER) ** 2, axis=1)
        best = grid[np.lexsort((spread, -inliers.sum(axis=1)))[0]]
        turn = frame_turn(moved, base)
        assert abs(np.angle(np.exp(1j * (turn - best)))) < np.radians(0.1)
        assert abs(np.angle(np.exp(1j * (turn + yaw)))) < 1e-6    # exactly undoes the yaw


@pytest.mark.parametrize(("start_key", "goal_key", "seed"),
                         [("S6N3-1.1", "S6N3-4.1", 11), ("S12N6-2.1", "S12N6-7.1", 12)])
def test_an_unseen_start_reaches_the_target(planner, start_key, goal_key, seed):
    start = unseen(start_key, seed)
    goal = library_config(goal_key)
    plan = planner.plan(start, goal)
    assert plan.actions and plan.actions[0].type is ActionType.MOVING
    assert f"{start_key} ->" in plan.notes[0]                        # matched where it is
    assert skeletal_error(start, plan.actions[0].target) < math.radians(10.0)
    assert skeletal_error(plan.goal, goal) < 1e-9                    # the target's shape
    assert set(plan.goal.modules()) == set(start.modules())          # in the system's ids
    assert all(isinstance(a.kinematic_tree, KinematicTree) for a in plan.actions)
    assert "system -> " in plan.actions[0].retrieved
    # Plan.mapping takes the system's ids to the goal file's: node pairs joined by a
    # strut in the goal file are the pairs joined in the plan's goal
    to_system = {g: m for m, g in plan.mapping.items()}
    assert len(to_system) == len(plan.mapping) == sum(1 for v in goal.vertices()
                                                      if not goal.is_virtual(v))
    assert node_pairs(goal, to_system) == node_pairs(plan.goal, {m: m for m in to_system.values()})


def test_a_plan_with_trees_and_a_behavior_survives_its_file(planner, tmp_path):
    start = unseen("S6N3-1.1", seed=4)
    plan = planner.plan_behavior(start, "wheeled-move", parameters={"speed": 0.05},
                                 duration=5.0)
    save_plan(plan, tmp_path / "plan.json")
    again = plugins.load_plan(tmp_path / "plan.json")
    assert [a.label for a in again.actions] == [a.label for a in plan.actions]
    for mine, read in zip(plan.actions, again.actions, strict=True):
        assert isinstance(read.kinematic_tree, KinematicTree)
        assert read.kinematic_tree.to_dict() == mine.kinematic_tree.to_dict()
        assert read.behavior == mine.behavior and read.retrieved == mine.retrieved


def test_a_mapping_behavior_is_planned_in_the_system_ids(planner):
    start = unseen("S6N3-1.1", seed=5)
    plan = planner.plan_behavior(start, "wheeled-move", parameters={"speed": 0.05},
                                 duration=5.0)
    action = plan.actions[-1]
    assert action.type is ActionType.BEHAVIOR and action.behavior is not None
    call = action.behavior
    library = load_library(FREESN / "libraries" / "S6N3.json")
    expected = library.sublibrary("S6N3").behaviors["wheeled-move"].commands
    assert sorted(c.gains for c in call.commands) == sorted(c.gains for c in expected)
    assert {c.module for c in call.commands} <= set(start.modules())  # the system's ids
    assert call.duration == 5.0 and np.isclose(np.linalg.norm(call.direction), 1.0)
    assert skeletal_error(plan.goal, action.target) < 1e-7   # arccos of 1 - rounding
    with pytest.raises(PlanningError, match="no parameter spin"):
        planner.plan_behavior(start, "wheeled-move", parameters={"spin": 1.0})
    with pytest.raises(PlanningError, match="wheeled-move"):
        planner.plan_behavior(start, "moonwalk")
    with pytest.raises(PlanningError, match="not loops"):
        planner.plan_behavior(start, "wheeled-move", loops=3)
