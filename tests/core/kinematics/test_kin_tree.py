"""Kinematic trees: partition, BFS layout, cycle check, default tree, JSON files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from kin_helpers import FREESN, freesn_tree, random_freesn

from msrr.core import Configuration
from msrr.core.io import load_configuration
from msrr.core.kinematics import (
    FixedNode,
    KinematicTree,
    KinematicTreeError,
    default_tree,
    load_tree,
    save_tree,
)
from msrr.plugins.freesn.joints import OppositeSteeringJoint, ParallelStrutNode, RevoluteJoint

ROOT = Path(__file__).resolve().parents[3]
TRIANGLE_LEG = ROOT / "plugins" / "freesn" / "configs" / "triangle-leg.json"


def chain(n: int) -> Configuration:
    """N1 - N2 - ... - N(n+1), struts S1..Sn along x."""
    config = Configuration("freesn", name=f"chain{n}")
    for i in range(n + 1):
        config.add_module(f"N{i + 1}", "node")
    for i in range(n):
        config.connect(f"N{i + 1}", f"N{i + 2}", id=f"S{i + 1}", kind="strut", z=[1, 0, 0])
    return config


def triangle_leg() -> Configuration:
    return load_configuration(TRIANGLE_LEG)


def test_default_tree_of_a_chain_roots_at_its_centre_and_lays_out_bfs():
    tree = freesn_tree(chain(4))                    # N1 .. N5, centre N3
    assert isinstance(tree.root, FixedNode) and tree.root.vertices == ("N3",)
    assert [type(n) for n in tree.nodes[1:]] == [OppositeSteeringJoint] * 4
    assert tree.edges == ("S2", "S3", "S1", "S4")    # breadth first from N3
    assert tree.dim == 12
    assert [tree.slices[k] for k in (1, 2)] == [slice(0, 3), slice(3, 6)]
    assert tree.parents == (-1, 0, 0, 1, 2)
    assert tree.input_ports == (None, "N3", "N3", "N2", "N4")
    assert tree.column("S1") == 2
    assert tree.node_of_vertex("N1").edges == ("S1",)


def test_default_tree_joint_mode_can_be_chosen():
    tree = default_tree(chain(2), RevoluteJoint)
    assert {type(n) for n in tree.nodes[1:]} == {RevoluteJoint} and tree.dim == 2
    with pytest.raises(KinematicTreeError, match="'fixed' is not a module joint"):
        default_tree(chain(2), FixedNode)


def test_default_tree_of_a_single_module():
    config = Configuration("freesn")
    config.add_module("N1", "node")
    tree = freesn_tree(config)
    assert len(tree) == 1 and tree.dim == 0 and tree.edges == ()


def test_default_tree_prefers_a_real_module_over_a_free_connector_as_root():
    config = Configuration("freesn")
    config.add_module("N1", "node")
    config.add_virtual("v1")
    config.connect("N1", "v1", id="S1", kind="strut", z=[0, 0, -1])
    tree = freesn_tree(config)
    assert tree.root.vertices == ("N1",) and tree.nodes[1].vertices == ("v1",)


def test_default_tree_holds_cycles_in_a_fixed_node():
    tree = freesn_tree(triangle_leg())
    assert tree.root.edges == ("S1", "S2", "S3")
    assert tree.root.vertices == ("N1", "N2", "N3")
    assert tree.nodes[1].edges == ("S4",) and tree.dim == 3


def test_default_tree_can_refuse_cycles_and_names_the_cycle():
    with pytest.raises(KinematicTreeError, match=r"cycle N\d - N\d - N\d - N\d \(edges S\d, S\d, "
                                                r"S\d\): the topology is not a tree"):
        freesn_tree(triangle_leg(), cycles="error")


def test_a_cycle_through_module_joints_is_refused_with_its_name():
    nodes = [FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"]),
             OppositeSteeringJoint(["S2"], ["N3"]), FixedNode(["S3"], []),
             OppositeSteeringJoint(["S4"], ["v1"])]
    with pytest.raises(KinematicTreeError) as info:
        KinematicTree(triangle_leg(), nodes)
    message = str(info.value)
    assert "cycle N1 - N2 - N3 - N1 (edges S1, S2, S3) is not inside one fixed or parallel" \
        in message
    assert "opposite_steering[S1]" in message and "fixed[S3]" in message


def test_a_parallel_node_may_close_a_cycle_through_a_fixed_parent():
    nodes = [FixedNode(["S1"], ["N1", "N2"]), ParallelStrutNode(["S2", "S3"], ["N3"]),
             OppositeSteeringJoint(["S4"], ["v1"])]
    tree = KinematicTree(triangle_leg(), nodes)
    assert tree.edges == ("S1", "S4", "S2", "S3") and tree.dim == 5
    assert tree.attachments[2] == ("N2", "N1")


def test_a_parallel_node_needs_a_fixed_parent_for_two_ports():
    config = triangle_leg()
    nodes = [FixedNode([], ["N1"]), RevoluteJoint(["S1"], ["N2"]),
             ParallelStrutNode(["S2", "S3"], ["N3"]), OppositeSteeringJoint(["S4"], ["v1"])]
    with pytest.raises(KinematicTreeError, match="cycle N.*runs through"):
        KinematicTree(config, nodes)


@pytest.mark.parametrize("nodes,match", [
    ([FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"])],
     "edge\\(s\\) S2 belong to no kinematic node"),
    ([FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"]),
      OppositeSteeringJoint(["S1"], ["N3"])], "edge S1 is in two nodes"),
    ([FixedNode([], ["N1", "N2"]), OppositeSteeringJoint(["S1"], ["N2"]),
      OppositeSteeringJoint(["S2"], ["N3"])], "vertex N2 is owned by two nodes"),
    ([FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"]),
      OppositeSteeringJoint(["S2"], ["N9"])], "no vertex 'N9'"),
])
def test_malformed_trees_are_refused_clearly(nodes, match):
    with pytest.raises(KinematicTreeError, match=match):
        KinematicTree(chain(2), nodes)


def test_a_tree_has_exactly_one_root():
    config = chain(2)
    config.add_module("N9", "node")                  # a second, separate group
    with pytest.raises(KinematicTreeError, match=r"exactly one root .* found fixed\[N1\], "
                                                 r"fixed\[N9\]"):
        KinematicTree(config, [FixedNode([], ["N1"]), OppositeSteeringJoint(["S1"], ["N2"]),
                               OppositeSteeringJoint(["S2"], ["N3"]), FixedNode([], ["N9"])])


def test_trees_round_trip_through_json(tmp_path):
    config = triangle_leg()
    tree = KinematicTree(config, [FixedNode(["S1"], ["N1", "N2"]),
                                  ParallelStrutNode(["S2", "S3"], ["N3"], beta=0.25),
                                  OppositeSteeringJoint(["S4"], ["v1"], alpha=0.3)])
    data = json.loads(json.dumps(tree.to_dict()))
    assert data["schema_version"] == 1 and data["robot"] == "freesn"
    assert data["nodes"][2] == {"type": "parallel_strut", "edges": ["S2", "S3"],
                                "vertices": ["N3"], "params": {"beta": 0.25}}
    assert KinematicTree.from_dict(data, config, modes=FREESN.joint_modes) == tree
    alone = KinematicTree.from_dict(data, modes=FREESN.joint_modes)            # the stored topology is enough
    assert alone == tree and alone.configuration.name == "triangle-leg"
    save_tree(tree, tmp_path / "tree.json")
    assert load_tree(tmp_path / "tree.json", config, modes=FREESN.joint_modes) == tree


def test_random_default_trees_round_trip():
    for seed in range(5):
        config = random_freesn(12, seed, free=2)
        tree = freesn_tree(config)
        assert KinematicTree.from_dict(tree.to_dict(), config, modes=FREESN.joint_modes) == tree
        assert sorted(tree.edges) == sorted(config.edge_ids())


def test_tree_files_with_errors_name_the_field():
    data = freesn_tree(chain(2)).to_dict()
    data["nodes"][1]["type"] = "teleport"
    with pytest.raises(KinematicTreeError, match=r"nodes\[1\]\.type: unknown node type .*"
                                                 r"known: differential_spherical"):
        KinematicTree.from_dict(data, modes=FREESN.joint_modes)
    data["nodes"][1] = {"type": "opposite_steering", "edges": "S1"}
    with pytest.raises(KinematicTreeError, match=r"nodes\[1\]\.edges"):
        KinematicTree.from_dict(data, modes=FREESN.joint_modes)
    with pytest.raises(KinematicTreeError, match="schema_version"):
        KinematicTree.from_dict({**freesn_tree(chain(2)).to_dict(), "schema_version": 7},
                                modes=FREESN.joint_modes)


def test_from_dict_checks_the_configuration_topology():
    data = freesn_tree(chain(2)).to_dict()
    other = chain(3)
    with pytest.raises(KinematicTreeError, match="does not have the tree's topology"):
        KinematicTree.from_dict(data, other, modes=FREESN.joint_modes)
