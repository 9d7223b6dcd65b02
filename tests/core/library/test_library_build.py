"""Automatic library creation (paper section 6.2, Fig. 14) on the ``stick`` test robot."""

from __future__ import annotations

import dataclasses

import pytest
from stick_library import RECORDING, STICK, TO_H1, closed_triangle, open_chain, stick_sources

from msrr.core.actions import classify
from msrr.core.library import (
    LibraryError,
    ModuleMap,
    build_library,
    build_steps,
    dump_library,
)
from msrr.core.library.sources import RecordedSequence, SequenceStep
from msrr.core.robot import Robot, RobotSpec


@pytest.fixture(scope="module")
def sources():
    return stick_sources()


@pytest.mark.parametrize("cost", ["distance", "ik"])
def test_build_is_deterministic(sources, cost):
    assert dump_library(build_library(sources, STICK, cost=cost)) == \
        dump_library(build_library(stick_sources(), STICK, cost=cost))


def test_progress_is_reported_once_per_configuration(sources):
    seen = []
    build_library(sources, STICK, progress=seen.append)
    assert len(seen) == build_steps(sources) == 7


def test_groups_follow_the_signature_label(stick_lib):
    (sub,) = stick_lib.sublibraries.values()
    assert sub.name == "H3R3"
    assert list(sub.groups) == ["H3R3-1", "H3R3-2"]
    for config in sub.configurations.values():
        reference = sub.groups[config.group].reference
        assert config.configuration.edge_ids() == reference.edge_ids() == ["R1", "R2", "R3"]
        assert sorted(config.configuration.vertices()) == sorted(reference.vertices())


def test_every_edge_is_the_recorded_legal_action(stick_lib):
    (sub,) = stick_lib.sublibraries.values()
    actions = []
    for edge in sub.edges:
        before = sub.configurations[edge.source].configuration
        after = sub.configurations[edge.target].configuration
        mapping = edge.module_map(before)
        assert classify(before, after, mapping) is edge.action
        assert STICK.rules.check_action(before, after) == []
        if sub.configurations[edge.source].group != sub.configurations[edge.target].group:
            assert edge.mapping is not None
        assert edge.feasible is None and edge.cost >= 0
        actions.append(edge.action.value)
    assert actions == ["moving", "connection", "disconnection", "moving"]


@pytest.mark.parametrize("cost", ["distance", "ik"])
def test_close_configurations_are_merged(sources, cost):
    """The flat start recorded at a yaw merges into the designed flat configuration."""
    (sub,) = build_library(sources, STICK, cost=cost).sublibraries.values()
    assert [c.names for c in sub.configurations.values()] == [
        ("flat", "flat-again"), ("triangle", "docked"), ("aim", "undocked"), ("leg-down",)]
    (never,) = build_library(sources, STICK, merge_threshold=-1.0).sublibraries.values()
    assert len(never.configurations) == build_steps(sources)


def test_recorded_ids_are_mapped_to_group_ids(stick_lib):
    (sub,) = stick_lib.sublibraries.values()
    spin = sub.behaviors["spin"]
    start = sub.configurations[spin.start]
    assert start.names == ("aim", "undocked")
    (command,) = spin.commands
    assert command.module == "R3" and command.gains == (("rate", 2.0),)
    aim = start.configuration
    assert aim.edge("R3").z == pytest.approx(TO_H1) and aim.is_virtual(aim.edge("R3").target)


def test_isomorphic_designed_groups_are_refused(sources):
    twice = dataclasses.replace(sources, groups=(*sources.groups, sources.groups[0]))
    with pytest.raises(LibraryError, match="isomorphic to group H3R3-1"):
        build_library(twice, STICK)


def test_configuration_without_a_designed_group_is_refused(sources):
    with pytest.raises(LibraryError, match="not isomorphic to any designed group"):
        build_library(dataclasses.replace(sources, groups=sources.groups[:1]), STICK)


def test_sources_of_another_robot_are_refused(sources):
    other = Robot(RobotSpec("other", "Other", STICK.spec.module_kinds), STICK.rules,
                  STICK.joint_modes)
    with pytest.raises(LibraryError, match="sources are for robot 'stick'"):
        build_library(sources, other)


def test_connect_and_disconnect_in_one_step_is_refused(sources):
    aimed = open_chain(TO_H1, ids=RECORDING)                 # r free, q docked
    swapped = closed_triangle(ids=RECORDING)                 # r docks to a ...
    swapped.disconnect("q")                                  # ... while q lets go of c
    swapped.add_virtual("q:end")
    swapped.connect("b", "q:end", id="q", kind="rod", z=[0.0, 0.0, -1.0])
    bad = RecordedSequence("bad", (SequenceStep(aimed), SequenceStep(swapped)),
                           origin="test.json")
    with pytest.raises(LibraryError, match="test.json:bad.*intermediate configuration"):
        build_library(dataclasses.replace(sources, sequences=(bad,), behaviors=()), STICK)


def test_module_map_of_identity_edge_is_identity(stick_lib):
    (sub,) = stick_lib.sublibraries.values()
    identities = [e for e in sub.edges if e.mapping is None]
    assert identities
    for edge in identities:
        source = sub.configurations[edge.source].configuration
        assert edge.module_map(source) == ModuleMap.identity(source)
