"""``platform validate``: check configuration files against their robots."""

from __future__ import annotations

from pathlib import Path

import click

from ... import plugins
from ...console import console, counts, err_console, error_line, styled
from ...errors import MAX_MESSAGE, ConfigurationError, MsrrError, one_line

__all__ = ["command"]


@click.command("validate")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--all", "every", is_flag=True,
              help="Print every problem of an invalid file, one line each, not the first.")
def command(files: tuple[Path, ...], every: bool) -> None:
    """Check configuration FILES against their robots' module kinds and docking rules.

    One line per file (``valid FILE: ...`` or ``invalid FILE: field: why``); with --all,
    one line per problem; exit 1 if any file is invalid."""
    failed = 0
    for path in files:
        try:
            config = plugins.load_configuration(path)
        except MsrrError as exc:
            problems = exc.problems if every and isinstance(exc, ConfigurationError) else ()
            for field, message in problems:
                _invalid(path, error_line(ConfigurationError(message, source=str(path),
                                                             field=field)))
            if not problems:
                _invalid(path, error_line(exc))
            failed += 1
            continue
        console.print(styled("valid", "green"), f"{path}: {config.robot}, {counts(config)}")
    if failed:
        raise SystemExit(1)


def _invalid(path: Path, line: str) -> None:
    """``invalid FILE: ...`` on one line."""
    if not line.startswith(str(path)):  # every line names its file
        line = error_line(f"{path}: {line}")
    # the whole line, "invalid " included, fits what "Error: " + a message does
    line = one_line(line, MAX_MESSAGE + len("Error: ") - len("invalid "))
    err_console.print(styled("invalid", "red"), line)
