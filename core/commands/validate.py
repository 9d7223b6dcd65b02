"""``platform validate``: check configuration files against their robots."""

from __future__ import annotations

from pathlib import Path

import click

from .. import plugins
from ..console import console, err_console
from ..errors import MsrrError

__all__ = ["command"]


@click.command("validate")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def command(files: tuple[Path, ...]) -> None:
    """Check configuration FILES against their robots' module kinds and docking rules."""
    failed = 0
    for path in files:
        try:
            config = plugins.load_configuration(path)
        except MsrrError as exc:
            err_console.print(f"[red]invalid[/red] {exc}", soft_wrap=True)
            failed += 1
            continue
        console.print(f"[green]valid[/green] {path}: {config.robot}, "
                      f"{len(config.modules())} modules, {len(config.edges())} connections")
    if failed:
        raise SystemExit(1)
