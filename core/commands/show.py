"""``platform show``: a configuration file as tables, its signature and validity."""

from __future__ import annotations

from pathlib import Path

import click

from .. import io, plugins
from ..console import console, show_configuration
from ..errors import MsrrError

__all__ = ["command"]


@click.command("show")
@click.argument("file", type=click.Path(path_type=Path))
def command(file: Path) -> None:
    """Summarise a configuration FILE: modules, connections, signature, validity."""
    config = io.load_configuration(file)
    robot = plugins.resolve(config.robot)
    show_configuration(config, title=f"{file}")
    signature = config.signature()
    console.print(f"signature: {signature.label(robot.spec)}  degrees: "
                  + "; ".join(f"{k} {list(d)}" for k, d in signature.degrees))
    try:
        io.check_configuration(config, robot)
        console.print("[green]valid[/green] for " + robot.spec.title)
    except MsrrError as exc:
        console.print(f"[red]invalid:[/red] {exc}")
        raise SystemExit(1) from None
