"""Run library edges in a simulator and judge them on its ground truth (section 6.2).

:func:`run_edge` executes one :class:`~msrr.core.library.check.EdgeCase` with the
executor's closed loop on a fresh driver and answers an
:class:`~msrr.core.library.check.EdgeCheck`; :func:`check_edges` and :func:`check_library`
do every edge of a library as one batch (:mod:`msrr.core.app.batch`). A run that *fails*
(the simulator raised, the worker was lost) is a failure of the batch, never a verdict:
it is not written as an infeasible edge.

The verdict never trusts the recognizer: the final shape and topology come from
:meth:`Driver.ground_truth`, the docks and undocks and any fault from
:meth:`Driver.faults` (the simulator's constraint state). Reasons, first found wins:

* ``connector broke`` / ``self-collision`` -- a fault the driver saw;
* ``torque limit`` -- the run did not finish and a connector's motors had been saturated
  (:meth:`Driver.saturation`) for the last ``SATURATION_TIME`` seconds or more: the motion
  stopped because a motor could not deliver more, not because the controller gave up;
* ``fell over`` -- the final shape is over 20 deg off after a turn about the vertical
  but matches the target once tilted (the robot lies on its side);
* ``timeout`` -- a phase did not finish (the executor's reason follows);
* ``error`` -- the executor ended the run unsuccessfully for another reason (its reason
  follows);
* ``wrong topology`` / ``wrong shape`` -- the ground truth ends elsewhere (over
  ``tolerance``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

import numpy as np

from .. import plugins
from ..actions import topology_diff
from ..capabilities import Controller, DriverFactory, Recognizer
from ..configuration import Configuration
from ..driver import Driver
from ..events import NoEvents, Run, Tick
from ..executor import Executor, ExecutorOptions
from ..library.check import CheckFile, EdgeCase, EdgeCheck, edge_cases
from ..library.model import Library
from ..plan import Plan
from ..robot import Robot
from ..shape import skeletal_error
from .batch import RETRIES, BatchResult, TaskFailure, run_batch

__all__ = ["FELL_OVER", "SATURATION_TIME", "EdgeRunner", "check_edges", "check_header",
           "check_library", "default_runner", "run_edge", "tilted_error"]


FELL_OVER = math.radians(20.0)
"""Smallest yaw-aligned error [rad] that can count as lying on the side."""

SATURATION_TIME = 3.0
"""Saturation streak [s] at the end of an unfinished run that counts as ``torque limit``."""


def tilted_error(current: Configuration, goal: Configuration) -> float:
    """RMS angle [rad] between the ``z`` of both after the best rotation of any axis
    (Kabsch): small when the shape is right but turned over."""
    ids = [e for e in goal.edge_ids() if e in set(current.edge_ids())]
    if not ids:
        return 0.0
    a, b = current.vectors(ids), goal.vectors(ids)
    u, _, vt = np.linalg.svd(a @ b.T)
    d = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag([1.0, 1.0, d]) @ vt
    cos = np.clip(np.einsum("ij,ij->j", a, rotation @ b), -1.0, 1.0)
    return float(np.sqrt(np.mean(np.arccos(cos) ** 2)))


@dataclass(frozen=True)
class EdgeRunner:
    """What runs an edge: the robot's capabilities and the run settings.

    Attributes:
        robot: the robot.
        driver: factory of the simulation driver (called ``driver(gui=False, seed=...,
            **driver_options)``).
        recognizer: the robot's recognizer.
        controller: the robot's controller.
        controllers: every controller of the robot, by name (a kinematic node's own
            drives it, as in ``platform run``).
        options: executor options (rate, timeout per phase, retries; no stall watch: an
            edge is judged on the time it is given).
        driver_options: keyword options of the driver (noise, slip, ...).
        seed: the run's seed.
        tolerance: largest final RMS strut angle to the target [rad] (ground truth).
        timeout_per_rad: extra driver time per phase for each radian of RMS angle between
            the edge's source and target [s/rad]: a big motion (S12N6's tree -> ring, 57
            deg) moves nodes over the floor for a minute, a small one should not get as long.
    """

    robot: Robot
    driver: DriverFactory
    recognizer: Recognizer
    controller: Controller
    controllers: Mapping[str, Controller] = field(default_factory=dict)
    options: ExecutorOptions = ExecutorOptions(action_timeout=30.0, retries=0, stall_window=0.0)
    driver_options: tuple[tuple[str, float | int | bool], ...] = ()
    seed: int = 0
    tolerance: float = math.radians(5.0)
    timeout_per_rad: float = 30.0


class _Faulted(Exception):
    """The driver saw a fault (a connector broke, bodies overlap): the edge's verdict."""


class _FirstFault(NoEvents):
    """Ends an edge's run at the first fault the driver saw (checked once per second of
    driver time, as the overlap scan is not free): the first fault is the verdict."""

    def __init__(self, driver: Driver):
        self.driver = driver
        self.checked = 0.0

    def tick(self, run: Run, tick: Tick) -> None:
        if tick.time - self.checked >= FAULT_CHECK_PERIOD:
            self.checked = tick.time
            if self.driver.faults():
                raise _Faulted


FAULT_CHECK_PERIOD = 1.0
"""How often [s of driver time] an edge's run asks the driver for faults."""


def run_edge(case: EdgeCase, runner: EdgeRunner) -> EdgeCheck:
    """Execute one edge from its source configuration; the verdict from ground truth.

    Each phase may take ``runner.options.action_timeout`` plus ``runner.timeout_per_rad``
    per radian of RMS angle between the source and the target (after yaw alignment)."""
    options = replace(runner.options, action_timeout=runner.options.action_timeout
                      + runner.timeout_per_rad * skeletal_error(case.start, case.target))
    plan = Plan(robot=runner.robot.name, planner="library-check", start=case.start,
                goal=case.target, actions=[case.action])
    run = Run(robot=runner.robot.name, scenario=case.key, plan=plan, spec=runner.robot.spec,
              driver=runner.driver.name, rate=runner.options.rate, seed=runner.seed)
    with runner.driver(gui=False, seed=runner.seed, **dict(runner.driver_options)) as driver:
        driver.reset(case.start)
        # an error the platform raises here (a command the driver refuses, a tree without
        # the data it needs) is a bug to fix, not a property of the edge: it fails the
        # task, and the check names it instead of recording the edge as infeasible
        executor = Executor(run, driver, runner.recognizer, runner.controller, options,
                            sink=_FirstFault(driver), robot=runner.robot,
                            controllers=runner.controllers)
        try:
            result = executor.execute()
        except _Faulted:  # the verdict is that fault: simulating on would change nothing
            result = executor.result
        truth = driver.ground_truth()
        faults = driver.faults()
        counts = driver.constraint_events()
        saturated = driver.saturation()
        sim_time = driver.time
    error = None if truth is None else skeletal_error(truth, case.target)
    reason = ""
    if faults:
        reason = faults[0]
    elif truth is not None and error is not None and error > FELL_OVER \
            and tilted_error(truth, case.target) < runner.tolerance:
        reason = f"fell over: {math.degrees(error):.1f} deg off after a yaw turn only"
    elif not result.success and "did not finish" in result.reason and saturated \
            and max(saturated.values()) >= SATURATION_TIME:
        worst = sorted(saturated.items(), key=lambda kv: (-kv[1], kv[0]))
        reason = (f"torque limit: {', '.join(k for k, t in worst if t >= SATURATION_TIME)} "
                  f"saturated for the last {worst[0][1]:.1f} s; " + result.reason)
    elif not result.success:
        reason = ("timeout: " if "did not finish" in result.reason else "error: ") + result.reason
    elif truth is not None and topology_diff(truth, case.target):
        reason = f"wrong topology: {topology_diff(truth, case.target)}"
    elif error is not None and error > runner.tolerance:
        reason = f"wrong shape: {math.degrees(error):.1f} deg RMS from the target"
    return EdgeCheck(edge=case.key, action=case.edge.action.value, feasible=not reason,
                     reason=reason, sim_time=round(sim_time, 3),
                     shape_error_deg=None if error is None else round(math.degrees(error), 3),
                     docks=counts.get("dock", 0), undocks=counts.get("undock", 0))


def check_edges(cases: Sequence[EdgeCase], runner: EdgeRunner, *, workers: int = 1,
                cluster: str | None = None, backend: str | None = None,
                progress: bool = True, previous: CheckFile | None = None,
                retries: int = RETRIES,
                record: Callable[[int, EdgeCheck | TaskFailure], None] | None = None,
                interrupt_note: Callable[[], str] | None = None,
                ) -> tuple[list[EdgeCheck], BatchResult[EdgeCheck]]:
    """Run every case (:func:`run_edge`) as one batch (:func:`msrr.core.app.batch.run_batch`).

    Every edge runs with ``runner.seed`` on a fresh driver, so the checks are the same
    serially, on a process pool and on Ray. An edge whose run raised (a simulator's bug)
    or whose worker was lost on every attempt is a *failure*, never an infeasible edge:
    it is in ``batch.failures`` and not among the checks. ``previous`` (an earlier check
    of the library) only orders the work: the edges that took the longest simulated
    time before start first. ``retries``, ``record`` and ``interrupt_note`` are
    :func:`~msrr.core.app.batch.run_batch`'s.

    Returns:
        the :class:`EdgeCheck` of every edge that ran to a verdict, in case order, and
        the batch (results by case index, timings, failures, retries).
    """
    before = {} if previous is None else {e.edge: e.sim_time for e in previous.edges}
    batch = run_batch(partial(run_edge, runner=runner), list(cases),
                      keys=[c.key for c in cases], workers=workers, cluster=cluster,
                      backend=backend, label="edges", progress=progress,
                      describe=lambda case: case.key,
                      cost=[before.get(c.key, math.inf) for c in cases] if before else None,
                      retries=retries, record=record, interrupt_note=interrupt_note)
    return [c for c in batch.results if c is not None], batch


def check_library(library: Library, runner: EdgeRunner, *, digest: str,
                  progress: Callable[[EdgeCheck], None] | None = None, workers: int = 1,
                  cluster: str | None = None) -> CheckFile:
    """Run every edge of ``library`` (see :func:`check_edges`); the check file's content.

    ``progress`` is called with each check, in edge order, once all have run.

    Raises:
        BatchError: an edge's run failed (its simulator raised, its worker was lost).
    """
    checks, batch = check_edges(edge_cases(library, runner.robot), runner, workers=workers,
                                cluster=cluster, progress=False)
    batch.values()  # raises, naming the failed edges
    if progress is not None:
        for check in checks:
            progress(check)
    return CheckFile(**check_header(library, runner, digest), edges=checks)


def check_header(library: Library, runner: EdgeRunner, digest: str) -> dict[str, Any]:
    """The fields of a :class:`CheckFile` but its edges: what was checked and how."""
    options: dict[str, float | int | str | bool] = {
        "rate_hz": runner.options.rate, "action_timeout_s": runner.options.action_timeout,
        "retries": runner.options.retries, "tolerance_deg": round(math.degrees(runner.tolerance), 6),
        "timeout_per_rad_s": runner.timeout_per_rad,
        **dict(runner.driver_options)}
    return {"library": library.name, "library_sha256": digest, "robot": library.robot,
            "driver": runner.driver.name, "seed": runner.seed, "options": options}


def default_runner(robot_name: str, **settings: object) -> EdgeRunner:
    """An :class:`EdgeRunner` with the robot's first driver, recognizer and controller."""
    capabilities = plugins.capabilities(robot_name)
    return EdgeRunner(capabilities.robot, capabilities.driver(), capabilities.recognizer(),
                      capabilities.controller(), dict(capabilities.controllers),
                      **settings)  # type: ignore[arg-type]
