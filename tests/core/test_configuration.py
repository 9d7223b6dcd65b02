"""The Configuration model: building, views, signature, relabelling, errors."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core import VIRTUAL, Configuration, ConfigurationError, parse_configuration, plugins


def triangle() -> Configuration:
    c = Configuration("freesn", name="triangle")
    for n in ("N1", "N2", "N3"):
        c.add_module(n, "node")
    c.add_virtual("v1")
    s = np.sqrt(3) / 2
    c.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0], x=[0, 0, 1])
    c.connect("N2", "N3", id="S2", kind="strut", z=[-0.5, s, 0])
    c.connect("N3", "N1", id="S3", kind="strut", z=[-0.5, -s, 0])
    c.connect("N1", "v1", id="S4", kind="strut", z=[0, 0, -1])
    return c


def test_modules_and_signature() -> None:
    c = triangle()
    assert c.modules() == {"N1": "node", "N2": "node", "N3": "node",
                           "S1": "strut", "S2": "strut", "S3": "strut", "S4": "strut"}
    sig = c.signature()
    assert sig.counts == (("node", 3), ("strut", 4))
    assert dict(sig.degrees) == {"node": (3, 2, 2), VIRTUAL: (1,)}
    assert sig.label(plugins.robot("freesn")) == "S4N3"


def test_signature_is_invariant_under_relabelling() -> None:
    c = triangle()
    r = c.relabel({"N1": "a", "N2": "b", "N3": "c", "v1": "free"}, {"S1": "x1"})
    assert r.signature() == c.signature()
    assert r.edge("x1").source == "a" and r.edge("x1").target == "b"
    assert r != c


def test_skeletal_view_drops_forward_vectors_only() -> None:
    c = triangle()
    s = c.skeletal()
    assert s.edge("S1").x is None
    np.testing.assert_array_equal(s.edge("S1").z, c.edge("S1").z)
    assert c.edge("S1").x is not None  # the original is untouched
    assert c.morphology() == c


def test_vectors_are_stacked_as_columns() -> None:
    z = triangle().vectors(["S1", "S4"])
    assert z.shape == (3, 2)
    np.testing.assert_array_equal(z[:, 1], [0, 0, -1])


def test_copy_is_deep() -> None:
    c = triangle()
    d = c.copy()
    d.disconnect("S4")
    assert "S4" in c.edge_ids() and "S4" not in d.edge_ids()
    assert d.degree("N1") == 2 and c.degree("N1") == 3


def test_generated_edge_ids_are_unique() -> None:
    c = Configuration("mmrp")
    c.add_module("1", "mmrp")
    c.add_module("2", "mmrp")
    assert c.connect("1", "2", ports=("T", "B")) == "1T-2B"
    assert c.connect("1", "2", ports=("T", "B")) == "1T-2B#2"


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda c: c.add_module("N1", "node"), "duplicate module id"),
        (lambda c: c.connect("N1", "nowhere", id="S9", kind="strut", z=[1, 0, 0]), "'nowhere'"),
        (lambda c: c.connect("N1", "N1", id="S9", kind="strut", z=[1, 0, 0]), "itself"),
        (lambda c: c.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0]), "duplicate connection"),
        (lambda c: c.connect("N1", "N2", id="S9", kind="strut", z=[1, 1, 0]), "unit vector"),
        (lambda c: c.connect("N1", "N2", id="S9", kind="strut", z=[1, 0]), "3 finite numbers"),
        (lambda c: c.edge("S42"), "no connection 'S42'"),
    ],
)
def test_bad_building_steps_raise_clear_errors(build, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        build(triangle())


def test_remove_module_removes_its_connections() -> None:
    c = triangle()
    c.remove_module("N1")
    assert set(c.edge_ids()) == {"S2"}
    assert "S4" not in c.modules()


def rebuilt(c: Configuration) -> Configuration:
    """``c`` built again vertex by vertex and edge by edge (the reference for derive)."""
    out = Configuration(c.robot, name=c.name, description=c.description)
    for v in c.vertices():
        out.add_module(v, c.kind_of(v), position=c.position(v))
    for e in c.edges():
        out.connect(e.source, e.target, id=e.id, kind=e.kind, z=e.z, x=e.x, ports=e.ports)
    return out


def shape(c: Configuration) -> tuple:
    """The networkx adjacency of ``c`` in both directions, with edge keys."""
    def side(adjacency) -> dict:
        return {u: {v: list(keys) for v, keys in nbrs.items()} for u, nbrs in adjacency.items()}
    return dict(c.graph.nodes(data="kind")), side(c.graph.succ), side(c.graph.pred)


def test_derive_builds_the_same_graph_as_building_step_by_step() -> None:
    c = triangle()
    c.add_module("N4", "node", position=[1.0, 2.0, 3.0])
    c.connect("N4", "N3", id="S5", kind="strut", z=[0, 1, 0], ports=("p", "q"))
    d = c.derive(vertices={"N1": "a"}, edges={"S2": "b2"}, reverse=["S5"])
    reference = rebuilt(d)
    assert d == reference
    assert shape(d) == shape(reference)
    assert list(d.edge_ids()) == ["S1", "b2", "S3", "S4", "S5"]       # order kept
    assert [e.id for e in d.incident("N3")] == [e.id for e in reference.incident("N3")]
    assert d.is_connected() and d.signature() == c.signature()
    d.disconnect("S5")
    d.remove_module("a")
    assert shape(d) == shape(rebuilt(d)) and list(d.graph.in_edges("N4")) == []
    assert c == rebuilt(c) and "S5" in c.edge_ids()                  # the original is untouched


def test_derive_turns_renames_replaces_and_rotates_in_that_order() -> None:
    c = triangle()
    quarter = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    d = c.derive(vertices={"N1": "a", "N2": "b"}, edges={"S1": "T"}, reverse=["S1"],
                 z={"S1": [0, 1, 0]}, rotation=quarter, name="turned")
    edge = d.edge("T")
    assert (edge.source, edge.target, d.name) == ("b", "a", "turned")
    np.testing.assert_allclose(edge.z, [1, 0, 0], atol=1e-15)        # quarter @ -[0, 1, 0]
    np.testing.assert_allclose(edge.x, [0, 0, 1], atol=1e-15)        # x is kept, then rotated
    assert d.edge("S2").z is None                                     # missing from z: None
    assert c.with_vectors(x={}) == c.skeletal() == c.derive(x={})
    assert c.relabel({"N1": "a"}) == c.derive(vertices={"N1": "a"})


def test_vectors_are_shared_read_only() -> None:
    c = triangle()
    d = c.copy()
    assert d.edge("S1").z is c.edge("S1").z
    with pytest.raises(ValueError, match="read-only"):
        d.edge("S1").z[0] = 2.0
    given = np.array([0.0, 0.0, 1.0])
    c.connect("N2", "v1", id="S6", kind="strut", z=given)
    given[2] = 5.0                                        # the caller's array stays theirs
    np.testing.assert_array_equal(c.edge("S6").z, [0, 0, 1])


@pytest.mark.parametrize(
    ("derive", "message"),
    [
        (lambda c: c.derive(vertices={"N1": "N2"}), "duplicate module id.*'N2'"),
        (lambda c: c.derive(edges={"S1": "N1"}), "duplicate module id.*'N1'"),
        (lambda c: c.derive(reverse=["S9"]), "unknown connection.*'S9'"),
        (lambda c: c.derive(z={"S1": [2, 0, 0]}), "z of S1 must be a unit vector"),
    ],
)
def test_bad_derivations_raise_clear_errors(derive, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        derive(triangle())


def test_union_of_disjoint_parts_keeps_ids_unless_taken() -> None:
    a = Configuration("mmrp")
    a.add_module("1", "mmrp")
    a.add_module("2", "mmrp")
    a.connect("1", "2", id="e", ports=("T", "B"))
    b = a.relabel({"1": "3", "2": "4"})
    whole = Configuration.union([a, b], robot="mmrp", name="two")
    assert whole.name == "two" and sorted(whole.vertices()) == ["1", "2", "3", "4"]
    assert whole.edge("e").source == "1" and whole.edge("3T-4B").source == "3"
    assert not whole.is_connected()
    with pytest.raises(ConfigurationError, match="duplicate module id"):
        Configuration.union([a, a], robot="mmrp")


@pytest.mark.parametrize("vector", [[0.0, 0.0, 2.0], [0.0, float("nan"), 1.0]])
def test_files_and_code_check_vectors_the_same_way(vector) -> None:
    """One unit-vector check (``configuration.unit``) behind files and ``connect``."""
    with pytest.raises(ConfigurationError) as in_code:
        triangle().connect("N1", "N2", id="S9", kind="strut", z=vector)
    data = {"schema_version": 1, "robot": "tiny",
            "modules": [{"id": "a", "kind": "cube"}, {"id": "b", "kind": "cube"}],
            "connections": [{"source": "a", "target": "b", "z": vector}]}
    with pytest.raises(ConfigurationError) as in_file:
        parse_configuration(data, "f.json")
    if all(np.isfinite(vector)):
        assert in_file.value.field == "connections[0].z"
        assert in_code.value.message in str(in_file.value)
    else:  # file models refuse a non-finite number itself, naming its index (issue 11)
        assert in_file.value.field == "connections[0].z[1]"
        assert "finite number" in in_file.value.message and "finite" in in_code.value.message


def test_a_read_only_array_is_still_checked() -> None:
    long = np.array([0.0, 0.0, 2.0])
    long.flags.writeable = False
    with pytest.raises(ConfigurationError, match="unit vector"):
        triangle().derive(z={"S1": long})
