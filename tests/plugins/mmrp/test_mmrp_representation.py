"""Section 3.1 and Theorem 1: face links, loops made virtual, layout, centre, heights."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import plugins
from msrr.core.errors import ConfigurationError
from msrr.core.io import check_configuration
from msrr.plugins.mmrp.centre import adjacency, centre, heights, tree_centre
from msrr.plugins.mmrp.random_trees import random_tree
from msrr.plugins.mmrp.representation import (
    edge_set,
    from_links,
    grid_cells,
    layout,
    overlapping_cells,
    pitch,
    to_tree,
)


def _brute_centre(adj: dict[str, list[str]]) -> set[str]:
    """Theorem 1 by definition: removing v leaves components of at most n/2 vertices."""
    n = len(adj)
    found = set()
    for v in adj:
        worst = 0
        seen = {v}
        for start in adj[v]:
            stack, size = [start], 0
            seen.add(start)
            while stack:
                u = stack.pop()
                size += 1
                for w in adj[u]:
                    if w not in seen:
                        seen.add(w)
                        stack.append(w)
            worst = max(worst, size)
        if 2 * worst <= n:
            found.add(v)
    return found


def test_illegal_faces_are_rejected_with_the_connection_named():
    with pytest.raises(ConfigurationError, match="faces T-L cannot dock"):
        to_tree(from_links(["1", "2"], [("1", "T", "2", "L")]))


def test_a_loop_becomes_one_virtual_connection():
    square = from_links("1234", [("1", "T", "2", "B"), ("2", "L", "3", "R"),
                                 ("3", "B", "4", "T"), ("4", "R", "1", "L")])
    converted = to_tree(square)
    assert len(converted.virtual) == 1
    assert len(converted.tree.edges()) == 3
    check_configuration(converted.tree, plugins.resolve("mmrp"))


def test_cross_layout_puts_the_centre_at_the_origin():
    cross = from_links("123456789", [("1", "T", "2", "B"), ("2", "T", "6", "B"),
                                     ("1", "R", "3", "L"), ("1", "B", "4", "T"),
                                     ("1", "L", "5", "R"), ("3", "R", "7", "L"),
                                     ("4", "B", "8", "T"), ("5", "L", "9", "R")])
    poses = layout(cross)
    p = pitch()
    assert poses["1"] == (0.0, 0.0, 0.0)
    assert poses["6"] == pytest.approx((2 * p, 0.0, 0.0))
    assert poses["7"] == pytest.approx((0.0, -2 * p, 0.0))
    assert poses["9"] == pytest.approx((0.0, 2 * p, 0.0))
    assert centre(cross) == ("1",)
    assert heights(adjacency(cross), "1") == {"1": 2, "2": 1, "3": 1, "4": 1, "5": 1,
                                              "6": 0, "7": 0, "8": 0, "9": 0}


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 30), seed=st.integers(0, 2**32 - 1))
def test_random_trees_are_legal_planar_and_their_centre_matches_theorem_1(n, seed):
    tree = random_tree(n, np.random.default_rng(seed))
    check_configuration(tree, plugins.resolve("mmrp"))
    assert not overlapping_cells(grid_cells(tree))
    adj = adjacency(tree)
    found = tree_centre(adj)
    assert set(found) == _brute_centre(adj)
    assert len(found) in (1, 2)
    if len(found) == 2:
        assert found[1] in adj[found[0]]
    h = heights(adj, found[0])
    assert h[found[0]] == max(h.values())
    assert all(h[v] == 0 for v in adj if len(adj[v]) == 1 and v != found[0])


@settings(max_examples=20, deadline=None)
@given(n=st.integers(2, 20), seed=st.integers(0, 2**32 - 1))
def test_layout_puts_docked_modules_one_pitch_apart_along_the_face_normal(n, seed):
    tree = random_tree(n, np.random.default_rng(seed))
    poses = layout(tree)
    normals = {"T": (1, 0), "B": (-1, 0), "L": (0, 1), "R": (0, -1)}
    for e in tree.edges():
        dx = poses[e.target][0] - poses[e.source][0]
        dy = poses[e.target][1] - poses[e.source][1]
        assert (dx, dy) == pytest.approx(tuple(pitch() * c for c in normals[e.ports[0]]))
    assert edge_set(to_tree(tree).tree) == edge_set(tree)
