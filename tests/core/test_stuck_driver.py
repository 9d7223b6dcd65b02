"""Issue 30, item 8: a driver call that does not return ends the run: the watchdog
interrupts it after ``--stall`` seconds of wall time (or past ``--wall-deadline``), the
modules are told to stop, one line, the three files; a driver that swallows the
interruption is ended by the last resort, which writes the files and ends the process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from tiny_robot import PointDriver, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.cli import get_cli
from msrr.core.app.run import RunRequest
from msrr.core.errors import ConfigurationError
from msrr.core.faults import GuardedDriver
from msrr.core.watchdog import DriverStalled, Watchdog

HERE = Path(__file__).parent


class _Stuck(PointDriver):
    """Blocks in ``where`` (``step`` from 0.5 s of driver time, ``reset``, ``connect``)."""

    name = "stuck"
    where = "step"
    calls: list[str] = []

    def _block(self, call: str) -> None:
        if call == self.where:
            threading.Event().wait()  # forever, but a signal gets through

    def connect(self) -> None:
        self._block("connect")
        super().connect()

    def reset(self, start) -> None:  # type: ignore[no-untyped-def]
        self._block("reset")
        super().reset(start)

    def step(self, dt: float) -> None:
        if self.t >= 0.5:
            self._block("step")
        super().step(dt)

    def send_action(self, commands) -> None:  # type: ignore[no-untyped-def]
        if not commands:
            _Stuck.calls.append("stop")
        super().send_action(commands)

    def disconnect(self) -> None:
        _Stuck.calls.append("disconnect")
        super().disconnect()


class _Slow(PointDriver):
    """Answers, slowly: 0.3 s of wall time per step."""

    name = "slow"

    def step(self, dt: float) -> None:
        time.sleep(0.3)
        super().step(dt)


class _Drivers:
    @hookimpl
    def msrr_drivers(self, robot: str, register) -> None:  # type: ignore[no-untyped-def]
        if robot == "tiny":
            register(_Stuck)
            register(_Slow)


@pytest.fixture
def own_alarm() -> Iterator[None]:
    saved = signal.getsignal(signal.SIGALRM)
    yield
    signal.signal(signal.SIGALRM, saved)


def _run(tmp_path: Path, *args: str) -> tuple[int, list[str], float]:
    _Stuck.calls = []
    started = time.monotonic()
    (tmp_path / "scenario").mkdir(exist_ok=True)
    with installed(tmp_path / "scenario"), plugins.temporary(_Drivers(), "stuck-drivers"):
        result = CliRunner().invoke(get_cli(), ["run", "--robot", "tiny", "--out",
                                                str(tmp_path / "out"), *args])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        result.exception
    return result.exit_code, result.stderr.strip().splitlines(), time.monotonic() - started


@pytest.mark.parametrize("where", ["step", "reset", "connect"])
def test_a_driver_call_that_blocks_ends_the_run_with_three_files(
        tmp_path: Path, own_alarm: None, where: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_Stuck, "where", where)
    code, lines, took = _run(tmp_path, "--driver", "stuck", "--stall", "1")
    assert code == 1 and took < 20
    assert len(lines) == 1, lines
    assert f"driver 'stuck' did not return from {where} within 1 s of wall time (--stall)" \
        in lines[0]
    out = tmp_path / "out"
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] is False and "did not return" in summary["reason"]
    assert _Stuck.calls[-2:] == ["stop", "disconnect"] or _Stuck.calls[-1:] == ["disconnect"]


def test_the_wall_deadline_ends_a_slow_run(tmp_path: Path, own_alarm: None) -> None:
    code, lines, took = _run(tmp_path, "--driver", "slow", "--wall-deadline", "1", "--no-log")
    assert code == 1 and took < 20
    assert len(lines) == 1 and "run deadline of 1 s of wall time reached (--wall-deadline)" \
        in lines[0], lines
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["plan.json",
                                                                    "summary.json"]


@pytest.mark.parametrize("field, value", [("stall", 0.0), ("stall", 1e9),
                                          ("wall_deadline", float("nan")),
                                          ("wall_deadline", -1.0)])
def test_the_watchdog_options_are_bounded(field: str, value: float) -> None:
    with pytest.raises(ConfigurationError, match=f"--{field.replace('_', '-')}"):
        RunRequest(robot="tiny", **{field: value}).check()


def test_the_watchdog_interrupts_only_a_call_in_progress(own_alarm: None) -> None:
    guard = GuardedDriver(PointDriver())
    with Watchdog(guard, stall=0.2, poll=0.01) as dog:
        time.sleep(0.4)  # nothing in progress: nothing fires
        assert dog.reason == ""
        with pytest.raises(DriverStalled, match="did not return from connect within 0.2 s"):
            guard._call("connect", threading.Event().wait)
    assert guard.stopped and dog.reason
    with pytest.raises(DriverStalled):  # a stopped driver takes nothing but the clean-up
        guard.step(0.1)
    guard.send_action({})
    guard.disconnect()


def test_a_driver_that_swallows_the_interruption_is_ended_by_the_last_resort(
        tmp_path: Path) -> None:
    env = {**os.environ, "MSRR_TEST_STUCK": "swallow",
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    started = time.monotonic()
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, str(HERE / "tiny_cli.py"), "run", "--robot", "tiny", "--driver",
         "recording", "--out", str(out), "--stall", "1"],
        env=env, capture_output=True, text=True, timeout=120)
    assert time.monotonic() - started < 60
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert "did not return from step within 1 s of wall time (--stall); the driver did not " \
           "let go" in lines[0] and lines[0].endswith(f"wrote {out}")
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "run.rrd", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] is False and "did not let go" in summary["reason"]
