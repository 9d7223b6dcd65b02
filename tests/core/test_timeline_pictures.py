"""The pictures are right (issue 25, item 3): the target outline at the robot's scale and
place, a behavior's target moving with the robot, legends per robot, flows on the
connections plot, legible labels, and ``platform snapshot --at/--action``.

Recordings are made by feeding ticks to the recorder (a robot of balls like FreeBOT, a
truss like FreeSN) or by running the tiny robot, the hinge example (the generic
kinematic driver) and, once, FreeBOT in MuJoCo (about 5 s).
"""

from __future__ import annotations

import importlib.util
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from test_timeline import TRUSS, _truss_ticks
from tiny_robot import GoalController, LinkRecognizer, PointDriver, make_run, swap_plan

from msrr.core import Configuration, ModuleKind, PortSpec, RobotSpec, plugins
from msrr.core.app.cli import get_cli
from msrr.core.driver import ModuleCommand, Observation, Pose
from msrr.core.events import ActionStatus, Phase, Run, RunResult, Tick, TopologyEvent
from msrr.core.executor import Executor
from msrr.core.plan import Action, ActionType, BehaviorCall, ConnectionChange, Plan
from msrr.core.timeline import read_recording
from msrr.core.timeline.geometry import BodyPose, fit_layout, shape_layout
from msrr.core.timeline.recorder import TimelineRecorder
from msrr.core.timeline.snapshot import (
    Moment,
    legend_entries,
    load_track,
    pick_moment,
    render_snapshot,
)

RADIUS = 0.05
BALL = ModuleKind("ball", "B", "vertex", ports=(PortSpec("c"),), geometry={"radius": RADIUS})
BALLS = RobotSpec("balls", "Balls (FreeBOT-like)", (BALL,))


def _chain(*links: tuple[str, str, tuple[float, float, float]]) -> Configuration:
    """Balls b1..b4, each link a contact along its vector (no ports, as FreeBOT's)."""
    config = Configuration("balls")
    for m in ("b1", "b2", "b3", "b4"):
        config.add_module(m, "ball")
    for source, target, z in links:
        config.connect(source, target, z=z)
    return config


LINE = _chain(("b1", "b2", (1.0, 0.0, 0.0)), ("b2", "b3", (1.0, 0.0, 0.0)),
              ("b3", "b4", (1.0, 0.0, 0.0)))
"""Four balls in a row along the vectors' +x."""
BENT = _chain(("b1", "b2", (1.0, 0.0, 0.0)), ("b2", "b3", (1.0, 0.0, 0.0)),
              ("b4", "b3", (0.5, -math.sqrt(0.75), 0.0)))
"""b4 handed from b3's end to the side of b3, touching b2 too (a flow's target)."""


def _ball_poses(shift: float = 0.0, turn: float = math.pi / 2) -> dict[str, Pose]:
    """The line on the ground, turned ``turn`` about z (the vectors' +x is world +y) and
    moved ``shift`` along world x; the balls roll, so their headings say nothing."""
    c, s = math.cos(turn), math.sin(turn)
    return {f"b{i + 1}": Pose.planar(1.0 + shift + c * 2 * RADIUS * i,
                                     -0.5 + s * 2 * RADIUS * i, 1.3 * i, RADIUS)
            for i in range(4)}


def _record_balls(path: Path, actions: list[Action], poses_of_tick) -> Path:
    """Feed ``actions`` to the recorder, five ticks each, poses from ``poses_of_tick``."""
    plan = Plan("balls", "test", LINE, actions[-1].target, actions)
    recorder = TimelineRecorder(Run("balls", "test", plan, BALLS, recording=path))
    tick = 0
    for index, action in enumerate(actions):
        recorder.action(action, ActionStatus.STARTED)
        for _ in range(5):
            recorder.tick(Tick(tick, 0.1 * (tick + 1), index, action, Phase.MOVE,
                               Observation(0.1 * tick, None, tracked=poses_of_tick(tick)),
                               action.target, {}, {}))
            tick += 1
        recorder.action(action, ActionStatus.SUCCEEDED)
    recorder.finish(RunResult(True, actions_done=len(actions), actions_total=len(actions)))
    return path


def _ghost(rows: dict, tick: int) -> dict[str, np.ndarray]:
    """Target outline centres by module at ``tick`` (ghost nodes and boxes)."""
    found = {}
    for path, key in (("/world/ghost/nodes", "Ellipsoids3D"), ("/world/ghost/boxes", "Boxes3D")):
        for row in rows.get(path, []):
            if row.tick == tick and f"{key}:centers" in row.values:
                found.update(zip(row.values[f"{key}:labels"],
                                 np.array(row.values[f"{key}:centers"]), strict=True))
    return found


def _module_at(rows: dict, module: str, tick: int) -> np.ndarray:
    timed = [r for r in rows[f"/world/modules/{module}"]
             if r.tick is not None and r.tick <= tick and "Transform3D:translation" in r.values]
    return np.array(timed[-1].values["Transform3D:translation"][0])


# -- the target outline: the robot's scale, the robot's place -----------------------------


def test_layout_takes_module_sizes_from_the_geometry() -> None:
    balls = shape_layout(LINE, {"ball": BALL})
    gaps = [np.linalg.norm(balls[f"b{i + 1}"].position - balls[f"b{i}"].position)
            for i in (1, 2, 3)]
    assert gaps == pytest.approx([2 * RADIUS] * 3)  # touching spheres, not 1 m apart
    from tiny_robot import CUBE, chain
    cubes = shape_layout(chain(("a", "b"), ("b", "c")), {"cube": CUBE})
    assert cubes["b"].position - cubes["a"].position == pytest.approx([0.4, 0.0, 0.0])
    assert cubes["c"].position - cubes["b"].position == pytest.approx([0.4, 0.0, 0.0])
    from test_timeline import _truss
    truss = shape_layout(_truss(False), {k.name: k for k in TRUSS.module_kinds})
    assert truss["s:b"].position - truss["n1"].position == pytest.approx([0.2, 0.0, 0.0])


def test_layout_follows_the_vectors_not_the_positions_a_target_carries() -> None:
    """FreeSN's plan targets keep their start's positions (a flat star); the target's
    shape is in its vectors (struts tilted 40 deg down to the ground)."""
    config = Configuration("truss")
    config.add_module("n1", "node", position=(0.0, 0.0, 0.0))
    config.add_module("n2", "node", position=(0.2, 0.0, 0.0))
    down = (math.cos(math.radians(40)), 0.0, -math.sin(math.radians(40)))
    config.connect("n1", "n2", id="s", kind="strut", z=down)
    layout = shape_layout(config, {k.name: k for k in TRUSS.module_kinds})
    assert layout["n2"].position - layout["n1"].position == pytest.approx(0.2 * np.array(down))


def test_fit_puts_the_outline_on_the_part_already_in_place() -> None:
    """A flow's target (b4 beside b3) fitted onto the line: b1..b3 exactly where they
    are, b4 where it is going (touching b2 and b3), not a compromise between."""
    layout = shape_layout(BENT, {"ball": BALL})
    poses = {m: BodyPose(np.asarray(p.position), p.yaw) for m, p in _ball_poses().items()}
    placed = fit_layout(BENT, layout, poses, tolerance=RADIUS)
    for m in ("b1", "b2", "b3"):
        assert placed[m].position == pytest.approx(poses[m].position, abs=1e-9)
    for m in ("b2", "b3"):
        assert np.linalg.norm(placed["b4"].position - placed[m].position) == pytest.approx(
            2 * RADIUS)


def test_a_chain_of_boxes_is_not_turned_end_for_end_to_fit() -> None:
    """Two cubes whose target puts b in front of a, seen with b behind a: the outline
    keeps the modules' headings (boxes show theirs) instead of turning half a turn."""
    from tiny_robot import CUBE, chain
    target = chain(("a", "b"), modules="ab")
    layout = shape_layout(target, {"cube": CUBE})
    poses = {"a": BodyPose(np.array([0.0, 0.0, 0.05])), "b": BodyPose(np.array([-0.4, 0, 0.05]))}
    placed = fit_layout(target, layout, poses, oriented=["a", "b"])
    assert [placed[m].yaw for m in "ab"] == pytest.approx([0.0, 0.0])
    assert placed["b"].position[0] - placed["a"].position[0] == pytest.approx(0.4)


def test_recorded_outline_lies_on_the_balls(tmp_path: Path) -> None:
    action = Action(ActionType.MOVING, LINE, modules=("b1", "b2", "b3", "b4"))
    rows = read_recording(_record_balls(tmp_path / "run.rrd", [action],
                                        lambda tick: _ball_poses())).rows
    last = max(r.tick for r in rows["/world/modules/b1"] if r.tick is not None)
    for tick in (0, last):  # the action's target, then the run's goal at the end
        outline = _ghost(rows, tick)
        assert sorted(outline) == ["b1", "b2", "b3", "b4"]
        for module, centre in outline.items():
            assert np.linalg.norm(centre - _module_at(rows, module, tick)) < 1e-3, module


def test_hinge_outline_has_the_modules_length_and_ends_on_them(tmp_path: Path) -> None:
    """The hinge example: a robot described only by its modules (generic runtime)."""
    out = tmp_path / "hinge"
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "hinge", "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = read_recording(out / "run.rrd").rows
    drawn = [r for r in rows["/world/ghost/boxes"] if "Boxes3D:centers" in r.values]
    first = dict(zip(drawn[0].values["Boxes3D:labels"],
                     np.array(drawn[0].values["Boxes3D:centers"]), strict=True))
    assert np.linalg.norm(first["h2"] - first["h1"]) == pytest.approx(0.19)  # port to port
    last = drawn[-1].tick
    for module, centre in _ghost(rows, last).items():
        assert np.linalg.norm((centre - _module_at(rows, module, last))[:2]) < 1e-3, module


def test_tiny_robot_outline_uses_the_cube_size(tmp_path: Path) -> None:
    path = tmp_path / "run.rrd"
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController(),
                          sink=plugins.emit).execute()
        plugins.emit.run_end(run, result)
    rows = read_recording(path).rows
    ghost = _ghost(rows, max(r.tick for r in rows["/world/ghost/boxes"]))
    assert np.linalg.norm(ghost["c"] - ghost["b"]) == pytest.approx(0.4)  # 0.4 m cubes
    # fitted onto b and c (1 m apart: the point driver's modules are points)
    middle = (_module_at(rows, "b", 10**6) + _module_at(rows, "c", 10**6)) / 2
    assert ((ghost["b"] + ghost["c"]) / 2)[:2] == pytest.approx(middle[:2])


@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="needs MuJoCo")
def test_freebot_outline_within_02_m_of_the_modules_at_the_end(tmp_path: Path) -> None:
    """MuJoCo, about 5 s: ``platform run --robot freebot`` read back."""
    out = tmp_path / "freebot"
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "freebot", "--out", str(out)])
    assert result.exit_code == 0, result.output
    rows = read_recording(out / "run.rrd").rows
    last = max(r.tick for r in rows["/world/modules/F1"] if r.tick is not None)
    outline = _ghost(rows, last)
    assert len(outline) == 6
    for module, centre in outline.items():
        assert np.linalg.norm((centre - _module_at(rows, module, last))[:2]) < 0.2, module
    gaps = sorted(np.linalg.norm(a - b) for a, b in itertools.combinations(outline.values(), 2))
    assert gaps[0] == pytest.approx(0.1, abs=0.01)  # touching FreeBOT shells, 0.1 m across


# -- a behavior's target moves with the robot -----------------------------------------


def test_a_behaviors_target_follows_the_robot(tmp_path: Path) -> None:
    roll = BehaviorCall("roll", "mapping", parameters={"speed": 0.2}, duration=1.0)
    moving = Action(ActionType.BEHAVIOR, LINE, modules=("b1", "b2", "b3", "b4"), behavior=roll)
    still = Action(ActionType.MOVING, LINE, modules=("b1",))
    path = _record_balls(tmp_path / "run.rrd", [moving, still],
                         lambda tick: _ball_poses(shift=0.02 * tick))
    rows = read_recording(path).rows
    for tick in range(5):  # re-fitted every tick of the behavior: on the balls
        outline = _ghost(rows, tick)
        assert len(outline) == 4, tick
        for module, centre in outline.items():
            assert np.linalg.norm(centre - _module_at(rows, module, tick)) < 1e-3
    logged = {r.tick for r in rows["/world/ghost/nodes"] if "Ellipsoids3D:centers" in r.values}
    assert logged == {0, 1, 2, 3, 4, 5, 9}  # the moving action: once at its start; the end


def test_a_travelling_robot_is_drawn_in_windows_that_follow_it(tmp_path: Path) -> None:
    """A robot that drives 2 m: each panel is a window of one size centred on it."""
    roll = BehaviorCall("roll", "mapping", parameters={"speed": 0.2}, duration=1.0)
    moving = Action(ActionType.BEHAVIOR, LINE, modules=("b1", "b2", "b3", "b4"), behavior=roll)
    path = _record_balls(tmp_path / "run.rrd", [moving, moving, moving],
                         lambda tick: _ball_poses(shift=0.15 * tick))
    track = load_track(path)
    panels = [ax for ax in render_snapshot(track).axes if ax.get_aspect() == 1.0]
    widths = {round(ax.get_xlim()[1] - ax.get_xlim()[0], 9) for ax in panels}
    assert len(panels) == 4 and len(widths) == 1 and widths.pop() < 1.0  # not the 2.6 m run
    for ax, tick in zip(panels, sorted({0, 4, 9, 14}), strict=True):
        x, _, _ = track.pose("b1", tick)
        assert sum(ax.get_xlim()) / 2 == pytest.approx(x, abs=1e-6)  # the balls' middle


# -- legends ---------------------------------------------------------------------------


def test_legend_names_only_what_the_recording_draws(tmp_path: Path) -> None:
    balls = legend_entries(load_track(_record_balls(
        tmp_path / "balls.rrd", [Action(ActionType.MOVING, LINE, modules=("b1",))],
        lambda tick: _ball_poses())))
    assert balls[0] == "circle: ball (id)"
    text = "; ".join(balls)
    for foreign in ("port", "front", "orange extending", "goal pose", "box"):
        assert foreign not in text, foreign  # no MMRP faces, FreeSN struts or goals
    assert not any(entry.startswith("bar:") for entry in balls)
    truss = "; ".join(legend_entries(load_track(_truss_ticks(tmp_path / "truss.rrd"))))
    assert "circle: node" in truss and "bar: strut" in truss and "port" not in truss
    assert "black bar" not in truss  # struts are drawn as themselves


def test_legend_of_a_box_robot_with_goals(tiny_recording: Path) -> None:
    entries = legend_entries(load_track(tiny_recording))
    assert entries[:2] == ["box: cube (id, bold edge: front)", "red/blue dot: active/passive port"]
    assert any("goal pose" in e for e in entries) and not any("circle" in e for e in entries)


# -- flows -----------------------------------------------------------------------------


def test_a_flow_is_marked_on_the_connections_plot(tmp_path: Path) -> None:
    old, new = ConnectionChange("b4", "b3"), ConnectionChange("b4", "b2")
    target = _chain(("b1", "b2", (1.0, 0.0, 0.0)), ("b2", "b3", (1.0, 0.0, 0.0)),
                    ("b4", "b2", (0.0, -1.0, 0.0)))
    flow = Action(ActionType.FLOW, target, modules=("b4", "b3", "b2"), changes=(old, new))
    plan = Plan("balls", "test", LINE, target, [flow])
    path = tmp_path / "run.rrd"
    recorder = TimelineRecorder(Run("balls", "test", plan, BALLS, recording=path))
    recorder.action(flow, ActionStatus.STARTED)
    for tick, config in enumerate([LINE, LINE, target]):
        recorder.tick(Tick(tick, 0.1 * (tick + 1), 0, flow, Phase.HANDOVER,
                           Observation(0.1 * tick, None, tracked=_ball_poses()), config, {}, {}))
    for kind, change in (("undock", old), ("dock", new)):
        recorder.topology_change(TopologyEvent(kind, change, 2, 0.3, 0, True))
    recorder.action(flow, ActionStatus.SUCCEEDED)
    recorder.finish(RunResult(True, actions_done=1, actions_total=1, docks=1, undocks=1))
    rows = read_recording(path).rows
    assert [r.values["TextLog:text"][0] for r in rows["/events/flows"]] == [
        "flow b3-b4 -> b2-b4 at t=0.3 s"]
    assert [r.values["Scalars:scalars"] for r in rows["/topology/flows"] if r.tick is not None] \
        == [[3.0]]
    track = load_track(path)
    conn = render_snapshot(track).axes[-2]
    diamonds = [line for line in conn.get_lines() if line.get_marker() == "D"]
    assert len(diamonds) == 1 and list(diamonds[0].get_xdata()) == [pytest.approx(0.3)]
    assert any(t.get_text() == "b3-b4→b2-b4" for t in conn.texts)
    assert "purple: flow" in conn.get_title()


# -- labels ----------------------------------------------------------------------------


def _crowded(path: Path) -> Path:
    """18 modules: six nodes in a ring, six struts around it and six across it, two on
    each diameter (their middles, where the ids go, all at the centre)."""
    node = ModuleKind("node", "N", "vertex", geometry={"radius": 0.04})
    ring = ModuleKind("strut", "S", "edge", ports=(PortSpec("a"), PortSpec("b")),
                      geometry={"length": 0.2, "radius": 0.0125})
    across = ModuleKind("long", "L", "edge", ports=(PortSpec("a"), PortSpec("b")),
                        geometry={"length": 0.4, "radius": 0.0125})
    spec = RobotSpec("ring", "Ring", (ring, across, node))
    config = Configuration("ring")
    nodes = [f"n{i}" for i in range(6)]
    poses: dict[str, Pose] = {}
    for i, n in enumerate(nodes):
        config.add_module(n, "node")
        poses[n] = Pose.planar(0.2 * math.cos(i * math.pi / 3), 0.2 * math.sin(i * math.pi / 3),
                               0.0, 0.04)
    pairs = [(i, (i + 1) % 6, "strut") for i in range(6)]
    pairs += [(i % 3, i % 3 + 3, "long") for i in range(6)]
    for k, (i, j, kind) in enumerate(pairs):
        pa, pb = poses[nodes[i]].position, poses[nodes[j]].position
        d = (pb - pa) / np.linalg.norm(pb - pa)
        config.connect(nodes[i], nodes[j], id=f"s{k}", kind=kind, z=d)
        yaw = math.atan2(d[1], d[0])  # body z along d: a quarter turn about (-sin, cos, 0)
        h = math.sqrt(0.5)
        poses[f"s{k}"] = Pose((pa + pb) / 2, np.array([-h * math.sin(yaw), h * math.cos(yaw),
                                                       0.0, h]))
    action = Action(ActionType.MOVING, config, modules=tuple(nodes))
    recorder = TimelineRecorder(Run("ring", "crowded", Plan("ring", "t", config, config,
                                                            [action]), spec, recording=path))
    recorder.action(action, ActionStatus.STARTED)
    for tick in range(3):
        recorder.tick(Tick(tick, 0.1 * (tick + 1), 0, action, Phase.MOVE,
                           Observation(0.1 * tick, None, tracked=poses), config, {}, {}))
    recorder.action(action, ActionStatus.SUCCEEDED)
    recorder.finish(RunResult(True, actions_done=1, actions_total=1))
    return path


def test_labels_on_18_modules_do_not_cover_each_other(tmp_path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    track = load_track(_crowded(tmp_path / "run.rrd"))
    fig = render_snapshot(track)
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    panels = [ax for ax in fig.axes if ax.get_aspect() == 1.0]
    assert len(panels) == 3  # start, the middle tick, the end: two columns of wide panels
    assert panels[0].get_position().width * fig.get_figwidth() > 4.0
    for ax in panels:
        shown = [t for t in ax.texts if t.get_visible() and t.get_text()]
        assert {t.get_text() for t in shown} >= {f"n{i}" for i in range(6)}
        assert len(shown) >= 14  # most strut ids kept (moved beside if crowded)
        boxes = [t.get_window_extent(renderer) for t in shown]
        for a, b in itertools.combinations(range(len(boxes)), 2):
            assert not boxes[a].overlaps(boxes[b]), (shown[a].get_text(), shown[b].get_text())
        frame = ax.get_window_extent(renderer)
        for box in boxes:
            assert frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1


# -- one moment: --at and --action -------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("tiny") / "run.rrd"
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController(),
                          sink=plugins.emit).execute()
        plugins.emit.run_end(run, result)
    assert result.success and len(plan.actions) == 3
    return path


def test_pick_moment_by_time_and_by_action(tiny_recording: Path) -> None:
    track = load_track(tiny_recording)
    assert pick_moment(track) is None
    at = pick_moment(track, at=0.5)
    assert at.tick == max(t for t, time in track.times.items() if time <= 0.5)
    ends = [r for r in track.actions if r.values["TextLog:text"][0].startswith("action 2:")
            and "succeeded" in r.values["TextLog:text"][0]]
    end = pick_moment(track, action=2)
    assert (end.tick, end.at) == (ends[0].tick, ends[0].order)
    # the end of the moving action still shows its goal (cleared just after)
    assert track.action_text(end.at).startswith("2/3: move c -- succeeded")
    fig = render_snapshot(track, moment=end)
    panel = fig.axes[0]
    assert "end of action 2" in panel.get_title()
    dashed = [p for p in panel.patches if p.get_linestyle() == "--"]
    assert dashed, "the goal of action 2"
    assert len([ax for ax in fig.axes if ax.get_aspect() == 1.0]) == 1
    assert Moment.of_tick(3).at[0] == 3


@pytest.mark.parametrize(("option", "message"), [
    (["--at", "99"], "Error: --at 99: outside the recording (simulated time 0.00 to "),
    (["--at", "-1"], "Error: --at -1: outside the recording"),
    (["--at", "nan"], "Error: --at nan: outside the recording"),
    (["--action", "0"], "Error: --action 0: the plan has 3 actions (1 to 3)"),
    (["--action", "4"], "Error: --action 4: the plan has 3 actions (1 to 3)"),
    (["--at", "1", "--action", "1"], "Error: --at and --action cannot be combined"),
])
def test_snapshot_refuses_a_moment_outside_the_recording(
        tiny_recording: Path, tmp_path: Path, option: list[str], message: str) -> None:
    image = tmp_path / "snap.png"
    result = CliRunner().invoke(get_cli(), ["snapshot", str(tiny_recording), "-o", str(image),
                                            *option])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), result.output
    assert not image.exists()


def test_snapshot_draws_the_chosen_moment(tiny_recording: Path, tmp_path: Path) -> None:
    for option in (["--at", "0.45"], ["--action", "3"]):
        image = tmp_path / f"{option[0][2:]}.png"
        result = CliRunner().invoke(get_cli(), ["snapshot", str(tiny_recording), "-o",
                                                str(image), *option])
        assert result.exit_code == 0, result.output
        assert image.stat().st_size > 10_000


def test_an_action_that_did_not_end_is_refused(tmp_path: Path) -> None:
    plan = swap_plan()
    path = tmp_path / "run.rrd"
    recorder = TimelineRecorder(make_run(plan, recording=path))
    action = plan.actions[0]
    recorder.action(action, ActionStatus.STARTED)
    recorder.tick(Tick(0, 0.1, 0, action, Phase.RELEASE,
                       Observation(0.0, None, tracked={m: Pose.planar(float(i), 0.0, 0.0)
                                                       for i, m in enumerate("abc")}),
                       plan.start, {"a": ModuleCommand(undock=("T",))}, {}))
    recorder.finish(RunResult(False, reason="stopped", actions_total=3))
    with pytest.raises(Exception, match=r"^--action 1: action 1 did not end in this "):
        pick_moment(load_track(path), action=1)
