"""The ``platform`` (alias ``msrr``) command line.

Every :class:`~msrr.core.errors.MsrrError` raised by a command becomes one line on
stderr and exit status 1; no traceback reaches the user. Plugins add commands
through ``msrr_register_commands(cli)``.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.console import Console
from rich.table import Table

from . import plugins
from .configuration import Configuration
from .errors import MsrrError
from .io import check_configuration, load_configuration

__all__ = ["cli", "get_cli", "main", "console", "err_console", "table"]

# Piped output (files, CI logs, tests) gets wide tables instead of rich's 80 columns.
_WIDTH = None if sys.stdout.isatty() else 160
console = Console(highlight=False, soft_wrap=True, width=_WIDTH)
err_console = Console(stderr=True, highlight=False, soft_wrap=True, width=_WIDTH)

NONE = "[dim]none[/dim]"


class MsrrGroup(click.Group):
    """A click group that turns msrr errors into one-line messages."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except MsrrError as exc:
            raise click.ClickException(str(exc)) from None


@click.group(cls=MsrrGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="msrr-platform", prog_name="platform")
def cli() -> None:
    """msrr: locomotion and self-reconfiguration for modular robots.

    Robots are plugins; see `platform robots` for the installed ones.
    """
    for error in plugins.load_errors():
        err_console.print(f"[yellow]warning:[/yellow] {error}")


def table(title: str | None, columns: Iterable[str], rows: Iterable[Iterable[Any]]) -> Table:
    """A rich table with the house style."""
    out = Table(title=title, title_justify="left", header_style="bold")
    for column in columns:
        out.add_column(column)
    for row in rows:
        out.add_row(*(str(cell) for cell in row))
    return out


def _names(items: dict[str, Any]) -> str:
    return ", ".join(items) if items else NONE


def _capability(lookup: Callable[[str], dict[str, Any]], robot: str) -> str:
    try:
        return _names(lookup(robot))
    except MsrrError as exc:  # one broken plugin must not hide the others' rows
        return f"[red]error: {exc}[/red]"


@cli.command()
def robots() -> None:
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
    if not specs:
        console.print("No robot plugin is installed.")


@cli.command("plugins")
def list_plugins() -> None:
    """List loaded plugins, the hooks each implements, and plugins that failed to load."""
    rows = [[name, module, ", ".join(hooks) or NONE] for name, module, hooks in plugins.plugin_rows()]
    console.print(table("Loaded plugins", ["plugin", "module", "hooks"], rows))
    for error in plugins.load_errors():
        console.print(f"[red]not loaded[/red] {error.entry_point}: {error.reason}")


@cli.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def validate(files: tuple[Path, ...]) -> None:
    """Check configuration FILES against their robots' docking rules."""
    failed = 0
    for path in files:
        try:
            config = load_configuration(path)
        except MsrrError as exc:
            err_console.print(f"[red]invalid[/red] {exc}", soft_wrap=True)
            failed += 1
            continue
        console.print(f"[green]valid[/green] {path}: {config.robot}, "
                      f"{len(config.modules())} modules, {len(config.edges())} connections")
    if failed:
        raise SystemExit(1)


def _vector(v: np.ndarray | None) -> str:
    return "" if v is None else "(" + ", ".join(f"{c:+.3f}" for c in v) + ")"


@cli.command()
@click.argument("file", type=click.Path(path_type=Path))
def show(file: Path) -> None:
    """Summarise a configuration FILE: modules, connections, signature."""
    config = load_configuration(file, check=False)
    spec = plugins.robot(config.robot)
    show_configuration(config, title=f"{file}")
    console.print(f"signature: {config.signature().label(spec)}  degrees: "
                  + "; ".join(f"{k} {list(d)}" for k, d in config.signature().degrees))
    try:
        check_configuration(config)
        console.print("[green]valid[/green] for " + spec.title)
    except MsrrError as exc:
        console.print(f"[red]invalid:[/red] {exc}")
        raise SystemExit(1) from None


def show_configuration(config: Configuration, title: str = "") -> None:
    """Print the module and connection tables of ``config``."""
    head = f"{title} — {config.name or 'unnamed'} ({config.robot})"
    if config.description:
        head += f": {config.description}"
    console.print(head)
    modules = [[v, config.kind_of(v), config.degree(v), _vector(config.position(v))]
               for v in config.vertices()]
    console.print(table("Modules", ["id", "kind", "degree", "position [m]"], modules))
    edges = [[e.id, f"{e.source} → {e.target}", e.kind or "",
              "–".join(e.ports) if e.ports else "", _vector(e.z), _vector(e.x)]
             for e in config.edges()]
    console.print(table("Connections", ["id", "ends", "kind", "ports", "z", "x"], edges))


@functools.cache
def get_cli() -> click.Group:
    """The CLI with the built-in commands of :mod:`msrr.core.commands` and plugin commands."""
    from .commands import add_builtin_commands

    add_builtin_commands(cli)
    plugins.register_commands(cli)
    return cli


def main() -> None:
    """Console-script entry point of ``platform`` and ``msrr``."""
    get_cli()(prog_name="platform")
