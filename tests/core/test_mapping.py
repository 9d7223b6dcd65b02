"""Module maps (msrr.core.mapping): reversed edges, round trip, composition, completion."""

from __future__ import annotations

import numpy as np
import pytest
from config_strategies import configurations, random_map
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import Configuration, ConfigurationError
from msrr.core.alignment import rot_z
from msrr.core.mapping import ModuleMap
from msrr.core.matching import Mapping


def leg() -> Configuration:
    config = Configuration("tiny")
    for n in ("N1", "N2"):
        config.add_module(n, "node")
    config.add_virtual("v")
    config.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0], x=[0, 0, 1],
                   ports=("p", "q"))
    config.connect("N1", "v", id="S2", kind="strut", z=[0, 0, -1])
    return config


def test_a_reversed_edge_swaps_ends_and_ports_negates_z_and_keeps_x():
    """Alg. 3 lines 12-13: ``inv`` negates z (source -> target); x is the body's forward
    direction, which does not turn when the edge is seen from its other end."""
    out, _ = ModuleMap({"N1": "A", "N2": "B", "v": "w"},
                       {"S1": ("T1", True), "S2": ("T2", False)}).apply(leg())
    edge = out.edge("T1")
    assert (edge.source, edge.target, edge.ports) == ("B", "A", ("q", "p"))
    np.testing.assert_array_equal(edge.z, [-1, 0, 0])
    np.testing.assert_array_equal(edge.x, [0, 0, 1])
    assert out.edge("T2").target == "w"


@settings(max_examples=60, deadline=None)
@given(config=configurations, seed=st.integers(0, 2**32 - 1))
def test_map_then_inverse_gives_back_the_configuration_exactly(config, seed):
    mapping = random_map(config, seed)
    mapped, used = mapping.apply(config)
    assert used == mapping
    assert mapped.signature() == config.signature()
    back, _ = used.inverse().apply(mapped)
    assert back == config


@settings(max_examples=60, deadline=None)
@given(config=configurations, seed=st.integers(0, 2**32 - 1))
def test_then_is_applying_one_map_after_the_other(config, seed):
    a = random_map(config, seed, "a")
    once, _ = a.apply(config)
    b = random_map(once, seed + 1, "b")
    assert a.then(b).apply(config)[0] == b.apply(once)[0]
    assert a.then(a.inverse()).is_identity()


def test_unmapped_free_end_gets_a_name_from_its_edge():
    out, used = ModuleMap({"N1": "A", "N2": "B"}, {"S1": ("T1", False),
                                                   "S2": ("T2", True)}).apply(leg())
    assert used.nodes["v"] == "T2:a"          # the free end is T2's source end after inversion
    assert out.edge("T2").source == "T2:a"


def test_unmapped_module_is_an_error_naming_it():
    with pytest.raises(ConfigurationError, match="'N2'"):
        ModuleMap({"N1": "A"}, {"S1": ("T1", False), "S2": ("T2", False)}).apply(leg())
    with pytest.raises(ConfigurationError, match="'S2'"):
        ModuleMap({"N1": "A", "N2": "B"}, {"S1": ("T1", False)}).apply(leg())


def test_two_ids_mapped_to_one_are_an_error():
    with pytest.raises(ConfigurationError, match="duplicate"):
        ModuleMap({"N1": "A", "N2": "A"}, {"S1": ("T1", False), "S2": ("T2", False)}
                  ).apply(leg())


def test_then_composes_inversions_and_identity_is_neutral():
    a = ModuleMap({"N1": "A"}, {"S1": ("T1", True)})
    b = ModuleMap({"A": "X"}, {"T1": ("U1", True)})
    composed = a.then(b)
    assert composed.nodes == {"N1": "X"}
    assert composed.edges == {"S1": ("U1", False)}
    assert ModuleMap.identity(leg()).then(a.inverse().inverse()) == a
    assert ModuleMap.identity(leg()).is_identity()
    assert not a.is_identity()
    assert a.inverted() == ["S1"]


def test_completed_pairs_free_ends_that_stay_free():
    after = leg().relabel({"v": "free"})
    completed = ModuleMap({"N1": "N1", "N2": "N2"},
                          {"S1": ("S1", False), "S2": ("S2", False)}).completed(leg(), after)
    assert completed.nodes["v"] == "free"


def test_dict_round_trip():
    mapping = ModuleMap({"N1": "A"}, {"S1": ("T1", True)})
    assert ModuleMap.from_dict(mapping.to_dict()) == mapping


def test_a_match_is_a_module_map_with_a_score():
    """The matcher's result renames through the one module map, rotated by its yaw."""
    config = leg()
    match = Mapping({"N1": "A", "N2": "B", "v": "w"}, {"S1": ("T1", True), "S2": ("T2", False)},
                    distance=0.25, yaw=0.5)
    reference, _ = ModuleMap(match.nodes, match.edges).apply(config, rotation=rot_z(-0.5))
    assert isinstance(match, ModuleMap)
    assert match.system_in_reference_ids(config, rotate=True) == reference
    back = match.reference_in_system_ids(reference)
    for edge in config.edges():
        np.testing.assert_allclose(back.edge(edge.id).z, edge.z, atol=1e-12)
    assert back.edge("S1").source == "N1"


def test_image_of_a_module_swaps_the_connector_end_of_a_reversed_strut():
    mapping = ModuleMap({"N1": "A"}, {"S1": ("T1", True), "S2": ("T2", False)})
    assert mapping.image("S1", "source") == ("T1", "target")
    assert mapping.image("S2", "source") == ("T2", "source")
    assert mapping.image("S1") == ("T1", None)
    assert mapping.image("N1", "source") == ("A", "source")
    with pytest.raises(ConfigurationError, match="'N9' is not mapped"):
        mapping.image("N9")
