"""The human example's travel, estimated straight, under the topological pairing and the
pairing by places (issue 28, item 6).

``miso`` plans Luo and Lam's human example (six chains of 568 FreeBOTs into a human
figure) twice: by topology alone, and with the world's layout, which sends the pieces of
one shape to the nearer of their interchangeable places (:mod:`msrr.core.freeform.miso.places`).
For every step that docks a piece over the floor it prints the piece's size and the
straight distance its centroid covers: the piece's modules whose connections up to its
top are the goal's go to their goal places (the goal in the start's frame, fitted on the
piece that stays), the rest (riders that leave it later) are carried along by the
shift of the module they hang from. No way is planned: this is a lower bound of the
floor travel ``human_floor.py`` measures, turns and detours left out.

Usage: ``python benchmarks/human_travel.py [--start FILE] [--seed 0]``.
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from msrr.core.console import console, table
from msrr.core.io import load_configuration

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "plugins" / "freebot" / "configs" / "human"


def _goal_places(plan, start, goal, layout) -> dict[str, np.ndarray]:
    """Each start module's goal place (3,) [m] in the start's frame."""
    from msrr.core.freeform.miso import MisoProblem, goal_in_start_frame

    problem = MisoProblem.from_configurations(start, goal)
    index = {m: b for b, m in enumerate(problem.goal_ids)}
    pair = [index[plan.mapping[m]] for m in problem.start_ids]
    here, there = layout(start), layout(goal)
    laid = goal_in_start_frame(problem, pair, np.array([here[m] for m in problem.start_ids]),
                               np.array([there[m] for m in problem.goal_ids]))
    return {m: laid[pair[a]] for a, m in enumerate(problem.start_ids)}


def steps(plan, start, goal, layout) -> list[tuple[int, str, int, float]]:
    """Per docking step: (action, dock, modules, centroid's straight travel [m])."""
    place = _goal_places(plan, start, goal, layout)
    final = {e.source: e.target for e in plan.goal.edges()}
    pos = {m: np.asarray(p, dtype=np.float64) for m, p in layout(start).items()}
    parent = {e.source: e.target for e in start.edges()}
    out = []
    for k, action in enumerate(plan.actions, 1):
        made = [c for c in action.changes
                if {e.source: e.target for e in action.target.edges()}.get(c.source) == c.target]
        new = {e.source: e.target for e in action.target.edges()}
        for c in made:
            on: dict[str, list[str]] = {}
            for m, p in new.items():
                on.setdefault(p, []).append(m)
            piece, todo = [], [c.source]
            while todo:
                m = todo.pop()
                piece.append(m)
                todo.extend(sorted(on.get(m, ())))
            if c.target in piece or parent.get(c.source) == c.target:
                continue
            before = np.mean([pos[m] for m in piece], axis=0)
            for m in piece:   # top down: a module after the one it hangs from
                settled = m == c.source or (final.get(m) == new.get(m) and m in _at_goal)
                if settled:
                    shift_of[m] = place[m] - pos[m]
                    pos[m] = place[m]
                    _at_goal.add(m)
                else:
                    shift_of[m] = shift_of[new[m]]
                    pos[m] = pos[m] + shift_of[m]
            out.append((k, f"{c.source} -> {c.target}", len(piece),
                        float(np.linalg.norm(np.mean([pos[m] for m in piece], axis=0) - before))))
        parent = new
    return out


_at_goal: set[str] = set()
shift_of: dict[str, np.ndarray] = {}


@click.command()
@click.option("--seed", default=0, show_default=True)
@click.option("--start", "start_file", type=click.Path(exists=True, dir_okay=False,
                                                       path_type=Path),
              default=HUMAN / "human-chains-near.json", show_default=True)
def main(seed: int, start_file: Path) -> None:
    from dataclasses import replace

    from msrr.core import plugins

    start = load_configuration(start_file)
    goal = load_configuration(HUMAN / "human.json")
    by_places = plugins.planners("freebot")["miso"]
    layout = by_places.layout
    runs = {}
    for name, planner in (("topology", replace(by_places, layout=None)),
                          ("places", by_places)):
        plan = planner.plan(start, goal, seed=seed)
        _at_goal.clear()
        shift_of.clear()
        runs[name] = (plan, steps(plan, start, goal, layout))
    console.print(f"seed {seed}; start {start_file.name}")
    rows = []
    for (k, dock, n, d), (k2, dock2, n2, d2) in zip(runs["topology"][1], runs["places"][1],
                                                     strict=False):
        rows.append([str(k), dock, str(n), f"{d:.2f}", str(k2), dock2, str(n2), f"{d2:.2f}"])
    sums = [sum(s[3] for s in runs[r][1]) for r in ("topology", "places")]
    rows.append(["sum", "", "", f"{sums[0]:.1f}", "", "", "", f"{sums[1]:.1f}"])
    console.print(table("the human example's pieces, centroid travel straight [m]",
                        ["action", "dock (topology)", "modules", "straight [m]",
                         "action", "dock (places)", "modules", "straight [m]"], rows))
    stats = runs["places"][0].stats
    for name, (plan, _) in runs.items():
        console.print(f"{name}: {plan.stats['changes']:.0f} changes, {plan.stats['steps']:.0f}"
                      " steps")
    console.print(f"module-metres (every module's straight distance, start to goal place): "
                  f"topology {stats.get('module_metres_topology', float('nan')):.0f}, places "
                  f"{stats.get('module_metres', float('nan')):.0f}")


if __name__ == "__main__":
    main()
