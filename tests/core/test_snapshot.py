"""``platform snapshot`` draws a PNG of a run from its recording alone."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.patches import Circle
from test_timeline import _truss_ticks
from tiny_robot import NAME, GoalController, LinkRecognizer, PointDriver, make_run, swap_plan

from msrr.core import Configuration, plugins
from msrr.core.app.cli import get_cli
from msrr.core.executor import Executor
from msrr.core.timeline.geometry import capsule_between, palette, place_on, vector_layout
from msrr.core.timeline.snapshot import load_track, render_snapshot


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("run") / "run.rrd"
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController(), sink=plugins.emit).execute()
        plugins.emit.run_end(run, result)
    assert result.success
    return path


def test_track_reads_what_the_run_did(recording: Path) -> None:
    track = load_track(recording)
    assert track.modules == ["a", "b", "c"]
    assert track.half["a"] == pytest.approx((0.2, 0.1))  # the tiny robot's 0.4 x 0.2 m cube
    first, last = min(track.times), track.last_tick
    assert track.edges(first) == [("a", "b")] and track.edges(last) == [("b", "c")]
    assert track.pose("c", first)[0] == pytest.approx(2.0)
    assert [text.split(" at ")[0] for _, _, text in track.events] == ["undock aT-bB",
                                                                      "dock bT-cB"]


def test_snapshot_of_a_recorded_run(recording: Path, tmp_path: Path) -> None:
    image = tmp_path / "out" / "snap.png"
    result = CliRunner().invoke(get_cli(), ["snapshot", str(recording), "-o", str(image)])
    assert result.exit_code == 0, result.output
    pixels = matplotlib.image.imread(image)
    assert pixels.shape[0] > 400 and pixels.shape[1] > 800
    assert pixels[..., :3].std() > 0.05  # not a blank canvas
    assert [p.name for p in image.parent.iterdir()] == ["snap.png"]  # no temp file left
    mask = os.umask(0)
    os.umask(mask)
    assert image.stat().st_mode & 0o777 == 0o666 & ~mask  # not the temp file's 0o600


def test_bad_input_is_one_line_and_writes_nothing(tmp_path: Path) -> None:
    not_rrd = tmp_path / "notes.rrd"
    not_rrd.write_text("not a recording\n")
    for source in (tmp_path / "missing.rrd", not_rrd):
        image = tmp_path / "snap.png"
        result = CliRunner().invoke(get_cli(), ["snapshot", str(source), "-o", str(image)])
        assert result.exit_code == 1
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and str(source) in lines[0], result.output
        assert not image.exists()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.rrd"]


def test_title_names_robot_and_scenario(recording: Path) -> None:
    track = load_track(recording)
    assert track.title == f"{NAME}: test"
    fig = render_snapshot(track)
    assert fig._suptitle.get_text().splitlines()[0] == f"{NAME}: test"


def test_snapshot_draws_struts_and_counts_their_docked_ends(tmp_path: Path) -> None:
    track = load_track(_truss_ticks(tmp_path / "run.rrd"))
    assert track.shapes == {"n1": "sphere", "n2": "sphere", "s": "capsule", "t": "capsule"}
    first, last = min(track.times), track.last_tick
    assert (track.docked(first), track.docked(last)) == (3, 4)
    ends = track.capsule_ends("s", last)
    assert ends[0] == pytest.approx((1.0, 2.05)) and ends[1] == pytest.approx((1.0, 2.15))
    assert sorted(track.edges_with_ids(last)) == [("n1", "n2", "s"), ("n2", "n1", "t")]
    assert [label for label, _ in track.connector_states("s", first)] == [
        "a: docked to n1", "b: extending"]
    first_panel = render_snapshot(track).axes[0]
    circles = [p for p in first_panel.patches if isinstance(p, Circle)]
    solid = [c for c in circles if c.get_fill()]  # nodes and connectors; dashed: the ghost
    assert sorted(round(c.radius, 3) for c in solid) == [0.018] * 4 + [0.05, 0.05]
    nodes = sorted(c.center for c in solid if round(c.radius, 3) == 0.05)
    assert np.array(nodes) == pytest.approx(np.array([(1.0, 2.0), (1.0, 2.2)]), abs=1e-6)
    ghost = [c for c in circles if not c.get_fill()]
    assert np.array(sorted(c.center for c in ghost)) == pytest.approx(
        np.array([(1.0, 2.0), (1.0, 2.2)]), abs=1e-6)


def test_vector_layout_round_trips_positions() -> None:
    rng = np.random.default_rng(3)
    points = {f"v{i}": rng.normal(size=3) for i in range(5)}
    config = Configuration("x")
    for v in points:
        config.add_module(v, "node")
    for a, b in [("v0", "v1"), ("v1", "v2"), ("v1", "v3"), ("v4", "v3")]:
        d = points[b] - points[a]
        config.connect(a, b, kind="strut", id=f"{a}{b}", z=d / np.linalg.norm(d))
    lengths = {"strut": 1.0}
    layout = vector_layout(config, lengths)
    for a, b in [("v0", "v1"), ("v1", "v2"), ("v1", "v3"), ("v4", "v3")]:
        d = points[b] - points[a]
        assert layout[b] - layout[a] == pytest.approx(d / np.linalg.norm(d))
    turned = {v: np.array([-p[1], p[0], p[2]]) + [3.0, -1.0, 0.5] for v, p in layout.items()}
    placed = place_on(layout, turned)  # a planar rigid motion is undone exactly
    for v in layout:
        assert placed[v] == pytest.approx(turned[v])


def test_capsule_between_and_palette() -> None:
    a, b = np.array([1.0, 2.0, 0.0]), np.array([1.0, 2.0, 0.0]) + [0.3, -0.4, 0.0]
    t, q, length = capsule_between(a, b)
    x, y, z, w = q
    tip = t + length * np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    assert length == pytest.approx(0.5) and tip == pytest.approx(b)
    colors = palette(30)
    assert len(set(colors)) == 30
