"""The configuration files shipped with the built-in robots and the example plugin,
and the robot-specific rules they are checked against."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core import DockingRuleError, parse_configuration, plugins, save_configuration
from msrr.core.app.cli import get_cli
from msrr.core.io import check_configuration

from msrr_test_support import BUILTIN_ROBOTS, ROOT, shipped_configurations


@pytest.mark.parametrize("path", shipped_configurations(), ids=lambda p: p.stem)
def test_shipped_configurations_validate_and_round_trip(path: Path, tmp_path: Path) -> None:
    config = plugins.load_configuration(path)
    save_configuration(config, tmp_path / "copy.json")
    assert plugins.load_configuration(tmp_path / "copy.json") == config
    result = CliRunner().invoke(get_cli(), ["validate", str(path)])
    assert result.exit_code == 0 and result.output.startswith("valid"), result.output


@pytest.mark.parametrize("robot", BUILTIN_ROBOTS)
def test_every_builtin_robot_ships_a_configuration(robot: str) -> None:
    robots_with_files = {json.loads(p.read_text())["robot"] for p in shipped_configurations()}
    assert robot in robots_with_files


def _check(data: dict) -> None:
    config = parse_configuration(data)
    check_configuration(config, plugins.resolve(config.robot))


def _file(relative: str) -> dict:
    return json.loads((ROOT / "plugins" / relative).read_text())


def test_mmrp_face_pairs_and_loops() -> None:
    series = _file("mmrp/configs/series.json")
    with pytest.raises(DockingRuleError, match="illegal port pair 1T-2T"):
        _check(dict(series, connections=[{"source": "1", "target": "2", "ports": ["T", "T"]},
                                         *series["connections"][1:]]))
    with pytest.raises(DockingRuleError, match="closed loop"):
        _check(dict(series, connections=[
            {"source": "1", "target": "2", "ports": ["T", "B"]},
            {"source": "2", "target": "3", "ports": ["L", "R"]},
            {"source": "3", "target": "4", "ports": ["B", "T"]},
            {"source": "4", "target": "1", "ports": ["R", "L"]},
        ]))


def test_freebot_module_with_two_out_connections_is_refused() -> None:
    data = _file("freebot/configs/chain3.json")
    data["connections"].append({"source": "F1", "target": "F3", "z": [0.0, 1.0, 0.0]})
    with pytest.raises(DockingRuleError, match="module F1: has 2 out-connections"):
        _check(data)


def test_freesn_strut_needs_a_vector() -> None:
    data = _file("freesn/configs/triangle-leg.json")
    del data["connections"][0]["z"]
    with pytest.raises(DockingRuleError, match="connection S1: needs a unit z vector"):
        _check(data)
