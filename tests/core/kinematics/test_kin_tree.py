"""Kinematic trees: partition, BFS layout, cycle check, default tree, cycles, JSON files."""

from __future__ import annotations

import json

import networkx as nx
import pytest
from kin_helpers import (
    STICK,
    BraceNode,
    GimbalJoint,
    TwistJoint,
    chain,
    random_stick,
    stick_tree,
    triangle_leg,
)

from msrr.core import Configuration
from msrr.core.kinematics import (
    FixedNode,
    KinematicTree,
    KinematicTreeError,
    cyclic_groups,
    default_tree,
    find_cycle_through,
    load_tree,
    save_tree,
    tree_centre,
)

MODES = STICK.joint_modes


def test_default_tree_of_a_chain_roots_at_its_centre_and_lays_out_bfs():
    tree = stick_tree(chain(4))                      # H1 .. H5, centre H3
    assert isinstance(tree.root, FixedNode) and tree.root.vertices == ("H3",)
    assert [type(n) for n in tree.nodes[1:]] == [GimbalJoint] * 4
    assert tree.edges == ("R2", "R3", "R1", "R4")    # breadth first from H3
    assert tree.dim == 8
    assert [tree.slices[k] for k in (1, 2)] == [slice(0, 2), slice(2, 4)]
    assert tree.parents == (-1, 0, 0, 1, 2)
    assert tree.input_ports == (None, "H3", "H3", "H2", "H4")
    assert tree.column("R1") == 2
    assert tree.node_of_vertex("H1").edges == ("R1",)
    assert tree.node_of_edge("R4").vertices == ("H5",)


def test_default_tree_takes_the_joint_class_and_refuses_a_non_joint():
    tree = default_tree(chain(2), TwistJoint)
    assert {type(n) for n in tree.nodes[1:]} == {TwistJoint} and tree.dim == 2
    assert default_tree(chain(2), STICK.default_joint_mode()).dim == 4   # gimbal
    with pytest.raises(KinematicTreeError, match="'fixed' is not a module joint"):
        default_tree(chain(2), FixedNode)
    with pytest.raises(KinematicTreeError, match="'brace' is not a module joint"):
        default_tree(chain(2), BraceNode)


def test_default_tree_of_a_single_module():
    config = Configuration("stick")
    config.add_module("H1", "hub")
    tree = stick_tree(config)
    assert len(tree) == 1 and tree.dim == 0 and tree.edges == ()


def test_default_tree_needs_one_connected_configuration():
    config = chain(1)
    config.add_module("H9", "hub")
    with pytest.raises(KinematicTreeError, match="one connected configuration"):
        stick_tree(config)


def test_default_tree_prefers_a_real_module_over_a_free_connector_as_root():
    config = Configuration("stick")
    config.add_module("H1", "hub")
    config.add_virtual("v1")
    config.connect("H1", "v1", id="R1", kind="rod", z=[0, 0, -1])
    tree = stick_tree(config)
    assert tree.root.vertices == ("H1",) and tree.nodes[1].vertices == ("v1",)


def test_default_tree_holds_cycles_in_a_fixed_node():
    tree = stick_tree(triangle_leg())
    assert tree.root.edges == ("R1", "R2", "R3")
    assert tree.root.vertices == ("H1", "H2", "H3")
    assert tree.nodes[1].edges == ("R4",) and tree.dim == 2


def test_default_tree_can_refuse_cycles_and_names_the_cycle():
    with pytest.raises(KinematicTreeError, match=r"cycle H\d - H\d - H\d - H\d \(edges R\d, R\d, "
                                                 r"R\d\): the topology is not a tree"):
        stick_tree(triangle_leg(), cycles="error")


def test_random_default_trees_with_cycles_are_valid_trees():
    """Invariants: every module joint's edge is a bridge; every edge on a cycle is in a
    fixed node together with both its ends (or their group reaches the root)."""
    for seed in range(12):
        config = random_stick(9, seed, free=1, extra=2)
        tree = stick_tree(config)
        bridges = {frozenset(b) for b in nx.bridges(nx.Graph(config.undirected()))}
        groups = cyclic_groups(config)
        for node in tree.nodes:
            if isinstance(node, GimbalJoint):
                edge = config.edge(node.edges[0])
                doubled = sum(1 for e in config.edges()
                              if {e.source, e.target} == {edge.source, edge.target}) > 1
                assert not doubled and frozenset((edge.source, edge.target)) in bridges
        for group in groups:   # one fixed node owns all of a group but (at most) its entry
            owners = {type(tree.node_of_vertex(v)) for v in group}
            assert FixedNode in owners
        assert sorted(tree.edges) == sorted(config.edge_ids())


def test_cyclic_groups_merge_cycles_that_touch_and_count_doubled_edges():
    config = chain(5)                                 # H1 - ... - H6
    config.connect("H1", "H3", id="X1", kind="rod", z=[1, 0, 0])   # cycle H1 H2 H3
    config.connect("H3", "H4", id="X2", kind="rod", z=[1, 0, 0])   # doubled R3: touches it
    config.connect("H5", "H6", id="X3", kind="rod", z=[1, 0, 0])   # separate doubled edge
    assert cyclic_groups(config) == [{"H1", "H2", "H3", "H4"}, {"H5", "H6"}]
    assert cyclic_groups(chain(3)) == []


def test_find_cycle_through_returns_the_shortest_cycle_or_none():
    config = triangle_leg()
    vertices, edges = find_cycle_through(config, ["R1"])
    assert vertices == ["H2", "H3", "H1"] and edges == ["R2", "R3", "R1"]
    assert find_cycle_through(config, ["R4"]) is None
    assert find_cycle_through(config, ["R4", "R2"])[1][-1] == "R2"


def test_tree_centre_breaks_ties_by_rank():
    path = nx.path_graph(["a", "b", "c", "d"])        # centres b and c
    assert tree_centre(path, {v: (i,) for i, v in enumerate("abcd")}) == "b"
    assert tree_centre(path, {"a": (0,), "b": (5,), "c": (1,), "d": (2,)}) == "c"
    single = nx.Graph()
    single.add_node("x")
    assert tree_centre(single, {}) == "x"


def test_a_cycle_through_module_joints_is_refused_with_its_name():
    nodes = [FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"]),
             GimbalJoint(["R2"], ["H3"]), FixedNode(["R3"], []),
             GimbalJoint(["R4"], ["v1"])]
    with pytest.raises(KinematicTreeError) as info:
        KinematicTree(triangle_leg(), nodes)
    message = str(info.value)
    assert "cycle H1 - H2 - H3 - H1 (edges R1, R2, R3) is not inside one fixed or parallel" \
        in message
    assert "gimbal[R1]" in message and "fixed[R3]" in message


def test_a_parallel_node_may_close_a_cycle_through_a_fixed_parent():
    nodes = [FixedNode(["R1"], ["H1", "H2"]), BraceNode(["R2", "R3"], ["H3"]),
             GimbalJoint(["R4"], ["v1"])]
    tree = KinematicTree(triangle_leg(), nodes)
    assert tree.edges == ("R1", "R4", "R2", "R3") and tree.dim == 3
    assert tree.attachments[2] == ("H2", "H1")


def test_a_parallel_node_needs_a_fixed_parent_for_two_ports():
    nodes = [FixedNode([], ["H1"]), TwistJoint(["R1"], ["H2"]),
             BraceNode(["R2", "R3"], ["H3"]), GimbalJoint(["R4"], ["v1"])]
    with pytest.raises(KinematicTreeError, match="cycle H.*runs through"):
        KinematicTree(triangle_leg(), nodes)


@pytest.mark.parametrize("nodes,match", [
    ([FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"])],
     "edge\\(s\\) R2 belong to no kinematic node"),
    ([FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"]),
      GimbalJoint(["R1"], ["H3"])], "edge R1 is in two nodes"),
    ([FixedNode([], ["H1", "H2"]), GimbalJoint(["R1"], ["H2"]),
      GimbalJoint(["R2"], ["H3"])], "vertex H2 is owned by two nodes"),
    ([FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"]),
      GimbalJoint(["R2"], ["H9"])], "no vertex 'H9'"),
])
def test_malformed_trees_are_refused_clearly(nodes, match):
    with pytest.raises(KinematicTreeError, match=match):
        KinematicTree(chain(2), nodes)


def test_a_tree_has_exactly_one_root():
    config = chain(2)
    config.add_module("H9", "hub")                   # a second, separate group
    with pytest.raises(KinematicTreeError, match=r"exactly one root .* found fixed\[H1\], "
                                                 r"fixed\[H9\]"):
        KinematicTree(config, [FixedNode([], ["H1"]), GimbalJoint(["R1"], ["H2"]),
                               GimbalJoint(["R2"], ["H3"]), FixedNode([], ["H9"])])


def test_trees_round_trip_through_json(tmp_path):
    config = triangle_leg()
    tree = KinematicTree(config, [FixedNode(["R1"], ["H1", "H2"]),
                                  BraceNode(["R2", "R3"], ["H3"], bound=0.25),
                                  GimbalJoint(["R4"], ["v1"], bound=0.3)])
    data = json.loads(json.dumps(tree.to_dict()))
    assert data["schema_version"] == 1 and data["robot"] == "stick"
    assert data["nodes"][2] == {"type": "brace", "edges": ["R2", "R3"],
                                "vertices": ["H3"], "params": {"bound": 0.25}}
    assert "z" not in data["connections"][0]          # topology only, no vectors
    assert KinematicTree.from_dict(data, config, modes=MODES) == tree
    alone = KinematicTree.from_dict(data, modes=MODES)   # the stored topology is enough
    assert alone == tree and alone.configuration.name == "triangle-leg"
    save_tree(tree, tmp_path / "tree.json")
    assert load_tree(tmp_path / "tree.json", config, modes=MODES) == tree


def test_random_default_trees_round_trip():
    for seed in range(5):
        config = random_stick(12, seed, free=2)
        tree = stick_tree(config)
        assert KinematicTree.from_dict(tree.to_dict(), config, modes=MODES) == tree
        assert sorted(tree.edges) == sorted(config.edge_ids())


def test_tree_files_with_errors_name_the_field():
    data = stick_tree(chain(2)).to_dict()
    data["nodes"][1]["type"] = "teleport"
    with pytest.raises(KinematicTreeError, match=r"nodes\[1\]\.type: unknown node type .*"
                                                 r"known: brace, fixed, gimbal, twist"):
        KinematicTree.from_dict(data, modes=MODES)
    data["nodes"][1] = {"type": "gimbal", "edges": "R1"}
    with pytest.raises(KinematicTreeError, match=r"nodes\[1\]\.edges"):
        KinematicTree.from_dict(data, modes=MODES)
    data["nodes"][1] = {"type": "gimbal", "edges": ["R1"], "vertices": ["H1"],
                        "params": {"wobble": 1}}
    with pytest.raises(KinematicTreeError, match=r"nodes\[1\].*unknown parameter"):
        KinematicTree.from_dict(data, modes=MODES)
    with pytest.raises(KinematicTreeError, match="schema_version"):
        KinematicTree.from_dict({**stick_tree(chain(2)).to_dict(), "schema_version": 7},
                                modes=MODES)


def test_from_dict_knows_only_the_modes_it_is_given():
    data = stick_tree(chain(2)).to_dict()
    with pytest.raises(KinematicTreeError, match=r"unknown node type .*'gimbal' \(known: fixed\)"):
        KinematicTree.from_dict(data, modes={})


def test_from_dict_checks_the_configuration_topology():
    data = stick_tree(chain(2)).to_dict()
    with pytest.raises(KinematicTreeError, match="does not have the tree's topology"):
        KinematicTree.from_dict(data, chain(3), modes=MODES)
