"""`platform robots`, `validate`, `show`, `plugins`, `schema`, `plan`: output and bad input.

In-process with click's ``CliRunner`` on the tiny robot; one test runs the installed
console script, because what it prints on an error is the point.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from tiny_robot import chain, installed

from msrr.core import save_configuration
from msrr.core.app.cli import get_cli


def run(*args: str):
    return CliRunner().invoke(get_cli(), list(args))


@pytest.fixture
def tiny(tmp_path: Path):
    with installed(tmp_path) as plugin:
        yield plugin


def _write(tmp_path: Path, name: str, data) -> Path:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_robots_lists_every_robot_with_its_capabilities(tiny) -> None:
    result = run("robots")
    assert result.exit_code == 0
    lines = result.output.splitlines()
    start = lines.index("tiny: Tiny test robot")
    rows = {}
    for line in lines[start + 1:]:
        if line.startswith("└"):
            break
        if line.startswith("│"):
            what, items = (c.strip() for c in line.strip("│").split("│"))
            rows[what] = items
    rows.pop("capability", None)
    assert rows == {"module kinds": "cube (C)", "joint modes": "tiny_hinge",
                    "controllers": "goal, latches*", "recognizers": "links, latches*",
                    "planners": "line, generic*", "drivers": "points, kinematic*, link*",
                    "scenarios": "swap"}


def test_validate_accepts_a_good_file(tiny, tmp_path: Path) -> None:
    result = run("validate", str(tmp_path / "start.json"))
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"valid {tmp_path / 'start.json'}: tiny, 3 modules, " \
                                    "1 connection"


def _bad_files(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    good = json.loads((tmp_path / "start.json").read_text())
    bb = dict(good, connections=[{"source": "a", "target": "b", "ports": ["B", "B"]}])
    twice = dict(good, connections=[{"source": "a", "target": "b", "ports": ["T", "B"]},
                                    {"source": "a", "target": "c", "ports": ["T", "B"]}])
    return {
        "missing": (tmp_path / "missing.json", "missing.json: no such file"),
        "truncated": (_write(tmp_path, "truncated.json", json.dumps(good)[:40]),
                      "truncated.json: invalid JSON"),
        "unknown robot": (_write(tmp_path, "tank.json", dict(good, robot="tank")),
                          "unknown robot 'tank'"),
        "B-B ports": (_write(tmp_path, "bb.json", bb),
                      "bb.json: connection aB-bB: illegal port pair aB-bB"),
        "port used twice": (_write(tmp_path, "twice.json", twice),
                            "twice.json: connection aT-cB: port T of module a is already used"),
    }


@pytest.mark.parametrize("case", ["missing", "truncated", "unknown robot", "B-B ports",
                                  "port used twice"])
def test_validate_rejects_bad_files_with_one_line(tiny, tmp_path: Path, case: str) -> None:
    path, message = _bad_files(tmp_path)[case]
    result = run("validate", str(path))
    assert result.exit_code == 1
    assert message in result.output
    assert "Traceback" not in result.output
    assert len([line for line in result.output.splitlines() if line.strip()]) == 1


HEAVY = {"rerun", "pybullet", "mujoco", "matplotlib"}


def test_console_script_prints_no_traceback(tmp_path: Path) -> None:
    """The installed script turns an error into one line, and starts without the heavy
    simulation and plotting packages (imported only by the commands that use them)."""
    exe = Path(sys.executable).parent / "platform"
    assert exe.exists(), "the platform console script is not installed"
    bad = _write(tmp_path, "bad.json", "{")
    env = {**os.environ, "PYTHONPROFILEIMPORTTIME": "1"}
    done = subprocess.run([exe, "show", str(bad)], capture_output=True, text=True, timeout=120,
                          env=env)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    imported = {line.rsplit("|", 1)[-1].strip().split(".")[0] for line in lines
                if line.startswith("import time:")}
    assert "msrr" in imported and not imported & HEAVY, imported & HEAVY
    assert [line for line in lines if not line.startswith("import time:")] == [
        f"Error: {bad}: invalid JSON at line 1 column 2: "
        "Expecting property name enclosed in double quotes"]
    assert "Traceback" not in done.stdout + done.stderr


def test_show_prints_modules_connections_and_signature(tiny, tmp_path: Path) -> None:
    result = run("show", str(tmp_path / "start.json"))
    assert result.exit_code == 0, result.output
    assert "signature: C3" in result.output
    assert "a → b" in result.output and "T–B" in result.output
    assert "valid for Tiny test robot" in result.output


def test_show_of_an_invalid_file_says_why_in_one_line(tiny, tmp_path: Path) -> None:
    config = chain(("a", "b"), ("a", "c"))  # port T of a used twice
    save_configuration(config, tmp_path / "twice.json")
    result = run("show", str(tmp_path / "twice.json"))
    assert result.exit_code == 1
    assert result.output == (f"Error: {tmp_path / 'twice.json'}: connection aT-cB: port T of "
                             "module a is already used by connection aT-bB\n")


def test_plugins_lists_hooks(tiny) -> None:
    result = run("plugins")
    assert result.exit_code == 0
    start = result.output.index("tiny-robot")
    rows = result.output[start:start + 600]
    assert "msrr_planners" in rows and "msrr_robot" in rows


def test_schema_prints_json() -> None:
    assert json.loads(run("schema", "configuration").output)["title"] == "ConfigurationFile"
    assert json.loads(run("schema", "plan").output)["title"] == "PlanFile"


def test_plan_prints_the_actions_and_writes_the_plan(tiny, tmp_path: Path) -> None:
    out = tmp_path / "plan.json"
    result = run("plan", "--robot", "tiny", str(tmp_path / "start.json"),
                 str(tmp_path / "goal.json"), "--json", str(out))
    assert result.exit_code == 0, result.output
    assert "Undock │ a" in result.output and "Dock   │ b" in result.output
    assert "3 actions: 1 undock, 1 dock, 1 move" in result.output
    assert json.loads(out.read_text())["planner"] == "line"


def _commands() -> dict[str, click.Command]:
    """Every top-level command by name, the built-ins loaded."""
    cli, ctx = get_cli(), click.Context(get_cli())
    return {name: cli.get_command(ctx, name) for name in cli.list_commands(ctx)}


def test_every_command_has_help() -> None:
    for name in _commands():
        result = run(name, "--help")
        assert result.exit_code == 0 and "Usage:" in result.output, name


def _options(command) -> set[str]:
    return {opt for param in command.params for opt in getattr(param, "opts", [])}


def test_help_and_docs_name_only_options_that_exist() -> None:
    """Every ``platform <command> ... --option`` written in --help texts, docs and the
    README is an option of that command."""
    cli, commands = get_cli(), _commands()
    root = Path(__file__).resolve().parents[2]
    texts = [p.read_text() for p in [root / "README.md", *sorted((root / "docs").glob("*.md"))]]
    texts += [CliRunner().invoke(cli, [name, "--help"]).output for name in commands]
    texts += [(command.help or "") + " ".join(getattr(p, "help", "") or "" for p in command.params)
              for command in commands.values()]
    wrong = []
    for text in texts:
        for name, rest in _command_lines(text):
            command = commands[name]
            while isinstance(command, click.Group) and rest and rest[0] in command.commands:
                command, rest = command.commands[rest[0]], rest[1:]
            known = _options(command) | {"--help", "-h"}
            wrong += [f"platform {name} {flag}" for flag in rest
                      if flag.startswith("--") and flag not in known]
    assert not wrong, wrong


def _command_lines(text: str) -> list[tuple[str, list[str]]]:
    found = []
    commands = set(_commands())
    for part in text.replace("`", "\n").splitlines():
        words = part.replace("[", " ").replace("]", " ").replace("=", " ").split()
        for i, word in enumerate(words[:-1]):
            if word in ("platform", "msrr") and words[i + 1] in commands:
                found.append((words[i + 1], [w.rstrip(".,;:)") for w in words[i + 2:]]))
    return found

