"""Library files are validated whole on load (issue 11, deliverable 1): trees on their
group's reference with the robot's joint modes, references against the robot's rules,
behaviors, unique names, finite gains, sub-library names against their content."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.errors import MAX_MESSAGE
from msrr.core.library import LibraryError, load_library

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "plugins/freesn/libraries/S6N3.json"


def _sub(d: dict) -> dict:
    return d["sublibraries"][0]


def _name(d):
    _sub(d)["name"] = "S7N3"


def _names(d):
    _sub(d)["configurations"][1]["names"] = ["fig20a"]


def _command_module(d):
    _sub(d)["behaviors"][0]["commands"][0]["module"] = "S99"


def _gain(d):
    _sub(d)["behaviors"][0]["commands"][0]["gains"]["speed"] = "__nan__"


def _gain_parameter(d):
    _sub(d)["behaviors"][0]["commands"][0]["gains"]["warp"] = 1.0


def _kind(d):
    _sub(d)["groups"][1]["reference"]["modules"][0]["kind"] = "warpdrive"


def _robot(d):
    _sub(d)["groups"][1]["reference"]["robot"] = "mmrp"


def _tree(d):
    _sub(d)["groups"][0]["trees"][0]["tree"] = {"garbage": True}


def _tree_edge(d):
    _sub(d)["groups"][0]["trees"][0]["tree"]["connections"][0]["id"] = "S9"


def _loop(d):
    _sub(d)["behaviors"][0]["loop"] = 1


CASES: dict[str, tuple[Callable[[dict], None], str]] = {
    "sub-library name": (_name, "sublibraries[0].groups[0].reference: has modules S6N3, not "
                                "those of sub-library S7N3"),
    "duplicate names": (_names, "sublibraries[0].configurations[1].names[0]: 'fig20a' already "
                                "names configuration 'S6N3-1.1'"),
    "command module": (_command_module, "sublibraries[0].behaviors[0].commands[0].module: no "
                                        "module 'S99' in the start configuration"),
    "NaN gain": (_gain, "sublibraries[0].behaviors[0].commands[0].gains.speed: NaN is not a "
                        "finite number"),
    "gain parameter": (_gain_parameter, "sublibraries[0].behaviors[0].commands[0].gains: "
                                        "unknown parameter 'warp'"),
    "reference kind": (_kind, "sublibraries[0].groups[1].reference: module N1: unknown module "
                              "kind 'warpdrive'"),
    "reference robot": (_robot, "sublibraries[0].groups[1].reference.robot: is 'mmrp', the "
                                "library is for 'freesn'"),
    "garbage tree": (_tree, "sublibraries[0].groups[0].trees[0].tree.schema_version: Field "
                            "required"),
    "tree topology": (_tree_edge, "sublibraries[0].groups[0].trees[0].tree: configuration "
                                  "does not have the tree's topology"),
    "boolean as flag": (_loop, "sublibraries[0].behaviors[0].loop: Input should be a valid "
                               "boolean"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_broken_library_is_one_line_naming_file_and_field(tmp_path: Path, case: str) -> None:
    change, expected = CASES[case]
    data = json.loads(LIBRARY.read_text())
    change(data)
    path = tmp_path / "lib [x].json"
    path.write_text(json.dumps(data).replace('"__nan__"', "NaN"))
    with pytest.raises(LibraryError) as info:
        plugins.load_library(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {expected}"), message
    assert "\n" not in message and len(message) <= MAX_MESSAGE
    result = CliRunner().invoke(get_cli(), ["library", "show", str(path)])
    assert result.exit_code == 1 and result.stderr == f"Error: {message}\n"


def test_the_checks_that_need_no_robot_run_without_one(tmp_path: Path) -> None:
    data = json.loads(LIBRARY.read_text())
    _names(data)
    path = tmp_path / "lib.json"
    path.write_text(json.dumps(data))
    with pytest.raises(LibraryError, match="already names configuration"):
        load_library(path)
    _name(data)  # the sub-library name needs the robot's module kinds
    _sub(data)["configurations"][1]["names"] = ["ref2"]
    path.write_text(json.dumps(data))
    assert "S7N3" in load_library(path).sublibraries


def test_the_shipped_libraries_load_whole() -> None:
    for path in sorted((ROOT / "plugins/freesn/libraries").glob("S*N*.json")):
        if not path.name.endswith(".check.json"):
            assert plugins.load_library(path).robot == "freesn"
