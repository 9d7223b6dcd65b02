"""Small command-line points: ``validate --all`` prints every problem, ``plan`` takes the
robot from its files, ``library build`` takes its source folder."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from msrr.core.app.cli import get_cli

ROOT = Path(__file__).resolve().parents[2]


def run(*args: str):
    return CliRunner().invoke(get_cli(), list(args))


def test_validate_all_prints_every_problem(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({
        "schema_version": 1, "robot": "mmrp", "name": "bad",
        "modules": [{"id": m, "kind": "mmrp"} for m in "123"],
        "connections": [{"source": "1", "target": "2", "ports": ["B", "B"]},
                        {"source": "2", "target": "3", "ports": ["L", "L"]}]}))
    first = run("validate", str(bad))
    assert first.exit_code == 1 and "(and 1 more)" in first.output
    every = run("validate", "--all", str(bad))
    lines = [line for line in every.output.splitlines() if line.startswith("invalid")]
    assert every.exit_code == 1 and len(lines) == 2
    assert "illegal port pair 1B-2B" in lines[0] and "illegal port pair 2L-3L" in lines[1]
    assert all(str(bad) in line for line in lines) and "more)" not in every.output


def test_plan_takes_the_robot_from_its_files() -> None:
    configs = ROOT / "plugins" / "mmrp" / "configs"
    done = run("plan", str(configs / "cross.json"), str(configs / "probe.json"))
    assert done.exit_code == 0, done.output
    assert "3 undocks, 3 docks" in done.output  # the optimum, whatever legs the moves take
    mixed = run("plan", str(configs / "cross.json"),
                str(ROOT / "plugins" / "freebot" / "configs" / "chain6.json"))
    assert mixed.exit_code == 1 and "not 'mmrp'" in mixed.output


def test_library_build_takes_its_source_folder(tmp_path: Path) -> None:
    sources = ROOT / "plugins" / "freesn" / "library_sources" / "S6N3"
    out = tmp_path / "S6N3.json"
    done = run("library", "build", str(sources), "-o", str(out))
    assert done.exit_code == 0, done.output
    assert out.read_bytes() == (ROOT / "plugins" / "freesn" / "libraries" / "S6N3.json").read_bytes()
    empty = tmp_path / "empty"
    empty.mkdir()
    refused = run("library", "build", str(empty), "-o", str(tmp_path / "x.json"))
    assert refused.exit_code == 1 and f"{empty}: is a folder without a *.json" in refused.output
