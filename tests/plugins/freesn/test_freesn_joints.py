"""FreeSN joint modes (Figs. 6-7, eqs. 1-5): registration, equations, analytic derivatives."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msrr.core import Configuration, plugins
from msrr.core.app.testing import node_jacobian_errors, tree_gradient_error
from msrr.core.io import load_configuration
from msrr.core.kinematics import (
    FixedNode,
    IKOptions,
    KinematicNode,
    KinematicTree,
    KinematicTreeError,
    default_tree,
    forward,
    solve_ik,
)
from msrr.core.kinematics.rotations import rodrigues, rotation_between
from msrr.core.random_configurations import random_configuration
from msrr.plugins.freesn.joints import (
    JOINT_MODES,
    DifferentialSphericalJoint,
    FullOppositeJoint,
    OppositeSteeringJoint,
    ParallelStrutNode,
    RevoluteJoint,
)

ALL_TYPES = [*JOINT_MODES, FixedNode]


def make(cls: type[KinematicNode], **params: float) -> KinematicNode:
    if cls is ParallelStrutNode:
        return cls(["S1", "S2"], ["N3"], **params)
    if cls is FixedNode:
        return cls(["S1", "S2"], ["N1", "N2"])
    return cls(["S1"], ["N2"], **params)


def units(rng: np.random.Generator, m: int) -> np.ndarray:
    v = rng.normal(size=(3, m))
    return v / np.linalg.norm(v, axis=0)


def forward_x(node: KinematicNode, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = len(node.edges)
    z = units(rng, m)
    x = units(rng, m)
    x -= z * np.einsum("im,im->m", x, z)  # forward vectors are perpendicular to z
    return z, x / np.linalg.norm(x, axis=0), rng.normal(size=node.dim) * 0.8


def test_freesn_registers_its_joint_modes_with_the_default_first():
    modes = plugins.kinematic_nodes("freesn")
    assert list(modes) == ["opposite_steering", "differential_spherical", "full_opposite",
                           "revolute", "parallel_strut", "planted", "swing"]
    assert plugins.resolve("freesn").default_joint_mode() is OppositeSteeringJoint
    assert {m.family for m in modes.values()} == {"module_joint", "parallel"}
    assert all(m.controller for m in modes.values())


@pytest.mark.parametrize("cls", ALL_TYPES, ids=lambda c: c.name)
def test_analytic_derivatives_match_central_differences(cls):
    rng = np.random.default_rng(7)
    node = make(cls)
    for _ in range(20):
        z, x, sigma = forward_x(node, rng)
        for what, err in node_jacobian_errors(node, z, x, sigma).items():
            assert err < 1e-6, f"{cls.name} {what}: relative error {err:.2e}"


@pytest.mark.parametrize("cls", ALL_TYPES, ids=lambda c: c.name)
def test_zero_joint_values_change_nothing(cls):
    rng = np.random.default_rng(8)
    node = make(cls)
    z, x, _ = forward_x(node, rng)
    out = node.forward(z, x, np.zeros(node.dim))
    assert np.array_equal(out.z, z) and np.array_equal(out.x, x)
    assert np.array_equal(out.cost, np.zeros(len(node.edges)))
    assert np.array_equal(out.rotations, np.broadcast_to(np.eye(3), out.rotations.shape))


def test_revolute_turns_x_about_z_at_cost_abs_sigma():          # eq. 1
    rng = np.random.default_rng(9)
    node = make(RevoluteJoint)
    z, x, _ = forward_x(node, rng)
    out = node.forward(z, x, np.array([0.7]))
    assert np.allclose(out.z, z)
    assert np.isclose(np.arccos(out.x[:, 0] @ x[:, 0]), 0.7)
    assert np.isclose(np.linalg.det(np.column_stack([x[:, 0], out.x[:, 0], z[:, 0]])),
                      np.sin(0.7))                                # positive turn about z
    assert np.allclose(out.cost, [0.7])
    assert np.allclose(out.rotations[0] @ z[:, 0], z[:, 0])


def test_opposite_steering_moves_z_to_z_plus_sigma():            # eqs. 3-4
    rng = np.random.default_rng(10)
    node = make(OppositeSteeringJoint, alpha=0.0)
    z, x, sigma = forward_x(node, rng)
    out = node.forward(z, x, sigma)
    zj = (z[:, 0] + sigma) / np.linalg.norm(z[:, 0] + sigma)
    assert np.allclose(out.z[:, 0], zj)
    assert np.allclose(out.rotations[0], rotation_between(z[:, 0], zj))
    assert np.allclose(out.x[:, 0], out.rotations[0] @ x[:, 0])
    assert np.isclose(out.cost[0], np.arccos(z[:, 0] @ zj))      # alpha = 0: the arc only


def test_steering_cost_counts_twice_for_opposite_steering():
    rng = np.random.default_rng(11)
    z, x, _ = forward_x(make(OppositeSteeringJoint), rng)
    sigma = np.cross(z[:, 0], x[:, 0]) * 0.5                      # move sideways: steer 90 deg
    arc = np.arccos(z[:, 0] @ ((z[:, 0] + sigma) / np.linalg.norm(z[:, 0] + sigma)))
    fade = 0.25 / (0.25 + 0.05 ** 2)
    single = make(DifferentialSphericalJoint).forward(z, x, sigma).cost[0]
    double = make(OppositeSteeringJoint).forward(z, x, sigma).cost[0]
    assert np.isclose(single, arc + 0.1 * np.pi / 2 * fade)
    assert np.isclose(double, arc + 2 * 0.1 * np.pi / 2 * fade)


def test_differential_spherical_steers_the_subtree_about_z():    # eq. 3
    rng = np.random.default_rng(12)
    z, x, sigma = forward_x(make(DifferentialSphericalJoint), rng)
    out = make(DifferentialSphericalJoint, steer_epsilon=0.0).forward(z, x, sigma)
    zj = out.z[:, 0]
    steer = sigma - (sigma @ z[:, 0]) * z[:, 0]
    steer /= np.linalg.norm(steer)
    # after steering to x^steer and driving, the forward vector is the moved x^steer
    assert np.allclose(out.x[:, 0], rotation_between(z[:, 0], zj) @ steer)
    assert np.allclose(out.rotations[0] @ z[:, 0], zj)


def test_full_opposite_keeps_the_subtree_attitude_at_twice_the_cost():   # Fig. 6(d)
    rng = np.random.default_rng(13)
    z, x, sigma = forward_x(make(FullOppositeJoint), rng)
    full = make(FullOppositeJoint).forward(z, x, sigma)
    diff = make(DifferentialSphericalJoint).forward(z, x, sigma)
    assert np.allclose(full.rotations[0], np.eye(3))
    assert np.allclose(full.z, diff.z)
    assert np.isclose(full.cost[0], 2 * diff.cost[0])


def test_antiparallel_motion_is_a_valid_half_turn():             # eq. 2 singular case
    z = np.array([[0.0], [0.0], [1.0]])
    x = np.array([[1.0], [0.0], [0.0]])
    out = make(OppositeSteeringJoint).forward(z, x, np.array([0.0, 0.0, -2.0]))
    r = out.rotations[0]
    assert np.allclose(out.z[:, 0], [0, 0, -1])
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
    assert np.allclose(r @ z[:, 0], out.z[:, 0])


def test_parallel_strut_turns_about_the_parent_axis():           # eq. 5, Fig. 7
    z = np.column_stack([[0.5, 0.0, np.sqrt(0.75)], [-0.5, 0.0, np.sqrt(0.75)]])
    x = np.column_stack([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0]])   # = x^steer = z1 x z2
    node = make(ParallelStrutNode, beta=0.5)
    out = node.forward(z, x, np.array([0.3, 0.2]))
    axis = np.array([1.0, 0.0, 0.0])                             # x^joint = z1 - z2
    assert np.allclose(out.z, rodrigues(axis, 0.3) @ z)          # both struts turn by sigma_1
    assert np.allclose(out.x, rodrigues(axis, 0.3) @ x)
    assert np.allclose(out.rotations[0], rodrigues(axis, 0.5))   # the node by sigma_1 + sigma_2
    assert np.allclose(out.cost, 0.3 + 0.5 * 0.2)                # no steering needed
    x_up = np.column_stack([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    steered = node.forward(z, x_up, np.array([0.3, 0.2]))
    fade = 0.13 / (0.13 + 0.05 ** 2)
    assert np.allclose(steered.cost, 0.4 + 2 * 0.1 * np.pi / 2 * fade)


@pytest.mark.parametrize("edges,vertices", [(["S1", "S2"], ["N2"]), (["S1"], [])])
def test_a_module_joint_has_one_edge_and_one_vertex(edges, vertices):
    with pytest.raises(KinematicTreeError, match="exactly one edge and one vertex"):
        OppositeSteeringJoint(edges, vertices)


def test_unknown_parameters_are_refused_listing_the_known_ones():
    with pytest.raises(KinematicTreeError, match="known: alpha, bound, steer_epsilon"):
        OppositeSteeringJoint(["S1"], ["N2"], gamma=1.0)


# -- FreeSN joints in trees: default tree, reverse-mode gradient, IK ------------------------------

FREESN = plugins.resolve("freesn")
TRIANGLE_LEG = Path(__file__).resolve().parents[3] / "plugins/freesn/configs/triangle-leg.json"


def random_freesn(n_edges: int, seed: int, free: int = 0) -> Configuration:
    rng = np.random.default_rng(seed)
    return random_configuration(FREESN.spec, FREESN.rules, n_edges + 1 - free, rng,
                                free_connectors=free)


def test_the_default_tree_uses_the_default_mode_and_holds_the_triangle_rigid():
    config = load_configuration(TRIANGLE_LEG)
    tree = default_tree(config, FREESN.default_joint_mode())
    assert tree.root.edges == ("S1", "S2", "S3") and tree.root.vertices == ("N1", "N2", "N3")
    assert type(tree.nodes[1]) is OppositeSteeringJoint and tree.dim == 3
    assert KinematicTree.from_dict(tree.to_dict(), config, modes=FREESN.joint_modes) == tree


@pytest.mark.parametrize("mode", [m for m in JOINT_MODES if m.family == "module_joint"],
                         ids=lambda m: m.name)
def test_reverse_mode_gradient_of_freesn_trees_matches_central_differences(mode):
    for seed in range(3):
        config = random_freesn(9, seed, free=1)
        assert tree_gradient_error(default_tree(config, mode), config, seed) < 1e-6


def test_reverse_mode_gradient_through_a_parallel_strut():
    config = load_configuration(TRIANGLE_LEG)
    tree = KinematicTree(config, [FixedNode(["S1"], ["N1", "N2"]),
                                  ParallelStrutNode(["S2", "S3"], ["N3"]),
                                  OppositeSteeringJoint(["S4"], ["v1"])])
    for seed in range(3):
        assert tree_gradient_error(tree, config, seed) < 1e-6


def test_ik_recovers_a_freesn_configuration_moved_by_its_default_joints():
    for seed in range(5):
        config = random_freesn(12, seed, free=2)
        tree = default_tree(config, FREESN.default_joint_mode())
        sigma = np.random.default_rng(seed).normal(size=tree.dim) * 0.3
        target = forward(tree, config, sigma).configuration
        sol = solve_ik(tree, config, target, IKOptions(seed=seed))
        assert sol.success and sol.reason == "tolerance"
