"""The timeline plugin writes a recording that rerun's reader gives back; ``platform run``
end to end on the tiny robot."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import rerun.blueprint as rrb
from click.testing import CliRunner
from tiny_robot import (
    CUBE,
    NAME,
    SPEC,
    GoalController,
    LinkRecognizer,
    PointDriver,
    installed,
    make_run,
    swap_plan,
)

from msrr.core import (
    Configuration,
    ModuleKind,
    MsrrError,
    PortSpec,
    RobotDefaults,
    RobotSpec,
    hookimpl,
    plugins,
)
from msrr.core.app.cli import get_cli
from msrr.core.driver import ModuleCommand, Observation, Pose
from msrr.core.events import ActionStatus, Phase, Run, RunResult, Tick
from msrr.core.executor import Executor
from msrr.core.plan import Action, ActionType, ConnectionChange, Plan, load_plan
from msrr.core.robot import DEFAULT_HALF_SIZE, body_half_size
from msrr.core.timeline import read_recording, summarize_recording
from msrr.core.timeline import recorder as recorder_module
from msrr.core.timeline.blueprint import build_blueprint, camera_eye
from msrr.core.timeline.geometry import body_of
from msrr.core.timeline.recorder import CONNECTOR_COLORS, TimelineRecorder


def _record(path: Path) -> Path:
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        assert path.with_name(path.name + ".part").exists() and not path.exists()
        result = Executor(run, driver, LinkRecognizer(), GoalController(), sink=plugins.emit).execute()
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


# -- what the viewer shows: bodies of every shape, connectors, graphs, gaps, layout ----

NODE = ModuleKind("node", "N", "vertex", geometry={"radius": 0.05})
STRUT = ModuleKind("strut", "S", "edge", ports=(PortSpec("a"), PortSpec("b")),
                   geometry={"length": 0.2, "radius": 0.02})
TRUSS = RobotSpec("truss", "Truss (FreeSN-like)", (STRUT, NODE))


def _truss(docked: bool) -> Configuration:
    """Nodes n1, n2 0.2 m apart along x; strut s on n1 (end a), its end b on n2 or free."""
    config = Configuration("truss")
    config.add_module("n1", "node")
    config.add_module("n2", "node")
    if not docked:
        config.add_virtual("s:b")
    config.connect("n1", "n2" if docked else "s:b", id="s", kind="strut", z=(1.0, 0.0, 0.0))
    config.connect("n2", "n1", id="t", kind="strut", z=(-1.0, 0.0, 0.0))
    return config


def _truss_ticks(path: Path) -> Path:
    """A connection of the truss logged tick by tick: end b of strut s extends, docks."""
    free, docked = _truss(False), _truss(True)
    action = Action(ActionType.CONNECTION, docked, modules=("s",),
                    changes=(ConnectionChange("s", "n2", "b", None, "s"),))
    plan = Plan("truss", "test", free, docked, [action])
    run = Run("truss", "connect", plan, TRUSS, recording=path)
    recorder = TimelineRecorder(run)
    h = np.sqrt(0.5)  # the truss lies along world +y (its vectors say +x): turned 90 deg
    poses = {"n1": Pose.planar(1.0, 2.0, 0.0, 0.05), "n2": Pose.planar(1.0, 2.2, 0.0, 0.05),
             "s": Pose(np.array([1.0, 2.1, 0.05]), np.array([-h, 0.0, 0.0, h])),
             "t": Pose(np.array([1.0, 2.1, 0.05]), np.array([h, 0.0, 0.0, h]))}
    recorder.action(action, ActionStatus.STARTED)
    for index, (config, command) in enumerate([
            (free, {"s": ModuleCommand(joints={"b.dir_x": 1.0}, dock=("b",))}),
            (docked, {"s": ModuleCommand(joints={"b.dir_x": 1.0})}),
            (docked, {})]):
        recorder.tick(Tick(index, 0.1 * (index + 1), 0, action, Phase.CONNECT,
                           Observation(0.1 * index, None, tracked=poses), config, command,
                           {"s": 0.01} if command else {}))
    recorder.action(action, ActionStatus.SUCCEEDED)
    recorder.finish(RunResult(True, actions_done=1, actions_total=1, docks=1))
    return path


@pytest.fixture(scope="module")
def truss_rows(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return read_recording(_truss_ticks(tmp_path_factory.mktemp("truss") / "run.rrd")).rows


def test_nodes_are_spheres_and_struts_capsules_between_the_sphere_surfaces(truss_rows) -> None:
    node = truss_rows["/world/modules/n1"][0]
    assert node.values["Ellipsoids3D:half_sizes"] == [pytest.approx([0.05] * 3)]
    strut = truss_rows["/world/modules/s"][0]
    assert strut.tick is None
    # ends 0.1 m from the centre, inset by the node radius 0.05: from z -0.05 to +0.05
    assert strut.values["Capsules3D:lengths"] == [pytest.approx(0.1)]
    assert strut.values["Capsules3D:translations"] == [pytest.approx([0.0, 0.0, -0.05])]
    assert strut.values["Capsules3D:radii"] == [pytest.approx(0.02)]
    assert body_of(STRUT).shape == "capsule" and body_of(CUBE).shape == "box"


def test_connectors_show_extending_then_docked(truss_rows) -> None:
    rows = [r for r in truss_rows["/world/modules/s/connectors"] if r.tick is not None]
    assert [r.values["Points3D:labels"] for r in rows] == [
        ["a: docked to n1", "b: extending"], ["a: docked to n1", "b: docked to n2"]]
    packed = [(c >> 24, (c >> 16) & 255, (c >> 8) & 255) for c in rows[0].values["Points3D:colors"]]
    assert packed == [CONNECTOR_COLORS["docked"], CONNECTOR_COLORS["extending"]]


def test_docked_count_counts_each_strut_end(truss_rows) -> None:
    counts = [r.values["Scalars:scalars"][0] for r in truss_rows["/topology/connections"]
              if r.tick is not None]  # the static row styles the line
    assert counts == [3.0, 4.0]  # s on n1, t on both; then s docks its end b too


def test_idle_ticks_log_one_nan_so_plots_break(truss_rows) -> None:
    def values(path: str) -> list[tuple[int, float]]:
        return [(r.tick, r.values["Scalars:scalars"][0]) for r in truss_rows[path]]

    # strut s is commanded at ticks 0 and 1, idle at 2: one NaN there, nothing after
    for path in ("/commands/s/b/dir_x", "/errors/s"):
        found = values(path)
        assert [t for t, _ in found] == [0, 1, 2], path
        assert all(np.isfinite(v) for _, v in found[:2]) and np.isnan(found[2][1]), path


def test_ghost_target_is_laid_out_on_the_robot(truss_rows) -> None:
    ghost = next(r for r in truss_rows["/world/ghost/nodes"] if r.tick == 0)
    centers = np.array(ghost.values["Ellipsoids3D:centers"])
    assert centers == pytest.approx(np.array([[1.0, 2.0, 0.05], [1.0, 2.2, 0.05]]), abs=1e-6)
    strut = next(r for r in truss_rows["/world/ghost/struts"] if r.tick == 0).values
    assert strut["Capsules3D:lengths"] == pytest.approx([0.1, 0.1])  # surface to surface
    assert [r.tick for r in truss_rows["/world/ghost"]] == [2]  # cleared when it succeeded


def test_graph_nodes_keep_their_place_and_edges_carry_labels(tmp_path: Path) -> None:
    rows = read_recording(_record(tmp_path / "run.rrd"), "/topology").rows
    graphs = [r for p in ("/topology/current", "/topology/target") for r in rows[p]]
    assert len(graphs) >= 4
    seen: dict[str, tuple[float, float]] = {}
    for graph in graphs:
        ids, positions = graph.values["GraphNodes:node_ids"], graph.values["GraphNodes:positions"]
        for node, position in zip(ids, positions, strict=True):
            if not node.startswith("edge:"):
                assert seen.setdefault(node, tuple(position)) == pytest.approx(tuple(position))
    assert {"a", "b", "c"} <= set(seen)
    first = rows["/topology/current"][0].values
    assert "T-B" in first["GraphNodes:labels"]  # the ports, on the label node mid-edge


def test_blueprint_has_a_top_view_for_a_planar_robot_and_plugin_views() -> None:
    plugin_view = rrb.TimeSeriesView(name="Plugin panel", origin="commands")
    planar = _views(build_blueprint(make_run(swap_plan()), planar=True, extra=[plugin_view]))
    assert ("Spatial2DView", "Top view (y up)") in planar
    assert ("TimeSeriesView", "Plugin panel") in planar
    assert not any(kind == "Spatial2DView" for kind, _ in _views(build_blueprint()))


def _views(blueprint: rrb.Blueprint) -> list[tuple[str, str]]:
    """``(view class, name)`` of every view in ``blueprint``."""
    found, stack = [], [blueprint.root_container]
    while stack:
        item = stack.pop()
        if isinstance(item, rrb.Container):
            stack.extend(item.contents)
        else:
            found.append((type(item).__name__, str(item.name)))
    return found


def test_a_planar_robot_records_the_top_view(tmp_path: Path) -> None:
    plan = swap_plan()
    run = replace(make_run(plan, recording=tmp_path / "run.rrd"),
                  spec=replace(SPEC, defaults=RobotDefaults(planar=True)))
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController(), sink=plugins.emit).execute()
        plugins.emit.run_end(run, result)
    rows = read_recording(tmp_path / "run.rrd", "/top").rows
    static, first = rows["/top/modules"][:2]
    assert static.tick is None and static.values["LineStrips2D:labels"] == ["a", "b", "c"]
    outline = first.values["LineStrips2D:strips"]
    assert len(outline) == 3 and len(outline[0]) == 5  # three closed rectangles
    xs = sorted(p[0] for p in outline[0])
    assert xs[-1] - xs[0] == pytest.approx(0.4)  # the cube's 0.4 m length


def test_hook_msrr_timeline_views(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sent: list = []

    class Panels:
        @hookimpl
        def msrr_timeline_views(self, run, register) -> None:
            register(rrb.TimeSeriesView(name=f"{run.robot} panel", origin="commands"))
            register("not a view")

    monkeypatch.setattr(recorder_module, "build_blueprint",
                        lambda *a, **k: sent.append(k["extra"]) or build_blueprint(*a, **k))
    with plugins.temporary(Panels()):
        _record(tmp_path / "run.rrd")
    assert [[str(v.name) for v in extra] for extra in sent] == [[f"{NAME} panel"]]
    log = read_recording(tmp_path / "run.rrd", "/events/actions").rows["/events/actions"]
    left_out = [r.values["TextLog:text"][0] for r in log if "left out" in r.values["TextLog:text"][0]]
    assert left_out == ["msrr_timeline_views: left out a str (not a rerun.blueprint view or "
                        "container)"]


def test_camera_looks_at_the_middle_of_the_modules_from_above() -> None:
    points = [np.array([0.0, 0.0, 0.0]), np.array([2.0, 1.0, 0.1]), np.array([1.0, -1.0, 0.0])]
    eye, target = camera_eye(points)
    assert target == pytest.approx([1.0, 0.0, 0.05])
    size = float(np.linalg.norm([2.0, 2.0, 0.1]))  # the bounding box diagonal
    assert np.linalg.norm(eye - target) == pytest.approx(1.8 * size)
    assert eye[2] - target[2] > 0.6 * np.linalg.norm(eye - target)  # from well above
