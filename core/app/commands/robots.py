"""``platform robots``: installed robots and what each can do."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import click

from ... import plugins
from ...console import NONE, console, styled, table
from ...errors import MsrrError

__all__ = ["command"]


CAPABILITIES: tuple[tuple[str, plugins.Capability], ...] = (
    ("joint modes", plugins.kinematic_nodes),
    ("controllers", plugins.controllers),
    ("recognizers", plugins.recognizers),
    ("planners", plugins.planners),
    ("drivers", plugins.drivers),
    ("scenarios", plugins.scenarios),
)
"""The capability columns, in the order of the hooks."""


def _capability(lookup: Callable[[str], Mapping[str, object]], robot: str) -> object:
    from ...generic import is_generic  # the generic runtime loads when a robot is listed

    try:
        items = lookup(robot)
    except MsrrError as exc:  # one broken plugin must not hide the others' rows
        return styled(f"error: {exc}", "red")
    names = [f"{name}*" if is_generic(item) else name for name, item in items.items()]
    return ", ".join(names) if names else NONE


def _markdown(rows: list[list[object]], header: list[str]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def _driver_options(names: list[str]) -> None:
    """One table per robot and driver: the options ``--driver-option`` takes."""
    from ...driver import declared_options

    for robot in names:
        try:
            drivers = plugins.drivers.items(robot)
        except MsrrError as exc:
            console.print(styled(f"{robot}: error: {exc}", "red"))
            continue
        for name, factory in drivers.items():
            declared = declared_options(factory)
            if declared is None:
                console.print(f"{robot} {name}: options not declared (passed on unchecked)",
                              markup=False)
                continue
            rows = [[o.name, o.takes, "" if o.default is None else f"{o.default:g}"
                     if isinstance(o.default, float) else str(o.default), o.description]
                    for o in declared]
            console.print(table(f"{robot} {name}: --driver-option", ["option", "takes",
                                                                     "default", "what"],
                                rows) if rows else f"{robot} {name}: no options")


@click.command("robots")
@click.option("--markdown", is_flag=True,
              help="Print the capability table as Markdown (docs/architecture.md holds it).")
@click.option("--options", "show_options", is_flag=True,
              help="Print the options each driver takes (--driver-option NAME=VALUE of "
                   "platform run), with their types, units and bounds.")
def command(markdown: bool, show_options: bool) -> None:
    """List installed robots with their module kinds and every capability: joint modes,
    controllers, recognizers, planners, drivers and scenarios (* marks the generic
    runtime's)."""
    specs = plugins.robots()
    if show_options:
        _driver_options(list(specs))
        return
    rows = []
    for name, spec in specs.items():
        kinds = ", ".join(f"{k.name} ({k.symbol})" for k in spec.module_kinds)
        rows.append([name, spec.title, kinds,
                     *(_capability(lookup, name) for _, lookup in CAPABILITIES)])
    header = ["robot", "title", "module kinds", *(what for what, _ in CAPABILITIES)]
    if markdown:
        click.echo(_markdown(rows, header))
        return
    for row in rows:  # one narrow table per robot reads at any terminal width
        console.print(table(f"{row[0]}: {row[1]}", ["capability", "items"],
                            [[what, cell] for what, cell in zip(header[2:], row[2:],
                                                                strict=True)]))
    for name, owners in plugins.robot_clashes().items():
        console.print(styled("refused", "red"), f"robot {name!r}: described by plugins "
                      f"{', '.join(map(repr, owners))}")
    for problem in plugins.problems():
        console.print(styled("failed", "red"), str(problem))
    if not specs:
        console.print("No robot plugin is installed.")
    else:
        console.print("* the generic runtime every robot gets (msrr.core.generic); a robot's "
                      "own capabilities come first and are the default.")
