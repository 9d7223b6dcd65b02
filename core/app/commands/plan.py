"""``platform plan``: plan a reconfiguration between two configuration files.

Prints the planner's notes (for MMRP the decomposition), the module mapping and the
actions as a table in the form of the MMRP paper's Table 4 (Action | ID | Face | ID |
Face); ``--json`` writes the plan in the plan file format
(:func:`msrr.core.plan.load_plan` reads it back; ``platform schema plan`` prints its
JSON Schema).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ... import plugins
from ...console import SEED, console, drop_empty_columns, plural, table
from ...errors import PlanningError

if TYPE_CHECKING:
    from ...plan import Action, Plan

__all__ = ["action_rows", "command", "print_plan"]

VERBS = {"moving": "Move", "behavior": "Behavior"}
"""Table verb of the action types without connection changes (by
:class:`~msrr.core.plan.ActionType` value: the type module loads with the planner, not at
``--help``); a change is a ``Dock`` or an ``Undock`` row by what it does, whatever its
action's type (a parallel step holds both), ``Flow (dock)``/``Flow (undock)`` in a flow."""

HEADER = ["#", "Action", "ID", "Face", "ID", "Face", "x [m]", "y [m]", "yaw [deg]", "goal"]
"""Columns of the action table: the MMRP paper's Table 4 (Action | ID | Face | ID | Face)
with the action's number, then a moving module's goal: planar ``[x, y, yaw]`` goals in
their own columns, any other goal as one vector."""


def _goal(values: list[float]) -> list[str]:
    """The x, y, yaw and goal cells of one goal pose."""
    if len(values) == 3:
        x, y, yaw = values
        return [f"{x:+.3f}", f"{y:+.3f}", f"{math.degrees(yaw):+.1f}", ""]
    return ["", "", "", "(" + ", ".join(f"{v:+.3f}" for v in values) + ")"]


def action_rows(actions: list[Action]) -> list[list[str]]:
    """One row per connection change of an action (``Dock`` or ``Undock``, ends in the
    connection's :attr:`~msrr.core.plan.ConnectionChange.ends` order), per moving module
    with a goal, or per action otherwise; the first column is the action's number (from
    1), so a move of two modules is two rows of one action."""
    rows = []
    for number, action in enumerate(actions, start=1):
        if action.changes:
            made = set(action.made())
            for c in action.changes:
                verb = "Dock" if c in made else "Undock"
                if action.type.value == "flow":
                    verb = f"Flow ({verb.lower()})"
                rows.append([str(number), verb, *c.ends[0], *c.ends[1], "", "", "", ""])
            continue
        verb = VERBS.get(action.type.value, action.type.value)
        if action.goals:
            rows += [[str(number), verb, module, "", "", "", *_goal(pose)]
                     for module, pose in action.goals.items()]
        else:  # no module named: the target configuration says how every module moves
            rows.append([str(number), verb, ", ".join(action.modules) or "all", "", "", "",
                         "", "", "", ""])
    return rows


def print_plan(plan: Plan) -> None:
    """Print a plan's notes, mapping, action table and counts (:func:`plan_counts`)."""
    for note in plan.notes:
        console.print(f"- {note}", soft_wrap=True)
    if plan.mapping:
        pairs = sorted(plan.mapping.items(), key=lambda pair: (len(pair[0]), pair[0]))
        console.print(table("Mapping (start -> goal)", ["start", "goal"], pairs))
    header, rows = drop_empty_columns(HEADER, action_rows(plan.actions),
                                      {"x [m]", "y [m]", "yaw [deg]", "goal"})
    console.print(table(f"Actions ({plan.planner})", header, rows))
    console.print(plan_counts(plan))


def plan_counts(plan: Plan) -> str:
    """``"7 actions: 3 undocks, 3 docks, 1 move (2 modules)"``: the actions of the table
    (its ``#`` column), the connections they break and make (its ``Undock`` and ``Dock``
    rows), the moving actions and, when it differs, the modules those name."""
    moves = [a for a in plan.actions if a.type.value == "moving"]
    moved = sum(len(a.goals) or len(a.modules) for a in moves)  # 0: targets say it all
    text = (f"{plural(len(plan.actions), 'action')}: {plural(plan.undocks, 'undock')}, "
            f"{plural(plan.docks, 'dock')}, {plural(len(moves), 'move')}")
    if moved and moved != len(moves):
        text += f" ({plural(moved, 'module')})"
    flows = sum(1 for a in plan.actions if a.type.value == "flow")
    return text + (f", {plural(flows, 'flow')}" if flows else "")


@click.command("plan")
@click.option("--robot", default=None,
              help="Robot name (see `platform robots`); default the robot START names.")
@click.argument("start", type=click.Path(path_type=Path))
@click.argument("goal", type=click.Path(path_type=Path))
@click.option("--planner", "planner_name", default=None, help="Planner name; default the "
              "robot's first registered planner.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the planner.")
@click.option("--json", "json_out", type=click.Path(path_type=Path), default=None,
              help="Also write the plan to this file (format: `platform schema plan`).")
def command(robot: str | None, start: Path, goal: Path, planner_name: str | None, seed: int,
            json_out: Path | None) -> None:
    """Plan the reconfiguration from configuration file START to GOAL (both of one robot,
    the one they name unless --robot says which)."""
    from ...files import check_output_place
    from ...plan import save_plan

    if json_out is not None:  # before any work: one line, not a traceback after planning
        check_output_place(json_out, option="--json")

    configs = [plugins.load_configuration(path) for path in (start, goal)]
    robot = robot or configs[0].robot
    for path, config in zip((start, goal), configs, strict=True):
        if config.robot != robot:
            raise PlanningError(f"{path}: a configuration of robot {config.robot!r}, "
                                f"not {robot!r}")
    planner = plugins.planners.get(robot, planner_name)
    # a spinner on a terminal while the planner works (seconds at a thousand modules)
    with console.status(f"planning {plural(len(configs[0].modules()), 'module')} with "
                        f"{getattr(planner, 'name', planner_name or 'the planner')}…"):
        try:
            plan = planner.plan(configs[0], configs[1], seed=seed)
        except PlanningError as exc:  # about the pair: name both files
            raise PlanningError(f"{start} -> {goal}: {exc}") from None
    print_plan(plan)
    if json_out is not None:
        with console.status(f"writing {json_out}…"):
            save_plan(plan, json_out)
        console.print(f"plan written to {json_out}")
