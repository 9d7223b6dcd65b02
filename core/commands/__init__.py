"""Built-in subcommands of ``platform``, one module each.

Every module here defines a click command (or group) named ``command``;
:func:`add_builtin_commands` adds them all to the top-level group, so a new command
is a new file and nothing else.
"""

from __future__ import annotations

import importlib
import pkgutil

import click

__all__ = ["add_builtin_commands"]


def add_builtin_commands(cli: click.Group) -> None:
    """Import every module of this package and add its ``command`` to ``cli``."""
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        cli.add_command(module.command)
