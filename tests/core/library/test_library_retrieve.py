"""Retrieval (paper section 6.3, Fig. 15) on the shipped FreeSN libraries."""

from __future__ import annotations

import itertools

import networkx as nx
import pytest

from msrr.core import plugins
from msrr.core.actions import classify
from msrr.core.library import (
    RetrievalError,
    load_library,
    retrieve,
    shortest_path,
)
from msrr.core.plan import ActionType

from library_helpers import LIBRARIES, relabelled

FREESN = plugins.resolve("freesn")


@pytest.fixture(scope="module")
def s6n3():
    return load_library(LIBRARIES / "S6N3.json")


@pytest.fixture(scope="module")
def s4n5():
    return load_library(LIBRARIES / "S4N5.json")


@pytest.fixture(scope="module")
def s12n6():
    return load_library(LIBRARIES / "S12N6.json")


def system_from(library, key, seed=3, noise=0.03):
    _, config = library.find_configuration(key)
    return relabelled(config.configuration, "m", noise=noise, seed=seed)


def check_sequence(system, steps):
    """Every step in the system's ids, legal, and of the action type its topology says."""
    rules = plugins.docking_rules(system.robot)
    before = system
    for step in steps:
        assert set(step.target.modules()) == set(system.modules())
        assert rules.check(step.target) == []
        assert rules.check_action(before, step.target) == []
        assert classify(before, step.target) is step.action
        tree_topology = step.tree.configuration      # the tree is in system ids too
        moves_in = before if step.action in (ActionType.CONNECTION,
                                             ActionType.PARALLEL_CONNECTION) else step.target
        assert sorted(tree_topology.vertices()) == sorted(moves_in.vertices())
        before = step.target


@pytest.mark.parametrize("seed", [1, 2])
def test_retrieval_of_fig20_from_a_relabelled_perturbed_copy(s6n3, seed):
    system = system_from(s6n3, "fig20a", seed=seed)
    result = retrieve(s6n3, system, FREESN, to="fig20d")
    assert result.start == "S6N3-1.1"
    assert result.steps[-1].library_id == s6n3.find_configuration("fig20d")[1].id
    assert len(result.steps) > 1
    check_sequence(system, result.steps)
    assert {s.action for s in result.steps} >= {ActionType.MOVING, ActionType.CONNECTION}


def test_retrieval_back_from_fig20d_uses_disconnections(s6n3):
    system = system_from(s6n3, "fig20d")
    result = retrieve(s6n3, system, FREESN, to="fig20a")
    check_sequence(system, result.steps)
    assert ActionType.DISCONNECTION in {s.action for s in result.steps}


def brute_force_cost(sub, start, target):
    """The cheapest path cost by enumerating every simple path of the edge list."""
    graph = nx.MultiDiGraph()
    graph.add_nodes_from(sub.configurations)
    for edge in sub.edges:
        graph.add_edge(edge.source, edge.target, cost=edge.cost)
    best = None
    for path in nx.all_simple_edge_paths(graph, start, target):
        cost = sum(graph.edges[e]["cost"] for e in path)
        best = cost if best is None else min(best, cost)
    return best


@pytest.mark.parametrize("name", ["S6N3", "S12N6"])
def test_shortest_path_matches_brute_force(name):
    library = load_library(LIBRARIES / f"{name}.json")
    (sub,) = library.sublibraries.values()
    graph = sub.graph()
    for start, target in itertools.permutations(sub.configurations, 2):
        expected = brute_force_cost(sub, start, target) if start != target else 0.0
        if expected is None:
            with pytest.raises(RetrievalError):
                shortest_path(sub, start, target)
            continue
        path = shortest_path(sub, start, target)
        cost = sum(graph[u][v]["cost"] for u, v in itertools.pairwise(path))
        assert cost == pytest.approx(expected)


def test_unreachable_target_names_the_reachable_groups(s12n6):
    system = system_from(s12n6, "fig22a")
    with pytest.raises(RetrievalError, match=r"reachable groups: S12N6-1 \(octahedron\), "
                       r"S12N6-4 \(open-face\), S12N6-5 \(open-face-and-edge\)"):
        retrieve(s12n6, system, FREESN, to="fig21a")


def test_parallel_reconfiguration_of_fig22(s12n6):
    system = system_from(s12n6, "fig22a", noise=0.02)
    result = retrieve(s12n6, system, FREESN, behavior="node-wheels")
    check_sequence(system, result.steps)
    assert ActionType.PARALLEL_DISCONNECTION in {s.action for s in result.steps}
    assert {c.module for c in result.commands} <= set(system.modules())


def test_looping_sequence_behavior_comes_back_to_its_start(s4n5):
    system = system_from(s4n5, "star-flat")
    result = retrieve(s4n5, system, FREESN, behavior="crawl")
    check_sequence(system, [*result.steps, *result.behavior_steps])
    assert result.behavior_steps[-1].library_id == result.behavior.start
    assert len(result.behavior_steps) == 3


def test_system_of_another_topology_is_refused(s4n5):
    with pytest.raises(RetrievalError, match="reachable groups: S4N5-1"):
        retrieve(s4n5, system_from(s4n5, "star-flat"), FREESN, to="squirm-up")


def test_exactly_one_target(s6n3):
    from msrr.core.library import LibraryError

    with pytest.raises(LibraryError, match="exactly one target"):
        retrieve(s6n3, system_from(s6n3, "fig20a"), FREESN)
    with pytest.raises(LibraryError, match="no behavior 'dance'"):
        retrieve(s6n3, system_from(s6n3, "fig20a"), FREESN, behavior="dance")
