"""The timeline plugin writes a recording that rerun's own tooling reads back."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from fake_run import GoalController, LinkRecognizer, PointDriver, make_run, swap_plan

from msrr.core import plugins
from msrr.core.executor import Executor
from msrr.core.timeline import summarize_recording


def test_recording_has_entities_timelines_and_the_docks_that_happened(tmp_path: Path) -> None:
    plan = swap_plan()
    run = make_run(plan, recording=tmp_path / "run.rrd",
                   ports={"mmrp": {"T": ((1.0, 0.0, 0.0), "active"),
                                   "B": ((-1.0, 0.0, 0.0), "passive")}})
    with PointDriver() as driver:
        driver.reset(plan.start)
        plugins.emit.run_start(run)
        assert (tmp_path / "run.rrd.part").exists() and not (tmp_path / "run.rrd").exists()
        result = Executor(run, driver, LinkRecognizer(), GoalController()).execute()
        plugins.emit.run_end(run, result)
    assert result.success
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd"]
    verify = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify",
                             str(tmp_path / "run.rrd")], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stderr
    summary = summarize_recording(tmp_path / "run.rrd")
    assert {"tick", "sim_time"} <= summary.timelines
    for entity in ["/world/modules/a", "/world/modules/a/faces", "/topology/current",
                   "/topology/target", "/action", "/plan", "/mapping", "/errors/c",
                   "/commands/c/v", "/events/actions", "/world/targets"]:
        assert entity in summary.rows, entity
    assert summary.rows["/events/docks"] == plan.docks == result.docks == 1
    assert summary.rows["/events/undocks"] == plan.undocks == 1

