"""Presentation helpers of the command line: consoles, tables, one-line errors.

Shared by :mod:`msrr.core.cli` and every module of :mod:`msrr.core.commands`; it
imports neither, so the command modules and the top-level group never import each
other.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

import click
import numpy as np
from rich.console import Console
from rich.table import Table

from .configuration import Configuration
from .errors import MsrrError

__all__ = ["NONE", "MsrrGroup", "console", "err_console", "show_configuration", "table",
           "vector_text"]

# Piped output (files, CI logs, tests) gets wide tables instead of rich's 80 columns.
_WIDTH = None if sys.stdout.isatty() else 160
console = Console(highlight=False, soft_wrap=True, width=_WIDTH)
err_console = Console(stderr=True, highlight=False, soft_wrap=True, width=_WIDTH)

NONE = "[dim]none[/dim]"


class MsrrGroup(click.Group):
    """A click group that turns :class:`~msrr.core.errors.MsrrError` into one line on
    stderr and exit status 1, never a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except MsrrError as exc:
            raise click.ClickException(str(exc)) from None


def table(title: str | None, columns: Iterable[str], rows: Iterable[Iterable[Any]]) -> Table:
    """A rich table with the house style."""
    out = Table(title=title, title_justify="left", header_style="bold")
    for column in columns:
        out.add_column(column)
    for row in rows:
        out.add_row(*(str(cell) for cell in row))
    return out


def vector_text(v: np.ndarray | None) -> str:
    """``(+0.100, -0.200, +0.000)``, or empty for ``None``."""
    return "" if v is None else "(" + ", ".join(f"{c:+.3f}" for c in v) + ")"


def show_configuration(config: Configuration, title: str = "") -> None:
    """Print the module and connection tables of ``config``."""
    head = f"{title} — {config.name or 'unnamed'} ({config.robot})"
    if config.description:
        head += f": {config.description}"
    console.print(head)
    modules = [[v, config.kind_of(v), config.degree(v), vector_text(config.position(v))]
               for v in config.vertices()]
    console.print(table("Modules", ["id", "kind", "degree", "position [m]"], modules))
    edges = [[e.id, f"{e.source} → {e.target}", e.kind or "",
              "–".join(e.ports) if e.ports else "", vector_text(e.z), vector_text(e.x)]
             for e in config.edges()]
    console.print(table("Connections", ["id", "ends", "kind", "ports", "z", "x"], edges))
