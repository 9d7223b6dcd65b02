"""Library feasibility files: edge cases from a library, the sidecar round trip, flags."""

from __future__ import annotations

from pathlib import Path

import pytest

from msrr.core.actions import classify
from msrr.core.library import LibraryError, load_library
from msrr.core.library.check import (
    CheckFile,
    EdgeCheck,
    apply_check,
    check_path,
    edge_cases,
    edge_key,
    library_digest,
    load_check,
    save_check,
)
from msrr.core.plugins import resolve

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"


@pytest.mark.parametrize("name", ["S6N3", "S4N5", "S12N6"])
def test_every_edge_becomes_a_case_of_its_own_action_type(name):
    library = load_library(FREESN / "libraries" / f"{name}.json")
    cases = edge_cases(library, resolve("freesn"))
    assert len(cases) == sum(len(s.edges) for s in library.sublibraries.values())
    for case in cases:
        assert classify(case.start, case.target) is case.edge.action, case.key
        assert set(case.action.kinematic_tree.edges) <= set(case.start.edge_ids())


def test_check_round_trips_and_flags_the_library(tmp_path):
    path = FREESN / "libraries" / "S6N3.json"
    library = load_library(path)
    sub = library.sublibraries["S6N3"]
    first, second = sub.edges[:2]
    check = CheckFile(library="S6N3", library_sha256=library_digest(path), robot="freesn",
                      driver="mujoco", seed=0, edges=[
                          EdgeCheck(edge=edge_key("S6N3", first), action="moving", feasible=True,
                                    sim_time=1.5),
                          EdgeCheck(edge=edge_key("S6N3", second), action="moving",
                                    feasible=False, reason="timeout: ...", sim_time=20.0)])
    target = check_path(tmp_path / "S6N3.json")
    assert target.name == "S6N3.check.json"
    save_check(check, target)
    again = load_check(target)
    assert again == check and again.feasible_fraction == 0.5
    assert apply_check(library, again) == 2
    assert (first.feasible, second.feasible) == (True, False)
    assert not sub.graph().has_edge(second.source, second.target)


def test_a_check_of_another_library_is_refused():
    library = load_library(FREESN / "libraries" / "S6N3.json")
    check = CheckFile(library="S4N5", library_sha256="0", robot="freesn", driver="mujoco",
                      seed=0, edges=[])
    with pytest.raises(LibraryError, match="S4N5"):
        apply_check(library, check)
