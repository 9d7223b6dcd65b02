"""``platform validate``: check configuration files against their robots."""

from __future__ import annotations

from pathlib import Path

import click

from ... import plugins
from ...console import console, counts, err_console, error_line, styled
from ...errors import MAX_MESSAGE, MsrrError, one_line

__all__ = ["command"]


@click.command("validate")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def command(files: tuple[Path, ...]) -> None:
    """Check configuration FILES against their robots' module kinds and docking rules.

    One line per file (``valid FILE: ...`` or ``invalid FILE: field: why``); exit 1 if
    any file is invalid."""
    failed = 0
    for path in files:
        try:
            config = plugins.load_configuration(path)
        except MsrrError as exc:
            line = error_line(exc)
            if not line.startswith(str(path)):  # every line names its file
                line = error_line(f"{path}: {line}")
            # the whole line, "invalid " included, fits what "Error: " + a message does
            line = one_line(line, MAX_MESSAGE + len("Error: ") - len("invalid "))
            err_console.print(styled("invalid", "red"), line)
            failed += 1
            continue
        console.print(styled("valid", "green"), f"{path}: {config.robot}, {counts(config)}")
    if failed:
        raise SystemExit(1)
