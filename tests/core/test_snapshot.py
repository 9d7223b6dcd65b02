"""``platform snapshot`` draws a PNG of a run from its recording alone."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib.image
import pytest
from click.testing import CliRunner
from tiny_robot import GoalController, LinkRecognizer, PointDriver, make_run, swap_plan

from msrr.core import plugins
from msrr.core.cli import get_cli
from msrr.core.executor import Executor
from msrr.core.timeline.snapshot import load_track


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("run") / "run.rrd"
    plan = swap_plan()
    run = make_run(plan, recording=path)
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController()).execute()
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
