"""``platform robots``: installed robots and what each can do."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import click

from .. import plugins
from ..console import NONE, console, styled, table
from ..errors import MsrrError
from ..generic import is_generic

__all__ = ["command"]


def _capability(lookup: Callable[[str], Mapping[str, object]], robot: str) -> object:
    try:
        items = lookup(robot)
    except MsrrError as exc:  # one broken plugin must not hide the others' rows
        return styled(f"error: {exc}", "red")
    names = [f"{name}*" if is_generic(item) else name for name, item in items.items()]
    return ", ".join(names) if names else NONE


@click.command("robots")
def command() -> None:
    """List installed robots with their joint modes, planners, drivers and scenarios."""
    specs = plugins.robots()
    rows = []
    for name, spec in specs.items():
        kinds = ", ".join(f"{k.name} ({k.symbol})" for k in spec.module_kinds)
        rows.append([name, spec.title, kinds,
                     _capability(plugins.kinematic_nodes, name),
                     _capability(plugins.planners, name),
                     _capability(plugins.drivers, name),
                     _capability(plugins.scenarios, name)])
    console.print(table("Installed robots", ["robot", "title", "module kinds", "joint modes",
                                             "planners", "drivers", "scenarios"], rows))
    for name, owners in plugins.robot_clashes().items():
        console.print(styled("refused", "red"), f"robot {name!r}: described by plugins "
                      f"{', '.join(map(repr, owners))}")
    for problem in plugins.problems():
        console.print(styled("disabled", "red"), str(problem))
    if not specs:
        console.print("No robot plugin is installed.")
    else:
        console.print("* the generic runtime every robot gets (msrr.core.generic); a robot's "
                      "own planners and drivers come first and are the default.")
