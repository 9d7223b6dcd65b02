"""The executor: runs a plan action by action in a closed loop (FreeSN section 4.1).

Every tick, at a fixed rate (default 10 Hz of driver time): read the driver's
observation, recognize the configuration, detect topology changes against the
previous tick, ask the controller for commands, send them and advance the driver.

Per action type:

* moving: ``move`` until the target is reached;
* disconnection (also parallel): ``release`` (undock commands) until every planned
  disconnection is detected, then ``move`` to the target (with IK tracking, or when the
  action has goals);
* connection (also parallel): ``release`` first if the action also breaks
  connections, ``approach`` S_conn until reached, then ``connect`` (dock commands
  armed while pushing toward S_extr) until every planned connection is detected;
* flow (section 4.1: "the leaf module [...] can move from its parent module to the
  neighbors of the parent module directly. The disconnection and connection happen
  simultaneously"): ``flow`` (the leaf moves over its parent, still docked, until it
  touches the new parent), then ``handover`` (dock to the new parent and undock from
  the old in the same tick, until both changes are detected).

**Flow contract.** The paper leaves a flow's control to the hardware ("the control
strategy depends on the hardware implementation"), so the executor only sequences it
and the robot's controller moves the leaf. :func:`msrr.core.actions.flow_of` gives the
controller the :class:`~msrr.core.actions.Flow`: ``leaf``, ``parent``, ``new_parent``
and the ``broken``/``made`` links with their ports.

1. ``flow``: ``controller.begin(action, Phase.FLOW, observation)``, then
   ``controller.control(action, Phase.FLOW, observation)`` every tick, its commands sent
   as they are (the executor adds no dock or undock). The controller keeps the leaf on
   its parent and moves it until it touches the new parent (FreeBOT rolls its shell
   over the parent, SnailBot crawls), then returns ``Control(reached=True)``. No IK
   tracking runs in a flow. The only topology changes allowed are the flow's own two.
2. ``handover``: ``controller.begin(action, Phase.HANDOVER, ...)`` and ``control`` every
   tick (it should hold the leaf where it is); the executor adds, in the same tick,
   ``undock`` of the broken link's ports and ``dock`` of the made link's ports for
   links with ports; a link without ports (a freeform contact) is released and armed
   by the controller, as in connection and disconnection actions (the generic
   runtime's controller sends the leaf ``undock=("@parent",)`` and
   ``dock=("@new_parent",)``). The phase ends when the recognized topology is the
   action's target.

``RunResult.flows`` counts the flow actions whose undock and dock the driver reported.

* behavior (mapping behaviors, sections 4.3 and 6.3): ``behavior`` -- every tick the
  shape is held (IK tracking toward the target where it applies) and each
  :class:`~msrr.core.plan.CommandGain`'s value ``sum(gain * parameter)`` goes into
  ``ModuleCommand.wheels[key]`` (:func:`behavior_commands`), its ``yaw_rate`` closed in
  a heading loop on the estimated heading (:class:`HeadingLoop`: the commanded direction
  stays fixed in the world frame the behavior started in) whose reference, for a straight
  behavior that states its direction, a course loop sets so that the estimated place
  follows the commanded line (:class:`CourseLoop`; a behavior with a ``sideways``
  parameter has its travel turned instead, the heading held: :func:`steered`), for the
  call's duration
  or until the system moved its distance *as its own sensors estimate it*
  (:mod:`msrr.core.estimation`: odometry and IMU with their drift, or a pose sensor the
  robot has). The steps of a *sequence* behavior are ordinary actions; with a distance,
  the loops left once it is covered (by the same estimate) are skipped
  (``RunResult.actions_skipped``). A sequence that states its direction has a heading
  loop of its own (:class:`GaitLoop`, a :class:`CourseLoop` setting its reference),
  started where the behavior starts (the judge's commanded direction): each
  step but the behavior's first has its goal turned about the planted feet
  (:func:`~msrr.core.closed_loop.turned_goal`), and a gait that stops after a turned
  loop's last step takes that step again unturned (:func:`retakes_unturned`), so it
  stands in its designed stance. A step of a sequence whose stance is within
  ``timed_step_size`` of the one before ends when reached or on its time
  (:func:`timed_step`); one that ended on its time is counted
  (``RunResult.timed_out_steps``).

The executor judges nothing and reads only :class:`~msrr.core.driver.Observation`:
module reports, never a simulator's poses or dock state (:mod:`msrr.core.witness`). It
runs the plan and counts what the driver reported (docks, undocks, flows, retries,
ticks, times, on every way out: :attr:`Executor.result`), and its events let
:class:`~msrr.core.judge.Judge` judge each goal and behavior run on what the driver
witnessed.

**IK tracking** (section 4.1, Fig. 8; :mod:`msrr.core.closed_loop`) drives the moving
phases when the controller is a :class:`~msrr.core.closed_loop.JointController` and
the action carries a kinematic tree or the robot has joint modes: every tick the
recognized configuration goes through IK tracking toward the phase goal (the target,
``S_conn`` or ``S_extr``), the joint vectors go to the controller of each kinematic
node (the robot's controller of that name, handed in; the executor's controller
for fixed nodes), and the phase is reached when the tracked motion cost falls under the
threshold. During ``release`` only the undock commands are sent (everything else
holds: the controller's undock commands, for links without ports). Other robots (MMRP)
run through :meth:`Controller.control` as before.

A phase that does not finish within ``action_timeout`` seconds of driver time, on top
of the time the controller's ``begin`` says it needs, is retried (the controller is
restarted) up to ``retries`` times, then the action and the run fail with a one-line
reason naming the action. Events go to the :class:`~msrr.core.events.EventSink` the run
hands in (in ``platform run``, every plugin's event hooks); the executor never asks the
plugin host.
"""

from __future__ import annotations

import math
import time as wallclock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .actions import STRUT_ENDS, TopologyDiff, flow_move, topology_diff
from .alignment import rot_z, wrap_angle
from .capabilities import Recognizer
from .closed_loop import (
    DockCycle,
    JointController,
    PhaseTracker,
    TrackingOptions,
    connection_goal,
    reach_measure,
    tree_for,
    turned_goal,
)
from .configuration import Configuration
from .control import Control, Controller, StartLayout, WheelCorrector
from .driver import Driver, ModuleCommand, Observation
from .errors import ExecutionError, MsrrError
from .estimation import Estimate, estimator_for, report_filter_for
from .events import (
    ActionStatus,
    EventSink,
    NoEvents,
    Phase,
    Run,
    RunResult,
    Tick,
    TopologyEvent,
)
from .kinematics import GroundModel, KinematicTree
from .plan import (
    Action,
    ActionType,
    BehaviorCall,
    ConnectionChange,
    LinkLayout,
    behavior_runs,
    link_layout,
)
from .robot import Robot
from .shape import skeletal_errors

__all__ = ["SIDEWAYS", "CourseLoop", "Executor", "ExecutorOptions", "GaitLoop", "HeadingLoop",
           "StallWatch", "behavior_commands", "course_loop", "gait_loop", "heading_loop",
           "ends_loop", "held_heading", "retakes_unturned",
           "phases_of", "slid", "slides", "steered", "timed_step", "turn_bound"]


@dataclass(frozen=True)
class ExecutorOptions:
    """How the executor runs.

    Attributes:
        rate: control rate [Hz] of driver time.
        action_timeout: driver time one phase attempt may take [s] beyond what the
            controller says it needs.
        retries: attempts repeated after a timeout before the action fails.
        tracking: IK tracking settings (robots with joint modes).
        ik: use IK tracking where it applies (``False``: the controller's own path).
        heading_gain: gain of a mapping behavior's heading loop [1/s]: ``yaw_rate``
            added per radian of heading error (0: no loop; :class:`HeadingLoop`).
        heading_integral: its integral gain [1/s^2] (a turn the wheels make unasked).
        max_heading_correction: bound of what the loop adds to ``yaw_rate`` [rad/s].
        course_gain: gain of a straight behavior's course loop [1/m]: heading offset per
            metre off the commanded line (0: no course loop; :class:`CourseLoop`).
        course_integral: its integral gain [1/m^2], per metre of travel (a crab the
            wheels make unasked).
        max_course_offset: bound of the heading offset it sets [rad].
        gait_gain: gain of a sequence behavior's heading loop: the body's turn about its
            planted feet asked of a step per radian of heading error (0 with
            ``gait_integral`` 0: no loop; :class:`GaitLoop`).
        gait_integral: its integral gain, per step (a turn the gait makes unasked).
        max_gait_turn: bound of the turn one step is asked [rad].
        max_gait_course_offset: bound of the heading offset a sequence behavior's course
            loop sets [rad] (``max_course_offset`` is the mapping behaviors'). A gait turns
            its body by a few degrees a loop at most (the FreeSN squirm at its bound: +1 to
            +5 deg a loop exact, less under noise), so an offset of 45-60 deg after a step
            that slid sideways was one it could not turn to in its run: the loop turned the
            body the wrong way after it and stayed at its bound for the rest (issue 31).
        stall_window: a tracked ``approach`` or ``move`` phase whose estimated shape error
            improved by less than ``stall_gain`` [rad] over this long [s of driver time]
            ends early, stalled (:class:`StallWatch`; 0: never); stall_time: the
            error's low-pass time constant [s].
        gait_step_time: how long a *timed* gait step runs at most [s of driver time]: a
            step of a sequence behavior whose stance differs from the one before it by less
            than ``timed_step_size`` (RMS, eq. 8) ends when reached or after this long,
            whichever is first. The reaching test cannot tell such a step from its start
            under noise: the S12N6 trot's stances differ by 3.3 deg, and under 2 deg of
            report noise its estimate stayed 3.4-4.5 deg from the goal while the stance
            was held until the body sank (seeds 10-12 0/3, docs/freesn.md); with exact
            reports its steps end at their first or second tick anyway. 0: no timed steps.
        timed_step_size: see ``gait_step_time`` [rad]; the S4N5 crawl's and squirm's
            steps (18.3, 26.1 deg) are not timed.
        redocks: connections that break unplanned (a strut end torn off its node by a
            load over its strength, seen by the recognizer as an undock nobody asked for)
            docked again per action before it fails: the running phase stops, an
            approach and connect phase toward the action's target dock the end again
            (:meth:`Executor._redock_broken`), and the phase resumes with its deadline
            moved by the time that took (0: the action fails at the first break, as
            before stop 46). Only tracked actions (IK tracking) and strut ends.
        settle_tolerance: a ``move`` that stalls on its last attempt with its estimated
            shape error (the watch's) under this [rad] is taken as reached, not failed
            (0: never): 5 deg, the judge's goal tolerance. FreeBOT pieces-to-tree's final
            move under 2 deg of noise (seed 14) holds 18 of its 19 connections, each a
            latched piece's within 20 deg of its goal (``ContactController``), so nothing
            moves: the shape stayed 3.7-4.0 deg from the goal on the simulator's state, the
            estimate 3.3-6.3 deg, never under the phase's 3 deg, and the run failed.
    """

    rate: float = 10.0
    action_timeout: float = 60.0
    retries: int = 1
    tracking: TrackingOptions = TrackingOptions()
    ik: bool = True
    heading_gain: float = 1.0
    heading_integral: float = 0.2
    max_heading_correction: float = 0.5
    course_gain: float = 6.0
    course_integral: float = 9.0
    max_course_offset: float = math.radians(60.0)
    gait_gain: float = 0.5
    gait_integral: float = 0.2
    max_gait_turn: float = math.radians(8.0)
    max_gait_course_offset: float = math.radians(20.0)
    stall_window: float = 15.0
    stall_gain: float = math.radians(0.5)
    stall_time: float = 1.0
    gait_step_time: float = 0.2
    timed_step_size: float = math.radians(6.0)
    settle_tolerance: float = math.radians(5.0)
    redocks: int = 2

    def __post_init__(self) -> None:
        if not self.rate > 0:
            raise ExecutionError(f"control rate must be positive, got {self.rate} Hz")
        if not self.action_timeout > 0:
            raise ExecutionError(f"action timeout must be positive, got {self.action_timeout} s")
        if self.retries < 0 or self.redocks < 0:
            raise ExecutionError(f"retries and redocks must be >= 0, got {self.retries}, "
                                 f"{self.redocks}")
        loops = (self.heading_gain, self.heading_integral, self.max_heading_correction,
                 self.course_gain, self.course_integral, self.max_course_offset,
                 self.gait_gain, self.gait_integral, self.max_gait_turn,
                 self.max_gait_course_offset)
        if min(loops) < 0:
            raise ExecutionError(f"heading and course gains and bounds must be >= 0, got {loops}")
        if min(self.gait_step_time, self.timed_step_size) < 0:
            raise ExecutionError("gait step time and timed step size must be >= 0, got "
                                 f"{self.gait_step_time}, {self.timed_step_size}")
        if min(self.stall_window, self.stall_gain, self.settle_tolerance) < 0 \
                or not self.stall_time > 0:
            raise ExecutionError("stall window, gain and settle tolerance must be >= 0 and its "
                                 f"time > 0, got {self.stall_window}, {self.stall_gain}, "
                                 f"{self.settle_tolerance}, {self.stall_time}")


def phases_of(action: Action, diff: TopologyDiff, *, tracking: bool = False) -> list[Phase]:
    """The phases that execute ``action`` given the topology change it needs.

    With ``tracking`` (IK tracking toward the target), a disconnection moves to its
    target after the release (section 4.1, Fig. 10: "first disconnecting the connector
    and then moving to the target configuration").
    """
    if action.type is ActionType.FLOW:
        return [Phase.FLOW, Phase.HANDOVER]
    if action.type is ActionType.BEHAVIOR:
        return [Phase.BEHAVIOR]
    out: list[Phase] = []
    if diff.broken:
        out.append(Phase.RELEASE)
    if diff.made:
        out += [Phase.APPROACH, Phase.CONNECT]
    elif action.goals or not diff.broken or tracking:
        out.append(Phase.MOVE)
    return out


def _port_commands(changes: tuple[ConnectionChange, ...], attribute: str
                   ) -> dict[str, ModuleCommand]:
    ports: dict[str, list[str]] = {}
    for change in changes:
        for module, port in ((change.source, change.source_port),
                             (change.target, change.target_port)):
            if port is not None:
                ports.setdefault(module, []).append(port)
    return {m: ModuleCommand(**{attribute: tuple(p)}) for m, p in ports.items()}


def _merge(control: Control, extra: dict[str, ModuleCommand]) -> dict[str, ModuleCommand]:
    merged = dict(control.commands)
    for module, cmd in extra.items():
        base = merged.get(module, ModuleCommand())
        merged[module] = ModuleCommand(joints=base.joints, wheels=base.wheels,
                                       dock=base.dock + cmd.dock, undock=base.undock + cmd.undock)
    return merged


def _undocks(control: Control) -> Control:
    """``control`` with only its undock commands: a contact without ports (a freeform
    connector) is released by the controller (the flow contract), while IK tracking
    holds everything else during a release."""
    return Control(commands={m: ModuleCommand(undock=c.undock)
                             for m, c in control.commands.items() if c.undock})


def _needed_time(needed: object, controller: Controller) -> float:
    """The driver time [s] a controller's ``begin`` said its phase needs (``None``: 0)."""
    if needed is None:
        return 0.0
    if isinstance(needed, (int, float)) and not isinstance(needed, bool) \
            and math.isfinite(needed) and needed >= 0:
        return float(needed)
    raise ExecutionError(f"controller {getattr(controller, 'name', controller)!r}: begin "
                         f"returned {needed!r}, not a time >= 0 [s] or None")


class _ActionFailed(Exception):
    def __init__(self, reason: str):
        self.reason = reason


class _Broken(_ActionFailed):
    """Strut ends that came off their nodes unasked during a tracked action
    (:attr:`ExecutorOptions.redocks`); failing the action unless they are docked again."""

    def __init__(self, reason: str, changes: tuple[ConnectionChange, ...], time: float):
        super().__init__(reason)
        self.changes = changes
        self.time = time


def behavior_commands(action: Action, parameters: Mapping[str, float] | None = None
                      ) -> dict[str, dict[str, float]]:
    """A mapping behavior's wheel values for this tick, per module: each
    :class:`~msrr.core.plan.CommandGain`'s ``sum(gain * parameter)`` under its
    :attr:`~msrr.core.plan.CommandGain.key` (``{"S4": {"a": 12.5, "b": 12.5}}``), for
    ``parameters`` (default: the call's own)."""
    call = action.behavior
    out: dict[str, dict[str, float]] = {}
    if call is None or call.kind != "mapping":
        return out
    values = call.parameters if parameters is None else parameters
    for command in call.commands:
        wheels = out.setdefault(command.module, {})
        wheels[command.key] = wheels.get(command.key, 0.0) + command.value(values)
    return out


@dataclass
class HeadingLoop:
    """A mapping behavior's heading loop (issue 31): a PI loop on its ``yaw_rate`` that
    keeps the estimated heading on ``start + asked * t + offset``, so the commanded
    direction stays where it was in the world frame the behavior started in (``offset``:
    what a :class:`CourseLoop` asks on top).

    Attributes:
        start: the estimated heading when the behavior began [rad].
        asked: the ``yaw_rate`` the call asks for [rad/s].
        gain: proportional gain [1/s]; integral_gain: integral gain [1/s^2].
        bound: bound of the correction added to ``yaw_rate`` [rad/s] (the integral is
            held within it: no wind-up).
        integral: the heading error integrated so far [rad s].
    """

    start: float
    asked: float
    gain: float
    integral_gain: float
    bound: float
    integral: float = 0.0

    def correction(self, heading: float, elapsed: float, dt: float, offset: float = 0.0
                   ) -> float:
        """What to add to ``yaw_rate`` [rad/s] at ``elapsed`` [s] into the behavior, with
        the heading estimated at ``heading`` [rad], ``dt`` [s] after the last call, and
        the reference turned by ``offset`` [rad]."""
        error = (self.start + self.asked * elapsed + offset - heading + math.pi) \
            % (2 * math.pi) - math.pi
        if self.integral_gain > 0:
            held = self.bound / self.integral_gain
            self.integral = float(np.clip(self.integral + error * dt, -held, held))
        return float(np.clip(self.gain * error + self.integral_gain * self.integral,
                             -self.bound, self.bound))


@dataclass
class CourseLoop:
    """A straight mapping behavior's course loop (issue 31): wheels that crab (node
    wheels: the direction of travel is not the body's heading) or slip go off the
    commanded line however well the heading is held, so this outer loop follows the
    line itself, from the estimated place: it sets the :class:`HeadingLoop`'s
    reference ``offset = -gain y - integral_gain * integral(y ds)``, ``y`` [m] the
    estimated distance left of the line through ``origin`` along ``direction``, ``s``
    the estimated path length. With the travel turned by ``offset`` plus an unknown crab
    ``c``, ``y' = offset + c`` per metre travelled, so ``I = integral(y ds)`` obeys
    ``I'' + gain I' + integral_gain I = c``: no offset left from the line at rest
    (``y = 0``), the crab cancelled by the integral; a damped second-order loop in the
    path length (natural wavenumber ``sqrt(integral_gain)`` [1/m]), whatever the speed.

    Attributes:
        origin: the estimated place where the behavior began [m], shape (2,).
        direction: the commanded direction of travel in the estimate's frame, unit,
            shape (2,) (its sense that of the travel asked: ``-direction`` for a negative
            ``speed``).
        gain: [1/m]; integral_gain: [1/m^2]; bound: bound of the offset [rad] (the
            integral is held within it: no wind-up).
        integral: ``y`` integrated over the path so far [m^2].
        last: the estimated place at the last call [m], shape (2,).
    """

    origin: np.ndarray
    direction: np.ndarray
    gain: float
    integral_gain: float
    bound: float
    integral: float = 0.0
    last: np.ndarray | None = None

    def offset(self, position: np.ndarray) -> float:
        """The heading offset [rad] at the estimated place ``position`` [m], shape (2,)."""
        position = np.asarray(position, dtype=float)
        shift = position - self.origin
        left = float(self.direction[0] * shift[1] - self.direction[1] * shift[0])
        step = 0.0 if self.last is None else float(np.linalg.norm(position - self.last))
        self.last = position
        if self.integral_gain > 0:
            held = self.bound / self.integral_gain
            self.integral = float(np.clip(self.integral + left * step, -held, held))
        return float(np.clip(-self.gain * left - self.integral_gain * self.integral,
                             -self.bound, self.bound))


@dataclass
class GaitLoop:
    """A sequence behavior's heading loop (issue 31): a gait has no ``yaw_rate`` to
    correct, and one of its loops may turn the body unasked (the FreeSN squirm turned
    7.4 deg a loop, exact, every loop the same way). Before each step (but the
    behavior's first) this asks the step to turn the body about its planted feet by
    ``gain e + integral_gain sum(e)``, ``e`` the error of the estimated heading from
    ``start + offset`` (``offset``: what a :class:`CourseLoop` asks on top, per metre off
    the commanded line), bounded; the executor bends the step's goal by it
    (:func:`~msrr.core.closed_loop.turned_goal`). A discrete PI loop over the steps: a
    gait turns only as fast as its steps go.

    Attributes:
        start: the body's estimated heading when the behavior began [rad].
        gain, integral_gain: per step; bound: bound of one step's turn [rad] (the integral
            is held within it: no wind-up).
        integral: the heading errors summed over the steps so far [rad].
    """

    start: float
    gain: float
    integral_gain: float
    bound: float
    integral: float = 0.0

    def turn(self, heading: float, offset: float = 0.0, step: float = math.inf) -> float:
        """The turn [rad] to ask of the next step, the body's heading estimated at
        ``heading`` [rad] and the reference turned by ``offset`` [rad]; at most ``bound``
        and at most ``step`` [rad], the step's own size (RMS, eq. 8, between the stances
        it goes from and to): the S12N6 trot's steps of 3.3 deg turned by 8 deg folded the
        body at 4 deg + 10 % (seed 12; at most 3.3 deg it crawls, docs/freesn.md stop 48),
        the squirm's 26 deg steps keep 8 deg."""
        error = wrap_angle(self.start + offset - heading)
        if self.integral_gain > 0:
            held = self.bound / self.integral_gain
            self.integral = float(np.clip(self.integral + error, -held, held))
        most = min(self.bound, step)
        return float(np.clip(self.gain * error + self.integral_gain * self.integral,
                             -most, most))


@dataclass
class StallWatch:
    """Ends a phase that makes no progress (issue 31): a collapsed noisy S12N6 crawl ran
    its 90 s phase timeout twice, 15 min of wall time, for nothing. Progress is the
    phase's estimated error (from reports only, never the simulator's state: the IK
    tracker's, :attr:`~msrr.core.closed_loop.PhaseTracker.error`), low-passed again over
    ``time`` [s] so a report's white noise is not taken for progress; the phase has
    stalled when that error has not come ``gain`` [rad] under its best mark for
    ``window`` [s]. A slowly converging phase sets a new mark at least every
    ``window``, so it is never cut: the slowest progress kept is ``gain / window``
    (0.033 deg/s by default) plus about ``3 j / window`` for a jitter ``j`` left in the
    low-passed error (0.05 deg/s for the tracker's error under 2 deg of report noise).

    Attributes:
        window: [s]; gain: [rad]; time: [s].
        error: the low-passed error [rad], ``None`` before the first; began: when the
            first came [s].
        mark: the best error the last progress reached [rad]; since: when [s].
    """

    window: float
    gain: float
    time: float
    error: float | None = None
    began: float = 0.0
    mark: float = math.inf
    since: float = 0.0

    def stalled(self, error: float, now: float, dt: float) -> str:
        """Why the phase has stalled (``""``: it has not), with the estimated ``error``
        [rad] at driver time ``now`` [s], ``dt`` [s] after the last call."""
        if not math.isfinite(error):
            return ""
        if self.error is None:
            self.error, self.began = error, now
        self.error += min(1.0, dt / self.time) * (error - self.error)
        warming = now - self.began < self.time   # the first mark is a low-passed one
        if warming or self.error <= self.mark - self.gain:
            self.mark, self.since = math.inf if warming else self.error, now
            return ""
        if now - self.since < self.window - 1e-9:
            return ""
        return (f"shape error {math.degrees(self.error):.1f} deg for "
                f"{now - self.since:.0f} s (not {math.degrees(self.gain):g} deg better)")


def heading_loop(call: BehaviorCall | None, heading: float | None,
                 options: ExecutorOptions) -> HeadingLoop | None:
    """The heading loop of a mapping behavior that has a ``yaw_rate`` gain or
    :func:`slides`, starting at ``heading`` [rad]; ``None`` when it has neither or the
    heading is not known. A behavior that cannot turn (radial strut wheels) gets a loop
    bound to no correction: :func:`steered` holds its direction by turning its travel."""
    turns = call is not None and any(p == "yaw_rate" and g for c in call.commands
                                     for p, g in c.gains)
    if call is None or call.kind != "mapping" or heading is None or options.heading_gain == 0 \
            or not (turns or slides(call)):
        return None
    return HeadingLoop(heading, float(call.parameters.get("yaw_rate", 0.0)),
                       options.heading_gain, options.heading_integral,
                       min(options.max_heading_correction, turn_bound(call)) if turns else 0.0)


def gait_loop(call: BehaviorCall | None, heading: float | None, options: ExecutorOptions
              ) -> GaitLoop | None:
    """The heading loop of a sequence behavior that states its direction, starting at
    ``heading`` [rad]; ``None`` when there is none or the heading is not known."""
    if call is None or call.kind != "sequence" or call.direction is None or heading is None \
            or options.gait_gain == options.gait_integral == 0:
        return None
    return GaitLoop(heading, options.gait_gain, options.gait_integral, options.max_gait_turn)


def timed_step(action: Action, before: Configuration, options: ExecutorOptions) -> float:
    """How long [s] ``action`` may run when it is a *timed* gait step, else 0: a step of a
    sequence behavior whose target is within ``options.timed_step_size`` (RMS, eq. 8) of
    ``before``, the target of the action before it, both with connection vectors
    (:class:`ExecutorOptions`, ``gait_step_time``)."""
    call = action.behavior
    if not options.gait_step_time or call is None or call.kind != "sequence":
        return 0.0
    step, angles, _ = skeletal_errors(before, action.target)
    near = len(angles) > 0 and step < options.timed_step_size   # shapes with vectors only
    return options.gait_step_time if near else 0.0


def ends_loop(actions: Sequence[Action], index: int) -> bool:
    """Whether ``actions[index]`` is the last step of its loop of a sequence behavior (the
    plan's last action, or the next one is not in the same loop): a gait stops only there
    (:func:`retakes_unturned`)."""
    call = actions[index].behavior
    if call is None or index + 1 >= len(actions):
        return True
    following = actions[index + 1].behavior
    return following is None or following.name != call.name or following.loop != call.loop


def retakes_unturned(actions: Sequence[Action], index: int, turn: float) -> bool:
    """Whether a gait that stops after ``actions[index]``, run with its goal turned by
    ``turn`` [rad] (:class:`GaitLoop`; 0: not turned, as a tree that cannot pivot on one
    planted foot is not, :func:`~msrr.core.closed_loop.turned_goal`), takes that step
    again unturned: the step ends a
    loop (:func:`ends_loop`) and was turned. The judge measures the stance a gait stops
    in (the squirm's planted leg turned 8 deg left its last stance 5.2-5.6 deg RMS off
    under noise, over the 5 deg tolerance); asking no turn of these steps instead left
    the loop too weak to hold the squirm (issue 31: its squirm-down step's turn alone
    moved the body about 1 deg of the 8 asked, and each squirm-up step turned it -5 to
    -9 deg)."""
    return bool(turn) and ends_loop(actions, index)


def held_heading(heading: float, recognized: Configuration, target: Configuration) -> float:
    """The heading [rad] of the body a behavior holds in the shape of ``target``: the
    estimated ``heading`` of the frame ``recognized`` is stated in plus the turn of
    ``target`` onto ``recognized`` (eq. 8). That frame (FreeSN: the root node's, a shell
    its connectors roll on) may turn under the body; the sum does not (issue 31: fig22's
    rollers spun the root's shell 1.7 rad while the body held its heading)."""
    return heading + skeletal_errors(recognized, target)[2]


def turn_bound(call: BehaviorCall) -> float:
    """The largest ``yaw_rate`` correction [rad/s] that asks no wheel of ``call`` more than
    its travel does: ``min |sum of its other gains x parameters| / |yaw_rate gain|`` over
    the commands that have both (a roller asked to turn harder than it rolls forward
    scrubs the system round on the spot: fig22's wheeled move, issue 31). Infinite when
    none does (a turn on the spot: the turn is all it asks)."""
    straight = {**call.parameters, "yaw_rate": 0.0}
    bounds = [abs(command.value(straight) / turn) for command in call.commands
              if (turn := dict(command.gains).get("yaw_rate", 0.0)) and command.value(straight)]
    return min(bounds, default=math.inf)


def course_loop(call: BehaviorCall | None, estimate: Estimate, frame: float,
                options: ExecutorOptions, bound: float | None = None) -> CourseLoop | None:
    """The course loop of a straight mapping behavior (no ``yaw_rate`` asked) that states
    its direction, from the ``estimate`` where it begins; ``frame`` [rad] turns the
    action target's frame (the call's ``direction``) onto the recognized configuration's,
    whose heading the estimate gives; ``bound`` [rad] of its offset, default
    ``options.max_course_offset``. ``None`` when there is none to close, or the place
    or heading is not known."""
    if call is None or call.direction is None or call.parameters.get("yaw_rate", 0.0) \
            or estimate.position is None or estimate.heading is None \
            or options.course_gain == options.course_integral == 0:
        return None
    turned = (rot_z(estimate.heading + frame) @ np.asarray(call.direction, dtype=float))[:2]
    norm = float(np.linalg.norm(turned))
    if norm < 1e-9:
        return None
    sense = -1.0 if call.parameters.get("speed", 1.0) < 0 else 1.0
    return CourseLoop(np.asarray(estimate.position, dtype=float).copy(), sense * turned / norm,
                      options.course_gain, options.course_integral,
                      options.max_course_offset if bound is None else bound)


SIDEWAYS = "sideways"
"""The parameter of a mapping behavior's travel to the left of its heading [m/s] (a
holonomic base: fig22(j)'s node wheels roll along 60, 180 and -60 deg, a kiwi drive)."""


def slides(call: BehaviorCall) -> bool:
    """Whether ``call`` can travel sideways: a command has a :data:`SIDEWAYS` gain."""
    return any(p == SIDEWAYS and g for c in call.commands for p, g in c.gains)


def slid(parameters: Mapping[str, float], angle: float) -> dict[str, float]:
    """``parameters`` with the travel they ask (``speed`` ahead, :data:`SIDEWAYS` to the
    left, [m/s]) turned by ``angle`` [rad] counter-clockwise."""
    ahead, left = float(parameters.get("speed", 0.0)), float(parameters.get(SIDEWAYS, 0.0))
    c, s = math.cos(angle), math.sin(angle)
    return {**parameters, "speed": c * ahead - s * left, SIDEWAYS: s * ahead + c * left}


def steered(call: BehaviorCall, loop: HeadingLoop, course: CourseLoop | None, heading: float,
            place: np.ndarray | None, elapsed: float, dt: float) -> dict[str, float]:
    """The parameters of mapping behavior ``call`` at ``elapsed`` [s], the body's heading
    estimated at ``heading`` [rad] and its place at ``place`` [m] (shape (2,)): ``yaw_rate``
    corrected by ``loop``; the offset ``course`` sets turns the heading's reference, or,
    for a call that :func:`slides`, its travel itself, turned back by as much as the body
    turned, so it keeps its direction in the world (issue 31: the node wheels turn the
    body at a thirtieth of the rate asked, every wheel scrubbing, while a creep crosses
    the line; sliding, the travel turns at once; radial strut wheels cannot turn the
    body at all, and with no place known have no course loop either)."""
    offset = 0.0 if course is None or place is None else course.offset(place)
    if not slides(call):
        return {**call.parameters,
                "yaw_rate": loop.asked + loop.correction(heading, elapsed, dt, offset)}
    correction = loop.correction(heading, elapsed, dt)
    turned = wrap_angle(heading - loop.start - loop.asked * elapsed)
    return {**slid(call.parameters, offset - turned), "yaw_rate": loop.asked + correction}


def _with_wheels(commands: dict[str, ModuleCommand], wheels: dict[str, dict[str, float]]
                 ) -> dict[str, ModuleCommand]:
    merged = dict(commands)
    for module, values in wheels.items():
        base = merged.get(module, ModuleCommand())
        merged[module] = ModuleCommand(joints=base.joints, wheels={**base.wheels, **values},
                                       dock=base.dock, undock=base.undock)
    return merged


class Executor:
    """Runs one plan on one driver.

    Args:
        run: the run (its ``plan`` is executed); passed to every event.
        driver: a connected driver, already reset to the plan's start.
        recognizer: turns ``observation.sensors`` into a configuration (and, where it
            can, estimates where the system is: :mod:`msrr.core.estimation`).
        controller: turns actions into module commands.
        options: rate, timeout, retries.
        sink: where events go (none are sent without one).
        robot: the robot; its default joint mode builds kinematic trees for IK tracking.
        controllers: the robot's controllers by name: a kinematic node's ``controller``
            picks its own (else ``controller`` drives it).
        on_grant: called with the driver time [s] each phase attempt is given on top of
            ``action_timeout`` because its controller said it needs it (so the run can
            move a default overall deadline by as much).
        placed: the configuration the driver was reset to, as the modules were laid
            out (a :class:`~msrr.core.control.StartLayout` controller is told it);
            ``None``: the plan's start. They differ when the run planned again from the
            recognized start, whose vectors carry the sensors' noise.
    """

    def __init__(self, run: Run, driver: Driver, recognizer: Recognizer, controller: Controller,
                 options: ExecutorOptions | None = None, *, sink: EventSink | None = None,
                 robot: Robot | None = None, controllers: Mapping[str, Controller] | None = None,
                 on_grant: Callable[[float], None] | None = None,
                 placed: Configuration | None = None):
        self.run = run
        self.placed = placed
        self.on_grant = on_grant
        self.driver = driver
        self.recognizer = recognizer
        self.controller = controller
        self.options = options or ExecutorOptions(rate=run.rate)
        self.dt = 1.0 / self.options.rate
        self.tick_index = 0
        self.events: list[TopologyEvent] = []
        self.retries = 0
        self.flows = 0
        self._current: Configuration | None = None
        self._layout: tuple[Configuration, LinkLayout] | None = None   # of a recognized one
        self._expected: set = set()
        self._tracker: PhaseTracker | None = None
        self._docking: DockCycle | None = None  # a tracked connect phase's press/back cycle
        self.sink: EventSink = sink or NoEvents()
        self._joint_mode: type | None = None
        self._registered = dict(controllers or {})
        self._controllers: dict[str, JointController] = {}
        self._ik = self.options.ik and isinstance(controller, JointController)
        self.result = RunResult(success=False, actions_total=len(run.plan.actions))
        self._started = wallclock.perf_counter()
        self._spans = {span.start: span for span in behavior_runs(run.plan.actions)}
        self._moving_from: np.ndarray | None = None
        self._estimator = estimator_for(recognizer)
        self._filter = report_filter_for(recognizer)
        self.estimate = Estimate()
        self._loop: HeadingLoop | None = None  # the running mapping behavior's
        self._course: CourseLoop | None = None  # and its course loop, if straight
        self._gait: GaitLoop | None = None  # the running sequence behavior's
        self._gait_course: CourseLoop | None = None  # and its course loop
        self._turn = 0.0  # the turn the gait loop asks of the running action [rad]
        self._turned = False  # whether it turned the running action's goal
        self._seen: Configuration | None = None  # recognized with the last estimate
        self._skipping = False
        self._phase_began = 0.0
        self._redocks = 0  # unplanned undocks docked again in the running action
        if self._ik and robot is not None:
            try:
                self._joint_mode = robot.default_joint_mode()
            except MsrrError:
                self._joint_mode = None

    # -- public -----------------------------------------------------------------------

    def execute(self) -> RunResult:
        """Execute every action of the plan; never raises for a failed action.

        ``success`` says every action finished and the recognized topology is the goal's;
        whether the run did what was asked is the judge's verdict. Whatever ends the run
        (a failed action, a driver error, an interrupt), :attr:`result` holds the counts
        of what the driver reported up to there.
        """
        self.driver.require_connected()
        plan = self.run.plan
        self._started = wallclock.perf_counter()
        result = self.result
        self._current = self._estimated(self._observe())
        if isinstance(self.controller, StartLayout):
            self.controller.start(self.placed or plan.start)
        index, last, turned = -1, None, None
        try:
            for index, action in enumerate(plan.actions):
                if self._skips(index, action):
                    self._retake_unturned(turned)
                    turned = None
                    result.actions_skipped += 1
                    continue
                if index in self._spans:
                    self._moving_from = self._centre()
                self._turn, self._turned = self._gait_turn(index, action, last), False
                self._execute_action(index, action)
                turn = self._turn if self._turned else 0.0
                turned = (index, action) if retakes_unturned(plan.actions, index, turn) else None
                last = action
                result.actions_done += 1
            self._retake_unturned(turned)
            index = len(plan.actions)
            remaining = topology_diff(self._current, plan.goal)
            if remaining:
                raise _ActionFailed(f"final topology differs from the goal: {remaining}")
            result.success = True
        except _ActionFailed as failure:
            result.reason = failure.reason
            result.failed_action = index if 0 <= index < len(plan.actions) else None
        finally:
            self._tally()
            self.driver.send_action({})
        return result

    def _retake_unturned(self, turned: tuple[int, Action] | None) -> None:
        """A gait stopping after ``turned`` (index, action: a loop's last step run with its
        goal turned, :func:`retakes_unturned`) takes that step again unturned, into its designed
        stance; nothing when ``None``."""
        if turned is not None:
            self._turn = 0.0
            self._execute_action(*turned)

    def _tally(self) -> None:
        """Fill :attr:`result`'s counts from what the driver reported so far."""
        result = self.result
        result.docks = sum(1 for e in self.events if e.kind == "dock")
        result.undocks = sum(1 for e in self.events if e.kind == "undock")
        result.flows = self.flows
        result.retries = self.retries
        result.ticks = self.tick_index
        result.sim_time = self.driver.time
        result.wall_time = wallclock.perf_counter() - self._started
        result.final = self._current

    # -- actions ----------------------------------------------------------------------

    def _execute_action(self, index: int, action: Action) -> None:
        assert self._current is not None
        diff = topology_diff(self._current, action.target)
        self._check_plan_consistency(index, action, diff)
        if action.type is ActionType.FLOW and not action.changes:
            action = replace(action, changes=diff.changes())  # what flow_of reads
        self.sink.action(self.run, action, ActionStatus.STARTED)
        self._expected = {c.key for c in diff.changes()}
        self._redocks = 0
        tracking = self._tracks(action)
        try:
            for phase in phases_of(action, diff, tracking=tracking):
                self._run_phase(index, action, phase, diff)
        except _ActionFailed:
            self.sink.action(self.run, action, ActionStatus.FAILED)
            raise
        finally:
            self._expected = set()
            self._tracker = None
        if action.type is ActionType.FLOW:
            seen = {(e.kind, e.change.key) for e in self.events if e.action_index == index}
            wanted = ({("undock", c.key) for c in diff.broken}
                      | {("dock", c.key) for c in diff.made})
            self.flows += bool(wanted) and wanted <= seen
        self.sink.action(self.run, action, ActionStatus.SUCCEEDED)

    def _check_plan_consistency(self, index: int, action: Action, diff: TopologyDiff) -> None:
        assert self._current is not None
        planned = {c.key for c in action.changes}
        needed = {c.key for c in diff.changes()}
        if action.type is ActionType.MOVING and diff:
            raise _ActionFailed(f"action {index + 1} ({action}): a moving action cannot change "
                                f"the topology ({diff})")
        if planned and not needed <= planned:
            raise _ActionFailed(f"action {index + 1} ({action}): the current topology needs "
                                f"{diff}, not what the action plans")
        if action.type is ActionType.FLOW and flow_move(self._current, diff) is None:
            raise _ActionFailed(f"action {index + 1} ({action}): from the current topology, "
                                f"{diff} is not a flow (one leaf to a neighbour of its parent)")

    def _run_phase(self, index: int, action: Action, phase: Phase, diff: TopologyDiff) -> None:
        attempts = self.options.retries + 1
        for attempt in range(attempts):
            if attempt:
                self.retries += 1
                self.sink.action(self.run, action, ActionStatus.RETRYING)
            observation = self._observe()
            needed = None
            if not self._begin_tracking(action, phase, diff, observation, retry=attempt > 0) \
                    and phase is not Phase.BEHAVIOR:
                needed = self.controller.begin(action, phase, observation)
            granted = _needed_time(needed, self.controller)
            if granted and self.on_grant is not None:
                self.on_grant(granted)
            budget = self.options.action_timeout + granted
            self._phase_began = self.driver.time
            self._loop = heading_loop(action.behavior, self._heading(action), self.options) \
                if phase is Phase.BEHAVIOR else None
            self._course = None if self._loop is None else course_loop(
                action.behavior, self.estimate, self._frame(action), self.options)
            deadline = self.driver.time + budget
            if phase is Phase.BEHAVIOR and action.behavior is not None \
                    and action.behavior.duration is not None:
                deadline = self.driver.time + action.behavior.duration + self.dt
            timed = self._timed_step(index, action, phase)
            if timed:
                deadline = min(deadline, self.driver.time + timed)
            watch = self._stall_watch(phase)
            stalled = ""
            while self.driver.time < deadline - 1e-9 and not stalled:
                try:
                    if self._tick(index, action, phase, diff):
                        return
                except _Broken as broken:
                    deadline += self._redock_broken(index, action, phase, diff, broken)
                    watch = self._stall_watch(phase)
                    continue
                if watch is not None:
                    stalled = watch.stalled(self._progress(), self.driver.time, self.dt)
            if timed and not stalled:   # ended on its time (ExecutorOptions.gait_step_time)
                self.result.timed_out_steps += 1
                return
        if stalled and self._settled(phase, watch):
            assert watch is not None and watch.error is not None
            self.result.settled.append(
                f"action {index + 1} ({action}) settled at {math.degrees(watch.error):.1f} deg "
                f"estimated after {attempts} attempt(s)")
            return
        if stalled:
            raise _ActionFailed(f"action {index + 1} ({action}) failed: phase {phase.value} "
                                f"stalled: {stalled}, after {attempts} attempt(s)")
        raise _ActionFailed(
            f"action {index + 1} ({action}) failed: phase {phase.value} did not finish within "
            f"{budget:g} s of driver time after {attempts} attempt(s)"
            + self._pending(phase, diff))

    def _timed_step(self, index: int, action: Action, phase: Phase) -> float:
        """The time bound [s] of ``action``'s tracked ``move`` (:func:`timed_step`), else 0
        (a controller's own path, as MMRP's moves, is never timed)."""
        if phase is not Phase.MOVE or index == 0 or self._tracker is None:
            return 0.0
        return timed_step(action, self.run.plan.actions[index - 1].target, self.options)
    def _redock_broken(self, index: int, action: Action, phase: Phase, diff: TopologyDiff,
                       broken: _Broken) -> float:
        """Dock the strut ends that came off unasked again, then resume ``phase``; the
        driver time it took [s] (the phase's deadline moves by as much).

        An approach and a connect phase (section 4.1's ``S_conn`` and ``S_extr``, with the
        connect phase's press, back-off and re-aim) toward ``action``'s target, the ends
        docked as a connection action docks them: what a planned re-dock does. A
        behavior's wheels stop meanwhile (its commands name none). The break stays on the
        timeline as the unexpected undock it was, the action's status goes ``redocking``
        and the run's result notes it (:attr:`RunResult.redocked`).

        Raises:
            _ActionFailed: more breaks in this action than ``options.redocks``, or the
                re-dock did not finish (the reason names the break first).
        """
        if self._redocks >= self.options.redocks:
            raise _ActionFailed(broken.reason + ("" if not self.options.redocks else
                                f" (after {self._redocks} re-dock(s) in this action)"))
        self._redocks += 1
        began, names = self.driver.time, ", ".join(str(c) for c in broken.changes)
        saved = (self._loop, self._course, self._phase_began, self._expected)
        self.sink.action(self.run, action, ActionStatus.REDOCKING)
        self._expected = saved[3] | {c.key for c in broken.changes}
        again = TopologyDiff(made=broken.changes, broken=())
        try:
            for step in (Phase.APPROACH, Phase.CONNECT):
                self._run_phase(index, action, step, again)
        except _ActionFailed as failure:
            raise _ActionFailed(f"{broken.reason}; docking it again failed: "
                                f"{failure.reason}") from None
        finally:
            self._expected = saved[3]
        spent = self.driver.time - began
        # the phase's own clock stops while the ends dock again (a behavior runs its course)
        self._loop, self._course, self._phase_began = saved[0], saved[1], saved[2] + spent
        self.result.redocked.append(f"action {index + 1}: {names} broke at "
                                    f"{broken.time:.1f} s, re-docked at "
                                    f"{self.driver.time:.1f} s")
        observation = self._observe()
        if not self._begin_tracking(action, phase, diff, observation, retry=True) \
                and phase is not Phase.BEHAVIOR:
            self.controller.begin(action, phase, observation)
        return spent

    def _settled(self, phase: Phase, watch: StallWatch | None) -> bool:
        """A ``move`` stalled on its last attempt within ``settle_tolerance`` of its goal
        (estimated): taken as reached (:class:`ExecutorOptions`)."""
        return (phase is Phase.MOVE and watch is not None and watch.error is not None
                and watch.error < self.options.settle_tolerance)

    def _stall_watch(self, phase: Phase) -> StallWatch | None:
        """The watch of a tracked ``approach`` or ``move`` phase (a connection presses
        into its node and a behavior runs its course: neither converges on a shape)."""
        o = self.options
        if self._tracker is None or phase not in (Phase.APPROACH, Phase.MOVE) \
                or not o.stall_window:
            return None
        return StallWatch(o.stall_window, o.stall_gain, o.stall_time)

    def _progress(self) -> float:
        """The tracked phase's error as estimated now [rad] (:attr:`PhaseTracker.error`:
        the recognized configuration, low-passed, against the phase goal; reports only)."""
        assert self._tracker is not None
        return self._tracker.error

    def _pending(self, phase: Phase, diff: TopologyDiff) -> str:
        assert self._current is not None
        left = topology_diff(self._current, self._phase_goal(phase, diff))
        if left:
            return f"; still missing: {left}"
        tracker = self._tracker
        if tracker is None or tracker.last is None:
            return "; target not reached"
        # how far the robot is, and how far the IK's best answer is (a tree that cannot
        # reach the goal shows as a large residual)
        return (f"; target not reached ("
                f"{math.degrees(tracker.measure(self._current, tracker.goal)):.1f} deg RMS "
                f"from the phase goal, IK residual {math.degrees(tracker.last.rms_angle):.1f}"
                f" deg)")

    def _phase_goal(self, phase: Phase, diff: TopologyDiff) -> Configuration:
        """The topology expected at the end of ``phase``."""
        assert self._current is not None
        if phase is Phase.FLOW:
            return self._current
        return diff.applied_to(self._current, made=phase in (Phase.CONNECT, Phase.HANDOVER))

    # -- IK tracking (section 4.1) ------------------------------------------------------

    def _tracks(self, action: Action) -> bool:
        """Whether IK tracking drives ``action``'s moving phases."""
        return (self._ik and action.type is not ActionType.FLOW
                and (action.kinematic_tree is not None or self._joint_mode is not None))

    def _begin_tracking(self, action: Action, phase: Phase, diff: TopologyDiff,
                        observation: Observation, *, retry: bool) -> bool:
        """Set up IK tracking for ``phase``; ``False`` when the controller's path runs it."""
        if not self._tracks(action):
            self._tracker = None
            return False
        if phase is Phase.RELEASE:
            self._tracker = None
            return True
        current = self._recognize(observation)
        conn = connection_goal(current, action.target)
        self._docking = None
        if phase is Phase.CONNECT:
            self._docking = DockCycle(conn, diff.made, self.options.tracking, self.driver.time)
        if phase is Phase.CONNECT and self._tracker is not None and not retry:
            self._tracker.set_goal(self._turned_goal(self._docking.goal, self._tracker.tree))
            return True
        goal = conn if self._docking is None else self._docking.goal
        tree = tree_for(current, action.kinematic_tree, self._joint_mode)
        if tree is None:
            self._tracker = None
            return False
        goal = self._turned_goal(goal, tree)
        ground = GroundModel.for_configuration(current, self.run.spec)
        measure = reach_measure(tree, self._controller_for)
        self._tracker = PhaseTracker(tree, goal, self.options.tracking, seed=self.run.seed,
                                     ground=ground, median_yaw=self.run.spec.defaults.median_yaw,
                                     measure=measure)
        return True

    def _redock(self, configuration: Configuration) -> None:
        """A connect phase's goal as its :class:`DockCycle` turns (press, back off, re-aim
        at the recognized configuration, low-passed)."""
        if self._docking is None or self._tracker is None:
            return
        seen = self._tracker.seen
        goal = self._docking.update(self.driver.time,
                                    configuration if seen is None else seen)
        if goal is not None:
            self._tracker.set_goal(self._turned_goal(goal, self._tracker.tree))

    def _turned_goal(self, goal: Configuration, tree: KinematicTree) -> Configuration:
        """``goal`` turned by the gait loop's turn (:func:`turned_goal`), noting whether
        that changed it (a tree with no planted foot, or a root without edges, is not
        turned: nothing to take again, :func:`retakes_unturned`); the feet's places from
        the robot's edge lengths."""
        turned = goal if not self._turn else turned_goal(
            goal, tree, self._turn, GroundModel.for_configuration(goal, self.run.spec))
        self._turned |= turned is not goal
        return turned

    def _controller_for(self, name: str) -> JointController:
        """The joint controller registered as ``name``, else the executor's own."""
        if name not in self._controllers:
            found = self._registered.get(name)
            self._controllers[name] = (found if isinstance(found, JointController)
                                       else self.controller)  # type: ignore[assignment]
        return self._controllers[name]

    def _track(self, configuration: Configuration, observation: Observation,
               drive_root: str | None) -> Control:
        """One tracking tick: IK from the last solution, then each node's controller
        (driven from a running behavior's ``drive_root``)."""
        tracker = self._tracker
        assert tracker is not None
        joint = tracker.step(configuration)
        by_controller: dict[str, set[str]] = {}
        for node in tracker.tree.nodes:
            by_controller.setdefault(node.controller, set()).update(node.edges)
        commands: dict[str, ModuleCommand] = {}
        for name, edges in by_controller.items():
            sent = self._controller_for(name).commands(joint, observation, yaw=0.0,
                                                       drive_root=drive_root)
            # an edge module (a strut) takes its commands under its own id; a connection
            # between two modules moves through its source's connector (FreeBOT, SnailBot)
            owners = edges | {joint.edge(e).source for e in edges}
            commands.update({m: c for m, c in sent.items() if m in owners})
        solution = tracker.last
        errors = {} if solution is None else {"ik_motion_cost": solution.motion_cost,
                                              "ik_residual": solution.rms_angle}
        return Control(commands=commands, errors=errors, reached=tracker.reached)

    # -- one tick ---------------------------------------------------------------------

    def _tick(self, index: int, action: Action, phase: Phase, diff: TopologyDiff) -> bool:
        """Run one control tick; whether the phase is finished."""
        raw = self.driver.get_observation()
        observation = self._filtered(raw)
        configuration = self._estimated(observation)
        self._detect_changes(index, configuration)
        if phase is Phase.BEHAVIOR and self._covered(action):
            return True  # its distance, as this observation shows it: nothing more to send
        if self._tracks(action) and phase is Phase.RELEASE:  # the controller's undocks only
            control = _undocks(self.controller.control(action, phase, observation))
        elif self._tracker is not None:
            self._redock(configuration)
            control = self._track(configuration, observation,
                                  action.behavior.drive_root if action.behavior else None)
        elif phase is Phase.BEHAVIOR:  # nothing holds the shape: the behavior's commands only
            control = Control()
        else:
            control = self.controller.control(action, phase, observation)
        extra: dict[str, ModuleCommand] = {}
        if phase in (Phase.RELEASE, Phase.HANDOVER):
            extra.update(_port_commands(diff.broken, "undock"))
        if phase in (Phase.CONNECT, Phase.HANDOVER):
            extra = _merge(Control(commands=extra), _port_commands(diff.made, "dock"))
        commands = _merge(control, extra)
        if phase is Phase.BEHAVIOR:
            commands = _with_wheels(commands, self._wheels(action, configuration))
        self.driver.send_action(commands)
        self.driver.step(self.dt)
        self.tick_index += 1  # executed: counted even if a listener is interrupted below
        self.sink.tick(self.run, Tick(self.tick_index - 1, self.driver.time, index, action,
                                      phase, raw, configuration, commands,
                                      control.errors))
        if control.stalled:
            raise _ActionFailed(f"action {index + 1} ({action}) failed: phase {phase.value} "
                                f"stalled: {control.stalled}")
        if phase in (Phase.APPROACH, Phase.MOVE, Phase.FLOW):
            return control.reached
        if phase is Phase.BEHAVIOR:
            return self._behavior_done(action)
        return not topology_diff(configuration, self._phase_goal(phase, diff))

    # -- goals and behaviors ------------------------------------------------------------

    def _behavior_done(self, action: Action) -> bool:
        """A mapping behavior ran its duration (its distance is checked on the next
        tick's observation: :meth:`_covered`)."""
        call = action.behavior
        return call is None or (call.duration is not None and
                                self.driver.time - self._phase_began >= call.duration - 1e-9)

    def _covered(self, action: Action) -> bool:
        """The running behavior moved the system its distance, as estimated now."""
        call = action.behavior
        return call is not None and call.distance is not None and self._moved() >= call.distance

    def _steered(self, action: Action) -> dict[str, float] | None:
        """The behavior's parameters, ``yaw_rate`` corrected by its heading loop (and the
        travel turned by its course loop: :func:`steered`)."""
        loop, call, heading = self._loop, action.behavior, self._heading(action)
        if loop is None or call is None or heading is None:
            return None
        return steered(call, loop, self._course, heading, self.estimate.position,
                       self.driver.time - self._phase_began, self.dt)

    def _wheels(self, action: Action, configuration: Configuration) -> dict[str, dict[str, float]]:
        """The behavior's wheel values for this tick (:func:`behavior_commands` of the
        steered parameters), corrected by a :class:`~msrr.core.control.WheelCorrector`
        controller from ``configuration``, recognized now."""
        wheels = behavior_commands(action, self._steered(action))
        if wheels and isinstance(self.controller, WheelCorrector):
            wheels = self.controller.correct_wheels(action, configuration, wheels)
        return wheels

    def _heading(self, action: Action) -> float | None:
        """The estimated heading [rad] of the body ``action`` holds (:func:`held_heading`)."""
        heading = self.estimate.heading
        if heading is None or self._current is None:
            return heading
        return held_heading(heading, self._current, action.target)

    def _gait_turn(self, index: int, action: Action, last: Action | None) -> float:
        """The turn [rad] the gait loop asks of ``action``, a step of a sequence behavior
        (:class:`GaitLoop`); 0 for any other action and for a behavior's first step. The
        loop starts before that first step, where the judge takes the commanded
        direction: the body's heading read on the shape the behavior starts from against
        the first step's target, in the frame the behavior's targets (and its
        ``direction``) share; later steps read it on the shape the last step reached
        against that step's target. Started after the first step instead, the loop took
        that step's turn (the squirm's first squirm-up, -5.6 deg exact, -7 to -8 deg under
        noise) for its reference and its course loop's line, never to be taken out."""
        call = action.behavior
        if call is None or call.kind != "sequence":
            self._gait = None
            return 0.0
        first = index in self._spans or last is None or last.behavior is None
        heading, frame = self.estimate.heading, 0.0
        if heading is not None and self._seen is not None:
            frame = skeletal_errors(self._seen, (action if first else last).target)[2]
            heading += frame
        if first:
            self._gait = gait_loop(call, heading, self.options)
            self._gait_course = None if self._gait is None else course_loop(
                call, self.estimate, frame, self.options, self.options.max_gait_course_offset)
            return 0.0
        if self._gait is None or heading is None:
            return 0.0
        place, course = self.estimate.position, self._gait_course
        offset = 0.0 if course is None or place is None else course.offset(place)
        step, angles, _ = skeletal_errors(last.target, action.target)   # stances of one
        return self._gait.turn(heading, offset,                         # shape: no bound
                               step if len(angles) and step > 0 else math.inf)

    def _frame(self, action: Action) -> float:
        """The turn [rad] of ``action``'s target onto the configuration recognized now
        (eq. 8), the frame a behavior's ``direction`` is stated in."""
        return 0.0 if self._current is None else skeletal_errors(self._current, action.target)[2]

    def _estimated(self, observation: Observation) -> Configuration:
        """The configuration ``observation`` shows; the estimate updated with both."""
        configuration = self._recognize(observation)
        self.estimate = self._estimator.update(observation, configuration)
        self._seen = configuration
        return configuration

    def _centre(self) -> np.ndarray | None:
        """Where the system is [m], shape (2,), as its sensors estimate it now."""
        return self.estimate.position

    def _moved(self) -> float:
        """Horizontal distance [m] the centre moved since the running behavior began."""
        now = self._centre()
        if self._moving_from is None or now is None:
            return 0.0
        return float(np.linalg.norm(now - self._moving_from))

    def _skips(self, index: int, action: Action) -> bool:
        """Whether ``action`` is in a loop of a sequence behavior left out because the
        behavior's distance was covered (checked when each loop begins)."""
        call = action.behavior
        if call is None or index in self._spans:
            self._skipping = False
            return False
        if self._skipping:
            return True
        before = self.run.plan.actions[index - 1].behavior
        if call.kind == "sequence" and call.distance is not None and before is not None \
                and before.loop != call.loop:
            self._estimated(self._observe())  # where the last loop ended
            self._skipping = self._covered(action)
        return self._skipping

    def _observe(self) -> Observation:
        """The driver's observation, filtered (:meth:`_filtered`)."""
        return self._filtered(self.driver.get_observation())

    def _filtered(self, observation: Observation) -> Observation:
        """``observation`` with its reports filtered over the run where the recognizer
        offers a filter (:func:`~msrr.core.estimation.report_filter_for`)."""
        return observation if self._filter is None else self._filter.update(observation)

    def _recognize(self, observation: Observation) -> Configuration:
        """The configuration the reports show (separate groups are the recognizer's)."""
        return self.recognizer.recognize(observation.sensors, seed=self.run.seed)

    def _detect_changes(self, index: int, configuration: Configuration) -> None:
        assert self._current is not None
        layout = link_layout(configuration)
        same = self._layout is not None and self._layout[0] is self._current \
            and self._layout[1] == layout
        self._layout = (configuration, layout)
        if same:             # the same links as the last tick's: nothing made or broken
            self._current = configuration
            return
        change = topology_diff(self._current, configuration)
        self._current = configuration
        unexpected: list[TopologyEvent] = []
        for kind, items in (("undock", change.broken), ("dock", change.made)):
            for c in items:
                key = c.key
                event = TopologyEvent(kind, c, self.tick_index, self.driver.time, index,
                                      key in self._expected)
                self.events.append(event)
                self.sink.topology_change(self.run, event)
                if not event.expected:
                    unexpected.append(event)
        if not unexpected:
            return
        first = unexpected[0]
        reason = f"action {index + 1}: unexpected {first} detected at t={first.time:.1f} s"
        if self._tracks(self.run.plan.actions[index]) and all(
                e.kind == "undock" and e.change.source_port in STRUT_ENDS for e in unexpected):
            raise _Broken(reason, tuple(e.change for e in unexpected), first.time)
        raise _ActionFailed(reason)
