"""A run recognizes and matches itself (issue 32, item 3): the plan it executes (and
writes) starts from the configuration the recognizer reports at the first tick, not from
the start file, which only places the modules (refusals of bad input before the run
folder exists are tests/core/test_bad_input.py's, unchanged)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
from tiny_robot import PointDriver, chain, installed

from msrr.core.app.run import RunRequest, execute_run, prepare_run, write_outputs
from msrr.core.configuration import Configuration
from msrr.core.io import save_configuration


class Misplaced(PointDriver):
    """The modules are not as the start file says: b and c are docked, a is apart."""

    def reset(self, start: Configuration) -> None:
        super().reset(chain(("b", "c"), name=start.name))


def _request(tmp_path: Path, goal: Configuration) -> RunRequest:
    start, goal_path = tmp_path / "start.json", tmp_path / "goal.json"
    save_configuration(chain(("a", "b"), name="ab"), start)
    save_configuration(goal, goal_path)
    return RunRequest(robot="tiny", start=start, goal=goal_path, out=tmp_path / "run", log=False)


def test_the_plan_starts_from_what_the_modules_report(tmp_path):
    with installed():
        prepared = prepare_run(_request(tmp_path, chain(("b", "c"), name="bc")))
        assert len(prepared.run.plan.actions) == 3     # from the file: undock, move, dock
        prepared = replace(prepared, driver=Misplaced)
        result = execute_run(prepared)
        write_outputs(prepared.run, result)
    assert result.success, result.reason
    plan = prepared.run.plan                           # from recognition: nothing to do
    assert plan.actions == [] and result.actions_total == 0
    assert {(e.source, e.target) for e in plan.start.edges()} == {("b", "c")}
    written = json.loads((tmp_path / "run" / "plan.json").read_text())
    assert written["actions"] == [] and "recognized" in written["start"]["description"]



class Counting:
    """The planner, counting its calls."""

    def __init__(self, planner):
        self.planner, self.calls = planner, 0
        self.name, self.description = planner.name, planner.description

    def plan(self, start, goal, *, seed=0):
        self.calls += 1
        return self.planner.plan(start, goal, seed=seed)


def test_the_file_plan_runs_when_the_modules_are_as_it_started(tmp_path):
    with installed():
        prepared = prepare_run(_request(tmp_path, chain(("b", "c"), name="bc")))
        made = prepared.run.plan
        prepared = replace(prepared, planner=Counting(prepared.planner))
        result = execute_run(prepared)
    assert result.success, result.reason
    assert prepared.planner.calls == 0 and prepared.run.plan is made  # recognized == file
    assert len(made.actions) == 3 and result.actions_total == 3


def test_the_run_plans_again_when_the_modules_are_not_as_the_plan_started(tmp_path):
    with installed():
        prepared = prepare_run(_request(tmp_path, chain(("b", "c"), name="bc")))
        prepared = replace(prepared, driver=Misplaced, planner=Counting(prepared.planner))
        result = execute_run(prepared)
    assert result.success, result.reason
    assert prepared.planner.calls == 1 and prepared.run.plan.actions == []


def test_same_state_sets_only_connection_labels_aside():
    a = chain(("a", "b"), ("b", "c"), name="one")
    ids = [e.id for e in a.edges()]
    relabelled = a.derive(reverse=ids[:1], edges={ids[0]: "x"}, name="other",
                          description="as recognized")  # another direction and id
    assert a.same_state(relabelled) and relabelled.same_state(a) and a != relabelled
    ports = chain(("a", "b"), name="one")
    ports.connect("b", "c", ports=("T", "T"))
    assert not a.same_state(ports)                            # another face
    assert not a.same_state(chain(("a", "b"), name="one"))    # a connection fewer

    def placed(height):
        config = Configuration(a.robot)
        for m, d in a.graph.nodes(data=True):
            config.add_module(m, d["kind"], position=(0.0, 0.0, height if m == "a" else 0.0))
        return config
    assert placed(0.0).same_state(placed(0.0)) and not placed(0.0).same_state(placed(1e-6))
    up = a.with_vectors(z={i: (0, 0, 1) for i in ids})
    assert up.same_state(up.copy()) and not up.same_state(a.with_vectors(
        z={i: (0, 0, -1) for i in ids}))                      # a vector
    assert not up.same_state(up.derive(reverse=ids[:1]))      # a vector's direction


def test_same_state_within_a_resolution_and_without_the_labs_positions():
    a = chain(("a", "b"), ("b", "c"), name="one")
    ids = [e.id for e in a.edges()]
    turned = {i: (np.sin(0.0872), np.cos(0.0872), 0.0) for i in ids}

    def laid(z, position=(1.0, 2.0, 0.05)):
        config = Configuration(a.robot)
        for m, d in a.graph.nodes(data=True):
            config.add_module(m, d["kind"], position=position if m == "a" else None)
        for e in a.edges():
            config.connect(e.source, e.target, ports=e.ports, z=z[e.id])
        return config
    file = laid({i: tuple(round(c, 12) for c in v) for i, v in turned.items()})  # as saved
    seen = laid(turned, position=None)                   # as reported: no positions
    assert not seen.same_state(file)                     # exactly: positions and rounding
    assert seen.same_state(file, tolerance=1e-9, positions=False)
    assert not seen.same_state(file, tolerance=1e-9)     # positions count by default
    bent = laid({**turned, ids[0]: (np.sin(0.09), np.cos(0.09), 0.0)}, position=None)
    assert not bent.same_state(file, tolerance=1e-9, positions=False)   # 0.16 deg off
    assert not laid(turned, position=(1.0, 2.0 + 1e-6, 0.05)).same_state(
        file, tolerance=1e-9)


def test_the_file_plan_runs_when_only_the_file_says_where_the_modules_lie(tmp_path):
    with installed():
        request = _request(tmp_path, chain(("b", "c"), name="bc"))
        start = chain(("a", "b"), name="ab")
        laid = Configuration(start.robot, name="ab")
        for m, d in start.graph.nodes(data=True):
            laid.add_module(m, d["kind"], position=(0.5, 0.0, 0.0) if m == "a" else None)
        for e in start.edges():
            laid.connect(e.source, e.target, ports=e.ports)
        save_configuration(laid, request.start)
        prepared = prepare_run(request)
        made = prepared.run.plan
        prepared = replace(prepared, planner=Counting(prepared.planner))
        result = execute_run(prepared)
    assert result.success, result.reason
    assert prepared.planner.calls == 0 and prepared.run.plan is made   # the lab's placement
