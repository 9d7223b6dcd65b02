"""The one judge of a run: what the user asked for, judged on what happened.

Every verdict of a run is made here, from what the driver's *witness* shows (the
simulator's ground truth, :mod:`msrr.core.witness`, where it has one; what the modules
report otherwise -- the poses of a pose sensor the robot has -- and the verdict says
which), never from what the plan says:

* a **goal** (a scenario stage's goal, and the plan's goal at the end) by its topology
  and its shape: module poses against where the robot's driver lays the goal out,
  within the robot's ``shape_tolerance`` when it declares one; else connection vectors
  after yaw alignment (FreeSN paper, eq. 8) within :attr:`JudgeOptions.goal_tolerance`.
  A goal that differs from the start only in shape (joint angles) and has no shape
  the judge can measure is not called reached.
* a **behavior** by what it was asked for: the distance along its commanded direction
  against ``distance`` (``--distance``), else ``speed`` x ``duration``, at least
  :attr:`JudgeOptions.min_progress` of it, and the heading error within
  :attr:`JudgeOptions.max_heading`.

:class:`Judge` listens to a run's events (an :class:`~msrr.core.events.EventSink`)
to judge each stage when it ends, and :meth:`Judge.conclude` judges the whole run once
at the end: ``RunResult.success`` is its verdict alone. The executor and the controllers
never see the witness.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .actions import topology_diff
from .alignment import rot_z
from .configuration import Configuration
from .driver import Observation, Pose, horizontal_centre
from .events import (
    GROUND_TRUTH,
    REPORTED,
    ActionStatus,
    BehaviorVerdict,
    FaultEvent,
    GoalVerdict,
    Run,
    RunResult,
    Tick,
    TopologyEvent,
)
from .plan import Action, BehaviorCall, behavior_runs
from .shape import ShapeVerdict, pose_errors, skeletal_errors, skeletal_verdict
from .witness import Witness, poses_seen

__all__ = ["BehaviorVerdict", "GoalVerdict", "Judge", "JudgeOptions", "Witnessed",
           "asked_distance", "judge_behavior", "judge_goal"]

HEADING_DISTANCE = 0.01
"""Below this distance [m] a heading is not measured (it would be noise)."""


class Witnessed(Protocol):
    """What the judge sees of the world: a driver (the judge reads, never commands)."""

    @property
    def time(self) -> float: ...

    def ground_truth(self) -> Configuration | None: ...

    def witness(self) -> Witness | None: ...

    def get_observation(self) -> Observation: ...


Layout = Callable[[Configuration], Mapping[str, Pose] | None]
"""Where the robot's driver places a goal configuration (``None``: it cannot)."""


@dataclass(frozen=True)
class JudgeOptions:
    """The bounds of the verdicts.

    Attributes:
        goal_tolerance: RMS angle [rad] between connection vectors (eq. 8) a goal is
            reached within, for a robot that declares no ``shape_tolerance``.
        min_progress: the fraction of the asked distance a behavior must cover along
            its commanded direction.
        max_heading: the largest angle [rad] between the direction travelled and the
            commanded one.
    """

    goal_tolerance: float = math.radians(5.0)
    min_progress: float = 0.2
    max_heading: float = math.radians(45.0)


# -- pure verdicts ----------------------------------------------------------------------


def judge_goal(name: str, goal: Configuration, *, index: int | None, time: float,
               recognized: Configuration, truth: Configuration | None,
               poses: Mapping[str, Pose], layout: Mapping[str, Pose] | None,
               tolerance: object, options: JudgeOptions,
               shape_only: bool = False) -> GoalVerdict:
    """Judge ``goal`` on the ground truth where there is one, else on ``recognized``.

    Args:
        name: the goal's name.
        goal: the goal configuration.
        index: the action that ended at it, or ``None`` at the run's end.
        time: driver time [s].
        recognized: the configuration recognized from the modules' reports.
        truth: the simulator's configuration, or ``None``.
        poses: the driver's module poses now.
        layout: where the driver places ``goal``, or ``None``.
        tolerance: the robot's :class:`~msrr.core.robot.ShapeTolerance`, or ``None``.
        options: the judge's bounds.
        shape_only: the goal differs from where its stage began only in shape, so a
            goal without a measurable shape cannot be called reached.
    """
    seen = truth if truth is not None else recognized
    basis = GROUND_TRUTH if truth is not None else REPORTED
    where = name if index is None else f"goal {name} (action {index + 1})"
    remaining = topology_diff(seen, goal)
    shape: ShapeVerdict | None = None
    if tolerance is not None and layout and poses and set(layout) == set(poses):
        shape = pose_errors(poses, layout, tolerance)  # type: ignore[arg-type]
    else:
        shape = skeletal_verdict(seen, goal, options.goal_tolerance)
    reason = ""
    if remaining:
        reason = f"{where}: the topology differs ({remaining}), judged on {basis}"
    elif shape is not None and not shape.within:
        reason = f"{where}: shape outside the tolerance, {shape}, judged on {basis}"
    elif shape is None and shape_only:
        reason = (f"{where} differs from the start only in shape, which cannot be judged "
                  "for this robot (it declares no shape_tolerance and the goal has no "
                  "connection vectors)")
    return GoalVerdict(name, index, time, not remaining, shape, basis, not reason, reason)


def asked_distance(call: BehaviorCall) -> float | None:
    """The distance [m] a behavior was asked to cover: ``distance``, else ``speed`` x
    ``duration``; ``None`` when it asks none (a turn on the spot)."""
    if call.distance is not None:
        return call.distance
    speed = call.parameters.get("speed")
    if speed is None or call.duration is None or speed == 0:
        return None
    return abs(float(speed)) * call.duration


def judge_behavior(call: BehaviorCall, *, first_action: int, actions: int, duration: float,
                   shift: np.ndarray | None, direction: np.ndarray | None, basis: str,
                   options: JudgeOptions) -> BehaviorVerdict:
    """Judge a behavior run by the horizontal ``shift`` [m] (shape (2,)) of the modules'
    centre, against ``direction`` (unit, shape (2,), in the world) and what ``call`` asked.
    ``shift`` is ``None`` when the driver reports no module poses."""
    asked = asked_distance(call)
    if shift is None:
        return BehaviorVerdict(str(call), first_action, actions, duration, 0.0, None, asked,
                               None, basis, False, f"{call.name}: not judged, the driver "
                               "reports no module poses")
    distance = float(np.linalg.norm(shift))
    along = None if direction is None else float(shift @ direction)
    heading = None
    if direction is not None and distance >= HEADING_DISTANCE:
        heading = math.acos(float(np.clip(shift @ direction / distance, -1.0, 1.0)))
    covered = round(along if along is not None else distance, 4) + 0.0  # no "-0.000"
    reason = ""
    if asked is not None and covered < options.min_progress * asked:
        what = "along the commanded direction" if along is not None else "in all"
        reason = (f"{call.name} covered {covered:.3f} m {what} of the {asked:.3f} m asked "
                  f"({covered / asked:.0%}; at least {options.min_progress:.0%} is needed), "
                  f"judged on {basis}")
    elif heading is not None and heading > options.max_heading:
        reason = (f"{call.name} went {math.degrees(heading):.0f} deg off the commanded "
                  f"direction (at most {math.degrees(options.max_heading):.0f}), judged on "
                  f"{basis}")
    return BehaviorVerdict(str(call), first_action, actions, duration, distance, along, asked,
                           heading, basis, not reason, reason)


def _vectors_differ(a: Configuration, b: Configuration) -> bool:
    """Whether an edge both have points another way (``z`` or ``x``) in ``a`` than in ``b``."""
    mine = {e.id: e for e in a.edges()}
    for edge in b.edges():
        other = mine.get(edge.id)
        for name in ("z", "x"):
            u, v = (None if e is None else getattr(e, name) for e in (other, edge))
            if (u is None) != (v is None) or (u is not None and not np.allclose(u, v)):
                return True
    return False


# -- the judge of one run -----------------------------------------------------------------


@dataclass
class _Open:
    """A behavior run under way: where and when it began."""

    call: BehaviorCall
    span: range
    time: float
    centre: np.ndarray | None
    direction: np.ndarray | None
    basis: str
    actions: int = 0


@dataclass
class Judge:
    """Judges one run as it goes (an :class:`~msrr.core.events.EventSink`), and at its end.

    Args:
        run: the run.
        witness: the run's driver, read for the verdicts only.
        layout: where the robot's driver places a goal (for the pose measure).
        tolerance: the robot's ``shape_tolerance`` (``None``: it declares none).
        options: the bounds.
    """

    run: Run
    witness: Witnessed
    layout: Layout = lambda goal: None
    tolerance: object = None
    options: JudgeOptions = field(default_factory=JudgeOptions)
    goals: list[GoalVerdict] = field(default_factory=list)
    behaviors: list[BehaviorVerdict] = field(default_factory=list)

    def __post_init__(self) -> None:
        actions = self.run.plan.actions
        self._index = {id(a): i for i, a in enumerate(actions)}
        self._spans = {span.start: span for span in behavior_runs(actions)}
        self._recognized = self.run.plan.start
        self._stage_start = self.run.plan.start
        self._open: _Open | None = None

    # -- events --------------------------------------------------------------------------

    def run_start(self, run: Run) -> None:
        """Nothing to judge yet."""

    def tick(self, run: Run, tick: Tick) -> None:
        self._recognized = tick.configuration

    def action(self, run: Run, action: Action, status: ActionStatus) -> None:
        index = self._index.get(id(action))
        if index is None:
            return
        if status == ActionStatus.STARTED:
            if self._open is not None and index not in self._open.span:
                self.close()  # its remaining loops were skipped
            if index in self._spans:
                self._begin(action, self._spans[index])
        elif status == ActionStatus.SUCCEEDED:
            if self._open is not None:
                self._open.actions += 1
            if action.reaches:
                self.goals.append(self._goal(action.reaches, action.target, index))
                self._stage_start = action.target
            if self._open is not None and index == self._open.span.stop - 1:
                self.close()
        elif status == ActionStatus.FAILED:
            self.close()

    def topology_change(self, run: Run, change: TopologyEvent) -> None:
        """Judged at goals, not per change."""

    def fault(self, run: Run, fault: FaultEvent) -> None:
        """The run's result carries the faults."""

    def run_end(self, run: Run, result: RunResult) -> None:
        """Judged in :meth:`conclude`, while the driver still answers."""

    # -- verdicts ------------------------------------------------------------------------

    def conclude(self, result: RunResult) -> RunResult:
        """The run's verdict, once, at its end: the plan's goal judged, every stage's and
        behavior's verdict attached, ``success`` and ``reason`` set from all of them (a
        run the executor could not finish keeps its reason)."""
        self.close()
        plan = self.run.plan
        completed = result.success
        last = len(plan.actions) - 1
        if completed and self.goals and self.goals[-1].action_index == last:
            result.goal = self.goals[-1]  # the last stage ended the run: judged there
        elif completed:
            result.goal = self._goal(plan.goal.name or "the goal", plan.goal, None)
        result.targets = list(self.goals)
        result.locomotion = list(self.behaviors)
        failures = [v.reason for v in (*self.goals, *self.behaviors) if not v.success]
        if result.goal is not None and not result.goal.success and result.goal not in self.goals:
            failures.append(result.goal.reason)
        result.success = completed and not failures
        if completed and failures:
            result.reason = "; ".join(failures)
        return result

    def close(self) -> None:
        """Judge the behavior run under way, if any (where it stands now)."""
        opened, self._open = self._open, None
        if opened is None:
            return
        now = self._centre()
        shift = None if now is None or opened.centre is None else now - opened.centre
        self.behaviors.append(judge_behavior(
            opened.call, first_action=opened.span.start, actions=opened.actions,
            duration=self.witness.time - opened.time, shift=shift,
            direction=opened.direction, basis=opened.basis, options=self.options))

    def _goal(self, name: str, goal: Configuration, index: int | None) -> GoalVerdict:
        poses = self._poses()
        shape_only = not topology_diff(self._stage_start, goal) and \
            _vectors_differ(self._stage_start, goal)
        layout = self.layout(goal) if self.tolerance is not None else None
        return judge_goal(name, goal, index=index, time=self.witness.time,
                          recognized=self._recognized, truth=self.witness.ground_truth(),
                          poses=poses, layout=layout, tolerance=self.tolerance,
                          options=self.options, shape_only=shape_only)

    def _begin(self, action: Action, span: range) -> None:
        call = action.behavior
        assert call is not None
        truth = self.witness.ground_truth()
        seen = truth if truth is not None else self._recognized
        direction = None
        if call.direction is not None:
            yaw = skeletal_errors(seen, action.target)[2]
            world = (rot_z(yaw) @ np.asarray(call.direction, dtype=float))[:2]
            if np.linalg.norm(world) > 1e-9:
                direction = world / np.linalg.norm(world)
        self._open = _Open(call, span, self.witness.time, self._centre(), direction,
                           GROUND_TRUTH if truth is not None else REPORTED)

    def _poses(self) -> Mapping[str, Pose]:
        """Every module's world pose (:func:`~msrr.core.witness.poses_seen`)."""
        return poses_seen(self.witness)

    def _centre(self) -> np.ndarray | None:
        """Mean horizontal position of the modules [m], shape (2,), from the driver."""
        return horizontal_centre(self._poses())
