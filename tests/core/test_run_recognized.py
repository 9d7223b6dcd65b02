"""A run recognizes and matches itself (issue 32, item 3): the plan it executes (and
writes) starts from the configuration the recognizer reports at the first tick, not from
the start file, which only places the modules (refusals of bad input before the run
folder exists are tests/core/test_bad_input.py's, unchanged)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

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

