"""SnailBot joint modes: spherical (crawling) and sucker-revolute; derivatives and geometry."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from msrr.core import plugins
from msrr.core.alignment import rot_z
from msrr.core.app.cli import get_cli
from msrr.core.app.testing import node_jacobian_errors
from msrr.core.configuration import Configuration
from msrr.core.io import load_configuration
from msrr.core.kinematics import IKOptions, IKTracker, default_tree, forward
from msrr.core.kinematics.rotations import rodrigues
from msrr.core.kinematics.tracker import held_yaw, pinned_edges
from msrr.plugins.snailbot.joints import SphericalJoint, SuckerRevoluteJoint

from msrr_test_support import ROOT

PAIR = ROOT / "plugins" / "snailbot" / "configs" / "pair.json"

NODES = {
    "spherical": SphericalJoint(["e"], ["B1"]),
    "spherical-substrate-child": SphericalJoint(["e"], ["B2"], substrate_is_child=1.0),
    "sucker_revolute": SuckerRevoluteJoint(["e"], ["B1"]),
}


def test_snailbot_registers_both_modes_with_spherical_the_default():
    robot = plugins.resolve("snailbot")
    assert robot.joint_modes["spherical"] is SphericalJoint
    assert robot.joint_modes["sucker_revolute"] is SuckerRevoluteJoint
    assert robot.default_joint_mode() is SphericalJoint
    assert robot.spec.defaults.joint_mode == "spherical"


@pytest.mark.parametrize("key", list(NODES))
def test_jacobian_matches_central_differences(key, contact):
    node = NODES[key]
    rng = np.random.default_rng(17)
    for _ in range(20):
        z, x = contact(rng)
        sigma = rng.uniform(-1.5, 1.5, size=node.dim)
        for what, err in node_jacobian_errors(node, z, x, sigma).items():
            assert err < 1e-6, f"{key} {what}: relative error {err:.2e}"


@pytest.mark.parametrize("key", list(NODES))
def test_zero_joint_values_change_nothing(key, contact):
    node = NODES[key]
    z, x = contact(np.random.default_rng(1))
    out = node.forward(z, x, np.zeros(node.dim))
    assert np.allclose(out.z, z) and np.allclose(out.x, x)
    assert np.allclose(out.rotations[0], np.eye(3)) and out.cost[0] == 0.0


def test_crawling_turns_the_body_about_the_substrate_and_keeps_the_foot_flat():
    z, x = np.array([[0.0], [0.0], [1.0]]), np.array([[1.0], [0.0], [0.0]])
    out = SphericalJoint(["e"], ["B1"]).forward(z, x, np.array([0.5, 0.0, 0.3]))
    assert np.allclose(out.z[:, 0], [np.sin(0.5), 0.0, np.cos(0.5)])
    rot = out.rotations[0]
    assert np.allclose(rot @ z[:, 0], out.z[:, 0])      # the foot stays on the normal
    assert abs(out.x[:, 0] @ out.z[:, 0]) < 1e-12       # the heading stays tangent
    assert out.cost[0] == pytest.approx(0.5 + 0.5 * 0.3)


def test_either_tree_direction_gives_the_same_relative_pose(contact):
    """Substrate as parent (crawler turns about the substrate's centre) and crawler as
    parent (substrate turns about its own centre by the inverse) agree on the pose of
    the SnailBot in the substrate's frame."""
    rng = np.random.default_rng(4)
    ahead, behind = NODES["spherical"], NODES["spherical-substrate-child"]
    for _ in range(5):
        z, x = contact(rng)
        sigma = rng.uniform(-1, 1, size=3)
        a, b = ahead.forward(z, x, sigma), behind.forward(z, x, sigma)
        # ahead: substrate fixed at 0, SnailBot at a.z with orientation R
        # behind: SnailBot fixed at z, substrate at 0 with orientation R_b
        r_b = b.rotations[0]
        assert np.allclose(r_b.T @ b.z[:, 0], a.z[:, 0])
        assert np.allclose(r_b.T, a.rotations[0])
        assert np.allclose(b.z, z) and np.allclose(b.x, x)


def test_sucker_turns_only_about_the_contact_normal(contact):
    z, x = contact(np.random.default_rng(6))
    out = SuckerRevoluteJoint(["e"], ["B1"]).forward(z, x, np.array([0.4]))
    assert np.allclose(out.z, z)
    assert np.allclose(out.rotations[0], rodrigues(z[:, 0], 0.4))
    assert out.cost[0] == pytest.approx(0.4)


def chain(n: int) -> Configuration:
    """B1 -> B2 -> ... -> Bn (each SnailBot on the next), all stacked along +z."""
    config = Configuration("snailbot", name=f"chain{n}")
    for i in range(1, n + 1):
        config.add_module(f"B{i}", "snailbot")
    for i in range(1, n):
        config.connect(f"B{i}", f"B{i + 1}", z=[0.0, 0.0, 1.0])
    return config


def test_default_tree_marks_the_joints_whose_child_is_the_substrate():
    config = chain(5)  # the default tree is rooted at B3
    tree = default_tree(config, SphericalJoint)
    flags = {n.vertices[0]: n.params["substrate_is_child"] for n in tree.nodes[1:]}
    assert flags == {"B2": 0.0, "B4": 1.0, "B1": 0.0, "B5": 1.0}
    sigma = np.random.default_rng(0).uniform(-0.5, 0.5, tree.dim)
    moved = forward(tree, config, sigma).configuration
    assert set(moved.edge_ids()) == set(config.edge_ids())
    # B3 -> B4 is below the root: the SnailBot B3 stays, its connection vector too
    b3 = next(e for e in config.edges() if e.source == "B3")
    assert np.allclose(moved.edge(b3.id).z, config.edge(b3.id).z)


def test_default_tree_of_a_snailbot_file():
    robot = plugins.resolve("snailbot")
    config = load_configuration(PAIR)
    tree = default_tree(config, robot.default_joint_mode())
    assert tree.dim == 3
    assert forward(tree, config, np.zeros(3)).configuration == config


def test_platform_match_uses_the_spherical_joint():
    folder = ROOT / "plugins" / "snailbot" / "configs"
    system, other = str(folder / "chain5.json"), str(folder / "tree5.json")
    result = CliRunner().invoke(get_cli(), ["match", system, other, system])
    assert result.exit_code == 0, result.output
    assert f"best match of {system}: {system}" in result.output
    assert "(ik)" in result.output


def test_a_snailbot_that_roots_the_tree_pins_the_connection_it_crawls_on():
    """pieces-to-tree's final tree is rooted at B6, which crawls on B7: the tree reaches
    B7 through that joint, which turns B7 about its own centre and leaves B6-B7 where it
    is, so a tracking step holds B6-B7's yaw. Held over every connection instead, with the
    rows docked askew under 2 deg of noise, the yaw put B6-B7 up to 18 deg off its
    target, the step's residual all on it; the rows were swung about B6 and B6-B7 broke."""
    goal = load_configuration(ROOT / "plugins" / "snailbot" / "configs" / "forest20"
                              / "forest20-tree.json")
    tree = default_tree(goal, SphericalJoint)
    assert tree.root.vertices == ("B6",) and not tree.root.edges
    assert pinned_edges(tree, goal) == ("B6-B7",)
    rows = {e.id for e in goal.edges() if e.source in {f"B{i}" for i in range(13, 21)}}
    turn = {e.id: rot_z(0.3 + (0.35 if e.id in rows else 0.0) + (0.1 if e.id == "B6-B7"
                                                                  else 0.0)) @ e.z
            for e in goal.edges()}
    current = goal.with_vectors(z=turn)   # turned 0.3 rad; the rows 20 deg off, B6-B7 6 deg
    assert held_yaw(tree, current, goal, IKOptions(), near=0.0) == pytest.approx(0.4, abs=1e-3)
    with IKTracker(tree, goal, IKOptions(seed=1), tick_budget=None, explore=False) as tracker:
        tracker.step(current)
        solution = tracker.step(current)     # a tracking step: the yaw held
    assert solution.rms_angle < np.deg2rad(0.5)
