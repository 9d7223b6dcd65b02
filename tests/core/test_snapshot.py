"""``platform snapshot`` draws a PNG of a run from its recording alone."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import matplotlib.image
from fake_run import GoalController, LinkRecognizer, PointDriver, make_run, swap_plan

from msrr.core import plugins
from msrr.core.executor import Executor
from msrr.core.timeline.snapshot import load_track

PLATFORM = [sys.executable, "-c", "from msrr.core.cli import main; main()"]


def _record(tmp_path: Path) -> Path:
    plan = swap_plan()
    run = make_run(plan, recording=tmp_path / "run.rrd",
                   ports={"mmrp": {"T": ((1.0, 0.0, 0.0), "active"),
                                   "B": ((-1.0, 0.0, 0.0), "passive")}})
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        result = Executor(run, driver, LinkRecognizer(), GoalController()).execute()
        plugins.emit.run_end(run, result)
    assert result.success
    return tmp_path / "run.rrd"


def test_snapshot_of_a_recorded_run(tmp_path: Path) -> None:
    recording = _record(tmp_path)
    track = load_track(recording)
    assert track.modules and track.last_tick > 0 and track.topology
    image = tmp_path / "out" / "snap.png"
    proc = subprocess.run([*PLATFORM, "snapshot", str(recording), "-o", str(image)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    assert image.stat().st_size > 20_000
    pixels = matplotlib.image.imread(image)
    assert pixels.shape[0] > 400 and pixels.shape[1] > 800
    assert pixels[..., :3].std() > 0.05  # not a blank canvas
    assert [p.name for p in image.parent.iterdir()] == ["snap.png"]  # no temp file left


def test_bad_input_is_one_line_and_writes_nothing(tmp_path: Path) -> None:
    not_rrd = tmp_path / "notes.rrd"
    not_rrd.write_text("not a recording\n")
    for source in (tmp_path / "missing.rrd", not_rrd):
        image = tmp_path / "snap.png"
        proc = subprocess.run([*PLATFORM, "snapshot", str(source), "-o", str(image)],
                              capture_output=True, text=True, check=False)
        assert proc.returncode == 1
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and str(source) in lines[0], proc.stderr
        assert "Traceback" not in proc.stderr
        assert not image.exists()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.rrd"]
