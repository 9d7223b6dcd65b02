"""The console-script entry point of ``platform`` and ``msrr``.

It imports nothing but the standard library before it makes SIGINT and SIGTERM end
the process with one line (:mod:`msrr.core.interrupts`), so a Ctrl-C while the
command line is still importing its dependencies (about a second) is no traceback
either. ``msrr.core`` loads its exports lazily, which keeps this import cheap.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable

from .. import interrupts

__all__ = ["main"]


def _load_cli() -> Callable[[], None]:
    from .cli import main as cli_main  # the heavy imports: click, rich, numpy, the plugins

    return cli_main


def main() -> None:
    """Install the signal handlers, then import and run the command line."""
    interrupts.install()
    # rerun's own log lines (a failed flush on a full disk) would be a second line after
    # the one error the command prints; its failures reach the recorder as exceptions
    os.environ.setdefault("RUST_LOG", "off")
    try:
        cli_main = _load_cli()
    except interrupts.Interrupted as exc:
        sys.stderr.write(f"Error: interrupted during start-up ({exc.name})\n")
        raise SystemExit(exc.exit_code) from None
    cli_main()
