"""The ``platform`` (alias ``msrr``) command line.

Every :class:`~msrr.core.errors.MsrrError` raised by a command becomes one line on
stderr and exit status 1; no traceback reaches the user. The built-in commands are
the modules of :mod:`msrr.core.commands`; plugins add theirs through the historic
hook ``msrr_register_commands(cli)``, so a plugin registered after the CLI was
built still gets its commands.

Every ``--help`` starts within 0.5 s (``benchmarks/cli_startup.py``): building the
CLI imports the command modules and loads the plugins, and neither imports numpy,
scipy, networkx, rerun or a simulator at module level; each command imports its work
in its body (``tests/core/test_cli_startup.py`` checks the import set).
"""

from __future__ import annotations

import functools

import click

from . import interrupts, plugins
from .commands import add_builtin_commands
from .console import MsrrGroup, err_console, styled

__all__ = ["cli", "command_paths", "get_cli", "main"]


@click.group(cls=MsrrGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="msrr-platform", prog_name="platform")
def cli() -> None:
    """msrr: locomotion and self-reconfiguration for modular robots.

    Robots are plugins; see `platform robots` for the installed ones.
    """
    for error in plugins.load_errors():
        err_console.print(styled("warning:", "yellow"), str(error))


@functools.cache
def get_cli() -> click.Group:
    """The CLI with the built-in commands of :mod:`msrr.core.commands` and plugin commands."""
    add_builtin_commands(cli)
    plugins.register_commands(cli)
    return cli


def command_paths(group: click.Group, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command path under ``group``, in ``--help`` order: ``()`` for the group
    itself, each command (``("run",)``), and each subcommand of a nested group
    (``("library", "build")``), plugin commands included."""
    ctx = click.Context(group)
    paths = [prefix]
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if isinstance(command, click.Group):
            paths += command_paths(command, (*prefix, name))
        elif command is not None:
            paths.append((*prefix, name))
    return paths


def main() -> None:
    """Console-script entry point of ``platform`` and ``msrr``.

    SIGINT and SIGTERM end any command with one line and exit 130 or 143
    (:mod:`msrr.core.interrupts`); ``platform run`` says what it interrupted and still
    writes its files.
    """
    interrupts.install()
    try:
        get_cli()(prog_name="platform")
    except interrupts.Interrupted as exc:
        err_console.print(f"Error: interrupted ({exc.name})", markup=False)
        raise SystemExit(exc.exit_code) from None
