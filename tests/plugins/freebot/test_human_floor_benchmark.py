"""The human example's floor benchmark (``benchmarks/human_floor.py``) models what an
action does to a piece it docks: kinematically, no physics."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from msrr.core.configuration import Configuration

from msrr_test_support import ROOT, load_script


def _benchmark():
    return load_script(ROOT / "benchmarks" / "human_floor.py", "human_floor_benchmark")


def _config(bent: bool) -> Configuration:
    """T1-T2 along x; the piece P1-P2-P3 (P1 on T2, below it) straight down, or bent at
    P2 toward +x (``bent``: the action's goal)."""
    config = Configuration("freebot", name="bend")
    for m in ("T1", "T2", "P1", "P2", "P3"):
        config.add_module(m, "freebot")
    config.connect("T1", "T2", z=[1.0, 0.0, 0.0])
    config.connect("P2", "P1", z=[0.0, 1.0, 0.0])
    config.connect("P3", "P2", z=[-1.0, 0.0, 0.0] if bent else [0.0, 1.0, 0.0])
    if bent:
        config.connect("P1", "T2", z=[0.0, 1.0, 0.0])
    return config


def test_a_straight_piece_docked_at_its_goal_place_takes_the_goals_bend():
    # the human example's action 47: F101's 25, docked at action 41 straight out through
    # its root's goal place, kept that shape in the benchmark, where the action's last
    # move bends it at F107; F567's goal place was then where F108 still lay
    bench = _benchmark()
    s = 0.101
    pos = {"T1": np.array([0.0, 0.0]), "T2": np.array([s, 0.0]),
           "P1": np.array([1.0, -1.0]), "P2": np.array([1.0, -1.0 - s]),
           "P3": np.array([1.0, -1.0 - 2 * s])}
    current = _config(bent=False)
    action = SimpleNamespace(changes=[SimpleNamespace(source="P1", target="T2")],
                             target=_config(bent=True))
    row = bench._step(1, action, current, pos, s)
    assert row is not None and row[3].startswith("goal place, bent"), row
    assert np.allclose(pos["P1"], [s, -s], atol=0.01)
    assert np.allclose(pos["P3"], [2 * s, -2 * s], atol=0.01), pos["P3"]
