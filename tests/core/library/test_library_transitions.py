"""Action types from connector-end topology changes (paper section 4.1)."""

from __future__ import annotations

import pytest

from msrr.core import Configuration, ConfigurationError
from msrr.core.library import ModuleMap, action_type, topology_changes
from msrr.core.plan import ActionType


def triangle(docked: set[str], free_names: dict[str, str] | None = None) -> Configuration:
    """Triangle N1 N2 N3 with legs S4 (N1), S5 (N2); a docked leg reaches the next node."""
    names = free_names or {}
    config = Configuration("freesn")
    for n in ("N1", "N2", "N3"):
        config.add_module(n, "node")
    for sid, s, t in (("S1", "N1", "N2"), ("S2", "N2", "N3"), ("S3", "N3", "N1")):
        config.connect(s, t, id=sid, kind="strut", z=[1, 0, 0])
    for sid, s, t in (("S4", "N1", "N2"), ("S5", "N2", "N3")):
        if sid not in docked:
            t = names.get(sid, f"{sid}:b")
            config.add_virtual(t)
        config.connect(s, t, id=sid, kind="strut", z=[0, 1, 0])
    return config


@pytest.mark.parametrize(("before", "after", "expected"), [
    (set(), set(), ActionType.MOVING),
    (set(), {"S4"}, ActionType.CONNECTION),
    ({"S4"}, set(), ActionType.DISCONNECTION),
    (set(), {"S4", "S5"}, ActionType.PARALLEL_CONNECTION),
    ({"S4", "S5"}, set(), ActionType.PARALLEL_DISCONNECTION),
])
def test_action_types(before, after, expected):
    assert action_type(triangle(before), triangle(after)) is expected


def test_renamed_free_connector_is_not_a_change():
    assert not topology_changes(triangle(set()), triangle(set(), {"S4": "elsewhere"}))


def test_connect_and_disconnect_in_one_step_is_refused():
    with pytest.raises(ConfigurationError, match="intermediate configuration"):
        action_type(triangle({"S4"}), triangle({"S5"}))


def test_flow_is_a_connector_sliding_to_another_module():
    after = triangle({"S4"})
    after.disconnect("S4")
    after.connect("N1", "N3", id="S4", kind="strut", z=[0, 1, 0])
    assert action_type(triangle({"S4"}), after) is ActionType.FLOW


def test_mapping_is_followed_through_inverted_edges():
    before, after = triangle(set()), triangle({"S4"})
    flipped = after.copy()
    flipped.disconnect("S4")
    flipped.connect("N2", "N1", id="X", kind="strut", z=[0, -1, 0])
    mapping = ModuleMap({n: n for n in ("N1", "N2", "N3")},
                        {"S1": ("S1", False), "S2": ("S2", False), "S3": ("S3", False),
                         "S4": ("X", True), "S5": ("S5", False)})
    changes = topology_changes(before, flipped, mapping)
    assert changes.connections == (("S4", False),)
    assert not changes.disconnections and not changes.flows
