"""Presentation helpers of the command line: consoles, tables, one-line errors.

Shared by :mod:`msrr.core.app.cli` and every module of :mod:`msrr.core.app.commands`; it
imports neither, so the command modules and the top-level group never import each
other.

Everything is printed literally: both consoles have rich markup switched off, so a
module named ``"[/red]"``, a path with ``[`` or a vector ``[nan, 0.0, 1.0]`` prints as
written and never breaks or vanishes. Colour is asked for explicitly with
:func:`styled` (a :class:`rich.text.Text`), never with ``[red]`` in a string. Tables
show at most :data:`MAX_ROWS` rows and say how many they left out.
"""

from __future__ import annotations

import importlib
import math
import os
import sys
from collections.abc import Callable, Iterable
from itertools import islice
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, TypeVar

import click
from rich.console import Console
from rich.table import Table
from rich.text import Text

from .errors import MsrrError, one_line

if TYPE_CHECKING:  # this module is on every command's --help path: no numpy, no graphs
    import numpy as np

    from .configuration import Configuration

_F = TypeVar("_F", bound=Callable[..., Any])

__all__ = ["COSTS", "MAX_ROWS", "NONE", "SEED", "FiniteFloat", "MsrrGroup", "check_display",
           "console", "counts", "drop_empty_columns", "err_console", "error_line", "exit_unless_installed", "plural",
           "printable", "require", "run_selection_options", "show_configuration", "styled",
           "table", "vector_text"]


def printable(text: str) -> str:
    """``text`` with unprintable characters (lone surrogates from undecodable file
    names, control characters) escaped, so writing it never fails."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in text)


class _LiteralConsole(Console):
    """A console that prints strings literally and safely (no markup, no emoji codes,
    unprintable characters escaped)."""

    def print(self, *objects: Any, **kwargs: Any) -> None:  # noqa: A003 - rich's name
        kwargs.setdefault("markup", False)
        super().print(*(printable(o) if isinstance(o, str) else o for o in objects), **kwargs)


# Piped output (files, CI logs, tests) gets wide tables instead of rich's 80 columns.
_WIDTH = None if sys.stdout.isatty() else 160
console = _LiteralConsole(highlight=False, soft_wrap=True, width=_WIDTH, markup=False,
                          emoji=False)
err_console = _LiteralConsole(stderr=True, highlight=False, soft_wrap=True, width=_WIDTH,
                              markup=False, emoji=False)

MAX_ROWS: Final = 200
"""Most rows a table prints; the rest are counted in a last row."""


def plural(count: int, noun: str, many: str | None = None) -> str:
    """``count`` with ``noun`` in the right number: ``plural(1, "connection")`` is
    ``"1 connection"``, ``plural(3, "connection")`` ``"3 connections"``; ``many`` is the
    plural of an irregular noun (``plural(2, "body", "bodies")``)."""
    return f"{count} {noun if count == 1 else many or noun + 's'}"


def counts(config: Configuration) -> str:
    """``"7 modules, 4 connections"``: every physical module (vertex modules and modules
    that are connections, FreeSN's struts; free ends are none) and every connection.
    ``validate`` and ``show`` both say it this way."""
    return f"{plural(len(config.modules()), 'module')}, {plural(len(config.edges()), 'connection')}"


def require(module: str, extra: str, needed_by: str) -> None:
    """Check that the optional dependency ``module`` (of the install extra ``extra``) is
    installed before ``needed_by`` (``"platform snapshot"``, ``"--plot"``) starts work.

    Raises:
        MsrrError: one line, ``"platform snapshot needs matplotlib: pip install
            'msrr-platform[plot]'"``, when it is not.
    """
    try:
        importlib.import_module(module)  # the command is about to use it anyway
    except ImportError:
        raise MsrrError(f"{needed_by} needs {module}: pip install 'msrr-platform[{extra}]'"
                        ) from None


def check_display(option: str) -> None:
    """Check that a window can open (``DISPLAY`` or ``WAYLAND_DISPLAY`` on Linux) before
    ``option`` asks for one.

    Raises:
        MsrrError: one line naming ``option`` and what to do instead.
    """
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise MsrrError(f"{option} needs a display, and DISPLAY is not set: run without "
                        f"{option} and watch the recording (rerun run.rrd), or use xvfb-run")


def exit_unless_installed(module: str, extra: str, needed_by: str) -> None:
    """:func:`require` for scripts (the benchmarks' ``--plot``): its one line on stderr and
    exit status 1, no traceback, before any work."""
    try:
        require(module, extra, needed_by)
    except MsrrError as exc:
        raise SystemExit(f"Error: {exc}") from None


def styled(text: str, style: str) -> Text:
    """``text`` printed literally in ``style`` (``"green"``, ``"bold red"``)."""
    return Text(text, style=style)


NONE = styled("none", "dim")


def error_line(exc: BaseException) -> str:
    """The one line (at most :data:`~msrr.core.errors.MAX_MESSAGE` characters) an error
    is shown as."""
    return one_line(str(exc))


class MsrrGroup(click.Group):
    """A click group that turns :class:`~msrr.core.errors.MsrrError` into one line on
    stderr and exit status 1, never a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except MsrrError as exc:
            raise click.ClickException(error_line(exc)) from None


class FiniteFloat(click.ParamType):
    """A click option type: a finite number within ``[low, high]`` (either bound
    optional; ``open_low`` excludes ``low``). ``nan``, ``inf`` and out-of-range values
    are usage errors (exit 2, one line) before any work starts."""

    name = "number"

    def __init__(self, low: float | None = None, high: float | None = None, *,
                 open_low: bool = False):
        self.low, self.high, self.open_low = low, high, open_low

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> float:
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        low_ok = self.low is None or (number > self.low if self.open_low else number >= self.low)
        if not low_ok or (self.high is not None and number > self.high):
            self.fail(f"{value!r} is not in {self._range()}", param, ctx)
        return number

    def _range(self) -> str:
        low = "-inf" if self.low is None else f"{self.low:g}"
        high = "inf" if self.high is None else f"{self.high:g}"
        return f"{'(' if self.open_low or self.low is None else '['}{low}, {high}]"


SEED = click.IntRange(0, 2**32 - 1)
"""Option type of every ``--seed``: numpy's seed range."""

COSTS = ("ik", "distance")
"""Choices of every ``--cost`` (motion cost of matching and library builds): the values of
:data:`msrr.core.matching.cost.COST_KINDS`, spelled here so a command's ``--help`` does not
import the matching code (tests/core/test_cli_startup.py checks that they are equal)."""


def _cell(value: Any) -> Text:
    return value if isinstance(value, Text) else Text(printable(str(value)))


def table(title: str | None, columns: Iterable[str], rows: Iterable[Iterable[Any]],
          max_rows: int = MAX_ROWS) -> Table:
    """A rich table with the house style; cells are printed literally (a
    :class:`~rich.text.Text` keeps its style); beyond ``max_rows`` rows, one last row
    says how many were left out."""
    out = Table(title=None if title is None else _cell(title), title_justify="left",
                header_style="bold")
    for column in columns:
        out.add_column(_cell(column))
    iterator = iter(rows)
    for row in islice(iterator, max_rows):
        out.add_row(*(_cell(cell) for cell in row))
    left = sum(1 for _ in iterator)
    if left:
        out.add_row(styled(f"… {left} more rows not shown", "dim"))
    return out


def vector_text(v: np.ndarray | None) -> str:
    """``(+0.100, -0.200, +0.000)``, or empty for ``None``."""
    return "" if v is None else "(" + ", ".join(f"{c:+.3f}" for c in v) + ")"


def drop_empty_columns(header: list[str], rows: list[list[Any]], optional: set[str]
            ) -> tuple[list[str], list[list[Any]]]:
    """``header`` and ``rows`` without the ``optional`` columns that are ``""`` in every row
    (a table shows a column only where it has something to say)."""
    keep = [i for i, name in enumerate(header)
            if name not in optional or any(row[i] != "" for row in rows)]
    return [header[i] for i in keep], [[row[i] for i in keep] for row in rows]


def show_configuration(config: Configuration, title: str = "") -> None:
    """Print ``config``'s counts (:func:`counts`), its vertex and connection tables;
    the position, kind, ports, z and x columns only where some row has a value."""
    head = f"{title} — {config.name or 'unnamed'} ({config.robot}): {counts(config)}"
    if config.description:
        head += f"\n{config.description}"
    console.print(head)
    vertices = config.vertices()
    all_modules = len(vertices) == len(config.modules())  # no free end, no module as connection
    header, rows = drop_empty_columns(["id", "kind", "degree", "position [m]"],
                           [[v, config.kind_of(v), config.degree(v), vector_text(config.position(v))]
                            for v in vertices], {"position [m]"})
    console.print(table(f"{'Modules' if all_modules else 'Vertices'} ({len(vertices)})",
                        header, rows))
    edges = config.edges()
    header, rows = drop_empty_columns(["id", "ends", "kind", "ports", "z", "x"],
                           [[e.id, f"{e.source} → {e.target}", e.kind or "",
                             "–".join(e.ports) if e.ports else "", vector_text(e.z),
                             vector_text(e.x)] for e in edges], {"kind", "ports", "z", "x"})
    console.print(table(f"Connections ({len(edges)})", header, rows))


def run_selection_options(command: _F) -> _F:
    """The options that say what to run, shared by ``platform run`` and ``platform sweep``:
    ``--robot`` with ``--scenario``, or ``--from``/``--to`` files."""
    for option in reversed((
            click.option("--robot", required=True, help="Robot name (see `platform robots`)."),
            click.option("--scenario", default=None,
                         help="Scenario name; default: the robot's default."),
            click.option("--from", "start", type=click.Path(path_type=Path), default=None,
                         help="Start configuration file (with --to, instead of a scenario)."),
            click.option("--to", "goal", type=click.Path(path_type=Path), default=None,
                         help="Goal configuration file."))):
        command = option(command)
    return command
