"""The benchmark topologies of Fig. 16 (``benchmarks/fig16.py``) have the isomorphism counts
they claim."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from msrr.core.matching import enumerate_isomorphisms

_PATH = Path(__file__).resolve().parents[3] / "benchmarks" / "fig16.py"
_SPEC = importlib.util.spec_from_file_location("fig16", _PATH)
fig16 = sys.modules.setdefault("fig16", importlib.util.module_from_spec(_SPEC))
_SPEC.loader.exec_module(fig16)
FIG16_TOPOLOGIES = fig16.FIG16_TOPOLOGIES


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
