"""The ``platform`` (alias ``msrr``) command line.

Every :class:`~msrr.core.errors.MsrrError` raised by a command becomes one line on
stderr and exit status 1; no traceback reaches the user. The built-in commands are
the modules of :mod:`msrr.core.commands`; plugins add theirs through the historic
hook ``msrr_register_commands(cli)``, so a plugin registered after the CLI was
built still gets its commands.
"""

from __future__ import annotations

import functools

import click

from . import interrupts, plugins
from .commands import add_builtin_commands
from .console import MsrrGroup, err_console, styled

__all__ = ["cli", "get_cli", "main"]


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
