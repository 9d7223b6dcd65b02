"""`platform robots`, `validate`, `show`, `plugins`, `schema`: output and bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core.cli import get_cli

from msrr_test_support import ROOT, shipped_configurations

MMRP = ROOT / "plugins/mmrp/configs"


def run(*args: str):
    return CliRunner().invoke(get_cli(), list(args), catch_exceptions=False)


def test_robots_lists_every_builtin_robot() -> None:
    result = run("robots")
    assert result.exit_code == 0
    for name in ("freesn", "mmrp", "freebot", "snailbot"):
        assert name in result.output


@pytest.mark.parametrize("path", shipped_configurations(), ids=lambda p: p.stem)
def test_validate_accepts_shipped_files(path: Path) -> None:
    result = run("validate", str(path))
    assert result.exit_code == 0, result.output
    assert "valid" in result.output


def _write(tmp_path: Path, name: str, data) -> Path:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def _bad_files(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    series = json.loads((MMRP / "series.json").read_text())
    chain = json.loads((ROOT / "plugins/freebot/configs/chain3.json").read_text())
    chain["connections"].append({"source": "F1", "target": "F3", "z": [0.0, 1.0, 0.0]})
    tt = dict(series, connections=[{"source": "1", "target": "2", "ports": ["T", "T"]},
                                   *series["connections"][1:]])
    return {
        "missing": (tmp_path / "missing.json", "missing.json: no such file"),
        "truncated": (_write(tmp_path, "truncated.json", (MMRP / "cross.json").read_text()[:200]),
                      "truncated.json: invalid JSON"),
        "unknown robot": (_write(tmp_path, "tank.json", dict(series, robot="tank")),
                          "unknown robot 'tank'"),
        "T-T faces": (_write(tmp_path, "tt.json", tt), "tt.json: connection 1T-2T: illegal port pair"),
        "two out-connections": (_write(tmp_path, "two.json", chain),
                                "two.json: module F1: has 2 out-connections"),
    }


@pytest.mark.parametrize("case", ["missing", "truncated", "unknown robot", "T-T faces",
                                  "two out-connections"])
def test_validate_rejects_bad_files_with_one_line(tmp_path: Path, case: str) -> None:
    path, message = _bad_files(tmp_path)[case]
    result = CliRunner().invoke(get_cli(), ["validate", str(path)])
    assert result.exit_code == 1
    assert message in result.output
    assert "Traceback" not in result.output
    assert len([line for line in result.output.splitlines() if line.strip()]) == 1


def test_console_script_prints_no_traceback(tmp_path: Path) -> None:
    exe = Path(sys.executable).parent / "platform"
    assert exe.exists(), "the platform console script is not installed"
    bad = _write(tmp_path, "bad.json", "{")
    done = subprocess.run([exe, "show", str(bad)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [f"Error: {bad}: invalid JSON at line 1 column 2: "
                                                "Expecting property name enclosed in double quotes"]
    assert "Traceback" not in done.stdout + done.stderr


def test_show_prints_modules_connections_and_signature() -> None:
    result = run("show", str(MMRP / "cross.json"))
    assert result.exit_code == 0
    assert "signature: M9" in result.output
    assert "1 → 2" in result.output and "T–B" in result.output
    assert "valid" in result.output


def test_plugins_lists_hooks() -> None:
    result = run("plugins")
    assert result.exit_code == 0
    assert "msrr_robot" in result.output and "mmrp" in result.output


def test_schema_prints_json() -> None:
    result = run("schema", "configuration")
    assert json.loads(result.output)["title"] == "ConfigurationFile"


def test_every_command_has_help() -> None:
    cli = get_cli()
    for name in cli.commands:
        result = run(name, "--help")
        assert result.exit_code == 0 and "Usage:" in result.output, name
