"""``platform plan``: plan a reconfiguration between two configuration files.

Prints the planner's notes (for MMRP the decomposition), the module mapping and the
actions as a table in the form of the MMRP paper's Table 4 (Action | ID | Face | ID |
Face); ``--json`` writes the plan in the plan file format
(:func:`msrr.core.plan.load_plan` reads it back; ``platform schema plan`` prints its
JSON Schema).
"""

from __future__ import annotations

from pathlib import Path

import click

from .. import plugins
from ..console import SEED, console, table
from ..errors import ConfigurationError, PlanningError
from ..plan import Action, ActionType, Plan, save_plan
from ..plugins import load_configuration

__all__ = ["action_rows", "command"]

VERBS = {
    ActionType.CONNECTION: "Dock",
    ActionType.PARALLEL_CONNECTION: "Dock",
    ActionType.DISCONNECTION: "Undock",
    ActionType.PARALLEL_DISCONNECTION: "Undock",
    ActionType.MOVING: "Move",
    ActionType.FLOW: "Flow",
}


def _pose(values: list[float]) -> str:
    return "(" + ", ".join(f"{v:+.3f}" for v in values) + ")"


def action_rows(actions: list[Action]) -> list[list[str]]:
    """One ``[action, id, face, id, face]`` row per connection change or moving module."""
    rows = []
    for action in actions:
        verb = VERBS.get(action.type, action.type.value)
        if action.changes:
            rows += [[verb, c.source, c.source_port or "", c.target, c.target_port or ""]
                     for c in action.changes]
        elif action.goals:
            rows += [[verb, module, "", "to", _pose(pose)] for module, pose in action.goals.items()]
        else:
            rows.append([verb, ",".join(action.modules), "", "", ""])
    return rows


def print_plan(plan: Plan) -> None:
    """Print a plan's notes, mapping and action table."""
    for note in plan.notes:
        console.print(f"- {note}", soft_wrap=True)
    if plan.mapping:
        pairs = sorted(plan.mapping.items(), key=lambda pair: (len(pair[0]), pair[0]))
        console.print(table("Mapping (start -> goal)", ["start", "goal"], pairs))
    console.print(table(f"Actions ({plan.planner})", ["Action", "ID", "Face", "ID", "Face"],
                        action_rows(plan.actions)))
    console.print(f"{plan.undocks} undock, {plan.docks} dock, "
                  f"{sum(a.type is ActionType.MOVING for a in plan.actions)} move actions")


@click.command("plan")
@click.option("--robot", required=True, help="Robot name (see `platform robots`).")
@click.argument("start", type=click.Path(path_type=Path))
@click.argument("goal", type=click.Path(path_type=Path))
@click.option("--planner", "planner_name", default=None, help="Planner name; default the "
              "robot's first registered planner.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the planner.")
@click.option("--json", "json_out", type=click.Path(path_type=Path), default=None,
              help="Also write the plan to this file (format: `platform schema plan`).")
def command(robot: str, start: Path, goal: Path, planner_name: str | None, seed: int,
            json_out: Path | None) -> None:
    """Plan the reconfiguration from configuration file START to GOAL."""
    if json_out is not None and json_out.is_dir():
        raise ConfigurationError("is a directory, expected a file to write", source=str(json_out))
    planner = plugins.planners.get(robot, planner_name)
    configs = []
    for path in (start, goal):
        config = load_configuration(path)
        if config.robot != robot:
            raise PlanningError(f"{path}: a configuration of robot {config.robot!r}, "
                                f"not {robot!r}")
        configs.append(config)
    try:
        plan = planner.plan(configs[0], configs[1], seed=seed)
    except PlanningError as exc:  # about the pair: name both files
        raise PlanningError(f"{start} -> {goal}: {exc}") from None
    print_plan(plan)
    if json_out is not None:
        save_plan(plan, json_out)
        console.print(f"plan written to {json_out}")
