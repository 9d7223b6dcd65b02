"""``platform plugins``: loaded plugins, their hooks, and plugins that failed to load."""

from __future__ import annotations

import click

from .. import plugins
from ..console import NONE, console, table

__all__ = ["command"]


@click.command("plugins")
def command() -> None:
    """List loaded plugins, the hooks each implements, and plugins that failed to load."""
    rows = [[name, module, ", ".join(hooks) or NONE] for name, module, hooks in plugins.plugin_rows()]
    console.print(table("Loaded plugins", ["plugin", "module", "hooks"], rows))
    for error in plugins.load_errors():
        console.print(f"[red]not loaded[/red] {error.entry_point}: {error.reason}")
