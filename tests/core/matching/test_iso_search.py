"""Isomorphism tree search (Alg. 2-3) against the brute-force reference."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from matching_helpers import assert_isomorphism, random_freesn, scrambled

from msrr.core.io import load_configuration
from msrr.core.matching import brute_force_isomorphisms, iso_search

ROOT = Path(__file__).resolve().parents[3]
FREESN = ROOT / "plugins" / "freesn" / "configs"
MMRP = ROOT / "plugins" / "mmrp" / "configs"

small_graphs = st.tuples(st.integers(0, 2**32 - 1), st.integers(2, 4), st.integers(0, 3),
                         st.integers(0, 3))


def _pair(seed, nodes, struts, free, noise=0.0):
    rng = np.random.default_rng(seed)
    system = random_freesn(rng, nodes, struts, free)
    return system, scrambled(system, rng, noise=noise)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_graphs, st.sampled_from([0.0, 0.3, 3.0]))
def test_exhaustive_search_equals_brute_force(graph, noise):
    system, reference = _pair(*graph, noise=noise)
    found = list(iso_search(system, reference))
    reference_list = brute_force_isomorphisms(system, reference)
    assert len(found) == len(reference_list) > 0
    keys = {(tuple(sorted(m.nodes.items())), tuple(sorted(m.edges.items()))) for m in found}
    assert len(keys) == len(found)  # each isomorphism once
    assert keys == {(tuple(sorted(m.nodes.items())), tuple(sorted(m.edges.items())))
                    for m in reference_list}
    for mapping in found:
        assert_isomorphism(system, reference, mapping)
    distances = [m.distance for m in found]
    assert all(a <= b for a, b in itertools.pairwise(distances))
    assert distances[0] == reference_list[0].distance
    np.testing.assert_allclose(distances, [m.distance for m in reference_list], atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(small_graphs)
def test_isomorphic_pair_first_mapping_is_exact(graph):
    system, reference = _pair(*graph)
    first = next(iso_search(system, reference))
    assert first.distance < 1e-9
    assert_isomorphism(system, reference, first)
    back = first.reference_in_system_ids(reference)
    for e in system.edges():
        np.testing.assert_allclose(back.edge(e.id).z, e.z, atol=1e-6)
        assert (back.edge(e.id).source, back.edge(e.id).target) == (e.source, e.target)


def test_system_in_reference_ids_follows_reference_directions():
    system, reference = _pair(7, 4, 3, 2)
    mapping = next(iso_search(system, reference))
    moved = mapping.system_in_reference_ids(system, rotate=True)
    assert sorted(moved.edge_ids()) == sorted(reference.edge_ids())
    for f in reference.edges():
        g = moved.edge(f.id)
        assert (g.source, g.target) == (f.source, f.target)
        np.testing.assert_allclose(g.z, f.z, atol=1e-6)


def test_inverted_struts_are_flagged():
    system = load_configuration(FREESN / "triangle-leg.json")
    reference = system.copy()
    flipped = reference.disconnect("S1")
    reference.connect(flipped.target, flipped.source, id="S1", kind=flipped.kind, z=-flipped.z)
    first = next(iso_search(system, reference))
    assert first.edges["S1"] == ("S1", True)
    assert first.distance < 1e-12


def test_rejects_different_signatures():
    leg = load_configuration(FREESN / "triangle-leg.json")
    other = leg.copy()
    other.remove_module("v1")
    assert list(iso_search(leg, other)) == []
    assert brute_force_isomorphisms(leg, other) == []


def test_mmrp_ports_are_hard_constraints():
    cross = load_configuration(MMRP / "cross.json")
    reference = scrambled(cross, np.random.default_rng(3))
    found = list(iso_search(cross, reference))
    assert len(found) == len(brute_force_isomorphisms(cross, reference)) >= 1
    for mapping in found:
        assert_isomorphism(cross, reference, mapping)
        assert mapping.distance == 0.0  # MMRP edges carry no z: ports decide


def test_deadline_stops_the_search():
    system, reference = _pair(1, 4, 3, 3, noise=3.0)
    assert list(iso_search(system, reference, deadline=0.0)) == []


@pytest.mark.parametrize("seed", range(3))
def test_parallel_and_free_struts_permute(seed):
    rng = np.random.default_rng(seed)
    system = random_freesn(rng, 2, 2, 0)  # three parallel struts between two nodes
    assert len(brute_force_isomorphisms(system, system)) == 2 * 6
    assert len(list(iso_search(system, system))) == 2 * 6
