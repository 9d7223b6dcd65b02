"""Action detection from topology differences (FreeSN section 4.1)."""

from __future__ import annotations

import pytest

from msrr.core import Configuration
from msrr.core.actions import classify, detect_action, detect_actions, topology_diff
from msrr.core.errors import PlanningError
from msrr.core.plan import ActionType


def chain(*links: tuple[str, str, str, str], modules: str = "1234") -> Configuration:
    config = Configuration("mmrp")
    for m in modules:
        config.add_module(m, "mmrp")
    for u, fu, v, fv in links:
        config.connect(u, v, ports=(fu, fv))
    return config


SERIES = [("1", "T", "2", "B"), ("2", "T", "3", "B"), ("3", "T", "4", "B")]


def test_same_topology_is_moving_even_with_reversed_edges() -> None:
    flipped = chain(("2", "B", "1", "T"), ("2", "T", "3", "B"), ("4", "B", "3", "T"))
    assert not topology_diff(chain(*SERIES), flipped)
    assert classify(chain(*SERIES), flipped) is ActionType.MOVING


def test_one_broken_is_disconnection_and_one_made_is_connection() -> None:
    full, cut = chain(*SERIES), chain(*SERIES[:2])
    assert classify(full, cut) is ActionType.DISCONNECTION
    assert classify(cut, full) is ActionType.CONNECTION
    action = detect_action(full, cut)
    assert [str(c) for c in action.changes] == ["3T-4B"]
    assert set(action.modules) == {"3", "4"}


def test_several_changes_are_parallel() -> None:
    full, two = chain(*SERIES), chain(SERIES[0])
    assert classify(full, two) is ActionType.PARALLEL_DISCONNECTION
    assert classify(two, full) is ActionType.PARALLEL_CONNECTION
    swapped = chain(SERIES[0], SERIES[1], ("2", "L", "4", "R"))
    assert classify(full, swapped) is ActionType.FLOW  # leaf 4 leaves 3 for 3's neighbour 2
    far = chain(("4", "T", "1", "B"), SERIES[1], SERIES[0])
    assert classify(full, far) is ActionType.PARALLEL_CONNECTION  # 4 is not a neighbour's


def test_ports_matter() -> None:
    other_face = chain(SERIES[0], SERIES[1], ("3", "R", "4", "L"))
    diff = topology_diff(chain(*SERIES), other_face)
    assert [str(c) for c in diff.made] == ["3R-4L"] and [str(c) for c in diff.broken] == ["3T-4B"]


def test_sequences_and_module_mismatch() -> None:
    steps = [chain(*SERIES), chain(*SERIES[:2]), chain(*SERIES)]
    assert [a.type for a in detect_actions(steps)] == [ActionType.DISCONNECTION,
                                                        ActionType.CONNECTION]
    with pytest.raises(PlanningError, match="modules differ"):
        detect_action(chain(*SERIES), chain(modules="123"))
