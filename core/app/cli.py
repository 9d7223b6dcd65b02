"""The ``platform`` (alias ``msrr``) command line.

Every :class:`~msrr.core.errors.MsrrError` raised by a command becomes one line on
stderr and exit status 1; no traceback reaches the user. The built-in commands are
the modules of :mod:`msrr.core.app.commands`; plugins add theirs through the historic
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

from .. import interrupts, plugins
from ..console import MsrrGroup, err_console, styled
from . import commands

__all__ = ["TopGroup", "cli", "command_paths", "get_cli", "main"]


class TopGroup(MsrrGroup):
    """The ``platform`` group: the built-in commands of :data:`msrr.core.app.commands.BUILTIN`
    load on first use, plugin commands are added by their plugins; ``--help`` lists both
    without importing a built-in command's module."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*commands.BUILTIN, *self.commands})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in commands.BUILTIN:
            self.add_command(commands.load(cmd_name), cmd_name)
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(name) for name in names)
        rows = []
        for name in names:
            command = self.commands.get(name)
            if command is None:  # a built-in not loaded: its line from the table
                rows.append((name, commands.BUILTIN[name][1]))
            elif not command.hidden:
                rows.append((name, command.get_short_help_str(limit)))
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=TopGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="msrr-platform", prog_name="platform")
def cli() -> None:
    """msrr: locomotion and self-reconfiguration for modular robots.

    Robots are plugins; see `platform robots` for the installed ones.
    """
    for error in plugins.load_errors():
        err_console.print(styled("warning:", "yellow"), str(error))


@functools.cache
def get_cli() -> click.Group:
    """The CLI: the built-in commands of :mod:`msrr.core.app.commands` (loaded on first use)
    and the commands plugins add."""
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
