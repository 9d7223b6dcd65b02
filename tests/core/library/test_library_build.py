"""Automatic library creation (paper section 6.2, Fig. 14)."""

from __future__ import annotations

import dataclasses

import pytest

from msrr.core import plugins
from msrr.core.actions import classify
from msrr.core.library import (
    LibraryError,
    ModuleMap,
    build_library,
    build_steps,
    dump_library,
    load_sources,
)
from msrr.core.library.sources import RecordedSequence, SequenceStep

from library_helpers import source_files

FREESN = plugins.resolve("freesn")


@pytest.fixture(scope="module")
def sources():
    return load_sources(source_files("S6N3"), plugins.resolve)


def test_build_is_deterministic(s6n3, sources):
    assert dump_library(build_library(sources, FREESN, cost="distance")) == dump_library(s6n3)


def test_progress_is_reported_once_per_configuration(sources):
    seen = []
    build_library(sources, FREESN, cost="distance", progress=seen.append)
    assert len(seen) == build_steps(sources)


def test_groups_follow_the_signature_label(s6n3):
    (sub,) = s6n3.sublibraries.values()
    assert sub.name == "S6N3"
    assert list(sub.groups) == ["S6N3-1", "S6N3-2", "S6N3-3", "S6N3-4"]
    for config in sub.configurations.values():
        reference = sub.groups[config.group].reference
        assert config.configuration.edge_ids() == reference.edge_ids()
        assert sorted(config.configuration.vertices()) == sorted(reference.vertices())


def test_every_edge_is_the_recorded_legal_action(s6n3):
    (sub,) = s6n3.sublibraries.values()
    rules = plugins.docking_rules("freesn")
    for edge in sub.edges:
        before = sub.configurations[edge.source].configuration
        after = sub.configurations[edge.target].configuration
        mapping = edge.module_map(before)
        assert classify(before, after, mapping) is edge.action
        assert rules.check_action(before, after) == []
        modules = {m for m in before.modules()}
        mapped = set(mapping.edges) | {v for v in mapping.nodes if not before.is_virtual(v)}
        assert modules <= mapped, edge
        if sub.configurations[edge.source].group != sub.configurations[edge.target].group:
            assert edge.mapping is not None
        assert edge.feasible is None and edge.cost >= 0


def test_close_configurations_are_merged(s6n3, sources):
    (sub,) = s6n3.sublibraries.values()
    placed = build_steps(sources)
    assert len(sub.configurations) < placed
    merged = sub.configuration("aim-S6")
    assert len(merged.origins) == 2          # recorded in both directions of Fig. 20
    (never,) = build_library(sources, FREESN, cost="distance", merge_threshold=-1.0).sublibraries.values()
    assert len(never.configurations) == placed


def test_mapping_behavior_is_remapped_to_group_ids(s6n3):
    (sub,) = s6n3.sublibraries.values()
    wheels = sub.behaviors["wheeled-move"]
    start = sub.configurations[wheels.start].configuration
    assert wheels.kind == "mapping" and wheels.parameters == ("speed", "yaw_rate")
    assert {c.module for c in wheels.commands} <= set(start.modules())


def test_isomorphic_designed_groups_are_refused(sources):
    twice = dataclasses.replace(sources, groups=(*sources.groups, sources.groups[0]))
    with pytest.raises(LibraryError, match="isomorphic to group S6N3-1"):
        build_library(twice, FREESN)


def test_configuration_without_a_designed_group_is_refused(sources):
    with pytest.raises(LibraryError, match="not isomorphic to any designed group"):
        build_library(dataclasses.replace(sources, groups=sources.groups[:1]), FREESN)


def test_connect_and_disconnect_in_one_step_is_refused(sources):
    steps = sources.sequences[0].steps
    one_leg = steps[3].configuration               # S4 docked
    other_leg = one_leg.copy()                     # S5 docked instead of S4
    other_leg.disconnect("S4")
    other_leg.add_virtual("S4:b")
    other_leg.connect("N1", "S4:b", id="S4", kind="strut", z=one_leg.edge("S4").z)
    other_leg.disconnect("S5")
    other_leg.remove_module("S5:b")
    other_leg.connect("N2", "N3", id="S5", kind="strut", z=one_leg.edge("S2").z)
    bad = RecordedSequence("bad", (SequenceStep(one_leg), SequenceStep(other_leg)),
                           origin="test.json")
    with pytest.raises(LibraryError, match="test.json:bad.*intermediate configuration"):
        build_library(dataclasses.replace(sources, sequences=(bad,)), FREESN)


def test_module_map_of_identity_edge_is_identity(s6n3):
    (sub,) = s6n3.sublibraries.values()
    for edge in sub.edges:
        if edge.mapping is None:
            source = sub.configurations[edge.source].configuration
            assert edge.module_map(source) == ModuleMap.identity(source)
