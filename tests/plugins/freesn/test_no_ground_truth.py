"""A FreeSN run with the witness channel removed sends the same commands (issue 32,
item 1): the executor, IK tracking, controllers and recognizer decide on module reports
alone, so the simulator's poses and constraint state cannot change an action."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from msrr.core import plugins
from msrr.core.actions import detect_actions
from msrr.core.app.run import RunRequest, prepare_run
from msrr.core.events import NoEvents, Run, Tick
from msrr.core.executor import Executor, ExecutorOptions
from msrr.core.library import load_library
from msrr.core.plan import Plan
from msrr.plugins.freesn.robot import SPEC
from msrr.plugins.freesn.sim import FreeSNMujocoDriver

FREESN = Path(__file__).resolve().parents[3] / "plugins" / "freesn"


class Blind:
    """A driver with its witness channel removed: every read of it fails the test."""

    def __init__(self, inner: FreeSNMujocoDriver):
        self.inner = inner

    def __getattr__(self, name: str) -> Any:
        if name in ("witness", "ground_truth", "faults", "saturation", "constraint_events",
                    "world"):
            raise AssertionError(f"the control path read the witness channel: {name}")
        return getattr(self.inner, name)


class Commands(NoEvents):
    """Every tick's commands; with ``driver``, its witness read each tick as
    ``platform run`` reads it for the recording."""

    def __init__(self, driver: FreeSNMujocoDriver | None = None):
        self.driver, self.ticks = driver, []

    def tick(self, run: Run, tick: Tick) -> None:
        if self.driver is not None:
            assert self.driver.witness() is not None
        self.ticks.append({m: (sorted(c.joints.items()), sorted(c.wheels.items()), c.dock,
                               c.undock) for m, c in tick.commands.items()})


def _run(blind: bool) -> tuple[list[dict], object]:
    sub = next(iter(load_library(FREESN / "libraries" / "S6N3.json").sublibraries.values()))
    sequence = [sub.configurations[k].configuration for k in ("S6N3-2.3", "S6N3-3.1",
                                                               "S6N3-2.3")]
    plan = Plan(robot="freesn", planner="manual", start=sequence[0], goal=sequence[-1],
                actions=detect_actions(sequence))
    run = Run(robot="freesn", scenario="custom", plan=plan, spec=SPEC, driver="mujoco")
    with FreeSNMujocoDriver(noise=np.radians(2.0), slip=0.05, seed=3) as driver:
        driver.reset(sequence[0])
        sink = Commands(None if blind else driver)
        result = Executor(run, Blind(driver) if blind else driver,
                          plugins.recognizers.get("freesn"), plugins.controllers.get("freesn"),
                          ExecutorOptions(action_timeout=10.0, retries=0), sink=sink).execute()
    return sink.ticks, result


def test_a_run_without_the_witness_channel_sends_the_same_commands():
    seen, with_truth = _run(blind=False)
    blind, without = _run(blind=True)
    assert with_truth.success and without.success, (with_truth.reason, without.reason)
    assert len(seen) == len(blind) >= 5
    assert seen == blind


def _scenario(name: str, blind: bool, tmp_path: Path) -> tuple[list[dict], object]:
    prepared = prepare_run(RunRequest(robot="freesn", scenario=name, out=tmp_path / "run",
                                      force=True, log=False))
    run = prepared.run
    with prepared.driver(gui=False, seed=run.seed, **dict(prepared.driver_options)) as driver:
        driver.reset(run.plan.start)
        sink = Commands(None if blind else driver)
        result = Executor(run, Blind(driver) if blind else driver, prepared.recognizer,
                          prepared.controller, prepared.options, sink=sink,
                          robot=prepared.capabilities.robot,
                          controllers=prepared.capabilities.controllers).execute()
    return sink.ticks, result


def test_a_behavior_with_ik_tracking_and_odometry_sends_the_same_commands_blind(tmp_path):
    """The S4N5 crawl: IK tracking every tick, and loops skipped once the odometry says
    the distance is covered -- all from reports. (The S12N6 crawl was used until its
    quadruped lost its second bar, issue 32: it no longer finishes.)"""
    seen, with_truth = _scenario("fig19-crawl", False, tmp_path)
    blind, without = _scenario("fig19-crawl", True, tmp_path)
    assert with_truth.success and without.success, (with_truth.reason, without.reason)
    assert with_truth.actions_skipped > 0 and without.actions_skipped == \
        with_truth.actions_skipped
    assert seen == blind
