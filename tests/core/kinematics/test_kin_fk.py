"""Skeletal forward kinematics (Alg. 1): identity at zero, unit length, subtrees follow
their joint, reverse-mode gradient against central differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kin_helpers import (
    BraceNode,
    GimbalJoint,
    TwistJoint,
    random_stick,
    stick_tree,
    triangle_leg,
)

from msrr.core import Configuration
from msrr.core.app.testing import tree_gradient_error
from msrr.core.kinematics import (
    FixedNode,
    KinematicTree,
    forward,
    rodrigues,
)

MODES = [GimbalJoint, TwistJoint]
SETTINGS = settings(max_examples=25, deadline=None)


@SETTINGS
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), mode=st.sampled_from(MODES),
       free=st.integers(0, 2))
def test_fk_at_zero_returns_the_input_exactly(n, seed, mode, free):
    config = random_stick(n + free, seed, free=free)
    result = forward(stick_tree(config, mode), config)
    assert result.configuration == config
    assert np.array_equal(result.cost, np.zeros(len(config.edges())))


@SETTINGS
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), mode=st.sampled_from(MODES),
       scale=st.floats(0.0, 2.0))
def test_fk_keeps_vectors_unit(n, seed, mode, scale):
    config = random_stick(n, seed)
    tree = stick_tree(config, mode)
    sigma = np.random.default_rng(seed).normal(size=tree.dim) * scale
    result = forward(tree, config, sigma)
    assert np.allclose(np.linalg.norm(result.Z, axis=0), 1.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(result.X, axis=0), 1.0, atol=1e-12)
    assert np.all(result.cost >= 0)
    assert result.configuration.edge_ids() == config.edge_ids()


def test_a_joint_rotates_its_whole_subtree():
    config = Configuration("stick")                   # H1 - H2 - H3 with a free leg at H3
    for v in ("H1", "H2", "H3"):
        config.add_module(v, "hub")
    config.add_virtual("v1")
    config.connect("H1", "H2", id="R1", kind="rod", z=[1, 0, 0], x=[0, 1, 0])
    config.connect("H2", "H3", id="R2", kind="rod", z=[0, 1, 0])
    config.connect("H3", "v1", id="R3", kind="rod", z=[0, 0, -1])
    tree = KinematicTree(config, [FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"]),
                                  GimbalJoint(["R2"], ["H3"]), GimbalJoint(["R3"], ["v1"])])
    sigma = np.zeros(tree.dim)
    sigma[tree.slices[1]] = [0.3, 0.2]                # move rod R1 at H1
    result = forward(tree, config, sigma)
    rot = result.port_rotations["H2"]
    # by hand: about x = (0, 1, 0), then about z x a1 = (0, 0, 1)
    expected = rodrigues(np.array([0.0, 1, 0]), 0.3) @ rodrigues(np.array([0.0, 0, 1]), 0.2)
    assert np.allclose(rot, expected)
    assert np.allclose(result.z["R1"], rot @ [1, 0, 0])
    for edge in ("R2", "R3"):                          # everything beyond H2 follows
        assert np.allclose(result.z[edge], rot @ config.edge(edge).z)
    assert np.allclose(result.port_rotations["H3"], rot)
    assert np.allclose(result.port_rotations["H1"], np.eye(3))
    assert np.isclose(result.costs["R1"], 0.13) and result.costs["R2"] == result.costs["R3"] == 0
    assert set(result.x) == {"R1"}                     # forward vectors only where given


def test_a_twist_turns_x_and_the_subtree_about_z():
    config = Configuration("stick")
    for v in ("H1", "H2", "H3"):
        config.add_module(v, "hub")
    config.connect("H1", "H2", id="R1", kind="rod", z=[0, 0, 1], x=[1, 0, 0])
    config.connect("H2", "H3", id="R2", kind="rod", z=[1, 0, 0])
    tree = KinematicTree(config, [FixedNode([], ["H1"]), TwistJoint(["R1"], ["H2"]),
                                  TwistJoint(["R2"], ["H3"])])
    result = forward(tree, config, np.array([np.pi / 2, 0.0]))
    assert np.allclose(result.z["R1"], [0, 0, 1]) and np.allclose(result.x["R1"], [0, 1, 0])
    assert np.allclose(result.z["R2"], [0, 1, 0])


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
def test_reverse_mode_gradient_matches_central_differences(mode):
    for seed in range(4):
        config = random_stick(9, seed, free=1)
        assert tree_gradient_error(stick_tree(config, mode), config, seed) < 1e-6


def test_reverse_mode_gradient_with_mixed_node_types():
    config = random_stick(12, 3, free=2)
    base = stick_tree(config)
    nodes = [TwistJoint(n.edges, n.vertices) if k % 3 == 1 else n
             for k, n in enumerate(base.nodes)]
    tree = KinematicTree(config, nodes)
    assert {type(n) for n in tree.nodes} == {FixedNode, GimbalJoint, TwistJoint}
    for seed in range(3):
        assert tree_gradient_error(tree, config, seed) < 1e-6


def test_reverse_mode_gradient_through_a_parallel_node():
    config = triangle_leg()
    tree = KinematicTree(config, [FixedNode(["R1"], ["H1", "H2"]),
                                  BraceNode(["R2", "R3"], ["H3"]),
                                  GimbalJoint(["R4"], ["v1"])])
    for seed in range(4):
        assert tree_gradient_error(tree, config, seed) < 1e-6


def test_forward_checks_sigma_shape():
    config = random_stick(3, 0)
    with pytest.raises(Exception, match=r"sigma must have shape \(6,\)"):
        forward(stick_tree(config), config, np.zeros(4))
