"""The same MISO input gives the same plan file under any ``PYTHONHASHSEED`` (issue 28,
item 4), at the scale of Luo and Lam's largest instances.

For each robot (FreeBOT, SnailBot) and planner, writes a start (a forest of six trees)
and a goal (one tree) of ``--modules`` modules drawn with the benchmark's generators
(:mod:`msrr.core.freeform.miso`, six connections at most on a module); and, for the
pairing by places (pieces of one shape sent to the nearer places when the start says
where its modules lie), takes Luo and Lam's human example from its near start
(``human-chains-near.json``, 568 modules). For each it runs
``platform plan START GOAL --planner miso --json PLAN`` as a user does, once per hash
seed, and compares the plan files with their timings (``stats`` ending in ``_ms``)
removed. Prints the seed and a table; exits 1 if two plans differ.

Usage: ``python benchmarks/miso_determinism.py [--seed 0] [--modules 1000]
[--hash-seeds 1,2]``
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from msrr.core.configuration import Configuration
from msrr.core.console import console, table
from msrr.core.freeform.miso import random_forest, random_miso_tree
from msrr.core.io import save_configuration

ROBOTS = ("freebot", "snailbot")
HUMAN = Path(__file__).resolve().parents[1] / "plugins" / "freebot" / "configs" / "human"


def configuration(robot: str, parents: tuple[int, ...], name: str) -> Configuration:
    """Module ``i`` sits on ``parents[i]`` (``-1``: its connector is free)."""
    config = Configuration(robot, name=name)
    for i in range(len(parents)):
        config.add_module(f"M{i}", robot)
    for i, p in enumerate(parents):
        if p >= 0:
            config.connect(f"M{i}", f"M{p}", z=[1.0, 0.0, 0.0])
    return config


def plan_file(start: Path, goal: Path, out: Path, hash_seed: str) -> tuple[dict, float]:
    """``platform plan`` in a process with ``PYTHONHASHSEED=hash_seed``: the plan file
    without its timings, and the wall time [s]."""
    platform = Path(sys.executable).with_name("platform")
    started = time.perf_counter()
    subprocess.run([str(platform), "plan", str(start), str(goal), "--planner", "miso",
                    "--json", str(out)], check=True, stdout=subprocess.DEVNULL,
                   env={**os.environ, "PYTHONHASHSEED": hash_seed})
    wall = time.perf_counter() - started
    plan = json.loads(out.read_text())
    plan["stats"] = {k: v for k, v in plan["stats"].items() if not k.endswith("_ms")}
    return plan, wall


def _compare(start: Path, goal: Path, folder: Path, name: str, hash_seeds: str
             ) -> tuple[list[str], bool]:
    """Plan ``start`` -> ``goal`` once per hash seed: the table row's steps, changes,
    whether the plan files are identical, and the wall times."""
    runs = [plan_file(start, goal, folder / f"{name}-{h}.json", h) for h in hash_seeds.split(",")]
    identical = all(plan == runs[0][0] for plan, _ in runs)
    stats = runs[0][0]["stats"]
    return [str(int(stats["steps"])), str(int(stats["changes"])), "yes" if identical else "NO",
            " / ".join(f"{wall:.1f}" for _, wall in runs)], identical


@click.command()
@click.option("--seed", default=0, show_default=True, help="Seed of the instances.")
@click.option("--modules", default=1000, show_default=True, help="Modules per instance.")
@click.option("--hash-seeds", default="1,2", show_default=True,
              help="PYTHONHASHSEED of each run, comma-separated.")
def main(seed: int, modules: int, hash_seeds: str) -> None:
    console.print(f"seed {seed}, {modules} modules, PYTHONHASHSEED {hash_seeds}")
    rows, same = [], True
    with tempfile.TemporaryDirectory() as folder:
        for robot in ROBOTS:
            rng = np.random.default_rng([seed, modules])
            start, goal = Path(folder, f"{robot}-start.json"), Path(folder, f"{robot}-goal.json")
            save_configuration(configuration(robot, random_forest(modules, 6, rng), "forest"),
                               start)
            save_configuration(configuration(robot, random_miso_tree(modules, rng), "tree"),
                               goal)
            row, identical = _compare(start, goal, Path(folder), robot, hash_seeds)
            rows.append([robot, "miso", str(modules), *row])
            same &= identical
        row, identical = _compare(HUMAN / "human-chains-near.json", HUMAN / "human.json",
                                  Path(folder), "human", hash_seeds)
        rows.append(["freebot", "miso, by places", "568 (human, near start)", *row])
        same &= identical
    console.print(table("Plan files under different hash seeds (timings aside)",
                        ["robot", "planner", "modules", "steps", "changes", "identical",
                         "wall per run [s]"], rows))
    sys.exit(0 if same else 1)


if __name__ == "__main__":
    main()
