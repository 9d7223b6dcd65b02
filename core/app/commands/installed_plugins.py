"""``platform plugins``: loaded plugins, their hooks, and plugins that failed to load."""

from __future__ import annotations

import click

from ... import plugins
from ...console import NONE, console, styled, table

__all__ = ["command"]


@click.command("plugins")
def command() -> None:
    """List loaded plugins, the hooks each implements and their state: ok, disabled (a
    hook raised or answered with the wrong type), or describing a robot another plugin
    describes too (that robot is refused); then plugins that failed to load."""
    plugins.robots()  # asks every plugin once, so broken answers are found and shown
    disabled = {p.plugin: p for p in plugins.problems()}
    clashes: dict[str, list[str]] = {}
    for robot, owners in plugins.robot_clashes().items():
        for owner in owners:
            clashes.setdefault(owner, []).append(robot)
    rows = []
    for name, module, hooks in plugins.plugin_rows():
        if name in disabled:
            state = styled(f"disabled: {disabled[name].hook} {disabled[name].reason}", "red")
        elif name in clashes:
            state = styled(f"robot {', '.join(clashes[name])} refused: described by another "
                           "plugin too", "yellow")
        else:
            state = styled("ok", "green")
        rows.append([name, module, ", ".join(hooks) or NONE, state])
    console.print(table("Loaded plugins", ["plugin", "module", "hooks", "state"], rows))
    for problem in disabled.values():
        console.print(styled("disabled", "red"), str(problem))
    for error in plugins.load_errors():
        console.print(styled("not loaded", "red"), f"{error.entry_point}: {error.reason}")
