"""Issue 30, item 5: plans and libraries are validated whole against the robot before
use; a plan whose actions do not follow one another, and a library with an ill-typed
build, an incomplete mapping, a tree without its configuration or a command its module
does not take, are refused in one line naming the field."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.errors import ConfigurationError
from msrr.core.plan import save_plan

ROOT = Path(__file__).resolve().parents[2]
MMRP = ROOT / "plugins/mmrp/configs"
LIBRARY = ROOT / "plugins/freesn/libraries/S6N3.json"
SOURCES = ROOT / "plugins/freesn/library_sources/S6N3"


V1_PLAN = Path(__file__).resolve().parent / "plans_v1" / "mmrp-t-series.json"
"""The same plan in a version 1 file (every target whole), as the platform wrote it
before plan files stored changes."""


@pytest.fixture(scope="module")
def plan_doc(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """An MMRP plan file: undock 3R-1, undock 4L-1, two moves of 3 and 4 at once, dock
    4B-1, dock 3B-4."""
    planner = plugins.planners.get("mmrp")
    plan = planner.plan(plugins.load_configuration(MMRP / "t.json"),
                        plugins.load_configuration(MMRP / "series.json"), seed=0)
    path = tmp_path_factory.mktemp("plan") / "plan.json"
    save_plan(plan, path)
    return json.loads(path.read_text())


def _first(doc: dict[str, Any], kind: str) -> int:
    return next(i for i, a in enumerate(doc["actions"]) if a["type"] == kind)


def _without_modules(kind: str) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        del doc["actions"][_first(doc, kind)]["modules"]
    return mutate


def _duplicate(kind: str) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        i = _first(doc, kind)
        doc["actions"].insert(i, copy.deepcopy(doc["actions"][i]))
    return mutate


def _start_of_the_goal(doc: dict[str, Any]) -> None:
    doc["start"] = json.loads((MMRP / "series.json").read_text())


def _drop(index: int) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        del doc["actions"][index]
    return mutate


def _retype(doc: dict[str, Any]) -> None:
    doc["actions"][0]["type"] = "connection"


def _other_change(doc: dict[str, Any]) -> None:
    doc["actions"][0]["changes"] = doc["actions"][1]["changes"]


def _goal_of_the_start(doc: dict[str, Any]) -> None:
    doc["goal"] = doc["start"]


def _module_gone(doc: dict[str, Any]) -> None:
    target = doc["actions"][2]["target"]
    target["modules"] = [m for m in target["modules"] if m["id"] != "2"]
    target["connections"] = [c for c in target["connections"] if "2" not in
                             (c["source"], c["target"])]


def _module_added(doc: dict[str, Any]) -> None:
    """Module 9 appears in a move's target and leaves with the next move."""
    doc["actions"][2]["target"] = {"modules": [{"id": "9", "kind": "mmrp"}]}
    doc["actions"][3]["target"] = {"removed_modules": ["9"]}


def _changed(index: int, **delta: Any) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        doc["actions"][index]["target"] = delta
    return mutate


V1_PLANS = {
    "modules of an undock deleted": (_without_modules("disconnection"), "actions[0].modules",
                                     "leaves out 1, 3"),
    "modules of a move deleted": (_without_modules("moving"), "actions[2].modules",
                                  "leaves out 4"),
    "first action duplicated": (_duplicate("disconnection"), "actions[1].type",
                                "from actions[0].target its target makes none and breaks none"),
    "a move duplicated": (_duplicate("moving"), "actions[3]", "repeats the action before it"),
    "start of another configuration": (_start_of_the_goal, "actions[0].type", "from the start"),
    "an action missing": (_drop(0), "actions[0].type", "from the start"),
    "the last dock missing": (_drop(-1), "goal", "is not where the actions end"),
    "another type": (_retype, "actions[0].type", "a connection action"),
    "another change": (_other_change, "actions[0].changes", "are 1R-4L"),
    "goal of the start": (_goal_of_the_start, "goal", "is not where the actions end"),
    "a module gone": (_module_gone, "actions[2].target", "has other modules than"),
}
"""Broken version 1 files: every check of :func:`msrr.core.plan.check_chain` still
refuses them."""

PLANS = {
    "modules of an undock deleted": V1_PLANS["modules of an undock deleted"],
    "modules of a move deleted": (_without_modules("moving"), "actions[2].modules",
                                  "leaves out 3, 4"),  # both move at once
    "a move duplicated": V1_PLANS["a move duplicated"],
    "another type": V1_PLANS["another type"],
    "another change": V1_PLANS["another change"],
    "first action duplicated": (_duplicate("disconnection"),
                                "actions[1].target.removed_connections[0]",
                                "no connection '1L-3R' to remove"),
    "start of another configuration": (_start_of_the_goal,
                                       "actions[0].target.removed_connections[0]",
                                       "no connection '1L-3R' to remove"),
    "the last dock missing": (_drop(-1), "goal", "is not where the actions end"),
    "a module added": (_module_added, "actions[2].target", "modules not in "
                       "actions[1].target: 9"),
    "a dock to a module not there": (_changed(-1, connections=[
        {"id": "x", "source": "3", "target": "7", "ports": ["B", "T"]}]),
        "actions[5].target.connections[0].target", "connection end '7' is not a module"),
    "an index past the end": (_changed(-1, connections=[
        {"id": "x", "source": "3", "target": "4", "ports": ["B", "T"], "at": 9}]),
        "actions[5].target.connections[0].at", "index 9 is outside the 2 connections"),
    "a module removed with its connections": (_changed(2, removed_modules=["1"]),
                                              "actions[2].target.removed_modules[0]",
                                              "keeps connection(s)"),
    "a vector that is not unit": (_changed(2, connections=[
        {"id": "x", "source": "3", "target": "4", "z": [1, 1, 0]}]),
        "actions[2].target.connections[0].z", "must be a unit vector"),
    "an unknown version": (lambda doc: doc.update(schema_version=3), "schema_version",
                           "unknown plan file version 3"),
}
"""Broken version 2 files (changes to the target before)."""


@pytest.mark.parametrize("version, name", [*((2, name) for name in PLANS),
                                           *((1, name) for name in V1_PLANS)])
def test_a_plan_whose_actions_do_not_follow_is_refused(
        plan_doc: dict[str, Any], tmp_path: Path, version: int, name: str) -> None:
    mutate, field, says = (PLANS if version == 2 else V1_PLANS)[name]
    doc = copy.deepcopy(plan_doc if version == 2 else json.loads(V1_PLAN.read_text()))
    mutate(doc)
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ConfigurationError) as caught:
        plugins.load_plan(path)
    text = str(caught.value)
    assert text.startswith(f"{path}: {field}: ") and says in text, text


def test_a_good_plan_loads_and_a_bad_one_runs_nothing(plan_doc: dict[str, Any],
                                                      tmp_path: Path) -> None:
    good = tmp_path / "good.json"
    good.write_text(json.dumps(plan_doc))
    assert len(plugins.load_plan(good).actions) == len(plan_doc["actions"])
    doc = copy.deepcopy(plan_doc)
    _duplicate("disconnection")(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "mmrp", "--plan", str(bad),
                                            "--out", str(tmp_path / "run")])
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


# -- libraries ---------------------------------------------------------------------------


def _edge_with_mapping(doc: dict[str, Any]) -> dict[str, Any]:
    return next(e for e in doc["sublibraries"][0]["edges"] if e["mapping"])


def _tree(doc: dict[str, Any]) -> dict[str, Any]:
    return doc["sublibraries"][0]["groups"][0]["trees"][0]["tree"]


def _command(doc: dict[str, Any]) -> dict[str, Any]:
    return next(b for b in doc["sublibraries"][0]["behaviors"] if b["commands"])["commands"][0]


LIBRARIES: dict[str, tuple[Callable[[dict[str, Any]], None], str, str]] = {
    "merge threshold true": (lambda d: d["build"].update(merge_threshold=True),
                             "build.merge_threshold", "valid number"),
    "merge threshold negative": (lambda d: d["build"].update(merge_threshold=-1),
                                 "build.merge_threshold", "greater than or equal to 0"),
    "unknown cost": (lambda d: d["build"].update(cost="warp"), "build.cost", "'distance'"),
    "unknown build key": (lambda d: d["build"].update(joint=1), "build.joint", "Extra inputs"),
    "mapping without a node": (lambda d: _edge_with_mapping(d)["mapping"]["nodes"].pop("N1"),
                               "mapping", "leaves out N1"),
    "mapping without an edge": (lambda d: _edge_with_mapping(d)["mapping"]["edges"].pop("S1"),
                                "mapping", "leaves out S1"),
    "tree without its configuration": (lambda d: _tree(d).pop("configuration"),
                                       "trees[0].tree.configuration", "Field required"),
    "tree of another configuration": (lambda d: _tree(d).update(configuration="other"),
                                      "trees[0].tree.configuration", "is 'other'"),
    "unknown joint mode": (lambda d: _tree(d)["nodes"][1].update(type="warp"),
                           "trees[0].tree.nodes[1].type", "unknown node type"),
    "unknown command": (lambda d: _command(d).update(command="warp"), "commands[0].command",
                        "unknown command 'warp' of a strut module (known: wheel_speed, travel_along, travel_across)"),
}


@pytest.mark.parametrize("name", LIBRARIES)
def test_a_broken_library_is_refused_by_library_show(tmp_path: Path, name: str) -> None:
    mutate, field, says = LIBRARIES[name]
    doc = json.loads(LIBRARY.read_text())
    mutate(doc)
    path = tmp_path / "lib.json"
    path.write_text(json.dumps(doc))
    result = CliRunner().invoke(get_cli(), ["library", "show", str(path)])
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 1 and len(lines) == 1, lines
    assert field in lines[0] and says in lines[0], lines[0]


def test_every_shipped_library_still_loads_whole() -> None:
    for path in sorted((ROOT / "plugins/freesn/libraries").glob("S*.json")):
        if not path.name.endswith(".check.json"):
            plugins.load_library(path)


def test_a_source_behavior_with_an_unknown_command_is_refused(tmp_path: Path) -> None:
    from msrr.core.library import LibraryError, load_sources

    for source in sorted(SOURCES.glob("*.json")):
        doc = json.loads(source.read_text())
        if doc.get("behaviors"):
            doc["behaviors"][0]["commands"][0]["command"] = "warp"
        (tmp_path / source.name).write_text(json.dumps(doc))
    with pytest.raises(LibraryError, match=r"behaviors\[0\]\.commands\[0\]\.command: unknown "
                                           "command 'warp'"):
        load_sources([tmp_path], plugins.resolve)


def test_a_source_sequence_driven_from_no_node_of_it_is_refused(tmp_path: Path) -> None:
    from msrr.core.library import LibraryError, load_sources

    for source in sorted(SOURCES.glob("*.json")):
        doc = json.loads(source.read_text())
        for sequence in doc.get("sequences", []):
            sequence["drive_root"] = sequence["steps"][0]["configuration"]["connections"][0]["id"]
        (tmp_path / source.name).write_text(json.dumps(doc))
    with pytest.raises(LibraryError, match=r"sequences\[0\]\.drive_root: no node 'S\w+' in the "
                                           "sequence's first step"):
        load_sources([tmp_path], plugins.resolve)
