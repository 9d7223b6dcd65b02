"""Issue 30, item 7: counts are bounded where they are parsed (a sequence behavior's
loops, durations, distances, deadlines, plan files), and a second signal ends the process
at once with one line whatever the clean-up is doing."""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from msrr.core.app.cli import get_cli
from msrr.core.app.run import RunRequest
from msrr.core.errors import ConfigurationError
from msrr.core.scenario import MAX_LOOPS, Stage

HERE = Path(__file__).parent


@pytest.mark.parametrize("option, value, says", [
    ("--loops", "18446744073709551616", "--loops: must be a whole number in [1, 1000]"),
    ("--loops", "1000000", "--loops: must be a whole number in [1, 1000]"),
    ("--loops", "0", "--loops: must be a whole number in [1, 1000]"),
    ("--duration", "1e300", "--duration: must be a number in (0, 604800]"),
    ("--distance", "1e9", "--distance: must be a number in (0, 10000]"),
])
def test_a_huge_count_is_refused_where_it_is_parsed(tmp_path: Path, option: str, value: str,
                                                    says: str) -> None:
    started = time.monotonic()
    result = CliRunner().invoke(get_cli(), ["run", "--robot", "freesn", "--scenario",
                                            "fig19-crawl", "--behavior", "crawl", option, value,
                                            "--out", str(tmp_path / "run")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and lines[0].startswith(f"Error: {says}")
    assert time.monotonic() - started < 30 and not (tmp_path / "run").exists()


@pytest.mark.parametrize("field, value", [("deadline", 1e300), ("action_timeout", 1e12)])
def test_times_of_a_run_are_bounded(field: str, value: float) -> None:
    with pytest.raises(ConfigurationError, match="must be at most 604800"):
        RunRequest(robot="tiny", **{field: value}).check()


@pytest.mark.parametrize("seed", [-1, 2**32, 18446744073709551616, True])
def test_the_seed_of_a_run_is_in_numpys_range(seed: int) -> None:
    with pytest.raises(ConfigurationError, match=r"--seed: must be a whole number in \[0, "
                                                 r"4294967295\]"):
        RunRequest(robot="tiny", seed=seed).check()
    RunRequest(robot="tiny", seed=2**32 - 1).check()


def test_a_stage_takes_at_most_max_loops() -> None:
    assert Stage(behavior="crawl", loops=MAX_LOOPS).loops == MAX_LOOPS
    for loops in (MAX_LOOPS + 1, 2**64, True, 1.5):
        with pytest.raises(ConfigurationError, match="loops"):
            Stage(behavior="crawl", loops=loops)  # type: ignore[arg-type]


def test_a_plan_file_with_huge_loops_is_refused(tmp_path: Path) -> None:
    from msrr.core import plugins
    from msrr.core.app.run import _configurations, plan_stages
    from msrr.core.plan import save_plan

    capabilities = plugins.capabilities("freesn")
    _, start, stages = _configurations(RunRequest(robot="freesn", scenario="fig19-crawl",
                                                  behavior="crawl", loops=2))
    plan = plan_stages(capabilities, capabilities.planner(None), start, stages)
    path = tmp_path / "plan.json"
    save_plan(plan, path)
    plugins.load_plan(path)
    doc = json.loads(path.read_text())
    for value in (MAX_LOOPS + 1, 18446744073709551616):
        bad = copy.deepcopy(doc)
        last = bad["actions"][-1]
        last["behavior"]["loops"] = value
        path.write_text(json.dumps(bad))
        with pytest.raises(ConfigurationError, match=r"behavior\.loops"):
            plugins.load_plan(path)


def test_a_second_signal_ends_a_slow_clean_up_at_once(tmp_path: Path) -> None:
    """The tiny robot's run pauses 30 s while its driver disconnects (the clean-up of a
    finished run): the first SIGINT waits for it, the second ends the process at once."""
    marker = tmp_path / "marker"
    env = {**os.environ, "MSRR_TEST_PAUSE": "disconnect", "MSRR_TEST_MARKER": str(marker),
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    process = subprocess.Popen(
        [sys.executable, str(HERE / "tiny_cli.py"), "run", "--robot", "tiny", "--driver",
         "recording", "--out", str(tmp_path / "out"), "--no-log"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 60
        while not marker.exists():
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < end, "the run never reached its clean-up"
            time.sleep(0.01)
        process.send_signal(signal.SIGINT)
        time.sleep(0.3)
        assert process.poll() is None  # the first one waits for the clean-up
        sent = time.monotonic()
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=20)
    finally:
        if process.poll() is None:
            process.kill()
    assert time.monotonic() - sent < 10
    assert process.returncode == 143
    assert stderr.strip().splitlines() == [
        "Error: a second signal (SIGTERM): stopped at once; what was written is kept (a "
        "half-written file is named *.part or .*.tmp)"]
