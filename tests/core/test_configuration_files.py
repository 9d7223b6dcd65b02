"""Configuration files: round trips for random configurations of every robot, and errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import (
    ConfigurationError,
    DockingRuleError,
    UnknownRobotError,
    check_configuration,
    dump_configuration,
    load_configuration,
    parse_configuration,
    plugins,
    save_configuration,
)
from msrr.core.io import ConfigurationFile
from msrr.core.random_configurations import random_configuration

from msrr_test_support import ROOT, installed_robots, shipped_configurations


def _random(robot: str, seed: int, size: int):
    rng = np.random.default_rng(seed)
    return random_configuration(plugins.robot(robot), plugins.docking_rules(robot), size, rng,
                                extra_edges=int(rng.integers(0, 3)),
                                free_connectors=int(rng.integers(0, 3)),
                                positions=bool(rng.integers(0, 2)))


@settings(max_examples=60, deadline=None)
@given(robot=st.sampled_from(installed_robots()), seed=st.integers(0, 2**32 - 1),
       size=st.integers(1, 14))
def test_round_trip_through_json_is_identical(robot: str, seed: int, size: int) -> None:
    config = _random(robot, seed, size)
    again = parse_configuration(json.loads(dump_configuration(config)))
    assert again == config
    assert dump_configuration(again) == dump_configuration(config)


@settings(max_examples=40, deadline=None)
@given(robot=st.sampled_from(installed_robots()), seed=st.integers(0, 2**32 - 1),
       size=st.integers(1, 14))
def test_random_configurations_are_legal(robot: str, seed: int, size: int) -> None:
    check_configuration(_random(robot, seed, size))


@pytest.mark.parametrize("path", shipped_configurations(), ids=lambda p: p.stem)
def test_shipped_configurations_validate_and_round_trip(path: Path, tmp_path: Path) -> None:
    config = load_configuration(path)
    save_configuration(config, tmp_path / "copy.json")
    assert load_configuration(tmp_path / "copy.json") == config


def test_every_robot_has_a_shipped_configuration(robot_name: str) -> None:
    robots_with_files = {load_configuration(p, check=False).robot for p in shipped_configurations()}
    assert robot_name in robots_with_files


def _mmrp(**changes) -> dict:
    data = json.loads((ROOT / "plugins/mmrp/configs/series.json").read_text())
    data.update(changes)
    return data


@pytest.mark.parametrize(
    ("data", "error", "field", "message"),
    [
        (_mmrp(robot="nosuchbot"), UnknownRobotError, None, "unknown robot 'nosuchbot'"),
        (_mmrp(schema_version=2), ConfigurationError, "schema_version", "Input should be 1"),
        (_mmrp(colour="red"), ConfigurationError, "colour", "Extra inputs"),
        ({**_mmrp(), "modules": [{"id": "1"}]}, ConfigurationError, "modules[0].kind", "Field required"),
        ({**_mmrp(), "connections": [{"source": "1", "target": "2", "ports": ["T", "T"]}]},
         DockingRuleError, "connection 1T-2T", "illegal port pair 1T-2T"),
        ({**_mmrp(), "connections": [{"source": "1", "target": "2", "ports": ["T", "B"]}]},
         DockingRuleError, "connections", "3 separate groups"),
        ({**_mmrp(), "connections": [{"source": "1", "target": "9", "ports": ["T", "B"]}]},
         ConfigurationError, "connections[0]", "'9' is not a module"),
        ({**_mmrp(), "connections": [{"source": "1", "target": "2", "ports": ["X", "B"]}]},
         DockingRuleError, "connection 1X-2B", "no port 'X'"),
    ],
)
def test_invalid_configurations_name_the_field(data, error, field, message) -> None:
    with pytest.raises(error, match=message) as info:
        check_configuration(parse_configuration(data, "f.json"))
    if field is not None:
        assert info.value.field == field
        assert "\n" not in str(info.value)


def test_mmrp_loop_is_reported_with_its_modules() -> None:
    data = _mmrp(connections=[
        {"source": "1", "target": "2", "ports": ["T", "B"]},
        {"source": "2", "target": "3", "ports": ["L", "R"]},
        {"source": "3", "target": "4", "ports": ["B", "T"]},
        {"source": "4", "target": "1", "ports": ["R", "L"]},
    ])
    with pytest.raises(DockingRuleError, match="closed loop"):
        check_configuration(parse_configuration(data))


def test_freebot_module_with_two_out_connections_is_refused() -> None:
    data = json.loads((ROOT / "plugins/freebot/configs/chain3.json").read_text())
    data["connections"].append({"source": "F1", "target": "F3", "z": [0.0, 1.0, 0.0]})
    with pytest.raises(DockingRuleError, match="module F1: has 2 out-connections"):
        check_configuration(parse_configuration(data))


def test_freesn_strut_needs_a_vector() -> None:
    data = json.loads((ROOT / "plugins/freesn/configs/triangle-leg.json").read_text())
    del data["connections"][0]["z"]
    with pytest.raises(DockingRuleError, match="connection S1: needs a unit z vector"):
        check_configuration(parse_configuration(data))


def test_load_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema_version": 1, "robot": "mmrp", "modules": [')
    with pytest.raises(ConfigurationError, match=r"bad\.json: invalid JSON at line 1"):
        load_configuration(bad)
    with pytest.raises(ConfigurationError, match=r"missing\.json: no such file"):
        load_configuration(tmp_path / "missing.json")


def test_json_schema_in_docs_is_current() -> None:
    shipped = json.loads((ROOT / "docs/configuration.schema.json").read_text())
    assert shipped == ConfigurationFile.model_json_schema(), (
        "regenerate with: platform schema configuration > docs/configuration.schema.json")
