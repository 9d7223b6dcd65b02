"""FreeBOT spherical rolling contact joint: derivatives, integrated pure rolling, trees."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

from msrr.core import plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.testing import node_jacobian_errors
from msrr.core.io import load_configuration
from msrr.core.kinematics import KinematicTree, default_tree, forward
from msrr.core.kinematics.rotations import exp_so3, skew
from msrr.plugins.freebot.joints import RollingContactJoint

from msrr_test_support import ROOT

CHAIN3 = ROOT / "plugins" / "freebot" / "configs" / "chain3.json"


def test_freebot_registers_rolling_contact_as_its_default_joint_mode():
    robot = plugins.resolve("freebot")
    assert robot.joint_modes["rolling_contact"] is RollingContactJoint
    assert robot.default_joint_mode() is RollingContactJoint


@pytest.mark.parametrize("ratio", [1.0, 0.6])
def test_jacobian_matches_central_differences(ratio, contact):
    rng = np.random.default_rng(11)
    node = RollingContactJoint(["e"], ["F2"], radius_ratio=ratio)
    for scale in (1.0, 1e-2):
        for _ in range(20):
            z, x = contact(rng)
            sigma = rng.uniform(-1.5, 1.5, size=2) * scale
            for what, err in node_jacobian_errors(node, z, x, sigma).items():
                assert err < 1e-6, f"{what} at |sigma|={np.linalg.norm(sigma):.1e}: {err:.2e}"
    # below 1e-4 rad the series forms are used; |sigma| itself has no useful
    # difference quotient there, the vectors and rotations do
    for _ in range(10):
        z, x = contact(rng)
        sigma = rng.uniform(-2e-5, 2e-5, size=2)
        for what, err in node_jacobian_errors(node, z, x, sigma, h=1e-6).items():
            if "cost" not in what:
                assert err < 1e-6, f"{what} at |sigma|={np.linalg.norm(sigma):.1e}: {err:.2e}"


def test_equal_spheres_turn_twice_the_travel_and_the_contact_moves_on_a_geodesic():
    z, x = np.array([[0.0], [0.0], [1.0]]), np.array([[1.0], [0.0], [0.0]])
    theta = 0.7
    out = RollingContactJoint(["e"], ["F2"]).forward(z, x, np.array([theta, 0.0]))
    # forward along x: the contact turns about e2 = z x x = +y
    assert np.allclose(out.z[:, 0], [np.sin(theta), 0.0, np.cos(theta)])
    rot = out.rotations[0]
    angle = np.arccos((np.trace(rot) - 1) / 2)
    assert angle == pytest.approx(2 * theta)
    assert np.allclose(rot @ [0, 1, 0], [0, 1, 0])      # about +y
    assert out.cost[0] == pytest.approx(theta)
    assert np.allclose(out.x[:, 0] @ out.z[:, 0], 0.0)  # the heading stays tangent


def rolled(u0: np.ndarray, path_axis: np.ndarray, r_parent: float, r_child: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Integrate pure rolling of the child along ``u(t) = exp(t hat(path_axis)) u0``.

    At every instant the child's angular velocity solves the no-slip and no-spin
    constraints ``(r_p + r_c) u' = r_c omega x u`` and ``omega . u = 0`` (least
    squares over the 4 x 3 system), and ``R' = hat(omega) R``. Returns the final
    contact direction and child rotation.
    """

    def rhs(_t, y):
        u, rot = y[:3], y[3:].reshape(3, 3)
        du = np.cross(path_axis, u)
        a = np.vstack([-r_child * skew(u), u[None, :]])
        b = np.concatenate([(r_parent + r_child) * du, [0.0]])
        omega = np.linalg.lstsq(a, b, rcond=None)[0]
        return np.concatenate([du, (skew(omega) @ rot).ravel()])

    sol = solve_ivp(rhs, (0.0, 1.0), np.concatenate([u0, np.eye(3).ravel()]),
                    rtol=1e-11, atol=1e-12, method="DOP853")
    y = sol.y[:, -1]
    return y[:3], y[3:].reshape(3, 3)


@pytest.mark.parametrize("r_parent, r_child", [(0.05, 0.05), (0.08, 0.05)])
def test_forward_kinematics_agrees_with_integrated_pure_rolling(r_parent, r_child, contact):
    rng = np.random.default_rng(5)
    node = RollingContactJoint(["e"], ["F2"], radius_ratio=r_parent / r_child)
    for _ in range(5):
        z, x = contact(rng)
        sigma = rng.uniform(-1.2, 1.2, size=2)
        out = node.forward(z, x, sigma)
        jac_free = node.forward(z, x, sigma)  # same call twice: a pure function
        assert np.array_equal(out.rotations, jac_free.rotations)
        e1 = x[:, 0]
        e2 = np.cross(z[:, 0], e1)
        w = sigma[0] * e2 - sigma[1] * e1
        u1, rot = rolled(z[:, 0], w, r_parent, r_child)
        assert np.allclose(out.z[:, 0], u1, atol=1e-8)
        assert np.allclose(out.rotations[0], rot, atol=1e-8)


def two_legs(ratio: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Roll forward 0.8 rad then left 0.9 rad, by the node's chained steps and by
    integration; returns the end contact, the chained rotation and the integrated one."""
    node = RollingContactJoint(["e"], ["F2"], radius_ratio=ratio)
    z, x = np.array([[0.0], [0.0], [1.0]]), np.array([[1.0], [0.0], [0.0]])
    first = node.forward(z, x, np.array([0.8, 0.0]))
    second = node.forward(first.z, first.x, np.array([0.0, 0.9]))
    u_mid, rot1 = rolled(z[:, 0], np.array([0.0, 0.8, 0.0]), ratio, 1.0)
    u_end, rot2 = rolled(u_mid, -0.9 * first.x[:, 0], ratio, 1.0)
    assert np.allclose(second.z[:, 0], u_end, atol=1e-8)
    return u_end, second.rotations[0] @ first.rotations[0], rot2 @ rot1


def test_equal_spheres_roll_holonomically():
    """For equal radii the rotation depends only on the end points: two half-turns,
    ``R = (2 z' z'^T - I)(2 z z^T - I)``, whatever the path."""
    u_end, chained, integrated = two_legs(1.0)
    assert np.allclose(chained, integrated, atol=1e-8)
    z = np.array([0.0, 0.0, 1.0])
    half_turns = (2 * np.outer(u_end, u_end) - np.eye(3)) @ (2 * np.outer(z, z) - np.eye(3))
    assert np.allclose(integrated, half_turns, atol=1e-8)


def test_unequal_spheres_roll_path_dependently_and_compose_leg_by_leg():
    u_end, chained, integrated = two_legs(0.6)
    assert np.allclose(chained, integrated, atol=1e-8)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, u_end)
    direct = exp_so3(1.6 * np.arccos(z @ u_end) * axis / np.linalg.norm(axis))
    assert not np.allclose(direct, integrated, atol=1e-3)  # non-holonomic


def test_rolling_is_the_same_from_either_end_of_the_connection(contact):
    node = RollingContactJoint(["e"], ["F2"])
    rng = np.random.default_rng(2)
    z, x = contact(rng)
    sigma = rng.normal(size=2)
    # with -z the tangent basis is (e1, -e2): the same contact travel is (-s1, s2)
    ahead, behind = node.forward(z, x, sigma), node.forward(-z, x, sigma * [-1, 1])
    assert np.allclose(ahead.z, -behind.z)
    assert np.allclose(ahead.rotations, behind.rotations)


def test_default_tree_of_a_freebot_file_moves_the_chain():
    robot = plugins.resolve("freebot")
    config = load_configuration(CHAIN3)
    tree = default_tree(config, robot.default_joint_mode())
    assert isinstance(tree, KinematicTree) and tree.dim == 4
    assert {type(n) for n in tree.nodes[1:]} == {RollingContactJoint}
    assert forward(tree, config, np.zeros(tree.dim)).configuration == config
    moved = forward(tree, config, np.array([0.3, 0.0, 0.0, -0.2])).configuration
    assert moved != config and moved.is_connected()


def test_platform_match_uses_the_rolling_contact_joint():
    system = str(CHAIN3)
    result = CliRunner().invoke(get_cli(), ["match", system, system])
    assert result.exit_code == 0, result.output
    assert f"best match of {system}: {system}" in result.output
    assert "(ik)" in result.output
