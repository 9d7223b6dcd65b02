"""``benchmarks/human_floor.py``: the human example's floor steps planned on the centres
the steps before leave (issue 28, item 6)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from msrr.core import plugins
from msrr.core.freeform.world import place
from msrr.core.io import load_configuration

ROOT = Path(__file__).resolve().parents[3]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"


def _benchmark():
    path = ROOT / "benchmarks" / "human_floor.py"
    spec = importlib.util.spec_from_file_location("human_floor_benchmark", path)
    assert spec is not None and spec.loader is not None
    module = sys.modules.setdefault("human_floor_benchmark",
                                    importlib.util.module_from_spec(spec))
    spec.loader.exec_module(module)
    return module


def test_a_piece_docked_at_its_goal_place_is_left_in_its_goal_shape():
    # step 2 docks F563..F566 (straight) on F204; its goal is a shallow C (F565, F566
    # ride along, bent off the rib). The plan's last move bends it, so the next steps
    # plan round the C (before: left straight, so later pieces met the wrong figure and
    # the yaw fitted over it for their goal places turned them off the target)
    floor = _benchmark()
    start = load_configuration(HUMAN / "human-chains-near.json")
    plan = plugins.planners.get("freebot", "miso").plan(
        start, load_configuration(HUMAN / "human.json"), seed=0)
    pos = {m: c[:2].copy() for m, c in place(start, 0.101, 0.05)[0].items()}
    first = floor._goal_centres(plan.actions[0].target, 0.101)
    for m in ("F567", "F568"):             # step 1, docked on F226 (its way is long)
        pos[m] = pos["F226"] + (first[m] - first["F226"])[:2]
    action = plan.actions[1]
    row = floor._step(2, action, plan.actions[0].target, pos, 0.101)
    assert row is not None and row[1] == "F563 -> F204" and row[3] == "goal place"
    goal = floor._goal_centres(action.target, 0.101)
    for m in ("F563", "F564", "F565", "F566"):
        want = pos["F204"] + (goal[m] - goal["F204"])[:2]
        assert np.linalg.norm(pos[m] - want) < 0.01, m
