"""Configuration files: round trips for random configurations of every installed robot, and
errors (on the tiny robot of the tests)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tiny_robot import ROBOT, chain, installed

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
from msrr.core.errors import OutputError
from msrr.core.files import atomic_write_bytes, atomic_write_text
from msrr.core.io import ConfigurationFile
from msrr.core.random_configurations import random_configuration
from msrr.core.robot import tree_violations

from msrr_test_support import ROOT, installed_robots


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
    check_configuration(_random(robot, seed, size), plugins.resolve(robot))


def _tiny(**changes) -> dict:
    data = json.loads(dump_configuration(chain(("a", "b"), ("b", "c"), name="abc")))
    data.update(changes)
    return data


@pytest.mark.parametrize(
    ("data", "error", "field", "message"),
    [
        (_tiny(schema_version=2), ConfigurationError, "schema_version", "Input should be 1"),
        (_tiny(colour="red"), ConfigurationError, "colour", "Extra inputs"),
        ({**_tiny(), "modules": [{"id": "a"}]}, ConfigurationError, "modules[0].kind",
         "Field required"),
        ({**_tiny(), "connections": [{"source": "a", "target": "b", "ports": ["B", "B"]}]},
         DockingRuleError, "connection aB-bB", "illegal port pair aB-bB"),
        ({**_tiny(), "connections": [{"source": "a", "target": "z", "ports": ["T", "B"]}]},
         ConfigurationError, "connections[0]", "'z' is not a module"),
        ({**_tiny(), "connections": [{"source": "a", "target": "b", "ports": ["X", "B"]}]},
         DockingRuleError, "connection aX-bB", "no port 'X'"),
        ({**_tiny(), "modules": [{"id": "a", "kind": "sphere"}, {"id": "b", "kind": "cube"},
                                 {"id": "c", "kind": "cube"}]}, DockingRuleError, "module a",
         "unknown module kind 'sphere'"),
        ({**_tiny(), "connections": [{"source": "a", "target": "b", "z": [0.0, 0.0, 2.0]}]},
         ConfigurationError, "connections[0].z", "must be a unit vector"),
        (_tiny(robot="mmrp"), DockingRuleError, "robot", "is 'mmrp', expected 'tiny'"),
    ],
)
def test_invalid_configurations_name_the_field(data, error, field, message) -> None:
    with pytest.raises(error, match=message) as info:
        check_configuration(parse_configuration(data, "f.json"), ROBOT)
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_the_installed_robot_is_resolved_at_the_top_layer(tmp_path: Path) -> None:
    path = tmp_path / "abc.json"
    save_configuration(chain(("a", "b"), ("b", "c")), path)
    with pytest.raises(UnknownRobotError, match="unknown robot 'tiny'"):
        plugins.load_configuration(path)
    with installed():
        assert plugins.load_configuration(path) == load_configuration(path, ROBOT)
        path.write_text(path.read_text().replace('"B"', '"T"', 1))
        with pytest.raises(DockingRuleError, match=r"abc\.json: connection aT-bB: illegal port "
                                                       r"pair aT-bT"):
            plugins.load_configuration(path)
    assert load_configuration(path).robot == "tiny"  # parsing alone needs no robot


def test_tree_rules_name_the_groups_and_the_loop() -> None:
    apart = chain(("a", "b"))
    assert [str(v) for v in tree_violations(apart)] == [
        "connections: the modules form 2 separate groups (a b; c), expected one tree"]
    loop = chain(("a", "b"), ("b", "c"))
    loop.connect("c", "a", ports=("T", "B"))
    assert [v.message for v in tree_violations(loop)] == [
        "closed loop a - b - c: the topology must be a tree (make one loop edge a virtual "
        "connection)"]
    assert tree_violations(chain(("a", "b"), ("b", "c"))) == []


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


def test_atomic_write_leaves_the_old_file_or_the_new_one(tmp_path: Path, monkeypatch) -> None:
    target = tmp_path / "sub" / "c.json"
    assert atomic_write_text(target, "old\n") == target and target.read_text() == "old\n"
    mask = os.umask(0)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask

    def fail(src, dst):
        raise OSError("disk gone")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OutputError, match="disk gone"):
        atomic_write_bytes(target, b"new\n")
    assert target.read_text() == "old\n"
    assert [p.name for p in target.parent.iterdir()] == ["c.json"]  # no temporary file left
