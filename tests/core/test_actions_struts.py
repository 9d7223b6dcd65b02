"""Action detection for connections that are modules (FreeSN struts), end by end."""

from __future__ import annotations

import pytest

from msrr.core import Configuration
from msrr.core.actions import classify, detect_action
from msrr.core.plan import ActionType


def base() -> Configuration:
    """Three nodes; S1 joins N1-N2, S2 hangs from N1 with a free end, S3 hangs from N2."""
    c = Configuration("freesn")
    for n in ("N1", "N2", "N3"):
        c.add_module(n, "node")
    c.add_virtual("v2")
    c.add_virtual("v3")
    c.connect("N1", "N2", id="S1", kind="strut", z=[1, 0, 0])
    c.connect("N1", "v2", id="S2", kind="strut", z=[0, 1, 0])
    c.connect("N2", "v3", id="S3", kind="strut", z=[0, 1, 0])
    c.connect("N3", "N2", id="S4", kind="strut", z=[0, 0, 1])
    return c


def rewired(*changes: tuple[str, str, str]) -> Configuration:
    """``base()`` with strut ``edge`` re-attached from ``source`` to the given target."""
    c = base()
    for edge_id, source, target in changes:
        old = c.disconnect(edge_id)
        if target.startswith("v") and target not in c:
            c.add_virtual(target)
        c.connect(source, target, id=edge_id, kind="strut", z=old.z)
        if old.target.startswith("v") and c.degree(old.target) == 0:
            c.remove_module(old.target)
    return c


CASES = {
    "moving": (base(), ActionType.MOVING),
    "free end docks": (rewired(("S2", "N1", "N3")), ActionType.CONNECTION),
    "end leaves a node": (rewired(("S1", "N1", "v9")), ActionType.DISCONNECTION),
    # nodes are joined through struts, never directly: no node is a neighbour of another,
    # so an end moving between nodes releases and docks (section 4.1 flows are FreeBOT's
    # and SnailBot's)
    "end moves to another node": (rewired(("S4", "N3", "N1")), ActionType.PARALLEL_CONNECTION),
    "two free ends dock": (rewired(("S2", "N1", "N3"), ("S3", "N2", "N3")),
                           ActionType.PARALLEL_CONNECTION),
    "two ends leave": (rewired(("S1", "N1", "v8"), ("S4", "N3", "v9")),
                       ActionType.PARALLEL_DISCONNECTION),
}


@pytest.mark.parametrize("case", CASES)
def test_strut_ends_are_compared_one_by_one(case: str) -> None:
    after, expected = CASES[case]
    assert classify(base(), after) is expected


def test_a_docking_strut_end_is_one_change() -> None:
    action = detect_action(base(), rewired(("S2", "N1", "N3")))
    assert [str(c) for c in action.changes] == ["N3-S2b"]  # ends in natural order
