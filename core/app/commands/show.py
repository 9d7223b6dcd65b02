"""``platform show``: a configuration file as tables, its signature and validity."""

from __future__ import annotations

from pathlib import Path

import click

from ... import plugins
from ...console import console, plural, show_configuration, styled

__all__ = ["command"]


@click.command("show")
@click.argument("file", type=click.Path(path_type=Path))
def command(file: Path) -> None:
    """Summarise a valid configuration FILE: modules, connections, signature.

    An invalid file prints nothing but one error line naming the file and field (use
    ``platform validate`` for many files); tables longer than 200 rows are cut with a
    count of the rows left out."""
    config = plugins.load_configuration(file)
    robot = plugins.resolve(config.robot)
    show_configuration(config, title=f"{file}")
    signature = config.signature()
    degrees = "; ".join(f"{k} {list(d)}" for k, d in signature.degrees)
    if len(degrees) > 300:
        degrees = degrees[:300] + f" … ({plural(len(config), 'vertex', 'vertices')})"
    console.print(f"signature: {signature.label(robot.spec)}  degrees: {degrees}")
    console.print(styled("valid", "green"), f"for {robot.spec.title}")
