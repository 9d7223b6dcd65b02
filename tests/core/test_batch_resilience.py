"""Batch commands that survive a lost worker, a SIGKILL and a Ctrl-C (issue 27).

Each test runs ``platform`` in a process of its own, as a lab does, and kills what a lab
loses: a pool worker in the middle of an edge, the command itself, the command at
Ctrl-C. Linux only (the processes are found in ``/proc``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from batch_tasks import alive, command_line, cpu_seconds, descendants, pool_workers
from click.testing import CliRunner

from msrr.core.app.cli import get_cli

pytestmark = pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")

ROOT = Path(__file__).resolve().parents[2]
LIBRARIES = ROOT / "plugins" / "freesn" / "libraries"
# S6N3's longest edges (0.4-1.3 s of CPU each) and three short ones: the workers start
# with the longest, so a worker past 0.1 s of CPU is in the middle of an edge
EDGES = ("S6N3-1.2->S6N3-1.1", "S6N3-2.2->S6N3-2.3", "S6N3-2.3->S6N3-2.2",
         "S6N3-4.1->S6N3-4.2", "S6N3-4.2->S6N3-4.1", "S6N3-2.3->S6N3-3.1",
         "S6N3-3.1->S6N3-4.2", "S6N3-4.2->S6N3-3.1")
CHECK = ["library", "check", "S6N3.json", "--seed", "0"] + [a for e in EDGES for a in ("--edge", e)]
PLATFORM = [sys.executable, "-c", "import sys; from msrr.core.app.launch import main; "
            "sys.argv[0] = 'platform'; main()"]


def _platform(args: list[str], cwd: Path, **options: object) -> subprocess.Popen[str]:
    return subprocess.Popen([*PLATFORM, *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, **options)  # type: ignore[call-overload]


def _kill_a_worker_in_an_edge(process: subprocess.Popen[str]) -> int:
    """SIGKILL the first pool worker of ``process`` seen 0.1 s of CPU into its work."""
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[0]
        for worker in pool_workers(process.pid):
            if cpu_seconds(worker) > 0.1:
                os.kill(worker, signal.SIGKILL)
                return worker
        time.sleep(0.02)
    raise AssertionError("no worker started an edge in two minutes")


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A copy of S6N3 and of its shipped check file (the 'old' check file)."""
    for name in ("S6N3.json", "S6N3.check.json"):
        (tmp_path / name).write_bytes((LIBRARIES / name).read_bytes())
    return tmp_path


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The check file of the same edges, uninterrupted, in this process."""
    place = tmp_path_factory.mktemp("reference")
    (place / "S6N3.json").write_bytes((LIBRARIES / "S6N3.json").read_bytes())
    args = [*CHECK, "--workers", "1"]
    args[2] = str(place / "S6N3.json")
    result = CliRunner().invoke(get_cli(), args)
    assert result.exit_code == 0, result.output
    return (place / "S6N3.check.json").read_text()


def test_a_killed_worker_costs_one_retry_of_its_edge(folder, reference):
    process = _platform([*CHECK, "--workers", "2"], folder)
    _kill_a_worker_in_an_edge(process)
    out, _ = process.communicate(timeout=120)
    assert process.returncode == 0, out
    assert "the worker was killed by SIGKILL; ran it again" in out
    assert (folder / "S6N3.check.json").read_text() == reference
    assert not (folder / "S6N3.check.json.journal").exists()


def test_a_killed_worker_without_retries_fails_the_check_and_resume_finishes_it(folder,
                                                                                reference):
    old = (folder / "S6N3.check.json").read_text()
    process = _platform([*CHECK, "--workers", "2", "--retries", "0"], folder)
    _kill_a_worker_in_an_edge(process)
    out, _ = process.communicate(timeout=120)
    assert process.returncode == 1, out
    lines = out.strip().splitlines()
    failed = [line for line in lines if " failed: WorkerLost: the worker was killed by SIGKILL "
              "(1 attempt)" in line]
    assert len(failed) == 1 and failed[0].startswith("edge S6N3:")
    assert lines[-1].startswith("Error: 1 of 8 edges failed to run (S6N3:")
    assert "not recorded as infeasible; S6N3.check.json is unchanged" in lines[-1]
    assert (folder / "S6N3.check.json").read_text() == old  # the old check file is kept
    journal = (folder / "S6N3.check.json.journal").read_text()
    assert journal.count('"result"') == 7 and journal.count('"error"') == 1
    assert '"feasible":false' not in journal  # nothing infeasible because of the kill
    resumed = _platform([*CHECK, "--workers", "2", "--resume"], folder)
    out, _ = resumed.communicate(timeout=120)
    assert resumed.returncode == 0, out
    assert "resuming: 7 of 8 edges from S6N3.check.json.journal" in out
    assert (folder / "S6N3.check.json").read_text() == reference
    assert not (folder / "S6N3.check.json.journal").exists()


def test_sigkill_of_the_command_leaves_no_process_of_it(folder):
    process = _platform([*CHECK, "--workers", "2", "-o", "killed.check.json"], folder)
    try:
        deadline = time.monotonic() + 120.0
        while len(pool_workers(process.pid)) < 2:  # the forkserver and both workers are up
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        started = descendants(process.pid)
        process.kill()
        process.wait(timeout=10)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and any(alive(p) for p in started):
            time.sleep(0.1)
        assert [command_line(p) for p in started if alive(p)] == []
    finally:
        process.kill()
        process.communicate()


SWEEP = ["sweep", "--robot", "mmrp", "--scenario", "series-t", "--driver", "kinematic",
         "--runs", "120", "--seed", "3", "--out", "sweep"]


def test_ctrl_c_keeps_every_finished_run_and_resume_finishes_the_sweep(tmp_path):
    reference = CliRunner().invoke(get_cli(), [*SWEEP[:-1], str(tmp_path / "reference"),
                                               "--workers", "1"])
    assert reference.exit_code == 0, reference.output
    journal = tmp_path / "sweep" / "sweep.csv.journal"
    process = _platform([*SWEEP, "--workers", "2"], tmp_path)
    deadline = time.monotonic() + 120.0
    while not journal.exists() or journal.read_text().count("\n") < 10:
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    out, _ = process.communicate(timeout=60)
    assert process.returncode == 130, out
    last = out.strip().splitlines()[-1]
    assert last.startswith("Error: interrupted (SIGINT): ")
    assert last.endswith("runs kept in sweep/sweep.csv.journal: continue with --resume "
                         "--out sweep")
    assert not (tmp_path / "sweep" / "sweep.csv").exists()
    again = _platform([*SWEEP, "--workers", "2"], tmp_path)
    out, _ = again.communicate(timeout=60)
    assert again.returncode == 1 and "continue it with --resume" in out  # never overwritten
    resumed = _platform([*SWEEP, "--workers", "2", "--resume"], tmp_path)
    out, _ = resumed.communicate(timeout=120)
    assert resumed.returncode == 0, out
    assert (tmp_path / "sweep" / "sweep.csv").read_text() == \
        (tmp_path / "reference" / "sweep.csv").read_text()
    assert not journal.exists()
