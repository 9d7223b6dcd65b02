"""Where MMRP's cuts for motion arise (issue 29, item 4).

Plans seeded random pairs of legal planar trees (``random_tree(n, default_rng(s))``
twice, planner seed ``s``) and counts every time evacuate-and-assemble's peel finds
no moving group that can leave (``routing._Walled``), by what stood on the stuck
groups' cheapest ways out (the cells those ways sweep, turns included):

* **standing**: a group that stays put is among them; it moves out and back, no cut;
* **deadlock**: every one of them is a moving group that cannot leave either, so no
  order of the exits frees any (a group leaving only frees cells, and the peel tries
  every group left before it gives up); a kept connection is cut (one more pair).

Counts cover every alternative decomposition routed, also those given up (their cuts
would have cost as many pairs as the best plan), so deadlocks exceed the chosen
plans' cuts.

Usage: ``python benchmarks/mmrp_cuts.py [--modules N] [--seeds 1,2,3,4]``. The last
line is ``pairs=... cuts=... standing=... deadlocks=...`` (totals).
"""

from __future__ import annotations

import time

import click
import numpy as np

from msrr.core.console import console, table
from msrr.plugins.mmrp import routing
from msrr.plugins.mmrp.planner import plan_hybrid
from msrr.plugins.mmrp.random_trees import random_tree


class _Counted:
    """The peel's walls, counted by kind while installed (``with``)."""

    def __init__(self) -> None:
        self.standing = self.deadlocks = 0

    def __enter__(self) -> _Counted:
        self._run = run = routing._Peel.run

        def counted(peel, shapes, moving, frame):
            try:
                return run(peel, shapes, moving, frame)
            except routing._Walled as walled:
                if walled.neighbours - moving:
                    self.standing += 1
                else:
                    self.deadlocks += 1
                raise

        routing._Peel.run = counted  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        routing._Peel.run = self._run  # type: ignore[method-assign]


@click.command()
@click.option("--modules", "n", default=500, show_default=True, help="Modules per pair.")
@click.option("--seeds", default="1,2,3,4", show_default=True,
              help="Seeds of the pairs, comma-separated.")
def main(n: int, seeds: str) -> None:
    console.print(f"modules={n} seeds={seeds}")
    rows, totals = [], np.zeros(4, dtype=int)
    for s in (int(v) for v in seeds.split(",") if v):
        rng = np.random.default_rng(s)
        start, goal = random_tree(n, rng), random_tree(n, rng)
        cpu = time.process_time()
        with _Counted() as walls:
            result = plan_hybrid(start, goal, seed=s)
        cuts = int(result.plan.stats["cut_for_motion"])
        found = np.array([result.pairs, cuts, walls.standing, walls.deadlocks])
        totals += found
        rows.append([s, *found.tolist(), f"{time.process_time() - cpu:.1f}"])
    rows.append(["all", *totals.tolist(), ""])
    console.print(table(f"MMRP cuts for motion, {n}-module pairs",
                        ["seed", "pairs", "cuts", "walls: standing", "walls: deadlock",
                         "CPU s"], rows))
    print(f"pairs={totals[0]} cuts={totals[1]} standing={totals[2]} deadlocks={totals[3]}")


if __name__ == "__main__":
    main()
