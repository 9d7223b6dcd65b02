"""Section 3.2: distributed recognition equals the true tree under any message order."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import plugins
from msrr.core.errors import ConfigurationError
from msrr.plugins.mmrp.random_trees import random_tree
from msrr.plugins.mmrp.recognition import observe, recognize_with_stats
from msrr.plugins.mmrp.representation import edge_set, from_links


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 40), tree_seed=st.integers(0, 2**32 - 1),
       order_seed=st.integers(0, 2**32 - 1), max_delay=st.integers(1, 6))
def test_recognition_equals_the_true_tree_under_random_message_orders(n, tree_seed,
                                                                     order_seed, max_delay):
    tree = random_tree(n, np.random.default_rng(tree_seed))
    result = recognize_with_stats(observe(tree), seed=order_seed, max_delay=max_delay)
    assert edge_set(result.configuration) == edge_set(tree)
    assert sorted(result.configuration.vertices()) == sorted(tree.vertices())
    assert result.messages == 2 * (n - 1)
    assert result.rounds <= 2 * (n - 1)
    assert set(result.leaves) == {v for v in tree.vertices() if tree.degree(v) == 1}
    if n > 2:
        assert result.starter not in result.leaves


def test_different_seeds_start_elsewhere_but_agree():
    tree = random_tree(25, np.random.default_rng(3))
    results = [recognize_with_stats(observe(tree), seed=s) for s in range(8)]
    assert len({r.starter for r in results}) > 1
    assert len({edge_set(r.configuration) for r in results}) == 1


def test_a_closed_loop_is_reported_as_a_virtual_connection_whatever_the_order():
    square = from_links("1234", [("1", "T", "2", "B"), ("2", "L", "3", "R"),
                                 ("3", "B", "4", "T"), ("4", "R", "1", "L")])
    found = {recognize_with_stats(observe(square), seed=s).virtual for s in range(10)}
    assert len(found) == 1 and len(next(iter(found))) == 1


def test_inconsistent_observation_is_one_line_error():
    observation = {"1": {"T": ("2", "B")}, "2": {"B": None}}
    with pytest.raises(ConfigurationError, match="does not link back"):
        recognize_with_stats(observation)


def test_recognizer_is_registered_for_mmrp():
    recognizer = plugins.recognizers.get("mmrp", "distributed")
    tree = random_tree(9, np.random.default_rng(0))
    assert edge_set(recognizer.recognize(observe(tree), seed=4)) == edge_set(tree)
