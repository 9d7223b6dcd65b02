"""The way planner's search time (``piece_way.plan_legs``), on seeded scenes of a wall and
a row, and optionally on the human example's first step.

Each scene: a wall of 12 modules across the way and a row of 8 beyond it (placed by the
seed), a piece of 1 to 4 modules (straight, or bent every third scene) that must go
round them from the left to a goal pose on the right. Prints the seed, and per scene the
piece, the legs found (or the refusal), the farthest module's travel and the planning
time; ``--human`` adds the human example's action 1 from
``human-chains-near.json`` (``human_floor.py``'s ``_step``: its search fails twice
before its third place; stop 50: 662 s of planning at load 4-8).

The search's answers do not depend on the machine; its time does: run it against the
code before and after a change, at the same load (``uptime`` beside the table).

Usage: ``python benchmarks/piece_way_search.py [--seed 3] [--scenes 4] [--human]``.
"""

from __future__ import annotations

import os
import time

import click
import numpy as np

from msrr.core.console import console, table
from msrr.core.errors import ExecutionError
from msrr.core.freeform.piece_way import Leg, PieceWay, plan_legs

SPACING = 0.101


def _scene(rng: np.random.Generator, i: int):
    wall = np.column_stack([np.zeros(12), (np.arange(12) - 6) * SPACING + rng.uniform(-0.3, 0.3)])
    row = np.column_stack([0.6 + np.arange(8) * SPACING, np.full(8, rng.uniform(-0.8, 0.8))])
    others = np.vstack([wall, row]) + rng.normal(scale=0.002, size=(20, 2))
    m = 1 + i % 4
    if i % 3:
        offsets = np.column_stack([(np.arange(m) - (m - 1) / 2) * SPACING, np.zeros(m)])
        line = np.array([1.0, 0.0]) if m > 1 else None
    else:
        bent = np.array([[0, 0], [0.101, 0], [0.101, 0.101], [0.2, 0.15]][:m])
        offsets, line = bent - bent.mean(axis=0), None
    start = (np.array([-0.5, rng.uniform(-0.4, 0.4)]), float(rng.uniform(-np.pi, np.pi)))
    goal = (np.array([0.9, rng.uniform(-0.4, 0.4)]), float(rng.uniform(-np.pi, np.pi)))
    return others, offsets, line, start, goal


def _travel(legs: list[Leg], offsets: np.ndarray, start: tuple[np.ndarray, float]) -> float:
    way = PieceWay("", "", (), start[0], offsets, start[1], tuple(legs), start[0],
                   np.zeros(2), None)
    return way.travel()


@click.command()
@click.option("--seed", default=3, show_default=True)
@click.option("--scenes", default=4, show_default=True)
@click.option("--human", is_flag=True, help="also the human example's action 1")
def main(seed: int, scenes: int, human: bool) -> None:
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(scenes):
        others, offsets, line, start, goal = _scene(rng, i)
        t0 = time.perf_counter()
        try:
            legs = plan_legs(others, offsets, line, start, goal, SPACING)
            found, travel = f"{len(legs)} legs", f"{_travel(legs, offsets, start):.3f}"
        except ExecutionError as error:
            found, travel = str(error), "-"
        rows.append([str(i), f"{len(offsets)} {'straight' if line is not None else 'bent'}",
                     found, travel, f"{time.perf_counter() - t0:.1f}"])
    if human:
        rows.append(_human())
    console.print(f"seed {seed}; load {os.getloadavg()[0]:.1f}")
    console.print(table("the way planner's search", ["scene", "piece", "way", "travel [m]",
                                                      "planning [s]"], rows))


def _human() -> list[str]:
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    import human_floor as hf

    from msrr.core import plugins
    from msrr.core.freeform.world import place
    from msrr.core.io import load_configuration

    start = load_configuration(hf.HUMAN / "human-chains-near.json")
    plan = plugins.planners.get("freebot", "miso").plan(
        start, load_configuration(hf.HUMAN / "human.json"), seed=0)
    centres, _ = place(start, SPACING, 0.05)
    pos = {m: c[:2].copy() for m, c in centres.items()}
    t0 = time.perf_counter()
    row = hf._step(1, plan.actions[0], start, pos, SPACING)
    assert row is not None
    return ["human, action 1", f"{row[2]} {row[1]}", f"{row[4]} legs, {row[3]}", row[5],
            f"{time.perf_counter() - t0:.1f}"]


if __name__ == "__main__":
    main()
