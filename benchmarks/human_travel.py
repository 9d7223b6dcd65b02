"""The human example's travel, estimated straight, under the topological pairing and the
pairing by places (issue 28, item 6).

``miso`` plans Luo and Lam's human example (six chains of 568 FreeBOTs into a human
figure) twice: by topology alone, and with the world's layout, which sends the pieces of
one shape to the nearer of their interchangeable places (:mod:`msrr.core.freeform.miso.places`).
For every step that docks a piece it prints the piece's size and the straight distance
its centroid covers (:func:`~msrr.core.freeform.miso.places.step_travel`: the piece's
modules whose connections up to its top are the goal's go to their goal places, the goal
in the start's frame fitted on the piece that stays; riders that leave it later are
shifted with the module they hang from). No way is planned: a lower bound of the floor
travel ``human_floor.py`` measures, turns and detours left out.

Usage: ``python benchmarks/human_travel.py [--start FILE] [--seed 0]``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from msrr.core.console import console, table
from msrr.core.io import load_configuration

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"


def rows(plan, start, goal, layout) -> list[tuple[int, str, int, float]]:
    """Per step that docks: (action, dock, modules in the piece, straight travel [m])."""
    from msrr.core.freeform.miso import (
        FREE,
        MisoProblem,
        Step,
        goal_in_start_frame,
        step_travel,
    )

    problem = MisoProblem.from_configurations(start, goal)
    index = {m: i for i, m in enumerate(problem.start_ids)}
    goal_index = {m: b for b, m in enumerate(problem.goal_ids)}
    pair = [goal_index[plan.mapping[m]] for m in problem.start_ids]
    steps, docks = [], []
    for k, action in enumerate(plan.actions, 1):
        if not action.changes:
            continue
        now = {(e.source, e.target) for e in action.target.edges()}
        made = [c for c in action.changes if (c.source, c.target) in now]
        broken = [c for c in action.changes if (c.source, c.target) not in now]
        m = action.changes[0].source
        steps.append(Step(index[m], index[broken[0].target] if broken else FREE,
                          index[made[0].target] if made else FREE))
        docks.append((k, f"{m} -> {made[0].target}" if made else f"{m} free"))
    here, there = layout(start), layout(goal)
    s = np.array([here[m] for m in problem.start_ids])
    g = goal_in_start_frame(problem, pair, s, np.array([there[m] for m in problem.goal_ids]))
    out = []
    for (k, dock), step, (size, d) in zip(docks, steps,
                                          step_travel(problem, pair, steps, s, g), strict=True):
        if step.new != FREE:
            out.append((k, dock, size, d))
    return out


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--start", "start_file", type=click.Path(exists=True, dir_okay=False,
                                                       path_type=Path),
              default=HUMAN / "human-chains-near.json", show_default=True)
def main(seed: int, start_file: Path) -> None:
    from msrr.core import plugins

    start = load_configuration(start_file)
    goal = load_configuration(HUMAN / "human.json")
    by_places = plugins.planners("freebot")["miso"]
    plans = {name: planner.plan(start, goal, seed=seed) for name, planner in (
        ("topology", replace(by_places, layout=None)), ("places", by_places))}
    runs = {name: rows(plan, start, goal, by_places.layout) for name, plan in plans.items()}
    console.print(f"seed {seed}; start {start_file.name}")
    table_rows = [[str(k), dock, str(n), f"{d:.2f}", str(k2), dock2, str(n2), f"{d2:.2f}"]
                  for (k, dock, n, d), (k2, dock2, n2, d2) in zip(
                      runs["topology"], runs["places"], strict=False)]
    sums = [sum(r[3] for r in runs[name]) for name in ("topology", "places")]
    table_rows.append(["sum", "", "", f"{sums[0]:.1f}", "", "", "", f"{sums[1]:.1f}"])
    console.print(table("the human example's pieces, centroid travel straight [m]",
                        ["action", "dock (topology)", "modules", "straight [m]",
                         "action", "dock (places)", "modules", "straight [m]"], table_rows))
    for name, plan in plans.items():
        console.print(f"{name}: {plan.stats['changes']:.0f} changes, "
                      f"{plan.stats['steps']:.0f} steps")
    stats = plans["places"].stats
    console.print(f"planner's sums: travel_m topology {stats.get('travel_m_topology', 0):.1f}, "
                  f"places {stats.get('travel_m', 0):.1f}; module_metres topology "
                  f"{stats.get('module_metres_topology', 0):.0f}, places "
                  f"{stats.get('module_metres', 0):.0f}")


if __name__ == "__main__":
    main()
