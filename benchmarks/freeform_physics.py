"""FreeBOT and SnailBot break-and-make in MuJoCo (issue 28, items 5 and 6).

Runs the scenarios that free a module and dock it again (FreeBOT ``roll-to-dock``,
SnailBot ``crawl-to-dock``) and the one that uses SnailBot's sucker (``sucker-turn``)
with ``platform run``'s own functions, each at the given noise on every reported angle,
and prints per run: the judge's verdict on the simulator's ground truth (topology and
the final shape), the simulator's constraint switches, simulated and wall time.

Then the published human example (Luo and Lam 2023: six chains of 568 FreeBOTs into a
human shape; their IM heuristic needs 91 connection changes): the ``miso`` plan's steps
and connection changes beside 91, and what of it could run in the MuJoCo world (a module
travels over the floor only alone: the steps whose moving module carries others are
counted).

Usage: ``python benchmarks/freeform_physics.py [--seed 0] [--noise 0.0175]
[--only NAME]``. Prints the seed and two tables; exits 1 if a scenario fails.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import click

from msrr.core import plugins
from msrr.core.app.run import RunRequest, execute_run, prepare_run
from msrr.core.console import console, table

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"
IM_CHANGES = 91
"""Connection changes of the published IM heuristic on the human example."""
RUNS = (("freebot", "roll-to-dock"), ("snailbot", "crawl-to-dock"),
        ("snailbot", "sucker-turn"))


def _run(robot: str, scenario: str, seed: int, noise: float) -> list[object]:
    with tempfile.TemporaryDirectory() as out:
        options = (("noise", str(noise)),) if noise else ()
        prepared = prepare_run(RunRequest(robot, scenario=scenario, out=Path(out) / "run",
                                          log=False, seed=seed, driver_options=options))
        started = time.perf_counter()
        result = execute_run(prepared)
        wall = time.perf_counter() - started
    goal = result.goal
    shape = "-" if goal is None or goal.shape is None else f"{math.degrees(goal.shape.error):.2f}"
    switches = result.simulator or {}
    return [robot, scenario, "yes" if result.success else f"no: {result.reason}",
            f"{result.actions_done}/{result.actions_total}", shape,
            f"{switches.get('dock', 0)} / {switches.get('undock', 0)} / {switches.get('flow', 0)}",
            f"{result.sim_time:.1f}", f"{wall:.1f}"]


def _human() -> list[object]:
    capabilities = plugins.capabilities("freebot")
    start = plugins.load_configuration(HUMAN / "human-chains.json")
    goal = plugins.load_configuration(HUMAN / "human.json")
    started = time.perf_counter()
    plan = capabilities.planner("miso").plan(start, goal)
    elapsed = time.perf_counter() - started
    carrying = 0
    here = plan.start
    for action in plan.actions:
        on = {e.target for e in here.edges()}
        carrying += any(c.source in on for c in action.changes)
        here = action.target
    stats = plan.stats
    return [len(start.modules()), int(stats["steps"]), int(stats["changes"]), IM_CHANGES,
            f"{int(stats['changes']) - IM_CHANGES:+d}", carrying, f"{elapsed:.1f}"]


@click.command()
@click.option("--seed", default=0, show_default=True, help="Seed of every run.")
@click.option("--noise", default=0.0, show_default=True,
              help="Standard deviation of every reported angle [rad].")
@click.option("--only", default="", help="Run only the scenarios of this name.")
def main(seed: int, noise: float, only: str) -> None:
    console.print(f"seed {seed}, noise {noise} rad")
    rows = [_run(robot, name, seed, noise) for robot, name in RUNS if not only or name == only]
    console.print(table("Break-and-make in MuJoCo (judged on ground truth)",
                        ["robot", "scenario", "success", "actions", "final shape [deg RMS]",
                         "switches dock/undock/flow", "simulated [s]", "wall [s]"], rows))
    console.print(table("Published human example (Luo and Lam 2023), miso plan",
                        ["modules", "steps", "changes", "IM changes", "difference",
                         "steps carrying others (not run in MuJoCo)", "plan time [s]"],
                        [_human()]))
    sys.exit(0 if all(r[2] == "yes" for r in rows) else 1)


if __name__ == "__main__":
    main()
