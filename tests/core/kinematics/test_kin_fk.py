"""Skeletal forward kinematics (Alg. 1): identity at zero, unit length, reverse-mode gradient."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kin_helpers import central_difference, freesn_tree, random_freesn, relative_error

from msrr.core import Configuration
from msrr.core.io import load_configuration
from msrr.core.kinematics import (
    Evaluator,
    FixedNode,
    KinematicTree,
    forward,
    tree_vectors,
)
from msrr.core.kinematics.rotations import rotation_between
from msrr.plugins.freesn.joints import OppositeSteeringJoint, ParallelStrutNode

ROOT = Path(__file__).resolve().parents[3]
MODES = ["opposite_steering", "differential_spherical", "full_opposite", "revolute"]
SETTINGS = settings(max_examples=25, deadline=None)


@SETTINGS
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), mode=st.sampled_from(MODES),
       free=st.integers(0, 2))
def test_fk_at_zero_returns_the_input_exactly(n, seed, mode, free):
    config = random_freesn(n + free, seed, free=free)
    result = forward(freesn_tree(config, mode), config)
    assert result.configuration == config
    assert np.array_equal(result.cost, np.zeros(len(config.edges())))


@SETTINGS
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), mode=st.sampled_from(MODES),
       scale=st.floats(0.0, 2.0))
def test_fk_keeps_vectors_unit(n, seed, mode, scale):
    config = random_freesn(n, seed)
    tree = freesn_tree(config, mode)
    sigma = np.random.default_rng(seed).normal(size=tree.dim) * scale
    result = forward(tree, config, sigma)
    assert np.allclose(np.linalg.norm(result.Z, axis=0), 1.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(result.X, axis=0), 1.0, atol=1e-12)
    assert np.all(result.cost >= 0)
    assert result.configuration.edge_ids() == config.edge_ids()


def test_a_joint_rotates_its_whole_subtree():
    config = Configuration("freesn")                  # N1 - N2 - N3 with a free leg at N3
    for v in ("N1", "N2", "N3"):
        config.add_module(v, "node")
    config.add_virtual("v1")
    config.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0])
    config.connect("N2", "N3", id="S2", kind="strut", z=[0, 1, 0])
    config.connect("N3", "v1", id="S3", kind="strut", z=[0, 0, -1])
    tree = KinematicTree(config, [FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"]),
                                  OppositeSteeringJoint(["S2"], ["N3"]),
                                  OppositeSteeringJoint(["S3"], ["v1"])])
    sigma = np.zeros(tree.dim)
    sigma[tree.slices[1]] = [0.0, 0.3, 0.2]          # move strut S1 at N1
    result = forward(tree, config, sigma)
    rot = result.port_rotations["N2"]
    assert np.allclose(rot, rotation_between(config.edge("S1").z, result.z["S1"]))
    for edge in ("S2", "S3"):                          # everything beyond N2 follows
        assert np.allclose(result.z[edge], rot @ config.edge(edge).z)
    assert np.allclose(result.port_rotations["N3"], rot)
    assert np.allclose(result.port_rotations["N1"], np.eye(3))
    assert result.costs["S1"] > 0 and result.costs["S2"] == result.costs["S3"] == 0
    assert result.x == {}                             # no forward vectors in, none out


def gradient_check(tree: KinematicTree, config, seed: int) -> float:
    rng = np.random.default_rng(seed)
    z0, x0, _ = tree_vectors(tree, config)
    ev = Evaluator(tree, z0, x0)
    n = len(tree.edges)
    gz, gx, gc = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=n)
    sigma = rng.normal(size=tree.dim) * 0.6

    def loss(s: np.ndarray) -> float:
        state = ev.evaluate(s)
        return float(np.sum(state.z * gz) + np.sum(state.x * gx) + state.cost @ gc)

    analytic = ev.gradient(ev.evaluate(sigma, derivatives=True), gz, gx, gc)
    return relative_error(analytic, central_difference(loss, sigma))


@pytest.mark.parametrize("mode", MODES)
def test_reverse_mode_gradient_matches_central_differences(mode):
    for seed in range(4):
        config = random_freesn(9, seed, free=1)
        assert gradient_check(freesn_tree(config, mode), config, seed) < 1e-6


def test_reverse_mode_gradient_through_a_parallel_node():
    config = load_configuration(ROOT / "plugins/freesn/configs/triangle-leg.json")
    tree = KinematicTree(config, [FixedNode(["S1"], ["N1", "N2"]),
                                  ParallelStrutNode(["S2", "S3"], ["N3"]),
                                  OppositeSteeringJoint(["S4"], ["v1"])])
    for seed in range(4):
        assert gradient_check(tree, config, seed) < 1e-6


def test_forward_checks_sigma_shape():
    config = random_freesn(3, 0)
    with pytest.raises(Exception, match=r"sigma must have shape \(9,\)"):
        forward(freesn_tree(config), config, np.zeros(4))
