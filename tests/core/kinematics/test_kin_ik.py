"""Full-body inverse kinematics (eqs. 6-8): recovery, yaw, gradient, ground model, budget."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kin_helpers import (
    FREESN,
    central_difference,
    freesn_tree,
    random_freesn,
    relative_error,
    yawed,
)

from msrr.core import Configuration
from msrr.core.alignment import angles_between
from msrr.core.io import load_configuration
from msrr.core.kinematics import (
    GroundModel,
    GroundOp,
    IKOptions,
    IKProblem,
    forward,
    solve_ik,
    tree_vectors,
)

ROOT = Path(__file__).resolve().parents[3]
SETTINGS = settings(max_examples=20, deadline=None)


def wrap(angle: float) -> float:
    return float(np.arctan2(np.sin(angle), np.cos(angle)))


@SETTINGS
@given(n=st.integers(1, 12), seed=st.integers(0, 10_000), scale=st.floats(0.05, 0.5),
       yaw=st.floats(-np.pi, np.pi))
def test_ik_of_fk_recovers_the_configuration(n, seed, scale, yaw):
    config = random_freesn(n, seed, free=int(n > 3))
    tree = freesn_tree(config)
    sigma = np.random.default_rng(seed).normal(size=tree.dim) * scale
    target = yawed(forward(tree, config, sigma).configuration, yaw)
    options = IKOptions(time_budget=5.0, seed=seed)
    sol = solve_ik(tree, config, target, options)
    assert sol.success and sol.reason == "tolerance"
    assert sol.rms_angle < options.tolerance
    reached = sol.configuration
    ids = tree.edges
    aligned = np.array([[np.cos(sol.yaw), -np.sin(sol.yaw), 0], [np.sin(sol.yaw),
                        np.cos(sol.yaw), 0], [0, 0, 1]]) @ target.vectors(ids)
    rms = np.sqrt(np.mean(angles_between(reached.vectors(ids), aligned) ** 2))
    assert np.isclose(rms, sol.rms_angle, atol=1e-6)


@SETTINGS
@given(n=st.integers(1, 12), seed=st.integers(0, 10_000), yaw=st.floats(-3.1, 3.1))
def test_a_yaw_rotated_target_is_matched_with_the_right_yaw(n, seed, yaw):
    config = random_freesn(n, seed)
    sol = solve_ik(freesn_tree(config), config, yawed(config, yaw), IKOptions(seed=seed))
    assert sol.success
    assert abs(wrap(sol.yaw + yaw)) < 1e-3          # Rz(theta) undoes the frame's turn
    assert sol.rms_angle < 1e-3 and sol.motion_cost < 1e-2


def test_objective_gradient_matches_central_differences():
    for seed, (gamma, zeta) in enumerate([(0.0, 1e-3), (0.5, 0.2), (1.0, 0.0)]):
        config = random_freesn(10, seed, free=1)
        tree = freesn_tree(config)
        target = forward(tree, config, np.random.default_rng(seed).normal(size=tree.dim)
                         ).configuration
        problem = IKProblem(tree, config, yawed(target, 0.4),
                            IKOptions(gamma=gamma, zeta=zeta,
                                      weights=np.linspace(0.5, 2.0, len(tree.edges))))
        point = np.concatenate([[0.1], np.random.default_rng(seed + 9).normal(
            size=tree.dim) * 0.3])
        value, grad = problem.value_and_grad(point)
        assert np.isclose(value, problem.value(point))
        assert relative_error(grad, central_difference(problem.value, point)) < 1e-6


def star(n: int) -> Configuration:
    """A node with ``n`` struts to leaf nodes, each with a forward vector."""
    rng = np.random.default_rng(n)
    config = Configuration("freesn")
    config.add_module("N0", "node")
    for i in range(1, n + 1):
        config.add_module(f"N{i}", "node")
        z = rng.normal(size=3)
        z /= np.linalg.norm(z)
        x = np.cross(z, rng.normal(size=3))
        config.connect("N0", f"N{i}", id=f"S{i}", kind="strut", z=z, x=x / np.linalg.norm(x))
    return config


def test_forward_vectors_count_when_gamma_is_positive():
    config = star(4)
    tree = freesn_tree(config, "revolute")           # leaf revolute joints only turn x
    target = forward(tree, config, np.full(tree.dim, 0.4)).configuration
    skeletal = solve_ik(tree, config, target, IKOptions(gamma=0.0))
    morphology = solve_ik(tree, config, target, IKOptions(gamma=1.0, time_budget=5.0))
    assert skeletal.success and skeletal.motion_cost < 1e-6   # z already matches
    assert morphology.success
    assert np.allclose(morphology.sigma, 0.4, atol=2e-2)


def test_weights_by_module_id_and_their_errors():
    config = random_freesn(4, 1)
    tree = freesn_tree(config)
    problem = IKProblem(tree, config, config, IKOptions(weights={tree.edges[0]: 3.0}))
    assert problem.weights.tolist() == [3.0, 1.0, 1.0, 1.0]
    with pytest.raises(Exception, match="unknown modules S99"):
        IKProblem(tree, config, config, IKOptions(weights={"S99": 1.0}))
    with pytest.raises(Exception, match="must have shape"):
        IKProblem(tree, config, config, IKOptions(weights=[1.0]))


def test_an_unreachable_target_is_a_result_not_an_exception():
    config = random_freesn(5, 2)
    tree = freesn_tree(config, "revolute")            # revolute cannot move any z
    target = random_freesn(5, 77)
    target = target.relabel({}, {}) if target.edge_ids() == config.edge_ids() else None
    assert target is not None
    target = config.with_vectors(z={e.id: target.edge(e.id).z for e in config.edges()})
    sol = solve_ik(tree, config, target, IKOptions(time_budget=0.2, max_restarts=3))
    assert not sol.success and sol.reason in ("max_restarts", "time_budget")
    assert sol.restarts >= 1 and sol.rms_angle > sol.cost * 0  # a residual is reported


def test_finite_difference_gradient_option_solves_too():
    config = random_freesn(4, 5)
    tree = freesn_tree(config)
    target = forward(tree, config, np.full(tree.dim, 0.2)).configuration
    sol = solve_ik(tree, config, target, IKOptions(gradient="finite_difference",
                                                   time_budget=5.0))
    assert sol.success


def test_yaw_can_be_held():
    config = random_freesn(3, 4)
    sol = solve_ik(freesn_tree(config), config, yawed(config, 0.5),
                   IKOptions(solve_yaw=False, initial_yaw=0.0, time_budget=1.0))
    assert sol.yaw == 0.0


@pytest.mark.parametrize("bad", [{"time_budget": 0}, {"zeta": -1}, {"gradient": "magic"},
                                 {"max_restarts": -1}])
def test_invalid_options_are_refused(bad):
    with pytest.raises(Exception, match="IKOptions"):
        IKOptions(**bad)


# -- the ground model --------------------------------------------------------------------------


def test_ground_contact_rests_on_three_points_with_the_centre_of_mass_inside():
    config = load_configuration(ROOT / "plugins/freesn/configs/triangle-leg.json")
    tree = freesn_tree(config)
    z0 = tree_vectors(tree, config)[0]
    op = GroundOp(tree, GroundModel.for_configuration(config, FREESN.spec))
    contact, _ = op.contact(z0.T)
    # the leg points down: the robot tips over onto a face through the free strut end
    assert len(contact.contacts) == 3 and contact.stable
    assert np.allclose(contact.rotation @ contact.normal, [0, 0, -1])
    points = op.paths @ (z0.T @ contact.rotation.T)
    heights = points[:, 2]
    on_ground = [op.vertices.index(v) for v in contact.contacts]
    assert np.allclose(heights[on_ground], heights.min())   # the contacts are lowest


def test_ground_model_of_a_flat_triangle_is_its_own_plane():
    config = load_configuration(ROOT / "plugins/freesn/configs/triangle-leg.json")
    config.remove_module("v1")
    tree = freesn_tree(config)
    op = GroundOp(tree, GroundModel())
    contact, _ = op.contact(tree_vectors(tree, config)[0].T)
    assert contact.stable and sorted(contact.contacts) == ["N1", "N2", "N3"]
    assert np.allclose(np.abs(contact.normal), [0, 0, 1])


def test_ik_gradient_through_the_ground_model_matches_central_differences():
    for seed in range(3):
        config = random_freesn(8, seed + 20, free=2)
        tree = freesn_tree(config)
        target = forward(tree, config, np.random.default_rng(seed).normal(size=tree.dim) * 0.3
                         ).configuration
        problem = IKProblem(tree, config, target, IKOptions(ground=GroundModel.for_configuration(config, FREESN.spec),
                                                   gamma=0.3))
        point = np.concatenate([[0.2], np.random.default_rng(seed).normal(size=tree.dim)
                                * 0.1])
        _, grad = problem.value_and_grad(point)
        assert relative_error(grad, central_difference(problem.value, point, 1e-7)) < 1e-5


def test_ik_with_the_ground_model_reaches_a_grounded_target():
    config = random_freesn(7, 31, free=2)
    tree = freesn_tree(config)
    model = GroundModel.for_configuration(config, FREESN.spec)
    op = GroundOp(tree, model)
    grounded = forward(tree, config, np.random.default_rng(3).normal(size=tree.dim) * 0.2)
    contact, _ = op.contact(grounded.Z.T)
    target = config.with_vectors(
        z={e: contact.rotation @ v for e, v in grounded.z.items()},
        x={e: contact.rotation @ v for e, v in grounded.x.items()})
    sol = solve_ik(tree, config, target, IKOptions(ground=model, time_budget=5.0))
    assert sol.success and sol.ground is not None and sol.ground.stable
