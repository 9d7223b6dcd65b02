"""The Configuration model: building, views, signature, relabelling, errors."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core import VIRTUAL, Configuration, ConfigurationError, plugins


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
