"""The timeline plugin writes a recording that rerun's reader gives back; ``platform run``
end to end on the tiny robot."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import (
    CUBE,
    NAME,
    GoalController,
    LinkRecognizer,
    PointDriver,
    installed,
    make_run,
    swap_plan,
)

from msrr.core import MsrrError, hookimpl, plugins
from msrr.core.cli import get_cli
from msrr.core.executor import Executor
from msrr.core.plan import load_plan
from msrr.core.robot import DEFAULT_HALF_SIZE, body_half_size
from msrr.core.timeline import read_recording, summarize_recording


def _record(path: Path) -> Path:
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        assert path.with_name(path.name + ".part").exists() and not path.exists()
        result = Executor(run, driver, LinkRecognizer(), GoalController()).execute()
        plugins.emit.run_end(run, result)
    assert result.success and result.docks == plan.docks == 1
    return path


def test_recording_has_entities_timelines_and_the_docks_that_happened(tmp_path: Path) -> None:
    recording = _record(tmp_path / "run.rrd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd"]
    summary = summarize_recording(recording)
    assert {"tick", "sim_time"} <= summary.timelines
    for entity in ["/world/modules/a", "/world/modules/a/faces", "/topology/current",
                   "/topology/target", "/action", "/plan", "/mapping", "/errors/c",
                   "/commands/c/v", "/events/actions", "/world/targets"]:
        assert entity in summary.rows, entity
    assert summary.rows["/events/docks"] == 1 and summary.rows["/events/undocks"] == 1
    rows = read_recording(recording).rows
    assert summary.rows == {entity: len(found) for entity, found in rows.items()}
    undock, = rows["/events/undocks"]
    assert undock.tick is not None and "undock aT-bB" in undock.values["TextLog:text"][0]


def test_bodies_and_faces_come_from_the_robot_spec(tmp_path: Path) -> None:
    rows = read_recording(_record(tmp_path / "run.rrd"), "/world/modules/a").rows
    body = next(r for r in rows["/world/modules/a"] if r.tick is None)
    assert body.values["Boxes3D:half_sizes"] == [pytest.approx([0.2, 0.1, 0.05])]
    faces, = rows["/world/modules/a/faces"]
    assert faces.values["Points3D:labels"] == ["T", "B"]
    assert faces.values["Points3D:positions"] == [pytest.approx([0.21, 0.0, 0.0]),
                                                  pytest.approx([-0.21, 0.0, 0.0])]


def test_body_half_size_reads_box_or_radius() -> None:
    assert body_half_size(CUBE) == (0.2, 0.1, 0.05)
    radius = type(CUBE)("ball", "B", "vertex", geometry={"radius": 0.07})
    assert body_half_size(radius) == (0.07, 0.07, 0.07)
    assert body_half_size(type(CUBE)("x", "X", "vertex")) == (DEFAULT_HALF_SIZE,) * 3


def test_reading_a_missing_or_foreign_file_is_one_error(tmp_path: Path) -> None:
    (tmp_path / "notes.rrd").write_text("not a recording\n")
    for path in (tmp_path / "missing.rrd", tmp_path / "notes.rrd"):
        with pytest.raises(MsrrError, match=str(path.name)):
            summarize_recording(path)


class _CountLookups:
    """Counts capability-hook calls; registers nothing."""

    def __init__(self) -> None:
        self.calls: dict[str, int] = {}

    def _count(self, hook: str) -> None:
        self.calls[hook] = self.calls.get(hook, 0) + 1

    @hookimpl
    def msrr_planners(self, robot, register):
        self._count("planners")

    @hookimpl
    def msrr_drivers(self, robot, register):
        self._count("drivers")

    @hookimpl
    def msrr_controllers(self, robot, register):
        self._count("controllers")

    @hookimpl
    def msrr_recognizers(self, robot, register):
        self._count("recognizers")


def test_platform_run_writes_plan_summary_and_recording_resolving_each_capability_once(
        tmp_path: Path) -> None:
    out = tmp_path / "out"
    with installed(tmp_path), plugins.temporary(_CountLookups()) as counter:
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert counter.calls == {"planners": 1, "drivers": 1, "controllers": 1, "recognizers": 1}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] and (summary["docks"], summary["undocks"]) == (1, 1)
    assert (summary["scenario"], summary["planner"], summary["driver"]) == ("swap", "line",
                                                                           "points")
    assert load_plan(out / "plan.json").docks == 1
    assert summarize_recording(out / "run.rrd").rows["/events/docks"] == 1


@pytest.mark.parametrize(("option", "what", "capability"), [
    (["--driver", "hardware"], "driver", plugins.drivers),
    (["--planner", "astar"], "planner", plugins.planners),
    (["--scenario", "dance"], "scenario", plugins.scenarios),
])
def test_platform_run_names_unknown_choices_and_writes_nothing(
        tmp_path: Path, option: list[str], what: str, capability: plugins.Capability) -> None:
    out = tmp_path / "out"
    with installed(tmp_path):
        known = ", ".join(sorted(capability(NAME)))
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out),
                                                *option])
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        f"Error: unknown {what} for robot 'tiny' {option[1]!r} (known: {known})"]
    assert not out.exists()
