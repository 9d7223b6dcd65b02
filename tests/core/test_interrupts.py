"""SIGINT and SIGTERM sent to a real ``platform run`` subprocess (the tiny robot) at
several moments, and SIGKILL: one line naming what was interrupted, exit 130 / 143,
the modules told to stop and then disconnected, and a complete folder (a recording
rerun verifies under its final name, ``plan.json``, ``summary.json`` with
``success: false`` and the reason). The subprocess waits at each moment (it writes a
marker file first), so where the signal lands does not depend on timing."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import LinePlanner, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.cli import get_cli
from msrr.core.events import ActionStatus, Run, Tick
from msrr.core.interrupts import SIGNALS
from msrr.core.plan import Action, load_plan
from msrr.core.timeline import read_recording

HERE = Path(__file__).parent
RERUN = shutil.which("rerun", path=str(Path(sys.executable).parent))


def _start(tmp_path: Path, pause: str, *args: str) -> tuple[subprocess.Popen, Path]:
    marker = tmp_path / "marker"
    marker.unlink(missing_ok=True)
    env = {**os.environ, "MSRR_TEST_PAUSE": pause, "MSRR_TEST_MARKER": str(marker),
           "MSRR_TEST_CALLS": str(tmp_path / "calls.txt"),
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    process = subprocess.Popen(
        [sys.executable, str(HERE / "tiny_cli.py"), "run", "--robot", "tiny", "--driver",
         "recording", "--planner", "pausing", "--out", str(tmp_path / "out"), *args],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return process, marker


def _wait_for(process: subprocess.Popen, marker: Path) -> None:
    """Until the subprocess reached its pause (bounded: a failure, never a hang)."""
    end = time.monotonic() + 30
    while not marker.exists():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < end, "the subprocess never reached its pause"
        time.sleep(0.01)


def _verify(recording: Path) -> None:
    if RERUN is not None:
        done = subprocess.run([RERUN, "rrd", "verify", str(recording)], capture_output=True,
                              text=True, timeout=60)
        assert done.returncode == 0, done.stderr
    else:
        assert read_recording(recording).rows


def _check_interrupted(folder: Path, process: subprocess.Popen, signum: int, where: str) -> None:
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + signum, stderr
    name = signal.Signals(signum).name
    out = folder / "out"
    assert stderr.strip().splitlines() == [f"Error: {where} ({name}); wrote {out}"], stderr
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] is False and summary["reason"] == f"{where} ({name})"
    assert summary["interrupted"] == name
    assert len(load_plan(out / "plan.json").actions) == 3
    _verify(out / "run.rrd")
    calls = (folder / "calls.txt").read_text().split()
    assert calls[-2:] == ["stop", "disconnect"]


def _check_killed(folder: Path, process: subprocess.Popen) -> None:
    process.communicate(timeout=60)
    out = folder / "out"
    assert sorted(p.name for p in out.iterdir()) == ["run.rrd.part"]  # no final name
    with installed(folder):
        refused = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out)])
        assert refused.exit_code == 1
        assert refused.output.strip().splitlines() == [
            f"Error: {out}: --out: holds an interrupted run's leftovers (run.rrd.part); use "
            "--force to replace it"]
        again = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out),
                                               "--force"])
    assert again.exit_code == 0, again.output
    assert again.output.splitlines()[0] == (
        f"note: {out} held an interrupted run's leftovers (run.rrd.part): replaced")
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    assert json.loads((out / "summary.json").read_text())["success"] is True


def test_sigint_sigterm_and_sigkill_sent_to_real_subprocesses(tmp_path: Path) -> None:
    """SIGINT while an action starts, SIGTERM after a control tick: a complete, honest
    folder; SIGKILL: nothing under a final name, and the next run names the leftovers.
    The three subprocesses start together (their start-up is most of the time)."""
    cases = {"int": (signal.SIGINT, "action:1"), "term": (signal.SIGTERM, "tick:3"),
             "kill": (signal.SIGKILL, "tick:1")}
    started = {}
    for key, (_, pause) in cases.items():
        (tmp_path / key).mkdir()
        started[key] = _start(tmp_path / key, pause)
    for key, (signum, _) in cases.items():
        process, marker = started[key]
        _wait_for(process, marker)
        process.send_signal(signum)
    _check_interrupted(tmp_path / "int", started["int"][0], signal.SIGINT,
                       "interrupted during action 2/3: move c")
    _check_interrupted(tmp_path / "term", started["term"][0], signal.SIGTERM,
                       "interrupted during action 3/3: dock bT-cB")
    _check_killed(tmp_path / "kill", started["kill"][0])


class _SignalAt:
    """Sends ``signum`` to this process at one moment (in-process runs)."""

    def __init__(self, signum: int, moment: str):
        self.signum, self.moment = signum, moment
        self.sent = False

    def _maybe(self, moment: str) -> None:
        if moment == self.moment and not self.sent:  # once: a second signal stops at once
            self.sent = True
            os.kill(os.getpid(), self.signum)

    @hookimpl
    def msrr_on_action(self, run: Run, action: Action, status: ActionStatus) -> None:
        if status == ActionStatus.STARTED:
            self._maybe(f"action:{run.plan.actions.index(action)}")

    @hookimpl
    def msrr_on_run_start(self, run: Run) -> None:
        self._maybe("run_start")

    @hookimpl
    def msrr_on_tick(self, run: Run, tick: Tick) -> None:
        self._maybe(f"tick:{tick.index}")


@pytest.fixture
def own_handlers() -> Iterator[None]:
    """``platform run`` installs its SIGINT/SIGTERM handlers; put pytest's back after."""
    saved = {s: signal.getsignal(s) for s in SIGNALS}
    yield
    for signum, handler in saved.items():
        signal.signal(signum, handler)


@pytest.mark.parametrize(("signum", "moment", "where"), [
    (signal.SIGTERM, "action:0", "action 1/3: undock aT-bB"),
    (signal.SIGINT, "run_start", "the run's start, after the plan was made, before its first "
                                 "action"),
    (signal.SIGINT, "tick:2", "action 2/3: move c"),
])
def test_in_process_signals_at_more_moments(tmp_path: Path, own_handlers: None, signum: int,
                                           moment: str, where: str) -> None:
    out = tmp_path / "out"
    with installed(tmp_path), plugins.temporary(_SignalAt(signum, moment)):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out)])
    name = signal.Signals(signum).name
    assert result.exit_code == 128 + signum
    assert result.output.strip().splitlines()[-1] == (
        f"Error: interrupted during {where} ({name}); wrote {out}")
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["success"], summary["interrupted"]) == (False, name)
    assert read_recording(out / "run.rrd").rows["/action"]


def test_signal_while_planning_is_one_line_and_writes_nothing(
        tmp_path: Path, own_handlers: None) -> None:
    def plan_and_signal(self, start, goal, *, seed=0):  # type: ignore[no-untyped-def]
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError("the signal did not interrupt planning")

    out = tmp_path / "out"
    with installed(tmp_path), pytest.MonkeyPatch.context() as patch:
        patch.setattr(LinePlanner, "plan", plan_and_signal)
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out", str(out)])
    assert result.exit_code == 143
    assert result.output.strip().splitlines() == [
        "Error: interrupted (SIGTERM) during start-up, before the plan was made; nothing was run"]
    assert not out.exists()
