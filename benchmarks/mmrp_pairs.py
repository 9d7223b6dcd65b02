"""Every ordered pair of the shipped MMRP configurations (cross, probe, series, t: 12
pairs) through ``platform run``'s own functions in PyBullet (issue 11).

A pair of different module counts is refused by the planner before anything is written
(MMRP keeps its module count); every other pair must end in success: the goal topology
AND the goal shape within MMRP's ``shape_tolerance`` (final module positions and
headings against the goal layout after the best planar fit, :mod:`msrr.core.shape`).

Usage: ``python benchmarks/mmrp_pairs.py [--seed N]``. Prints the seed, one row per
pair and a last line ``pairs=12 refused=... succeeded=... failed=...``; exits 1 if a
runnable pair failed.
"""

from __future__ import annotations

import itertools
import tempfile
import time
from pathlib import Path

import click

from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.console import console, table
from msrr.core.errors import PlanningError

CONFIGS = Path(__file__).resolve().parents[1] / "plugins/mmrp/configs"
SHIPPED = ("cross", "probe", "series", "t")


@click.command()
@click.option("--seed", default=0, show_default=True, help="Seed of planning and recognition.")
def main(seed: int) -> None:
    console.print(f"seed={seed}")
    rows, counts = [], {"refused": 0, "succeeded": 0, "failed": 0}
    with tempfile.TemporaryDirectory() as folder:
        for start, goal in itertools.permutations(SHIPPED, 2):
            request = RunRequest("mmrp", start=CONFIGS / f"{start}.json",
                                 goal=CONFIGS / f"{goal}.json", seed=seed, log=False,
                                 out=Path(folder) / f"{start}-{goal}")
            began = time.perf_counter()
            try:
                prepared = prepare_run(request)
            except PlanningError as exc:
                counts["refused"] += 1
                rows.append([f"{start} -> {goal}", "refused", "", "", "", "", "", str(exc)])
                continue
            result = execute_run(prepared)
            wall = time.perf_counter() - began
            counts["succeeded" if result.success else "failed"] += 1
            shape = None if result.goal is None else result.goal.shape
            rows.append([f"{start} -> {goal}", "success" if result.success else "FAILED",
                         f"{result.actions_done}/{result.actions_total}",
                         f"{result.sim_time:.1f}", f"{wall:.1f}",
                         "" if shape is None else f"{shape.error * 1000:.2f}",
                         "" if shape is None else f"{(shape.rms or 0.0) * 1000:.2f}",
                         ("" if shape is None else f"{shape.heading or 0.0:.4f}")
                         + ("" if result.success else f"  {result.reason}")])
    console.print(table("MMRP shipped pairs in PyBullet", [
        "pair", "result", "actions", "sim time [s]", "wall [s]", "max pos err [mm]",
        "RMS pos err [mm]", "max heading err [rad] / reason"], rows))
    console.print(f"pairs=12 refused={counts['refused']} succeeded={counts['succeeded']} "
                  f"failed={counts['failed']}")
    if counts["failed"]:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
