"""Retrieval (paper section 6.3, Fig. 15) on the ``stick`` test robot's library."""

from __future__ import annotations

import itertools

import pytest
from stick_library import STICK, relabelled, stick_sources

from msrr.core.library import LibraryError, RetrievalError, build_library, shortest_path
from msrr.core.library.retrieve import retrieve
from msrr.core.plan import ActionType
from msrr.core.robot import Robot, RobotSpec

from msrr_test_support import brute_force_cost, check_sequence


def system_from(library, key, seed=3, noise=0.03):
    _, config = library.find_configuration(key)
    return relabelled(config.configuration, noise=noise, seed=seed)


@pytest.mark.parametrize("seed", [1, 2])
def test_retrieval_from_a_relabelled_perturbed_copy(stick_lib, seed):
    system = system_from(stick_lib, "flat", seed=seed)
    result = retrieve(stick_lib, system, STICK, to="triangle")
    assert result.start == "H3R3-1.1" and result.match_cost < 0.01
    assert [s.library_id for s in result.steps] == ["H3R3-1.1", "H3R3-1.2", "H3R3-2.1"]
    check_sequence(system, result.steps, STICK)
    assert [s.action for s in result.steps][-1] is ActionType.CONNECTION
    assert result.cost == pytest.approx(sum(s.cost for s in result.steps))


def test_retrieval_back_uses_the_disconnection(stick_lib):
    system = system_from(stick_lib, "triangle")
    result = retrieve(stick_lib, system, STICK, to="leg-down")
    check_sequence(system, result.steps, STICK)
    assert [s.action for s in result.steps[1:]] == [ActionType.DISCONNECTION, ActionType.MOVING]


def test_ik_cost_library_matches_with_the_ik_cost():
    library = build_library(stick_sources(), STICK, cost="ik")
    assert library.build["cost"] == "ik"
    system = system_from(library, "aim", seed=5, noise=0.02)
    result = retrieve(library, system, STICK, to="leg-down")
    assert result.start == "H3R3-1.2"
    check_sequence(system, result.steps, STICK)


def test_mapping_behavior_commands_are_in_system_ids(stick_lib):
    system = system_from(stick_lib, "flat")
    result = retrieve(stick_lib, system, STICK, behavior="spin")
    (command,) = result.commands
    assert command.module in system.edge_ids()
    last = result.steps[-1].target
    assert last.is_virtual(last.edge(command.module).target)    # the free rod spins


def test_shortest_path_matches_brute_force(stick_lib):
    (sub,) = stick_lib.sublibraries.values()
    graph = sub.graph()
    unreachable = 0
    for start, target in itertools.permutations(sub.configurations, 2):
        expected = brute_force_cost(sub, start, target)
        if expected is None:
            unreachable += 1
            with pytest.raises(RetrievalError):
                shortest_path(sub, start, target)
            continue
        path = shortest_path(sub, start, target)
        assert sum(graph[u][v]["cost"] for u, v in itertools.pairwise(path)) == \
            pytest.approx(expected)
    assert unreachable > 0


def test_unreachable_target_names_the_reachable_groups(stick_lib):
    with pytest.raises(RetrievalError, match=r"reachable groups: H3R3-1 \(open\)$"):
        retrieve(stick_lib, system_from(stick_lib, "leg-down"), STICK, to="triangle")


def test_exactly_one_target_and_the_right_robot(stick_lib):
    system = system_from(stick_lib, "flat")
    with pytest.raises(LibraryError, match="exactly one target"):
        retrieve(stick_lib, system, STICK)
    with pytest.raises(LibraryError, match="no behavior 'dance'"):
        retrieve(stick_lib, system, STICK, behavior="dance")
    other = Robot(RobotSpec("other", "Other", STICK.spec.module_kinds))
    with pytest.raises(LibraryError, match="is for stick, not other"):
        retrieve(stick_lib, system, other, to="triangle")
