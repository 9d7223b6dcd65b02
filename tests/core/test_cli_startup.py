"""Every ``--help`` starts fast because of what it does not import (issue 16 item 5).

The time itself is a benchmark (``benchmarks/cli_startup.py``); here one fresh
interpreter asks every command for its help, and the modules it then holds are
checked: no numpy, scipy, networkx, rerun, MuJoCo, PyBullet, matplotlib or Ray, while
every installed plugin did load (its commands are part of the help); after the top-level
``platform --help`` alone, no command module and no pydantic either.
"""

from __future__ import annotations

import json
import pkgutil
import subprocess
import sys
from importlib.metadata import entry_points

from msrr.core import plugins
from msrr.core.app import commands
from msrr.core.app.commands import library as library_command
from msrr.core.app.commands import match as match_command
from msrr.core.console import COSTS
from msrr.core.library.build import DEFAULT_MERGE_THRESHOLD
from msrr.core.matching import CONFIDENCE, COST_KINDS

HEAVY = ("numpy", "scipy", "networkx", "rerun", "mujoco", "pybullet", "matplotlib", "ray")
"""Packages the ``--help`` path must not import (each costs 0.1 to 1 s to import)."""

EVERY_HELP = """
import json, sys
from click.testing import CliRunner
from msrr.core.app.cli import command_paths, get_cli

cli = get_cli()
top = CliRunner().invoke(cli, ["--help"], prog_name="platform")
assert top.exit_code == 0, top.output
after_top = sorted(sys.modules)
paths = command_paths(cli)
for path in paths:
    result = CliRunner().invoke(cli, [*path, "--help"], prog_name="platform")
    assert result.exit_code == 0, (path, result.output)
    assert result.output.startswith("Usage: platform"), (path, result.output)
print(json.dumps({"paths": [" ".join(p) for p in paths], "after_top": after_top,
                  "modules": sorted(sys.modules)}))
"""


def test_every_help_imports_no_heavy_package() -> None:
    done = subprocess.run([sys.executable, "-c", EVERY_HELP], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert {"", "run", "plan", "library build", "snapshot", "sweep"} <= set(report["paths"])
    loaded = {name.split(".")[0] for name in report["modules"]}
    assert not loaded & set(HEAVY), f"--help imported {sorted(loaded & set(HEAVY))}"
    top = set(report["after_top"])  # platform --help: no command module, no pydantic models
    assert not {m for m in top if m.startswith("msrr.core.app.commands.")}
    assert "pydantic" not in {name.split(".")[0] for name in top}
    wanted = {ep.value for ep in entry_points(group=plugins.ENTRY_POINT_GROUP)}
    assert wanted and wanted <= set(report["modules"]), "a plugin was not loaded"


def test_the_option_vocabulary_spelled_for_help_is_the_cores() -> None:
    assert COSTS == COST_KINDS
    assert match_command.CONFIDENCE == CONFIDENCE
    assert library_command.MERGE_THRESHOLD == DEFAULT_MERGE_THRESHOLD


def test_the_builtin_table_names_every_command_module() -> None:
    modules = {info.name for info in pkgutil.iter_modules(commands.__path__)}
    assert {module for module, _ in commands.BUILTIN.values()} == modules
    for name, (_, line) in commands.BUILTIN.items():
        command = commands.load(name)
        assert command.name == name and command.short_help is None  # one line, one place
        assert line.endswith(".") and len(line) <= 66, line  # whole in an 80-column --help
