"""Ordered pairs of the shipped MMRP configurations: pairs of different module counts
are refused before anything is written; a pair that runs reaches the goal topology AND
the goal shape within MMRP's ``shape_tolerance``. cross -> probe runs in
``test_mmrp_sim.py``; all 12 pairs run in ``benchmarks/mmrp_pairs.py``."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest

from msrr.core import plugins
from msrr.core.app.run import RunRequest, execute_run, prepare_run, write_outputs
from msrr.core.driver import Pose
from msrr.core.errors import PlanningError
from msrr.core.io import load_configuration
from msrr.core.shape import pose_errors
from msrr.plugins.mmrp.representation import layout
from msrr.plugins.mmrp.sim import MmrpSimDriver

CONFIGS = Path(__file__).resolve().parents[3] / "plugins/mmrp/configs"
SHIPPED = ("cross", "probe", "series", "t")
PAIRS = list(itertools.permutations(SHIPPED, 2))


def _size(name: str) -> int:
    return len(json.loads((CONFIGS / f"{name}.json").read_text())["modules"])


def test_twelve_ordered_pairs_four_of_one_size() -> None:
    same = [(a, b) for a, b in PAIRS if _size(a) == _size(b)]
    assert len(PAIRS) == 12
    assert same == [("cross", "probe"), ("probe", "cross"), ("series", "t"), ("t", "series")]


@pytest.mark.parametrize(("start", "goal"), [p for p in PAIRS if _size(p[0]) != _size(p[1])])
def test_pairs_of_different_sizes_are_refused_before_anything_is_written(
        tmp_path: Path, start: str, goal: str) -> None:
    out = tmp_path / "out"
    with pytest.raises(PlanningError, match="keeps its module count"):
        prepare_run(RunRequest("mmrp", start=CONFIGS / f"{start}.json",
                               goal=CONFIGS / f"{goal}.json", out=out, log=False))
    assert not out.exists()


@pytest.mark.parametrize("name", SHIPPED)
def test_the_simulator_lays_out_a_goal_as_the_grid_representation_does(name: str) -> None:
    config = load_configuration(CONFIGS / f"{name}.json", plugins.resolve("mmrp"))
    with MmrpSimDriver(gui=False) as driver:
        driver.reset(config)
        placed = dict(driver.witness().poses)
    grid = {m: Pose.planar(x, y, yaw) for m, (x, y, yaw) in layout(config).items()}
    errors = pose_errors(placed, grid, plugins.robot("mmrp").defaults.shape_tolerance)
    assert errors.error < 1e-6 and errors.heading < 1e-6


def test_series_to_t_reaches_the_goal_shape(tmp_path: Path) -> None:
    prepared = prepare_run(RunRequest("mmrp", start=CONFIGS / "series.json",
                                      goal=CONFIGS / "t.json", out=tmp_path / "out", log=False))
    result = execute_run(prepared)
    write_outputs(prepared.run, result)
    assert result.success, result.reason
    assert result.goal is not None and result.goal.shape is not None
    assert result.goal.shape.metric == "poses" and result.goal.shape.within
    assert result.goal.basis == "ground truth"
    shape = json.loads((tmp_path / "out" / "summary.json").read_text())["goal"]["shape"]
    assert shape["max_position_error_m"] <= shape["position_tolerance_m"] == 0.02
    assert shape["max_heading_error_rad"] <= shape["heading_tolerance_rad"] == 0.06
