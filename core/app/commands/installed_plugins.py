"""``platform plugins``: loaded plugins, their hooks, and plugins that failed."""

from __future__ import annotations

import contextlib

import click

from ... import plugins
from ...console import NONE, console, styled, table
from ...errors import MsrrError

__all__ = ["command"]


@click.command("plugins")
def command() -> None:
    """List loaded plugins, the hooks each implements and their state: ok, failed (a hook
    raised, or registered or answered with the wrong type: every robot it touches is
    refused), or describing a robot another plugin describes too (that robot is refused);
    then plugins that failed to load."""
    for name in plugins.robots():  # every hook of every robot asked, so failures are found
        with contextlib.suppress(MsrrError):  # each failure is listed below, by plugin
            plugins.capabilities(name)
    failed: dict[str, list[plugins.PluginFailure]] = {}
    for failure in plugins.problems():
        failed.setdefault(failure.plugin, []).append(failure)
    clashes: dict[str, list[str]] = {}
    for robot, owners in plugins.robot_clashes().items():
        for owner in owners:
            clashes.setdefault(owner, []).append(robot)
    rows = []
    for name, module, hooks in plugins.plugin_rows():
        if name in failed:
            state = styled("failed: " + "; ".join(f"{f.hook} {f.reason}" for f in failed[name]),
                           "red")
        elif name in clashes:
            state = styled(f"robot {', '.join(clashes[name])} refused: described by another "
                           "plugin too", "yellow")
        else:
            state = styled("ok", "green")
        rows.append([name, module, ", ".join(hooks) or NONE, state])
    console.print(table("Loaded plugins", ["plugin", "module", "hooks", "state"], rows))
    for failures in failed.values():
        for failure in failures:
            console.print(styled("failed", "red"), str(failure))
    for error in plugins.load_errors():
        console.print(styled("not loaded", "red"), f"{error.entry_point}: {error.reason}")
