"""A behavior's drive root (issue 31): the node a joint controller that drives from one
node grows its drive from, chosen in the library's ids and carried to the system's by
retrieval, so a build labelled any way is driven from the same node. The squirm from an
unseen start was driven from whichever inner node the build named lowest; from the
raised middle one it crabbed 22 deg off its heading (docs/freesn.md, stop 53)."""

from __future__ import annotations

import dataclasses
import re

import pytest
from stick_library import STICK, stick_sources

from msrr.core import plugins
from msrr.core.errors import ConfigurationError
from msrr.core.library import LibraryError, build_library, load_library
from msrr.core.library.planner import LibraryPlanner
from msrr.core.library.retrieve import retrieve
from msrr.core.plan import load_plan, natural_key, save_plan

from library_helpers import LIBRARIES

FREESN = plugins.resolve("freesn")
S4N5 = LIBRARIES / "S4N5.json"


def _most_connected_first(config) -> str:
    """Brute force: every node, sorted by (connections, descending; natural id)."""
    nodes = [v for v in config.vertices() if not config.is_virtual(v)]
    return sorted(nodes, key=lambda n: (-len(config.incident(n)), natural_key(n)))[0]


def test_a_behavior_without_a_declared_root_is_driven_from_its_most_connected_node():
    library = build_library(stick_sources(), STICK)
    (sub,) = library.sublibraries.values()
    spin = sub.behaviors["spin"]
    reference = sub.group_of(spin.start).reference
    assert spin.drive_root == _most_connected_first(reference) == "H2"   # H3 ties, its rod free


def test_a_declared_root_is_mapped_from_the_recordings_ids_and_a_bad_one_is_named():
    sources = stick_sources()
    (spin,) = sources.behaviors
    library = build_library(dataclasses.replace(
        sources, behaviors=(dataclasses.replace(spin, drive_root="a"),)), STICK)
    (sub,) = library.sublibraries.values()
    # the recording's hub a is the reference's H1 (the build's placement of "aim")
    assert sub.behaviors["spin"].drive_root == "H1"
    for bad in ("r:end", "nowhere"):
        with pytest.raises(LibraryError, match=f"drive_root {bad!r}"):
            build_library(dataclasses.replace(
                sources, behaviors=(dataclasses.replace(spin, drive_root=bad),)), STICK)


def _chain_labelled(order: tuple[str, ...]):
    """The shipped S4N5 chain (``S4N5-2.1``) with its nodes renamed ``n0..n4`` in
    ``order`` (library id of ``n0`` first) and its struts ``s0..s3``."""
    library = load_library(S4N5)
    _, entry = library.find_configuration("S4N5-2.1")
    chain = entry.configuration
    names = {library_id: f"n{i}" for i, library_id in enumerate(order)}
    struts = {e: f"s{i}" for i, e in enumerate(chain.edge_ids())}
    return library, chain.relabel(names, struts), {v: k for k, v in names.items()}


@pytest.mark.parametrize("order", [("N3", "N1", "N2", "N4", "N5"),
                                   ("N2", "N3", "N4", "N5", "N1"),
                                   ("N4", "N5", "N3", "N2", "N1")])
def test_the_squirm_is_driven_from_one_library_node_however_the_chain_is_labelled(order):
    """``n0`` is the middle node, ``N2`` and ``N4`` in turn: by id each would be the root.
    The library's ``N2`` is, under the map retrieval finds (the chain's mirror may map
    ``N2`` onto the build's ``N4``, so the root is asked of the map, not the labels)."""
    library, system, _ = _chain_labelled(order)
    retrieval = retrieve(library, system, FREESN, behavior="squirm")
    assert retrieval.target_mapping.nodes["N2"] == retrieval.drive_root
    plan = LibraryPlanner(FREESN, [S4N5]).plan_behavior(system, "squirm", loops=2)
    assert {a.behavior.drive_root for a in plan.actions if a.behavior} == \
        {retrieval.drive_root}
    inner = {v for v in system.vertices() if len(system.incident(v)) == 2}
    middle = next(v for v in inner if all(
        e.source in inner and e.target in inner for e in system.incident(v)))
    assert retrieval.drive_root in inner - {middle}


def test_a_plan_file_keeps_the_drive_root_and_refuses_one_that_is_no_node(tmp_path):
    _, system, _ = _chain_labelled(("N1", "N2", "N3", "N4", "N5"))
    plan = LibraryPlanner(FREESN, [S4N5]).plan_behavior(system, "squirm", loops=1)
    root = plan.actions[-1].behavior.drive_root
    path = tmp_path / "plan.json"
    save_plan(plan, path)
    loaded = load_plan(path, FREESN)
    assert [a.behavior for a in loaded.actions] == [a.behavior for a in plan.actions]
    path.write_text(re.sub(f'"drive_root": ?"{root}"', '"drive_root": "s1"', path.read_text()))
    with pytest.raises(ConfigurationError, match=r"behavior\.drive_root") as caught:
        load_plan(path, FREESN)
    assert str(path) in str(caught.value)


def test_every_shipped_behavior_names_its_drive_root():
    for path in sorted(LIBRARIES.glob("S*[0-9].json")):
        for sub in load_library(path).sublibraries.values():
            for behavior in sub.behaviors.values():
                assert behavior.drive_root is not None, (path.name, behavior.name)
    assert len(list(LIBRARIES.glob("S*[0-9].json"))) == 4
