"""Paths and collections shared by tests in several folders (imported by name)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import networkx as nx

from msrr.core import plugins
from msrr.core.actions import classify
from msrr.core.plan import ActionType

ROOT = Path(__file__).resolve().parents[1]


def load_script(path: Path, name: str) -> ModuleType:
    """The script at ``path`` (a benchmark, a generator) run as module ``name``, kept in
    ``sys.modules`` (dataclasses it defines resolve their own module)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = sys.modules.setdefault(name, importlib.util.module_from_spec(spec))
    spec.loader.exec_module(module)
    return module


def control_until_reached(controller, action, phase, driver, ticks: int, dt: float = 0.1):
    """Tick ``controller``'s ``phase`` of ``action`` on ``driver`` (its commands sent, ``dt``
    [s] a tick) until it is reached or ``ticks`` have passed; the last
    :class:`~msrr.core.control.Control`."""
    for _ in range(ticks):
        control = controller.control(action, phase, driver.get_observation())
        if control.reached:
            break
        driver.send_action(control.commands)
        driver.step(dt)
    return control


BUILTIN_ROBOTS = ("freebot", "freesn", "mmrp", "snailbot")
"""The robots this repository ships; each ships at least one configuration file."""


def installed_robots() -> list[str]:
    """Every installed robot: built-in, the example, and any third-party plugin."""
    return list(plugins.robots())


def shipped_configurations() -> list[Path]:
    """Every configuration file shipped with a built-in robot plugin or the example."""
    files = sorted((ROOT / "plugins").glob("*/configs/*.json"))
    return files + sorted((ROOT / "examples").glob("*/*/configs/*.json"))


def brute_force_cost(sub, start: str, target: str) -> float | None:
    """The cheapest path cost in a sub-library by enumerating every simple path of its
    edge list (the reference for retrieval's Dijkstra)."""
    graph = nx.MultiDiGraph()
    graph.add_nodes_from(sub.configurations)
    for edge in sub.edges:
        graph.add_edge(edge.source, edge.target, cost=edge.cost)
    costs = [sum(graph.edges[e]["cost"] for e in path)
             for path in nx.all_simple_edge_paths(graph, start, target)]
    return min(costs, default=None)


def check_sequence(system, steps, robot) -> None:
    """Retrieved steps are in the system's ids, legal for ``robot`` (its rules and its
    action rules), of the action type their topology says, and each carries the tree
    of the configuration it moves in (the source for connections, else the target)."""
    before = system
    for step in steps:
        assert set(step.target.modules()) == set(system.modules())
        assert robot.rules.check(step.target) == []
        assert robot.rules.check_action(before, step.target) == []
        assert classify(before, step.target) is step.action
        moves_in = before if step.action in (ActionType.CONNECTION,
                                             ActionType.PARALLEL_CONNECTION) else step.target
        assert sorted(step.tree.configuration.vertices()) == sorted(moves_in.vertices())
        before = step.target
