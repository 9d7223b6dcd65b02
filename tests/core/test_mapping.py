"""Module maps: inversion, composition, relabelling with inverted edges, free ends."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core import Configuration
from msrr.core.library import ModuleMap


def leg() -> Configuration:
    config = Configuration("freesn")
    for n in ("N1", "N2"):
        config.add_module(n, "node")
    config.add_virtual("v")
    config.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0])
    config.connect("N1", "v", id="S2", kind="strut", z=[0, 0, -1])
    return config


def test_apply_renames_and_turns_inverted_edges():
    mapping = ModuleMap({"N1": "A", "N2": "B", "v": "w"}, {"S1": ("T1", True), "S2": ("T2", False)})
    out, used = mapping.apply(leg())
    edge = out.edge("T1")
    assert (edge.source, edge.target) == ("B", "A")
    np.testing.assert_allclose(edge.z, [-1, 0, 0])
    assert out.edge("T2").target == "w"
    back, _ = used.inverse().apply(out)
    assert back == leg()


def test_unmapped_free_end_gets_a_name_from_its_edge():
    out, used = ModuleMap({"N1": "A", "N2": "B"}, {"S1": ("T1", False),
                                                   "S2": ("T2", True)}).apply(leg())
    assert used.nodes["v"] == "T2:a"          # the free end is T2's source end after inversion
    assert out.edge("T2").source == "T2:a"


def test_unmapped_module_is_an_error():
    with pytest.raises(KeyError):
        ModuleMap({"N1": "A"}, {"S1": ("T1", False), "S2": ("T2", False)}).apply(leg())


def test_then_composes_inversions_and_identity_is_neutral():
    a = ModuleMap({"N1": "A"}, {"S1": ("T1", True)})
    b = ModuleMap({"A": "X"}, {"T1": ("U1", True)})
    composed = a.then(b)
    assert composed.nodes == {"N1": "X"}
    assert composed.edges == {"S1": ("U1", False)}
    assert ModuleMap.identity(leg()).then(a.inverse().inverse()) == a
    assert ModuleMap.identity(leg()).is_identity()
    assert not a.is_identity()


def test_completed_pairs_free_ends_that_stay_free():
    after = leg().relabel({"v": "free"})
    completed = ModuleMap({"N1": "N1", "N2": "N2"},
                          {"S1": ("S1", False), "S2": ("S2", False)}).completed(leg(), after)
    assert completed.nodes["v"] == "free"


def test_dict_round_trip():
    mapping = ModuleMap({"N1": "A"}, {"S1": ("T1", True)})
    assert ModuleMap.from_dict(mapping.to_dict()) == mapping
