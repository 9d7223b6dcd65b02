"""Action detection from topology differences (FreeSN section 4.1)."""

from __future__ import annotations

import pytest
from config_strategies import configuration_pairs, configurations, random_map
from hypothesis import given, settings
from hypothesis import strategies as st

from msrr.core import Configuration
from msrr.core.actions import classify, detect_action, detect_actions, topology_diff
from msrr.core.errors import PlanningError
from msrr.core.events import Phase
from msrr.core.executor import phases_of
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


def test_a_face_swap_is_one_parallel_connection_that_releases_first() -> None:
    """a-b, c-d -> a-d, c-b: two connections broken and two made in one action. Section 4.1's
    parallel action sends the disconnections, then the connections; no leaf flows."""
    before = chain(("1", "T", "2", "B"), ("3", "T", "4", "B"), ("2", "T", "3", "B"))
    after = chain(("1", "T", "4", "B"), ("3", "T", "2", "B"), ("2", "T", "3", "B"))
    action = detect_action(before, after)
    assert action.type is ActionType.PARALLEL_CONNECTION
    assert [str(c) for c in action.changes] == ["1T-2B", "3T-4B", "1T-4B", "2B-3T"]
    diff = topology_diff(before, after)
    assert phases_of(action, diff) == [Phase.RELEASE, Phase.APPROACH, Phase.CONNECT]


def test_changing_faces_between_the_same_two_modules_is_a_parallel_connection() -> None:
    """MMRP paper, Table 4: undock 7 Left-3 Right, dock 7 Bottom-3 Top."""
    before = chain(("7", "L", "3", "R"), modules="37")
    after = chain(("7", "B", "3", "T"), modules="37")
    assert classify(before, after) is ActionType.PARALLEL_CONNECTION
    assert classify(chain(modules="37"), after) is ActionType.CONNECTION


@settings(max_examples=80, deadline=None)
@given(config=configurations)
def test_nothing_changes_between_a_configuration_and_itself(config) -> None:
    assert not topology_diff(config, config)
    assert classify(config, config) is ActionType.MOVING


@settings(max_examples=80, deadline=None)
@given(pair=configuration_pairs())
def test_the_diff_applied_to_the_start_gives_the_target_topology(pair) -> None:
    before, after = pair
    diff = topology_diff(before, after)
    assert not topology_diff(diff.applied_to(before), after)
    halfway = diff.applied_to(before, made=False)
    assert topology_diff(halfway, after).made == diff.made
    assert not topology_diff(halfway, after).broken


@settings(max_examples=80, deadline=None)
@given(pair=configuration_pairs(), seed=st.integers(0, 2**32 - 1))
def test_classification_does_not_depend_on_ids(pair, seed) -> None:
    """Relabelling both sides consistently, or passing the relabelling as the mapping,
    gives the same diff sizes and the same action type."""
    before, after = pair
    mapping = random_map(before, seed)
    expected = classify(before, after)
    renamed_before, _ = mapping.apply(before)
    renamed_after, _ = mapping.apply(after)
    assert classify(renamed_before, renamed_after) is expected
    assert classify(before, renamed_after, mapping) is expected
    diff, renamed = topology_diff(before, after), topology_diff(before, renamed_after, mapping)
    assert (len(diff.made), len(diff.broken)) == (len(renamed.made), len(renamed.broken))
