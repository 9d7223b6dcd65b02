"""The human example's flat goal and its near start (issue 28, item 6): the files are
what ``human_layout.py`` writes, the goal lies flat on the floor with no shells
overlapping, and the plan between them keeps its 89 changes."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from msrr.core import plugins
from msrr.core.freeform.world import place
from msrr.core.io import load_configuration

HUMAN = Path(__file__).resolve().parents[3] / "plugins" / "freebot" / "configs" / "human"


def _layout():
    spec = importlib.util.spec_from_file_location("human_layout", HUMAN / "human_layout.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_files_are_what_the_layout_script_writes():
    layout = _layout()
    goal = json.loads((HUMAN / "human.json").read_text())
    start = json.loads((HUMAN / "human-chains.json").read_text())
    assert (HUMAN / "human.json").read_text() == layout.text(layout.flat(goal))
    assert (HUMAN / "human-chains-near.json").read_text() == layout.text(layout.lay(start))
    assert layout.main(["--check"]) == 0


def test_the_goal_lies_flat_on_the_floor_without_overlaps():
    layout = _layout()
    goal = json.loads((HUMAN / "human.json").read_text())
    assert layout.problems(goal) == []
    where = layout.centres(goal)
    assert len(where) == 568 and all(abs(p[2]) < 1e-9 for p in where.values())
    # every centre at least one spacing from every module it is not connected to, and
    # every connection one spacing long: shells touch their parent and children only
    names = sorted(where)
    points = np.array([where[m] for m in names])
    gaps = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    close = {frozenset((names[a], names[b]))
             for a, b in zip(*np.nonzero(gaps < 0.101 - 1e-6), strict=True) if a < b}
    assert close == set()
    for c in goal["connections"]:
        assert np.linalg.norm(where[c["source"]] - where[c["target"]]) == pytest.approx(0.101)
    # the world lays it out: no two shells overlap
    centres, _ = place(load_configuration(HUMAN / "human.json"), 0.101, 0.05)
    assert np.ptp([c[2] for c in centres.values()]) < 1e-9


def test_a_stacked_layout_is_reported():
    layout = _layout()
    goal = json.loads((HUMAN / "human.json").read_text())
    stacked = dict(goal)
    stacked["connections"] = [({**c, "z": [0.0, 0.0, -1.0]} if c["source"] == "F91" else c)
                              for c in goal["connections"]]
    found = layout.problems(stacked)
    assert any("F91 is +0.101 m above" in p for p in found)
    assert any("not connected" in p for p in found) or len(found) >= 15


def test_the_near_start_holds_the_six_chains_and_the_plan_keeps_its_89_changes():
    start = load_configuration(HUMAN / "human-chains-near.json")
    chains = load_configuration(HUMAN / "human-chains.json")
    assert {(e.source, e.target) for e in start.edges()} == \
        {(e.source, e.target) for e in chains.edges()}
    place(start, 0.101, 0.05)                 # laid without overlaps
    plan = plugins.planners("freebot")["miso"].plan(start, load_configuration(
        HUMAN / "human.json"), seed=0)
    assert (plan.stats["changes"], plan.stats["steps"]) == (89, 47)
