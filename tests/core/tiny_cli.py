"""``python tiny_cli.py run ...``: the real ``platform`` entry point with the tiny robot
installed, for tests that signal a subprocess. Not a test module.

``MSRR_TEST_PAUSE`` names a moment at which the process writes ``MSRR_TEST_MARKER``
(a file path) and then waits (at most 30 s) so the test can signal it there:
``plan`` (while planning), ``action:<index>`` (an action has started), ``tick:<n>``
(after control tick ``n``), ``disconnect`` (the clean-up: the driver is disconnecting).
``MSRR_TEST_STUCK=swallow`` makes the driver's ``step`` block from 0.5 s of driver time
on, swallowing every exception (a driver that never lets go). Every call of the driver's ``send_action`` with no command
(``stop``) and of ``disconnect`` is appended to ``MSRR_TEST_CALLS`` (a file path).
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import time
from collections.abc import Mapping
from pathlib import Path

from tiny_robot import LinePlanner, PointDriver, installed

from msrr.core import hookimpl, plugins
from msrr.core.app.cli import main
from msrr.core.driver import ModuleCommand
from msrr.core.events import ActionStatus, Run, Tick
from msrr.core.plan import Action

PAUSE = os.environ.get("MSRR_TEST_PAUSE", "")
MARKER = os.environ.get("MSRR_TEST_MARKER", "")
CALLS = os.environ.get("MSRR_TEST_CALLS", "")
STUCK = os.environ.get("MSRR_TEST_STUCK", "")


def _pause(moment: str) -> None:
    if moment != PAUSE or not MARKER:
        return
    Path(MARKER).write_text(moment)
    end = time.monotonic() + 30.0
    while time.monotonic() < end:
        time.sleep(0.005)


def _call(text: str) -> None:
    if CALLS:
        with open(CALLS, "a") as handle:
            handle.write(text + "\n")


class _PausingPlanner(LinePlanner):
    name = "pausing"

    def plan(self, start, goal, *, seed=0):  # type: ignore[no-untyped-def]
        _pause("plan")
        return super().plan(start, goal, seed=seed)


class _RecordingDriver(PointDriver):
    name = "recording"

    def send_action(self, commands: Mapping[str, ModuleCommand]) -> None:
        if not commands:
            _call("stop")
        super().send_action(commands)

    def step(self, dt: float) -> None:
        while STUCK == "swallow" and self.t >= 0.5:
            try:
                threading.Event().wait()
            except Exception:  # noqa: BLE001, S112 - the driver under test swallows
                continue
        super().step(dt)

    def disconnect(self) -> None:
        _call("disconnect")
        _pause("disconnect")
        super().disconnect()


class _Moments:
    @hookimpl
    def msrr_on_action(self, run: Run, action: Action, status: ActionStatus) -> None:
        if status == ActionStatus.STARTED:
            index = next(i for i, a in enumerate(run.plan.actions) if a is action)
            _pause(f"action:{index}")

    @hookimpl
    def msrr_on_tick(self, run: Run, tick: Tick) -> None:
        _pause(f"tick:{tick.index}")

    @hookimpl
    def msrr_planners(self, robot: str, register) -> None:  # type: ignore[no-untyped-def]
        if robot == "tiny":
            register(_PausingPlanner())

    @hookimpl
    def msrr_drivers(self, robot: str, register) -> None:  # type: ignore[no-untyped-def]
        if robot == "tiny":
            register(_RecordingDriver)


if __name__ == "__main__":
    with installed(Path(tempfile.mkdtemp())), plugins.temporary(_Moments(), "moments"):
        sys.argv[0] = "platform"
        main()
