"""Full-body inverse kinematics (eqs. 6-8): recovery, yaw, the terms and their gradients,
ground model, bounded and deterministic search."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kin_helpers import (
    SPEC,
    TwistJoint,
    central_difference,
    random_stick,
    relative_error,
    stick_tree,
    triangle_leg,
    yawed,
)

from msrr.core import Configuration
from msrr.core.alignment import angles_between, rot_z
from msrr.core.kinematics import (
    FixedNode,
    GroundModel,
    GroundOp,
    IKOptions,
    IKPose,
    IKProblem,
    IKTerm,
    KinematicTree,
    MotionCostTerm,
    TermValue,
    VectorAngleTerm,
    forward,
    solve_ik,
    tree_vectors,
)

SETTINGS = settings(max_examples=20, deadline=None)


def wrap(angle: float) -> float:
    return float(np.arctan2(np.sin(angle), np.cos(angle)))


@SETTINGS
@given(n=st.integers(1, 12), seed=st.integers(0, 10_000), scale=st.floats(0.05, 0.5),
       yaw=st.floats(-np.pi, np.pi))
def test_ik_of_fk_recovers_the_configuration(n, seed, scale, yaw):
    config = random_stick(n, seed, free=int(n > 3))
    tree = stick_tree(config)
    sigma = np.random.default_rng(seed).normal(size=tree.dim) * scale
    target = yawed(forward(tree, config, sigma).configuration, yaw)
    options = IKOptions(seed=seed)
    sol = solve_ik(tree, config, target, options)
    assert sol.success and sol.reason == "tolerance"
    assert sol.rms_angle < options.tolerance
    ids = tree.edges
    aligned = rot_z(sol.yaw) @ target.vectors(ids)
    rms = np.sqrt(np.mean(angles_between(sol.configuration.vectors(ids), aligned) ** 2))
    assert np.isclose(rms, sol.rms_angle, atol=1e-6)


@SETTINGS
@given(n=st.integers(1, 12), seed=st.integers(0, 10_000), yaw=st.floats(-3.1, 3.1))
def test_a_yaw_rotated_target_is_matched_with_the_right_yaw(n, seed, yaw):
    config = random_stick(n, seed)
    sol = solve_ik(stick_tree(config), config, yawed(config, yaw), IKOptions(seed=seed))
    assert sol.success
    assert abs(wrap(sol.yaw + yaw)) < 1e-3          # Rz(theta) undoes the frame's turn
    assert sol.rms_angle < 1e-3 and sol.motion_cost < 1e-2


# -- the objective: terms and gradients ---------------------------------------------------------


def random_pose(rng: np.random.Generator, n: int) -> IKPose:
    def units() -> np.ndarray:
        v = rng.normal(size=(n, 3))
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    yaw = float(rng.uniform(-np.pi, np.pi))
    return IKPose(yaw, rot_z(yaw).T, units(), units(), rng.random(n))


def pose_gradient(term: IKTerm, pose: IKPose, field: str) -> np.ndarray:
    """Central differences of ``term``'s value along one field of the pose (no projection:
    the angle terms are defined for any non-zero vectors)."""
    base = np.atleast_1d(getattr(pose, field)).astype(float)

    def value(flat: np.ndarray) -> float:
        moved = flat.reshape(base.shape) if field != "yaw" else float(flat[0])
        args = {"yaw": moved, "rz": rot_z(moved).T} if field == "yaw" else {field: moved}
        fields = {"yaw": pose.yaw, "rz": pose.rz, "z": pose.z, "x": pose.x, "cost": pose.cost}
        return term.evaluate(IKPose(**{**fields, **args})).value

    return central_difference(value, base.ravel()).reshape(base.shape if field != "yaw"
                                                           else ())


@pytest.mark.parametrize("vector", ["z", "x"])
def test_each_angle_term_gradient_matches_central_differences(vector):
    """The analytic pose gradient of an angle term is the tangential part of the
    numeric one (the vectors live on the unit sphere), and its yaw derivative equals it."""
    rng = np.random.default_rng(3)
    n = 7
    target = rng.normal(size=(n, 3))
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    counted = np.array([True, False, True, True, False, True, True])
    term = VectorAngleTerm(vector, target, rng.random(n) + 0.5, counted)
    pose = random_pose(rng, n)
    value = term.evaluate(pose, derivatives=True)
    assert value.value == term.evaluate(pose).value
    analytic = getattr(value, vector)
    numeric = pose_gradient(term, pose, vector)
    vectors = getattr(pose, vector)
    tangential = numeric - np.sum(numeric * vectors, axis=1, keepdims=True) * vectors
    assert relative_error(analytic - np.sum(analytic * vectors, axis=1, keepdims=True)
                          * vectors, tangential) < 1e-7
    assert np.isclose(value.yaw, pose_gradient(term, pose, "yaw"), rtol=1e-7)
    other = "x" if vector == "z" else "z"
    assert getattr(value, other) is None and value.cost is None
    assert len(value.residual) == counted.sum()     # only counted angles enter the RMS


def test_the_motion_cost_term_gradient_matches_central_differences():
    rng = np.random.default_rng(4)
    term = MotionCostTerm(rng.random(6))
    pose = random_pose(rng, 6)
    value = term.evaluate(pose, derivatives=True)
    assert np.isclose(value.value, term.weights @ pose.cost ** 2)
    assert relative_error(value.cost, pose_gradient(term, pose, "cost")) < 1e-8
    assert value.z is None and value.x is None and value.yaw == 0.0 and value.residual is None


@pytest.mark.parametrize("gamma,zeta", [(0.0, 1e-3), (0.5, 0.2), (1.0, 0.0)])
def test_objective_gradient_matches_central_differences(gamma, zeta):
    config = random_stick(10, 1, free=1)
    tree = stick_tree(config)
    target = forward(tree, config, np.random.default_rng(1).normal(size=tree.dim)
                     ).configuration
    problem = IKProblem(tree, config, yawed(target, 0.4),
                        IKOptions(gamma=gamma, zeta=zeta,
                                  weights=np.linspace(0.5, 2.0, len(tree.edges))))
    names = {"z_angle"} | ({"x_angle"} if gamma > 0 else set()) | (
        {"motion_cost"} if zeta > 0 else set())
    assert {t.name for t in problem.terms} == names
    point = np.concatenate([[0.1], np.random.default_rng(10).normal(size=tree.dim) * 0.3])
    value, grad = problem.value_and_grad(point)
    objective = problem.objective(point)
    assert value == problem.value(point) == objective.value
    assert np.isclose(sum(objective.terms.values()), value, rtol=1e-14)
    assert relative_error(grad, central_difference(problem.value, point)) < 1e-6


class _Upright(IKTerm):
    """A test term: ``k (1 - z_0 . e_z)`` keeps the first module's vector up."""

    name = "upright"

    def __init__(self, k: float):
        self.k = k

    def evaluate(self, pose: IKPose, derivatives: bool = False) -> TermValue:
        out = TermValue(self.k * (1.0 - pose.z[0, 2]))
        if derivatives:
            out.z = np.zeros_like(pose.z)
            out.z[0, 2] = -self.k
        return out


def test_a_new_term_is_one_object_and_the_gradient_follows():
    config = random_stick(6, 2)
    tree = stick_tree(config)
    problem = IKProblem(tree, config, config, IKOptions(zeta=0.1))
    point = np.concatenate([[0.2], np.random.default_rng(2).normal(size=tree.dim) * 0.3])
    before = problem.objective(point)
    problem.terms.append(_Upright(0.7))
    after = problem.objective(point, derivatives=True)
    z_row = problem.evaluator.evaluate(point[1:]).z[0]
    assert np.isclose(after.value - before.value, 0.7 * (1 - z_row[2]))
    assert after.terms["upright"] == pytest.approx(0.7 * (1 - z_row[2]))
    assert relative_error(after.grad, central_difference(problem.value, point)) < 1e-6


# -- the solver ------------------------------------------------------------------------------


def star(n: int) -> Configuration:
    """A hub with ``n`` rods to leaf hubs, each with a forward vector."""
    rng = np.random.default_rng(n)
    config = Configuration("stick")
    config.add_module("H0", "hub")
    for i in range(1, n + 1):
        config.add_module(f"H{i}", "hub")
        z = rng.normal(size=3)
        z /= np.linalg.norm(z)
        x = np.cross(z, rng.normal(size=3))
        config.connect("H0", f"H{i}", id=f"R{i}", kind="rod", z=z, x=x / np.linalg.norm(x))
    return config


def test_forward_vectors_count_when_gamma_is_positive():
    config = star(4)
    tree = stick_tree(config, TwistJoint)              # leaf twists only turn x
    target = forward(tree, config, np.full(tree.dim, 0.4)).configuration
    skeletal = solve_ik(tree, config, target, IKOptions(gamma=0.0))
    morphology = solve_ik(tree, config, target, IKOptions(gamma=1.0))
    assert skeletal.success and skeletal.motion_cost < 1e-6   # z already matches
    assert morphology.success
    assert np.allclose(morphology.sigma, 0.4, atol=2e-2)


def test_weights_by_module_id_and_their_errors():
    config = random_stick(4, 1)
    tree = stick_tree(config)
    problem = IKProblem(tree, config, config, IKOptions(weights={tree.edges[0]: 3.0}))
    assert problem.weights.tolist() == [3.0, 1.0, 1.0, 1.0]
    with pytest.raises(Exception, match="unknown modules R99"):
        IKProblem(tree, config, config, IKOptions(weights={"R99": 1.0}))
    with pytest.raises(Exception, match="must have shape"):
        IKProblem(tree, config, config, IKOptions(weights=[1.0]))


def unreachable() -> tuple:
    config = random_stick(5, 2)
    tree = stick_tree(config, TwistJoint)               # a twist cannot move any z
    other = random_stick(5, 77)
    target = config.with_vectors(z={e.id: other.edge(e.id).z for e in config.edges()})
    return tree, config, target


def test_an_unreachable_target_is_a_result_after_every_restart():
    tree, config, target = unreachable()
    sol = solve_ik(tree, config, target, IKOptions(max_restarts=3))
    assert not sol.success and sol.reason == "max_restarts" and sol.restarts == 3
    assert sol.rms_angle > np.deg2rad(5)               # a residual is reported


def test_the_search_is_deterministic_without_a_time_budget():
    tree, config, target = unreachable()
    first = solve_ik(tree, config, target, IKOptions(max_restarts=4, seed=5))
    again = solve_ik(tree, config, target, IKOptions(max_restarts=4, seed=5))
    assert np.array_equal(first.sigma, again.sigma) and first.yaw == again.yaw
    assert (first.cost, first.iterations, first.reason) == (again.cost, again.iterations,
                                                            again.reason)


def test_a_spent_time_budget_stops_the_search_and_says_so():
    tree, config, target = unreachable()
    sol = solve_ik(tree, config, target, IKOptions(max_restarts=50, time_budget=1e-9))
    assert sol.reason == "time_budget" and sol.restarts == 0 and sol.iterations <= 1


def test_finite_difference_gradient_option_solves_too():
    config = random_stick(4, 5)
    tree = stick_tree(config)
    target = forward(tree, config, np.full(tree.dim, 0.2)).configuration
    sol = solve_ik(tree, config, target, IKOptions(gradient="finite_difference"))
    assert sol.success


def test_yaw_can_be_held():
    config = random_stick(3, 4)
    sol = solve_ik(stick_tree(config), config, yawed(config, 0.5),
                   IKOptions(solve_yaw=False, initial_yaw=0.0, max_restarts=2))
    assert sol.yaw == 0.0


def test_a_tree_without_joints_solves_only_the_yaw():
    config = random_stick(3, 4)
    rigid = KinematicTree(config, [FixedNode(config.edge_ids(), config.vertices())])
    sol = solve_ik(rigid, config, yawed(config, 0.5))
    assert sol.reason == "tolerance" and abs(wrap(sol.yaw + 0.5)) < 1e-6
    other = random_stick(3, 9)
    sol = solve_ik(rigid, config, config.with_vectors(
        z={e.id: other.edge(e.id).z for e in config.edges()}))
    assert sol.reason == "no_joints" and not sol.success and sol.sigma.shape == (0,)


@pytest.mark.parametrize("bad", [{"time_budget": 0}, {"zeta": -1}, {"gradient": "magic"},
                                 {"max_restarts": -1}, {"tolerance": 0}])
def test_invalid_options_are_refused(bad):
    with pytest.raises(Exception, match="IKOptions"):
        IKOptions(**bad)


# -- the ground model --------------------------------------------------------------------------


def test_ground_model_reads_lengths_and_masses_from_the_spec():
    config = triangle_leg()
    model = GroundModel.for_configuration(config, SPEC)
    assert dict(model.lengths) == {e: 0.5 for e in ("R1", "R2", "R3", "R4")}
    assert dict(model.masses) == {**{e: 0.2 for e in ("R1", "R2", "R3", "R4")},
                                  **{v: 1.0 for v in ("H1", "H2", "H3")}}   # v1 is virtual


def test_ground_contact_rests_on_three_points_with_the_centre_of_mass_inside():
    config = triangle_leg()
    tree = stick_tree(config)
    z0 = tree_vectors(tree, config)[0]
    op = GroundOp(tree, GroundModel.for_configuration(config, SPEC))
    contact, _ = op.contact(z0.T)
    assert len(contact.contacts) == 3 and contact.stable
    assert np.allclose(contact.rotation @ contact.normal, [0, 0, -1])
    heights = (op.paths @ (z0.T @ contact.rotation.T))[:, 2]
    on_ground = [op.vertices.index(v) for v in contact.contacts]
    assert np.allclose(heights[on_ground], heights.min())   # the contacts are lowest


def test_support_face_is_the_brute_force_choice_over_every_triangle():
    """Reference: every triple of points whose plane has all points on one side is a hull
    face; among those whose centre-of-mass projection falls inside, the most downward."""
    op = GroundOp.__new__(GroundOp)
    rng = np.random.default_rng(7)
    for _ in range(25):
        points = rng.normal(size=(int(rng.integers(4, 10)), 3))
        com = points.mean(axis=0) + rng.normal(size=3) * 0.2
        best = None
        for a, b, c in combinations(range(len(points)), 3):
            normal = np.cross(points[b] - points[a], points[c] - points[a])
            normal /= np.linalg.norm(normal)
            side = (points - points[a]) @ normal
            if side.max() > 1e-9:
                normal, b, c = -normal, c, b
                side = -side
            if side.max() > 1e-9:
                continue   # not a hull face
            corners = points[[a, b, c]]
            stable = all(np.cross(corners[(i + 1) % 3] - corners[i], com - corners[i]) @ normal
                         >= 0 for i in range(3))
            key = (not stable, normal[2])
            if best is None or key < best[0]:
                best = (key, {a, b, c}, stable)
        (a, b, c), stable = op._support(points, com)
        assert {a, b, c} == best[1] and stable == best[2]
        face = np.cross(points[b] - points[a], points[c] - points[a])
        assert ((points - points[a]) @ face).max() < 1e-9   # outward order: all points below


def test_ground_model_of_a_flat_triangle_is_its_own_plane():
    config = triangle_leg()
    config.remove_module("v1")
    tree = stick_tree(config)
    op = GroundOp(tree, GroundModel())
    contact, _ = op.contact(tree_vectors(tree, config)[0].T)
    assert contact.stable and sorted(contact.contacts) == ["H1", "H2", "H3"]
    assert np.allclose(np.abs(contact.normal), [0, 0, 1])


def test_ik_gradient_through_the_ground_model_matches_central_differences():
    for seed in range(3):
        config = random_stick(8, seed + 20, free=2)
        tree = stick_tree(config)
        target = forward(tree, config, np.random.default_rng(seed).normal(size=tree.dim) * 0.3
                         ).configuration
        model = GroundModel.for_configuration(config, SPEC)
        problem = IKProblem(tree, config, target, IKOptions(ground=model, gamma=0.3))
        point = np.concatenate([[0.2], np.random.default_rng(seed).normal(size=tree.dim)
                                * 0.1])
        _, grad = problem.value_and_grad(point)
        assert relative_error(grad, central_difference(problem.value, point, 1e-7)) < 1e-5


def test_ik_with_the_ground_model_reaches_a_grounded_target():
    config = random_stick(7, 31, free=2)
    tree = stick_tree(config)
    model = GroundModel.for_configuration(config, SPEC)
    op = GroundOp(tree, model)
    grounded = forward(tree, config, np.random.default_rng(3).normal(size=tree.dim) * 0.2)
    contact, _ = op.contact(grounded.Z.T)
    target = config.with_vectors(
        z={e: contact.rotation @ v for e, v in grounded.z.items()},
        x={e: contact.rotation @ v for e, v in grounded.x.items()})
    sol = solve_ik(tree, config, target, IKOptions(ground=model))
    assert sol.success and sol.ground is not None and sol.ground.stable


def test_a_tree_without_joints_and_its_yaw_held_has_nothing_to_solve():
    """fig22 at 2 deg + 5 % seed 14 stopped in its first move with ``AttributeError: nit``:
    the tracking step holds the yaw, and a tree without joints then leaves L-BFGS-B no
    free variable, which scipy answers without an iteration count."""
    config = random_stick(3, 4)
    rigid = KinematicTree(config, [FixedNode(config.edge_ids(), config.vertices())])
    sol = solve_ik(rigid, config, yawed(config, 0.5),
                   IKOptions(solve_yaw=False, initial_yaw=0.2))
    assert sol.yaw == 0.2 and sol.iterations == 0 and sol.reason == "no_joints"
