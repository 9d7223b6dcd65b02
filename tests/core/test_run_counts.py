"""Counts are true on every way a run ends (issue: "every verdict, count and picture tells
the truth"): success, failure, the deadline, SIGINT, SIGTERM, a lost link, a driver's
exception. ``summary.json``'s docks, undocks, ticks and times are what the driver
reported, the same as the events every listener saw."""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest
import tiny_robot
from click.testing import CliRunner
from tiny_robot import installed

from msrr.core import ExecutionError, hookimpl, plugins
from msrr.core.app.cli import get_cli
from msrr.core.events import Run, Tick, TopologyEvent


class _Seen:
    """What a listener saw of the run, and a signal or a driver failure at one tick."""

    def __init__(self, signum: int | None = None, at: int = 3):
        self.signum, self.at = signum, at
        self.ticks = 0
        self.changes: list[str] = []

    @hookimpl
    def msrr_on_tick(self, run: Run, tick: Tick) -> None:
        self.ticks += 1
        if self.signum is not None and tick.index == self.at:
            os.kill(os.getpid(), self.signum)

    @hookimpl
    def msrr_on_topology_change(self, run: Run, change: TopologyEvent) -> None:
        self.changes.append(change.kind)


@pytest.fixture
def own_handlers() -> Iterator[None]:
    """``platform run`` installs its SIGINT/SIGTERM handlers; put pytest's back after."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for signum, handler in saved.items():
        signal.signal(signum, handler)


def _failing_step(error: Exception, after: float):
    step = tiny_robot.PointDriver.step

    def broken(self, dt: float) -> None:
        if self.time >= after:
            raise error
        step(self, dt)

    return broken


PATHS = {
    "success": ((), None, None, 0),
    "failure": (("--faults", "dock-fail:count=9", "--timeout", "0.3"), None, None, 1),
    "deadline": (("--deadline", "0.35"), None, None, 1),
    "SIGINT": ((), signal.SIGINT, None, 130),
    "SIGTERM": ((), signal.SIGTERM, None, 143),
    "link lost": ((), None, ExecutionError("module c: no report for 3 control periods"), 1),
    "driver exception": ((), None, RuntimeError("simulator diverged"), 1),
}


@pytest.mark.parametrize("path", sorted(PATHS))
def test_counts_are_what_the_driver_reported_on_every_way_out(
        path: str, tmp_path: Path, own_handlers: None, monkeypatch: pytest.MonkeyPatch) -> None:
    options, signum, error, code = PATHS[path]
    if error is not None:
        monkeypatch.setattr(tiny_robot.PointDriver, "step", _failing_step(error, 0.25))
    out = tmp_path / "out"
    seen = _Seen(signum)
    with installed(tmp_path), plugins.temporary(seen):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out),
                                                "--no-log", *options])
    assert result.exit_code == code, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["docks"], summary["undocks"]) == (seen.changes.count("dock"),
                                                      seen.changes.count("undock"))
    assert summary["ticks"] == seen.ticks > 0
    assert summary["sim_time_s"] > 0 and summary["wall_time_s"] > 0
    assert summary["success"] is (path == "success")
    if path != "success":
        assert summary["reason"] and summary["actions_done"] < summary["actions_total"]
    if path in ("SIGINT", "SIGTERM"):
        assert summary["interrupted"] == path


def test_default_deadlines_grow_by_what_a_phase_is_granted_up_to_a_week() -> None:
    from types import SimpleNamespace

    from msrr.core.app.run import WALL_FACTOR, _deadline_growth
    from msrr.core.faults import GuardedDriver
    from msrr.core.scenario import MAX_TIME

    guard = GuardedDriver(tiny_robot.PointDriver(), deadline=10.0, wall_deadline=100.0)
    grow = _deadline_growth(SimpleNamespace(deadline_grows=True, wall_deadline_grows=True),
                            guard)
    assert grow is not None
    grow(5.0)
    assert (guard.deadline, guard.wall_deadline) == (15.0, 100.0 + WALL_FACTOR * 5.0)
    grow(1e12)   # a controller that says it needs forever
    assert guard.deadline == MAX_TIME and guard.wall_deadline == MAX_TIME
    user_set = GuardedDriver(tiny_robot.PointDriver(), deadline=10.0, wall_deadline=100.0)
    only_wall = _deadline_growth(SimpleNamespace(deadline_grows=False,
                                                 wall_deadline_grows=True), user_set)
    assert only_wall is not None
    only_wall(5.0)
    assert user_set.deadline == 10.0 and user_set.wall_deadline == 200.0
    assert _deadline_growth(SimpleNamespace(deadline_grows=False, wall_deadline_grows=False),
                            user_set) is None
