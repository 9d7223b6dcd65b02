"""A tracked move that cannot progress (two legs that take no command) ends early, stalled, on module reports alone; the
same move with every strut answering is not cut (``executor.StallWatch``, issue 31)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from msrr.core import plugins
from msrr.core.actions import detect_actions
from msrr.core.events import Run
from msrr.core.executor import Executor, ExecutorOptions
from msrr.core.library import load_library
from msrr.core.plan import Plan
from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim import FreeSNMujocoDriver

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"


class Deaf:
    """A driver on which the struts ``deaf`` take no command (they stop where they are)."""

    def __init__(self, inner: FreeSNMujocoDriver, deaf: tuple[str, ...]):
        self.inner, self.deaf = inner, deaf

    def send_action(self, commands: Any) -> None:
        self.inner.send_action({m: c for m, c in commands.items() if m not in self.deaf})

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _stand_up(*deaf: str, settle: float = ExecutorOptions().settle_tolerance):
    """S4N5 lying flat -> the stand-up of fig18 (one move), 2 deg of report noise."""
    sub = load_library(FREESN / "libraries" / "S4N5.json").sublibraries["S4N5"]
    sequence = [sub.configurations[k].configuration for k in ("S4N5-1.1", "S4N5-1.2")]
    plan = Plan(robot="freesn", planner="manual", start=sequence[0], goal=sequence[-1],
                actions=detect_actions(sequence))
    run = Run(robot="freesn", scenario="custom", plan=plan, spec=SPEC, driver="mujoco")
    options = ExecutorOptions(action_timeout=30.0, retries=1, stall_window=3.0,
                              settle_tolerance=settle)
    with FreeSNMujocoDriver(noise=np.radians(2.0), slip=0.05, seed=2) as driver:
        driver.reset(sequence[0])
        capabilities = plugins.capabilities("freesn")   # IK tracking, as platform run
        return Executor(run, Deaf(driver, deaf), capabilities.recognizer(),
                        capabilities.controller(), options, robot=capabilities.robot,
                        controllers=capabilities.controllers).execute()


def test_a_move_with_two_deaf_struts_stalls_long_before_its_timeout():
    result = _stand_up("S1", "S2")
    assert not result.success
    assert "phase move stalled: shape error" in result.reason, result.reason
    assert "after 2 attempt(s)" in result.reason and result.retries == 1
    assert result.sim_time < 20.0   # two attempts; the 30 s timeout would take 60 s


def test_a_move_stalled_on_its_last_attempt_within_the_settle_tolerance_is_reached():
    """The same stall, on a tolerance that takes in its error: the first attempt stalls
    and is retried as before, the last one ends as reached (FreeBOT pieces-to-tree's
    final move, whose held connections leave it nothing to move, ExecutorOptions)."""
    result = _stand_up("S1", "S2", settle=np.radians(90.0))
    assert result.success, result.reason
    assert result.retries == 1 and result.sim_time < 20.0
    [line] = result.settled                      # the verdict says it settled, not reached
    assert "settled at" in line and "after 2 attempt(s)" in line, line
    assert result.summary()["settled"] == [line]


def test_the_same_move_with_every_strut_answering_is_not_cut():
    result = _stand_up()
    assert result.success, result.reason
    assert result.retries == 0
