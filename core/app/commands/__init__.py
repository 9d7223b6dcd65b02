"""Built-in subcommands of ``platform``, one module each.

Every module here defines a click command (or group) named ``command``, and
:data:`BUILTIN` names it with the one line ``platform --help`` shows for it: the
top-level group lists the commands from that table and imports a command's module only
when the command runs or shows its own help (:func:`load`), so ``platform --help``
imports none of them and ``platform run --help`` only ``run`` (a new command is a new
file and one line here; ``tests/core/test_cli_startup.py`` keeps the two in step).
"""

from __future__ import annotations

import importlib
from typing import Final

import click

__all__ = ["BUILTIN", "load"]

BUILTIN: Final[dict[str, tuple[str, str]]] = {
    "emulate": ("emulate", "Run simulated modules behind the network link, on loopback."),
    "library": ("library", "Build, show, check and retrieve from behavior libraries."),
    "match": ("match", "Find the best reference, module mapping and cost for a system."),
    "plan": ("plan", "Plan the reconfiguration from configuration file START to GOAL."),
    "plugins": ("installed_plugins", "List loaded plugins, their hooks and their state."),
    "robots": ("robots", "List installed robots and what each can do."),
    "run": ("run", "Plan and execute a reconfiguration in simulation and record it."),
    "schema": ("schema", "Print the JSON Schema of a file FORMAT (configuration or plan)."),
    "show": ("show", "Print a configuration's modules, connections and signature."),
    "snapshot": ("snapshot", "Draw a recorded run to a PNG, without a display."),
    "sweep": ("sweep", "Run a scenario over many seeds and faults: success, errors."),
    "validate": ("validate", "Check configuration files against their robots."),
}
"""Command name -> (module of this package, its line in ``platform --help``)."""


def load(name: str) -> click.Command:
    """The built-in command ``name``, importing its module."""
    return importlib.import_module(f"{__name__}.{BUILTIN[name][0]}").command
