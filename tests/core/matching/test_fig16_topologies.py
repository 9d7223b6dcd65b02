"""The benchmark topologies of Fig. 16 have the isomorphism counts they claim."""

import numpy as np
import pytest

from msrr.core.matching import enumerate_isomorphisms
from msrr.core.matching.fig16 import FIG16_TOPOLOGIES


@pytest.mark.parametrize("spec", FIG16_TOPOLOGIES, ids=lambda s: s.name)
def test_shape_and_count(spec):
    config = spec.configuration(np.random.default_rng(0))
    assert len(config.vertices(virtual=False)) == 5
    assert len(config.edges()) == 16
    assert sum(1 for _ in enumerate_isomorphisms(config, config)) == spec.isomorphisms


def test_one_topology_has_exactly_57600():
    assert [s.isomorphisms for s in FIG16_TOPOLOGIES].count(57600) == 1
    counts = [s.isomorphisms for s in FIG16_TOPOLOGIES]
    assert min(counts) >= 24 and max(counts) >= 10_000
