"""One answer through every public path (issue 10): the S6N3 library's action edges,
relabelled (edges reversed) and perturbed, classified by the one topology diff."""

from __future__ import annotations

import numpy as np
import pytest

from msrr.core import Configuration, plugins
from msrr.core.actions import classify, detect_action, topology_diff
from msrr.core.library import load_library
from msrr.core.library.retrieve import retrieve
from msrr.core.mapping import ModuleMap
from msrr.core.plan import ActionType

from library_helpers import LIBRARIES

FREESN = plugins.resolve("freesn")
S6N3 = load_library(LIBRARIES / "S6N3.json")
(SUB,) = S6N3.sublibraries.values()


def scrambled(config: Configuration, seed: int) -> ModuleMap:
    """Every module of ``config`` renamed, every second strut reversed."""
    rng = np.random.default_rng(seed)
    nodes = config.vertices(virtual=False)
    edges = config.edge_ids()
    return ModuleMap({v: f"m{i}" for i, v in zip(rng.permutation(len(nodes)), nodes,
                                                  strict=True)},
                     {e: (f"s{i}", i % 2 == 1) for i, e in zip(rng.permutation(len(edges)), edges,
                                                              strict=True)})


def perturbed(config: Configuration, seed: int, noise: float = 0.05) -> Configuration:
    rng = np.random.default_rng(seed)
    z = {}
    for edge in config.edges():
        v = edge.z + rng.normal(scale=noise, size=3)
        z[edge.id] = v / np.linalg.norm(v)
    return config.derive(z=z)


@pytest.mark.parametrize("index", range(len(SUB.edges)))
def test_every_library_edge_has_one_action_type(index):
    edge = SUB.edges[index]
    before = SUB.configurations[edge.source].configuration
    after = SUB.configurations[edge.target].configuration
    forward = edge.module_map(before)
    expected = edge.action
    assert classify(before, after, forward) is expected                  # the library's path
    in_before_ids, _ = forward.inverse().apply(after)                      # map/apply path
    assert classify(before, in_before_ids) is expected
    assert classify(after, before, forward.inverse()) is _reverse(expected)
    names = scrambled(before, index)                                       # a system's own ids
    system_before = perturbed(names.apply(before)[0], index)
    system_after = perturbed(names.apply(in_before_ids)[0], index + 1)
    assert classify(system_before, system_after) is expected
    assert detect_action(system_before, system_after).type is expected
    assert classify(before, system_after, names) is expected
    diff = topology_diff(before, in_before_ids)
    assert not topology_diff(diff.applied_to(before), in_before_ids)


def _reverse(action: ActionType) -> ActionType:
    return {ActionType.CONNECTION: ActionType.DISCONNECTION,
            ActionType.DISCONNECTION: ActionType.CONNECTION,
            ActionType.PARALLEL_CONNECTION: ActionType.PARALLEL_DISCONNECTION,
            ActionType.PARALLEL_DISCONNECTION: ActionType.PARALLEL_CONNECTION}.get(action, action)


def test_retrieved_actions_carry_the_type_their_topology_says():
    _, start = S6N3.find_configuration("fig20a")
    names = scrambled(start.configuration, 7)
    system = perturbed(names.apply(start.configuration)[0], 7)
    result = retrieve(S6N3, system, FREESN, to="fig20d")
    actions = result.actions(system)
    before = system
    for step, action in zip([*result.steps], actions, strict=True):
        assert action.type is step.action is classify(before, step.target)
        assert set(action.changes) == set(topology_diff(before, step.target).changes())
        before = step.target
    assert ActionType.CONNECTION in {a.type for a in actions}
